//! What each transport would cost a scene, estimated before anything is built, so that
//! `--transport auto` picks by cost rather than by element count alone (issue 31: "choose the
//! transport and element budget by the cost they imply for the scene").
//!
//! A model, not a measurement of this machine: seconds of one thread on the 2-core machine
//! the constants were measured on (2026-12-07, `bake --threads 1 --refine off`, the paper's
//! cube and the Cornell box at 150–4 243 elements; process start-up subtracted). Only the
//! ratio of the two estimates decides anything, so a faster machine scales both alike.
//!
//! - **Dense**: every ordered element pair is integrated ([`DENSE_PAIR_S`] each, including the
//!   LU of up to three bands at these sizes), and where some polygon can come between two
//!   others, [`OCCLUDABLE_SHARE`] of them cast `--rays` shadow rays each ([`RAY_S`]).
//! - **Hierarchical**: time per element ([`LINKED_ELEMENT_S`], or [`OCCLUDED_ELEMENT_S`] with
//!   occluders: shadow rays per link) at `--max-error` 1e-2, times `(E / 1e-2)^-0.8` (links
//!   grow as the tolerance shrinks: measured 3e-2 … 1e-3).
//! - **Refinement**: a refining bake solves several meshes on the way to its budget; the
//!   estimate charges the final mesh [`DENSE_REFINE_FACTOR`] (pairs grow quadratically, so the
//!   earlier solves add about half) or [`HIERARCHICAL_REFINE_FACTOR`] (each solve links the
//!   scene again, the earlier ones on smaller meshes) times.
//!
//! Measured against the model (one thread, seconds; model in brackets): cube 600 elements
//! dense 0.16 (0.17), hierarchical 0.03 (0.03); 2 400: dense 2.75 (2.65), hierarchical 0.11
//! (0.11); Cornell box 920: dense 2.86 (2.97), hierarchical 0.79 (0.49); 1 934 at 1e-3:
//! hierarchical 7.1 (6.4).

use crate::TransportKind;

/// Seconds per ordered element pair of the dense transport (form factor by `auto`, the LU
/// included): cube, 1 176 and 2 400 elements, 0.46 µs and 0.48 µs.
pub const DENSE_PAIR_S: f64 = 0.46e-6;

/// Seconds per shadow ray (the Cornell box, 14 M and 54 M rays: 0.18 µs and 0.17 µs).
pub const RAY_S: f64 = 0.18e-6;

/// The share of ordered element pairs that cast shadow rays in a scene with occluders
/// (Cornell box: 115 729 occludable of 302 212 pairs tested, 920² ordered pairs: 0.14).
pub const OCCLUDABLE_SHARE: f64 = 0.14;

/// Seconds per element of the hierarchical transport at `--max-error` 1e-2 with nothing to
/// occlude (cube, 600–2 400 elements: 46–51 µs).
pub const LINKED_ELEMENT_S: f64 = 46e-6;

/// The same with occluders (shadow rays per link; Cornell box, 920–4 243 elements: 530–860
/// µs).
pub const OCCLUDED_ELEMENT_S: f64 = 530e-6;

/// How the hierarchy's time grows as `--max-error` E shrinks: `(E / 1e-2)^-LINK_EXPONENT`
/// (cube 2.2× and Cornell box 2.6× from 1e-2 to 3e-3, 3.3× and 6.9× to 1e-3).
pub const LINK_EXPONENT: f64 = 0.8;

/// A refining dense bake's time over its final solve's.
pub const DENSE_REFINE_FACTOR: f64 = 1.5;

/// A refining hierarchical bake's time over its final solve's.
pub const HIERARCHICAL_REFINE_FACTOR: f64 = 2.0;

/// Below this estimate the dense transport is taken even where the hierarchy would be
/// faster: its form factors are exact to rounding (no link error), and a user does not see a
/// tenth of a second.
pub const DENSE_AFFORDABLE_S: f64 = 0.1;

/// One transport's estimate for a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The elements of its final solve (the refinement budget, when it refines).
    pub elements: u64,
    /// Whether it refines on the way there.
    pub refines: bool,
    /// Estimated seconds of one thread (see the module docs).
    pub seconds: f64,
}

/// Both transports' estimates for one scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Costs {
    pub dense: Estimate,
    pub hierarchical: Estimate,
}

/// What the estimate needs of the request and the scene.
#[derive(Clone, Copy, Debug)]
pub struct Inputs {
    /// The elements of each transport's final solve, and whether it refines.
    pub dense_elements: u64,
    pub dense_refines: bool,
    pub hierarchical_elements: u64,
    pub hierarchical_refines: bool,
    /// Whether some polygon can come between two others.
    pub occluded: bool,
    /// `--rays` (dense transport's shadow rays per occludable pair).
    pub samples: u32,
    /// `--max-error`.
    pub max_error: f64,
}

