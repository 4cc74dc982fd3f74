//! `--quality draft|normal|high`: one knob for the accuracy–time trade. Each preset fixes the
//! element size (relative to the scene), the form-factor estimator and its tolerance (the
//! hierarchical transport's; the dense transport derives its own from `max_error`), the
//! target relative error of `b`, and the shadow rays per occludable pair; explicit options
//! override it. The values were chosen from the Pareto front measured by
//! `tools/accuracy-report` on the paper's cube and the Cornell box; `docs/accuracy.md` lists
//! each preset's error and time there.

use form_factor::Estimator;
use scene::Polygon;

/// The presets, from cheapest to most accurate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Quality {
    Draft,
    Normal,
    High,
}

impl Quality {
    pub const ALL: [Quality; 3] = [Quality::Draft, Quality::Normal, Quality::High];

    pub fn name(self) -> &'static str {
        match self {
            Quality::Draft => "draft",
            Quality::Normal => "normal",
            Quality::High => "high",
        }
    }

    /// The knob values of this preset.
    pub fn preset(self) -> Preset {
        match self {
            Quality::Draft => Preset {
                max_error: 1e-2,
                elements_per_diagonal: 8.0,
                estimator: Estimator::Auto { tolerance: 1e-2 },
                visibility_samples: 49,
                link_tolerance: 0.05,
                link_samples: 9,
                light_samples: 4,
            },
            Quality::Normal => Preset {
                max_error: 1e-3,
                elements_per_diagonal: 16.0,
                estimator: Estimator::Auto { tolerance: 1e-3 },
                visibility_samples: 121,
                link_tolerance: 0.01,
                link_samples: 25,
                light_samples: 16,
            },
            Quality::High => Preset {
                max_error: 1e-4,
                elements_per_diagonal: 32.0,
                estimator: Estimator::Auto { tolerance: 1e-4 },
                visibility_samples: 961,
                link_tolerance: 0.002,
                link_samples: 49,
                light_samples: 64,
            },
        }
    }
}

/// The knob values one preset sets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preset {
    /// Target relative error of `b` (`--max-error`): the dense transport's per-pair tolerance
    /// for `auto` is derived from it and the scene's largest reflectance
    /// ([`crate::accuracy::pair_tolerance`]).
    pub max_error: f64,
    /// Elements no longer than the scene's bounding-box diagonal divided by this.
    pub elements_per_diagonal: f64,
    /// Form-factor estimator (and its tolerance).
    pub estimator: Estimator,
    /// Shadow rays per element pair that a polygon may come between.
    pub visibility_samples: u32,
    /// Hierarchical transport: the largest estimated error of one link's contribution to its
    /// receiver, relative to the scene's mean radiosity (`--link-tolerance`).
    pub link_tolerance: f64,
    /// Hierarchical transport: shadow rays per link that a polygon may come between.
    pub link_samples: u32,
    /// Shadow rays per element a polygon may shadow from a point or spot light.
    pub light_samples: u32,
}

impl Preset {
    /// The largest element edge for `polygons` (world units).
    pub fn max_element_size(&self, polygons: &[Polygon]) -> f64 {
        mesher::max_element_size(polygons, self.elements_per_diagonal)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each preset is at least as fine as the one before it in every knob.
    #[test]
    fn presets_are_ordered_knob_by_knob() {
        let tolerance = |p: Preset| match p.estimator {
            Estimator::Auto { tolerance } => tolerance,
            Estimator::Contour => 0.0,
            _ => f64::INFINITY,
        };
        for pair in Quality::ALL.windows(2) {
            let (a, b) = (pair[0].preset(), pair[1].preset());
            assert!(a.max_error > b.max_error);
            assert!(a.elements_per_diagonal < b.elements_per_diagonal);
            assert!(tolerance(a) > tolerance(b));
            assert!(a.visibility_samples < b.visibility_samples);
            assert!(a.link_tolerance > b.link_tolerance);
            assert!(a.link_samples < b.link_samples);
            assert!(a.light_samples < b.light_samples);
        }
    }
}
