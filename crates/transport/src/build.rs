//! [`build`]: one scene's transport operator, dense or hierarchical, from the same problem.
//!
//! Each kind is built in its own module (`dense` here, `hierarchical.rs` for the links); the
//! caller gets a [`Built`] and from then on asks the operator what it can do
//! ([`BuiltOperator::view`] for products, [`View::dense`] for LU, [`BuiltOperator::into_links`] for saving
//! links) instead of matching on the kind.

use crate::hierarchical::{HierarchicalOptions, HierarchicalStats, HierarchicalTransport};
use crate::{LinkError, LinkProgress, Transport};
use form_factor::{ContourOptions, Estimator, FormFactors, Occlusion, RowSumLimit};
use mesher::ElementMesh;
use rayon::prelude::*;
use scene::Polygon;
use solver::{DenseMatrix, Operator, SolveError, BANDS};
use visibility::Effects;
use visibility::Occluders;

/// Progress of a long stage, for a bar: the same three calls for every stage of a bake.
pub trait Progress: Sync {
    /// A stage of `total` steps (rows, polygons, iterations) begins; 0 when the number of
    /// steps is not known in advance.
    fn start(&self, stage: &str, total: u64);
    /// `steps` more steps are done.
    fn advance(&self, steps: u64);
    /// The stage is over.
    fn finish(&self);
}

/// What every transport is built from: the scene's polygons, their elements, the occluders,
/// and per element ρ and the source term (emission plus the lights' first reflection), which
/// the hierarchical transport's link refinement weighs links by.
#[derive(Clone, Copy)]
pub struct Problem<'a> {
    pub polygons: &'a [Polygon],
    pub mesh: &'a ElementMesh,
    pub occluders: &'a Occluders,
    pub rho: &'a [[f64; BANDS]],
    pub source: &'a [[f64; BANDS]],
}

/// Which transport to build, with its options.
#[derive(Clone, Debug)]
pub enum Options {
    /// Every element pair's form factor (Goral et al. 1984, eq. 13), rows past 1 scaled to 1.
    Dense(DenseOptions),
    /// Hierarchical radiosity (Hanrahan, Salzman & Aupperle 1991).
    Hierarchical(HierarchicalOptions),
}

/// The dense transport's options.
#[derive(Clone, Copy, Debug)]
pub struct DenseOptions {
    pub estimator: Estimator,
    pub contour: ContourOptions,
    /// Shadow rays per element pair some polygon may come between.
    pub samples: u32,
    /// Rows past `1 + margin` are named by [`RowSumLimit::beyond_margin`] (surfaces seen
    /// twice); every row past 1 is scaled to 1.
    pub row_sum_margin: f64,
}

/// A built transport and what building it did.
pub struct Built {
    pub operator: BuiltOperator,
    /// Which effects the scene called for (shadow rays or none) and why.
    pub effects: Effects,
    /// Per polygon: whether shadow rays decided part of its light (for the error estimate).
    pub sampled_polygons: Vec<bool>,
    /// Shadow rays per such pair (0 when none were cast).
    pub samples: u32,
    pub stats: Stats,
}

impl Built {
    /// The dense transport's row-sum limit (what geometry would have created); `None` for
    /// links.
    pub fn row_sums(&self) -> Option<&RowSumLimit> {
        match &self.stats {
            Stats::Dense { row_sums, .. } => Some(row_sums),
            Stats::Hierarchical(_) => None,
        }
    }
}

/// The work a transport did, in its own terms.
#[derive(Clone, Debug)]
pub enum Stats {
    /// The form-factor stage's counts and the row-sum limit (what geometry would have created).
    Dense {
        form_factors: form_factor::Stats,
        row_sums: RowSumLimit,
    },
    Hierarchical(HierarchicalStats),
}

/// The operator `F` as built.
pub enum BuiltOperator {
    /// Row-major `n × n` entries (`data[i * n + j] = F_ij`) and their row-sum accuracy.
    Dense {
        n: usize,
        data: Vec<f64>,
        accuracy: f64,
    },
    Hierarchical(Box<HierarchicalTransport>),
}