impl Costs {
    pub fn estimate(inputs: &Inputs) -> Costs {
        let n = inputs.dense_elements as f64;
        let mut pair = DENSE_PAIR_S;
        if inputs.occluded {
            pair += OCCLUDABLE_SHARE * f64::from(inputs.samples) * RAY_S;
        }
        let dense = n * n * pair * refine_factor(inputs.dense_refines, DENSE_REFINE_FACTOR);
        let per_element = if inputs.occluded {
            OCCLUDED_ELEMENT_S
        } else {
            LINKED_ELEMENT_S
        };
        let tolerance = (inputs.max_error / 1e-2).max(f64::MIN_POSITIVE);
        let hierarchical = inputs.hierarchical_elements as f64
            * per_element
            * tolerance.powf(-LINK_EXPONENT)
            * refine_factor(inputs.hierarchical_refines, HIERARCHICAL_REFINE_FACTOR);
        Costs {
            dense: Estimate {
                elements: inputs.dense_elements,
                refines: inputs.dense_refines,
                seconds: dense,
            },
            hierarchical: Estimate {
                elements: inputs.hierarchical_elements,
                refines: inputs.hierarchical_refines,
                seconds: hierarchical,
            },
        }
    }

    /// The cheaper transport, the dense one where it is below [`DENSE_AFFORDABLE_S`].
    pub fn cheaper(&self) -> TransportKind {
        if self.dense.seconds <= self.hierarchical.seconds.max(DENSE_AFFORDABLE_S) {
            TransportKind::Dense
        } else {
            TransportKind::Hierarchical
        }
    }

    /// One line for the plan's reason: both estimates.
    pub fn describe(&self) -> String {
        let one = |name: &str, e: &Estimate| {
            format!(
                "{name} ~{} for {} elements{}",
                seconds(e.seconds),
                e.elements,
                if e.refines { " (refined)" } else { "" }
            )
        };
        format!(
            "estimated cost {}, {}",
            one("dense", &self.dense),
            one("hierarchical", &self.hierarchical)
        )
    }
}

fn refine_factor(refines: bool, factor: f64) -> f64 {
    if refines {
        factor
    } else {
        1.0
    }
}

fn seconds(s: f64) -> String {
    if s < 0.01 {
        format!("{:.1} ms", s * 1e3)
    } else if s < 100.0 {
        format!("{s:.2} s")
    } else {
        format!("{s:.0} s")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inputs(n: u64, occluded: bool, max_error: f64) -> Inputs {
        Inputs {
            dense_elements: n,
            dense_refines: false,
            hierarchical_elements: n,
            hierarchical_refines: false,
            occluded,
            samples: 121,
            max_error,
        }
    }

    /// The model reproduces the measurements it was fitted to, within 10% (cube) and 50%
    /// (Cornell box, whose hierarchy's time per element varies with the mesh).
    #[test]
    fn the_model_matches_its_measurements() {
        let near = |x: f64, y: f64, r: f64| (x / y - 1.0).abs() <= r;
        let cube = Costs::estimate(&inputs(2_400, false, 1e-2));
        assert!(near(cube.dense.seconds, 2.75, 0.1), "{cube:?}");
        assert!(near(cube.hierarchical.seconds, 0.11, 0.1), "{cube:?}");
        let cornell = Costs::estimate(&inputs(920, true, 1e-2));
        assert!(near(cornell.dense.seconds, 2.86, 0.1), "{cornell:?}");
        assert!(near(cornell.hierarchical.seconds, 0.79, 0.5), "{cornell:?}");
        let fine = Costs::estimate(&inputs(1_934, true, 1e-3));
        assert!(near(fine.hierarchical.seconds, 7.1, 0.15), "{fine:?}");
    }

    /// Tiny scenes stay dense (exact, affordable); the crossover moves up as the hierarchy's
    /// links get finer (smaller E), and down with occluders.
    #[test]
    fn the_crossover_follows_the_costs() {
        assert_eq!(
            Costs::estimate(&inputs(150, false, 1e-2)).cheaper(),
            TransportKind::Dense
        );
        assert_eq!(
            Costs::estimate(&inputs(1_176, false, 1e-2)).cheaper(),
            TransportKind::Hierarchical
        );
        assert_eq!(
            Costs::estimate(&inputs(1_176, false, 1e-5)).cheaper(),
            TransportKind::Dense
        );
        assert_eq!(
            Costs::estimate(&inputs(400, true, 1e-2)).cheaper(),
            TransportKind::Hierarchical
        );
        // Refining the dense transport to 2 000 elements costs more than refining the
        // hierarchy to 4 000 (the paper's cube at `--quality normal`).
        let refined = Costs::estimate(&Inputs {
            dense_elements: 2_000,
            dense_refines: true,
            hierarchical_elements: 4_000,
            hierarchical_refines: true,
            ..inputs(600, false, 1e-2)
        });
        assert_eq!(
            refined.cheaper(),
            TransportKind::Hierarchical,
            "{refined:?}"
        );
    }
}
