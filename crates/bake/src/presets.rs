//! `--quality draft|normal|high`: one knob for the accuracy–time trade. Each preset fixes the
//! element size (relative to the scene), the form-factor estimator and its tolerance (the
//! hierarchical transport's; the dense transport derives its own from `max_error`), the
//! target relative error of `b` (from which the dense transport's per-pair tolerance, the
//! hierarchical transport's link tolerance and its solve's tolerance are derived), what
//! refinement splits for, and the shadow rays per occludable pair; explicit options override
//! it. The values were chosen from the Pareto front measured by `tools/accuracy-report` on the
//! paper's cube, the Cornell box, the sun floor and `small_room.obj`; `docs/accuracy.md` lists
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
                max_error: 3e-2,
                refine_target: 1e-2,
                refine_smooth: false,
                elements_per_diagonal: 8.0,
                estimator: Estimator::Auto { tolerance: 1e-2 },
                visibility_samples: 49,
                link_samples: 9,
                light_samples: 4,
                sky_samples: 256,
            },
            Quality::Normal => Preset {
                max_error: 1e-2,
                refine_target: 1e-3,
                refine_smooth: true,
                elements_per_diagonal: 16.0,
                estimator: Estimator::Auto { tolerance: 1e-3 },
                visibility_samples: 121,
                link_samples: 25,
                light_samples: 16,
                sky_samples: 1024,
            },
            Quality::High => Preset {
                max_error: 3e-3,
                refine_target: 1e-4,
                refine_smooth: true,
                elements_per_diagonal: 32.0,
                estimator: Estimator::Auto { tolerance: 1e-4 },
                visibility_samples: 961,
                link_samples: 49,
                light_samples: 64,
                sky_samples: 4096,
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
    /// What refinement splits for: an element whose discretisation estimate passes this times
    /// the mean radiosity (`--max-error` sets both). A third to a hundredth of `max_error`: the
    /// estimate (b against the plane through its neighbours) runs well below the error the
    /// displayed field has, and refining to it was measured to beat a uniformly finer grid at
    /// equal time on the cube, the Cornell box and `small_room.obj` (issue 31,
    /// docs/accuracy.md); these are the values the presets refined to before the transport's
    /// tolerances were derived from `max_error`.
    pub refine_target: f64,
    /// Whether refinement splits for the discretisation estimate too, or only where a light's
    /// shadow edge crosses an element (`--refine on`, `--max-error` or `--max-elements` ask for
    /// both). `draft` is one solve on its grid plus shadow edges: on the paper's cube its
    /// dense refinement 150 → 459 elements cost 13× the time for less than a uniform grid of
    /// as many elements gives (issue 31, docs/accuracy.md).
    pub refine_smooth: bool,
    /// Elements no longer than the scene's bounding-box diagonal divided by this.
    pub elements_per_diagonal: f64,
    /// Form-factor estimator (and its tolerance).
    pub estimator: Estimator,
    /// Shadow rays per element pair that a polygon may come between.
    pub visibility_samples: u32,
    /// Hierarchical transport: shadow rays per link that a polygon may come between.
    pub link_samples: u32,
    /// Shadow rays per element a polygon may shadow from a point or spot light.
    pub light_samples: u32,
    /// Rays per element a polygon may block from the sky (`--sky-samples`; measured on the
    /// black-walled courtyard at 0.5 m elements: 256 / 1024 / 4096 rays give 2.0% / 0.56% /
    /// 0.21% RMS against the closed form, and a windowed room's daylight factors 3.4% / 1.5%
    /// / 0.89%, see [`direct::sky::DEFAULT_SKY_SAMPLES`]).
    pub sky_samples: u32,
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
            assert!(a.refine_target > b.refine_target);
            assert!(a.refine_smooth <= b.refine_smooth);
            assert!(b.refine_target <= b.max_error / 5.0);
            assert!(a.elements_per_diagonal < b.elements_per_diagonal);
            assert!(tolerance(a) > tolerance(b));
            assert!(a.visibility_samples < b.visibility_samples);
            assert!(a.link_samples < b.link_samples);
            assert!(a.light_samples < b.light_samples);
            assert!(a.sky_samples < b.sky_samples);
        }
    }
}