/// A [`BuiltOperator`] checked and ready for products.
#[derive(Clone, Copy)]
pub enum View<'a> {
    Dense(DenseMatrix<'a>),
    Hierarchical(&'a HierarchicalTransport),
}

impl BuiltOperator {
    /// The operator for products (checks a dense matrix's entries once: finite, n × n).
    pub fn view(&self) -> Result<View<'_>, SolveError> {
        Ok(match self {
            BuiltOperator::Dense { n, data, accuracy } => {
                View::Dense(DenseMatrix::new(*n, data)?.with_accuracy(*accuracy))
            }
            BuiltOperator::Hierarchical(h) => View::Hierarchical(h),
        })
    }

    /// The links, when the operator is made of them (what `--save-links` writes).
    pub fn into_links(self) -> Option<HierarchicalTransport> {
        match self {
            BuiltOperator::Hierarchical(h) => Some(*h),
            BuiltOperator::Dense { .. } => None,
        }
    }
}

impl<'a> View<'a> {
    /// Per element and band, `(Σ_j (F_ij b_j)²)^½`: what each pair (or link) delivers, in
    /// quadrature. The form factors' errors are each pair's own (relative, at most the
    /// estimator's stated accuracy, of either sign), so this times the accuracy is what a row
    /// may miss of `H_i = Σ_j F_ij b_j`, rather than the accuracy times `H_i` (every error of
    /// one sign).
    pub fn delivered_quadrature(&self, b: &[[f64; BANDS]]) -> Vec<[f64; BANDS]> {
        match self {
            View::Dense(f) => (0..f.n())
                .into_par_iter()
                .map(|i| {
                    let mut sum = [0.0; BANDS];
                    for (&fij, bj) in f.row(i).iter().zip(b) {
                        for (s, v) in sum.iter_mut().zip(bj) {
                            let d = fij * v;
                            *s += d * d;
                        }
                    }
                    sum.map(f64::sqrt)
                })
                .collect(),
            View::Hierarchical(h) => h.link_error(b).delivered,
        }
    }

    /// Per element and band, the irradiance error the links' models and shadow rays leave
    /// with radiosities `b` ([`HierarchicalTransport::link_error`]); `None` for the dense
    /// transport, whose every pair is integrated.
    pub fn link_error(&self, b: &[[f64; BANDS]]) -> Option<crate::LinkMisses> {
        match self {
            View::Dense(_) => None,
            View::Hierarchical(h) => Some(h.link_error(b)),
        }
    }

    /// The entries, when the operator has them (what a direct solve factorises).
    pub fn dense(self) -> Option<DenseMatrix<'a>> {
        match self {
            View::Dense(f) => Some(f),
            View::Hierarchical(_) => None,
        }
    }
}

impl solver::Operator for View<'_> {
    fn n(&self) -> usize {
        match self {
            View::Dense(f) => f.n(),
            View::Hierarchical(h) => h.n(),
        }
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        match self {
            View::Dense(f) => f.apply(x, y),
            View::Hierarchical(h) => h.apply(x, y),
        }
    }

    fn apply_bands(&self, x: &[[f64; BANDS]], y: &mut [[f64; BANDS]]) {
        match self {
            View::Dense(f) => f.apply_bands(x, y),
            View::Hierarchical(h) => h.apply_bands(x, y),
        }
    }

    fn accuracy(&self) -> f64 {
        match self {
            View::Dense(f) => f.accuracy(),
            View::Hierarchical(h) => h.accuracy(),
        }
    }

    fn rows_bounded(&self) -> bool {
        match self {
            View::Dense(f) => f.rows_bounded(),
            View::Hierarchical(h) => h.rows_bounded(),
        }
    }
}

impl Transport for View<'_> {}

/// Builds the transport `options` asks for. `progress` hears each long stage; `stage_done`
/// is called with a stage's name as it ends (`occludable_pairs`, `form_factors`; `links`),
/// for timings.
pub fn build(
    problem: &Problem,
    options: &Options,
    progress: &dyn Progress,
    stage_done: &mut dyn FnMut(&'static str),
) -> Result<Built, LinkError> {
    match options {
        Options::Dense(options) => Ok(dense(problem, options, progress, stage_done)),
        Options::Hierarchical(options) => {
            let built = links(problem, options, progress);
            stage_done("links");
            Ok(hierarchical(
                built?,
                problem.polygons.len(),
                options.samples,
                false,
            ))
        }
    }
}

/// Dense: every element pair, exact (or within the estimator's tolerance); rows past 1
/// (coincident or interpenetrating surfaces) are scaled to 1, reciprocity kept: geometry
/// never creates light.
fn dense(
    p: &Problem,
    options: &DenseOptions,
    progress: &dyn Progress,
    stage_done: &mut dyn FnMut(&'static str),
) -> Built {
    let n = p.mesh.elements.len();
    // The occlusion pre-pass (polygon pairs × candidate occluders) can take seconds.
    progress.start("occlusion", p.occluders.len() as u64);
    let occludable = p
        .occluders
        .occludable_pairs_with_progress(&|k| progress.advance(k));
    progress.finish();
    let effects = occludable.effects();
    let mut sampled_polygons = vec![false; p.polygons.len()];
    for &(a, b) in occludable.pairs() {
        for k in [a, b] {
            if let Some(s) = sampled_polygons.get_mut(k as usize) {
                *s = true;
            }
        }
    }
    stage_done("occludable_pairs");
    let mut form_factors =
        FormFactors::new(p.mesh, options.contour).with_estimator(options.estimator);
    if effects.occlusion {
        form_factors = form_factors.with_occlusion(Occlusion {
            occluders: p.occluders,
            pairs: &occludable,
            samples: options.samples,
        });
    }
    progress.start("form factors", n as u64);
    let mut matrix = form_factors.dense_with_progress(&|rows| progress.advance(rows));
    progress.finish();
    // Glass stops only 1 − t of the light that reaches it; what is behind it is seen too.
    let stopped: Vec<f64> = if p.occluders.has_transmission() {
        p.mesh
            .elements
            .iter()
            .map(|el| 1.0 - p.occluders.transmission(el.polygon as usize))
            .collect()
    } else {
        Vec::new()
    };
    let row_sums = matrix.limit_row_sums_stopped(options.row_sum_margin, &stopped);
    stage_done("form_factors");
    Built {
        operator: BuiltOperator::Dense {
            n,
            data: matrix.data,
            accuracy: options.estimator.row_sum_accuracy(),
        },
        effects,
        sampled_polygons,
        samples: options.samples,
        stats: Stats::Dense {
            form_factors: matrix.stats,
            row_sums,
        },
    }
}

/// Links between the coarsest node pairs that meet the link tolerance.
fn links(
    p: &Problem,
    options: &HierarchicalOptions,
    progress: &dyn Progress,
) -> Result<HierarchicalTransport, LinkError> {
    progress.start("links", p.polygons.len() as u64);
    let built = HierarchicalTransport::build(
        p.polygons,
        p.mesh,
        p.occluders,
        p.rho,
        p.source,
        options,
        &|step| match step {
            LinkProgress::Polygons(k) | LinkProgress::Links(k) => progress.advance(k),
            LinkProgress::Pass { pass, links } => {
                progress.finish();
                progress.start(&format!("links pass {pass}"), links);
            }
        },
    );
    progress.finish();
    built
}

/// A hierarchical transport's [`Built`], from links just built or `loaded` from a file (whose
/// visible fractions are those computed when they were saved), over `polygons` polygons, with
/// `samples` shadow rays per occludable link.
pub fn hierarchical(
    h: HierarchicalTransport,
    polygons: usize,
    samples: u32,
    loaded: bool,
) -> Built {
    let s = h.stats();
    let effects = Effects {
        occlusion: s.pairs_occludable > 0,
        reason: if loaded {
            "links loaded: their visible fractions are those computed when they were saved"
                .to_string()
        } else if s.pairs_occludable > 0 {
            format!(
                "{} of the {} node pairs tested may be partly hidden by another polygon: \
                 shadow rays were cast for them",
                s.pairs_occludable, s.pairs_tested
            )
        } else {
            format!(
                "no polygon can come between any of the {} node pairs tested: no rays are cast",
                s.pairs_tested
            )
        },
    };
    // The hierarchy keeps no per-polygon record: every polygon is charged.
    let occluded = s.pairs_occludable > 0;
    Built {
        sampled_polygons: vec![occluded; polygons],
        samples: if occluded { samples } else { 0 },
        effects,
        stats: Stats::Hierarchical(s),
        operator: BuiltOperator::Hierarchical(Box::new(h)),
    }
}
