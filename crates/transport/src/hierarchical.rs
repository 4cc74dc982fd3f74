//! Hierarchical radiosity (Hanrahan, Salzman & Aupperle 1991, "A rapid hierarchical radiosity
//! algorithm", SIGGRAPH '91).
//!
//! Each input polygon is the root of a tree whose leaves are its elements (the mesher's grid):
//! a quad's nu × nv grid is halved along its longer side until single elements remain (grids
//! need not be powers of two), a triangle's n × n split is cut into four similar triangles
//! while n is even and into its elements when n is odd. On a refined mesh
//! (`ElementMesh::refine`) a grid element that was split is the node over its four quarters,
//! recursively, so links can go below the grid's leaves where the mesh was refined. Light moves along *links* between two
//! nodes p and q, each carrying `G = A_p F_pq = A_q F_qp` (the form-factor crate's estimator on
//! the two node polygons, times a visible fraction from shadow rays where some polygon can come
//! between them), so the operator is exactly reciprocal and conserves energy.
//!
//! **Linking (BF refinement, HSA91 §4).** Linking starts from the polygon pairs that a descent
//! of a volume hierarchy over the polygons (`clusters`) leaves: a pair of disjoint clusters
//! whose sampled shadow rays are all blocked, and whose missed light is within the tolerance,
//! is dropped (re-tested in later passes with their radiosities), so sealed-off rooms cost no
//! polygon pairs; light-carrying links still join two polygon trees (cluster links are part 2
//! of the plan). A link is kept when the estimated error of its contribution to its receiver's
//! radiosity is at most `ε = link_tolerance × B̄` (B̄ the scene's area-weighted mean radiosity):
//!
//! ```text
//!   error at p  =  ρ_p · (B_q · (G · residual_p + G₀ · uncertainty) + ΔB_q · G · residual_q) / A_p
//!                                                                        (and p ↔ q)
//! ```
//!
//! with `residual` what a least-squares plane through the point-to-polygon kernel, sampled at
//! 9 points of a node, leaves over relative to its mean (`form_factor::SideScreen`; 0 for an
//! element, which receives its exact average and, as a source, is constant), G₀ the unoccluded
//! value and `uncertainty` 1 when some polygon can come between the nodes (a shadow boundary
//! may cross the pair, whatever its few shadow rays saw) or when a node straddles the other's
//! plane (only its front part receives light, but a link spreads it over all of the node), 0
//! otherwise. ΔB_q is how much B varies over the source (max − min over its elements, largest
//! band): the link delivers the source's mean and first moment exactly, so what the kernel's
//! residual over the source misses is that residual times the part of B that is not constant
//! (0 for an element, whose B is constant, as the dense transport assumes of every source).
//! An occludable pair that only this uncertainty would refine gets its shadow rays at once: if
//! every one of its n rays is blocked and the light they can have missed (uncertainty `3 / n`
//! by the rule of three) is within `FAINT × ε`, it is kept as a *blocked* link (value 0)
//! instead of being refined down to elements (a looser bound lost light one-sidedly: issue 31,
//! docs/accuracy.md); blocked links stay
//! in the link list (a later pass may refine them) but not in the operator.
//! Otherwise the larger node of the pair (by area) is split and its children are linked to the
//! other node recursively; leaf–leaf pairs are always kept. The integrator's own uncertainty
//! plays no part: the estimators are accurate to their tolerance.
//!
//! **Linear links.** A link carries, besides G, the fitted gradients of the kernel over both
//! nodes: the receiver's irradiance from the link is the plane `F_pq B̄_q + ∇_p F · (x − c_p)
//! B̄_q` (a first-order Taylor model instead of HSA91's constant), plus the source's linear
//! term `∇_q F · m_q / A_p`, with `m_q = ∫_q B (y − c_q) dy` the first moment of the source's
//! radiosity. Both terms have zero mean over the receiver and the same gradients serve both
//! directions, so reciprocity and energy are exact as with constant links (README: measured
//! errors against the dense transport and the continuous solution).
//!
//! **Shadow masks.** A link between coarse nodes carries the right total, but pushed down by
//! area it lights every element of its receiver alike, those a desk hides included (and their
//! reflection then reaches the desk's back face and leaves the scene). So, once linking is done,
//! every interior node with links that a polygon can come between (or that straddle the
//! other's plane) gets a mask (`masks`): each of its elements casts 25 shadow rays to points on
//! the node's partners over those links, chosen by their share of its light, and that light is
//! handed to the elements in proportion to `area × seen fraction` (the sum is unchanged), with
//! the node's radiosity as a source weighted alike, so the operator stays exactly reciprocal
//! and conserving. Measured against the dense transport (issue 31, docs/accuracy.md).
//!
//! **Passes.** B is not known before solving, so (as in HSA91) linking runs in passes: first
//! with `B = max(e, B̄₀)` (B̄₀ the furnace estimate `Σ A e / Σ A (1 − ρ)`), then, after a coarse solve, again over the
//! kept links with the solved B, until no link is refined (or [`HierarchicalOptions::passes`]
//! is reached). Links are never coarsened.
//!
//! **Gather and push–pull.** `y = F x` ([`solver::Operator`]): pull x up the trees
//! (area-weighted means and first moments), gather `g_p = Σ_links F_pq x_q` (and the linear
//! terms) at every node, push g down (each child receives its parent's plane at its own area
//! centroid, so the children's area-weighted mean is the parent's exactly). Sums run in a fixed order, so the result is
//! bit-identical for any thread count; refinement is deterministic too (each candidate's
//! shadow rays are seeded by its node pair, passes visit links in a fixed order).
//!
//! Code: this module builds the transport in passes (`HierarchicalTransport::build`); `trees`
//! makes the per-polygon trees, `culling` descends the cluster tree to the polygon pairs worth
//! linking, `linking` refines node pairs into links, `masks` makes the shadow masks,
//! `operator` assembles the entries and applies `F` with push–pull, `links_file` saves and
//! loads the links.

use form_factor::{
    screened_pair, surface_screen, ContourOptions, Estimator, Method, PairKind, PairScreen, Surface,
};
use glam::DVec3;
use mesher::ElementMesh;
use rayon::prelude::*;
use scene::Polygon;
use solver::{IterativeOptions, Operator, SolveError, BANDS};
use std::sync::atomic::{AtomicU64, Ordering};
use visibility::Occluders;
use visibility::{pair_seed, Patch};

use crate::clusters::{self, Clusters, Weights};

mod culling;
mod linking;
mod links_file;
mod masks;
mod operator;
mod trees;

use culling::*;
use linking::*;
pub use links_file::LinksFileError;
use masks::*;
use operator::*;
use trees::*;

/// Settings of [`HierarchicalTransport::build`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HierarchicalOptions {
    /// ε: the largest estimated error of one link's contribution to its receiver.
    pub link_tolerance: LinkTolerance,
    /// Shadow rays per link that a polygon can come between.
    pub samples: u32,
    /// The form-factor estimator for link values.
    pub estimator: Estimator,
    pub contour: ContourOptions,
    /// Most linking passes (the first with B = e).
    pub passes: u32,
    /// Refuse to keep more links than this (a memory guard: each link costs about
    /// [`BYTES_PER_LINK`] bytes).
    pub max_links: u64,
    /// Spread occludable links' light by shadow masks (module docs); off only to measure
    /// what they change.
    pub shadow_masks: bool,
}

/// How large one link's estimated error may be: ε of the module docs, at each pass from that
/// pass's mean radiosity B̄ and mean emission Ē (area-weighted, brightest band).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LinkTolerance {
    /// `ε = t × B̄` (`--link-tolerance t`).
    OfMeanRadiosity(f64),
    /// From the target relative error `E` of b (`--max-error`): each link's error reaches b
    /// through the solve, which amplifies light spread like the scene's own by
    /// `a = B̄ / Ē` (the furnace estimate in the first pass, each coarse solve's after it),
    /// so `ε = E × B̄ / a` keeps the amplified error of one link at `E × B̄`. `a` is taken
    /// no larger than [`MAX_AMPLIFICATION`]: near ρ = 1 a scene's measured amplification
    /// would ask for links no memory holds (a plan warns there, and prefers the dense
    /// transport where it fits). Issue 31, docs/accuracy.md.
    FromMaxError(f64),
}

/// The largest amplification [`LinkTolerance::FromMaxError`] divides ε by (ρ ≈ 0.98 in a
/// closed grey scene).
pub const MAX_AMPLIFICATION: f64 = 50.0;

impl LinkTolerance {
    /// ε for a pass whose mean radiosity is `mean_b` and mean emission `mean_e`.
    pub fn epsilon(self, mean_b: f64, mean_e: f64) -> f64 {
        match self {
            LinkTolerance::OfMeanRadiosity(t) => t * mean_b,
            LinkTolerance::FromMaxError(e) => {
                let amplification = if mean_e > 0.0 {
                    (mean_b / mean_e).clamp(1.0, MAX_AMPLIFICATION)
                } else {
                    MAX_AMPLIFICATION
                };
                e * mean_b / amplification
            }
        }
    }

    /// `ε / B̄` for a pass whose mean radiosity is `mean_b` and mean emission `mean_e` (the
    /// relative tolerance it amounts to there).
    pub fn relative(self, mean_b: f64, mean_e: f64) -> f64 {
        if mean_b > 0.0 {
            self.epsilon(mean_b, mean_e) / mean_b
        } else {
            match self {
                LinkTolerance::OfMeanRadiosity(t) => t,
                LinkTolerance::FromMaxError(e) => e / MAX_AMPLIFICATION,
            }
        }
    }
}

/// Memory per link in the link list (light-carrying and blocked alike, as the guard counts
/// them): measured by `tools/memory-per-link` as the slope of peak RSS over links, 234–237
/// bytes on the Cornell box (11 520 elements; 0.19 M → 2.5 M links, `--max-error` 1e-2 →
/// 1e-3), rounded up with a margin. The peak is a refinement pass: the 72-byte links of the
/// pass before, their refinements and the next list side by side; a light-carrying link's
/// two operator entries (44 bytes each) come after that peak.
pub const BYTES_PER_LINK: u64 = 256;

impl Default for HierarchicalOptions {
    fn default() -> Self {
        HierarchicalOptions {
            link_tolerance: LinkTolerance::OfMeanRadiosity(0.01),
            samples: 25,
            estimator: Estimator::Auto { tolerance: 1e-3 },
            contour: ContourOptions::default(),
            passes: 4,
            max_links: u64::MAX,
            shadow_masks: true,
        }
    }
}

/// How far [`HierarchicalTransport::build`] is, for a progress bar.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkProgress {
    /// Polygons of the first pass finished.
    Polygons(u64),
    /// Refinement pass `pass` (2, 3, …) begins over `links` kept links.
    Pass { pass: u32, links: u64 },
    /// Kept links of the current refinement pass re-examined.
    Links(u64),
}

/// What building the hierarchy did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HierarchicalStats {
    /// Nodes of all trees, leaves (= elements) included.
    pub nodes: u64,
    /// Links kept that carry light (in the operator).
    pub links: u64,
    /// Links kept whose every shadow ray was blocked: held while linking (a later pass may
    /// refine them), not in the operator.
    pub blocked_links: u64,
    /// Cluster pairs (of several polygons) dropped in the first pass because every shadow ray
    /// between them was blocked (`clusters`), counted again when a later pass re-tests one.
    pub clusters_dropped: u64,
    /// Polygon pairs the cluster descent left for linking (of P (P − 1) / 2).
    pub polygon_pairs: u64,
    /// Node pairs screened (clipped, kernel variation and a rough value), kept or refined;
    /// only kept links are integrated by the estimator (`by_method`).
    pub pairs_evaluated: u64,
    /// Node pairs facing each other whose occludability was tested.
    pub pairs_tested: u64,
    /// Of those, pairs some polygon may come between (shadow rays were cast).
    pub pairs_occludable: u64,
    /// Shadow rays cast, the masks' included.
    pub rays_cast: u64,
    /// Nodes whose occludable links' light is spread by a shadow mask, and the rays cast for
    /// their masks ([`masks`]).
    pub masked_nodes: u64,
    pub mask_rays: u64,
    pub kernel_evaluations: u64,
    /// Evaluated pairs by estimator: contour, point-to-polygon, point-to-point.
    pub by_method: [u64; 3],
    /// Linking passes run.
    pub passes: u32,
    /// The last pass's ε over its mean radiosity (the relative link tolerance it ran with),
    /// and its measured amplification `B̄ / Ē` (0 when nothing emits).
    pub relative_tolerance: f64,
    pub amplification: f64,
}

/// Why the hierarchy could not be built.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error(
        "the hierarchy needs more than {limit} links (about {gib:.1} GiB) at a link tolerance \
         of {tolerance:.1e} of the mean radiosity; raise --max-error (or --link-tolerance) or \
         use a larger --max-element-size"
    )]
    TooManyLinks {
        limit: u64,
        gib: f64,
        tolerance: f64,
    },
    #[error("polygon {0} has no elements in the mesh")]
    Mesh(usize),
    #[error("polygon {0}'s refined elements are not quarters of its grid's elements")]
    Refinement(usize),
    #[error("a coarse solve between linking passes failed: {0}")]
    Solve(#[from] SolveError),
}

/// The scene's light transport as links between nodes of per-polygon hierarchies.
pub struct HierarchicalTransport {
    /// Elements (leaves): nodes `0..n` are elements `0..n`.
    n: usize,
    nodes: Vec<Node>,
    children: Vec<u32>,
    entries: Entries,
    masks: Masks,
    accuracy: f64,
    stats: HierarchicalStats,
}

/// Work counters summed over threads.
#[derive(Default)]
struct Counters {
    pairs_evaluated: AtomicU64,
    pairs_tested: AtomicU64,
    pairs_occludable: AtomicU64,
    rays_cast: AtomicU64,
    kernel_evaluations: AtomicU64,
    by_method: [AtomicU64; 3],
    clusters_dropped: AtomicU64,
    polygon_pairs: AtomicU64,
}

impl HierarchicalTransport {
    /// Builds the trees over `mesh` (made from `polygons`), links every polygon pair by BF
    /// refinement in passes (coarse GMRES solves in between), and assembles the operator.
    /// `rho` and `e` are per element; `progress` hears as polygons of the first pass
    /// finish.
    pub fn build(
        polygons: &[Polygon],
        mesh: &ElementMesh,
        occluders: &Occluders,
        rho: &[[f64; BANDS]],
        e: &[[f64; BANDS]],
        options: &HierarchicalOptions,
        progress: &(dyn Fn(LinkProgress) + Sync),
    ) -> Result<HierarchicalTransport, LinkError> {
        let n = mesh.elements.len();
        let (nodes, children, roots) = build_trees(polygons, mesh)?;
        let counters = Counters::default();
        let node_rho = node_max(&nodes, &children, n, rho);
        let leaves = leaf_counts(&nodes, &children, n);

        // Pass 1: B̄ from the furnace estimate Σ A e / Σ A (1 − ρ) (a closed grey scene's mean
        // radiosity), and B = max(e, B̄) (below).
        let (mut emitted, mut absorbing, mut total_area) = (0.0, 0.0, 0.0);
        for (k, el) in mesh.elements.iter().enumerate() {
            emitted += el.area * max3(e[k]);
            absorbing += el.area * (1.0 - max3(rho[k])).max(1e-3);
            total_area += el.area;
        }
        let mean_e = emitted / f64::max(total_area, f64::MIN_POSITIVE);
        let mean_b = if absorbing > 0.0 {
            emitted / absorbing
        } else {
            0.0
        };
        // Non-emitters are assumed at the mean in the first pass, so that links between
        // them refine before any rays are cast for links that would not be kept; how B varies
        // over them is not known yet (0: the later passes refine where it matters).
        let first_b: Vec<f64> = e.iter().map(|v| max3(*v).max(mean_b)).collect();
        let (mut b_node, mut spread_node) = node_range(&nodes, &children, n, &first_b);
        let limit = options.max_links;
        let too_many = || LinkError::TooManyLinks {
            limit,
            gib: limit as f64 * BYTES_PER_LINK as f64 / (1u64 << 30) as f64,
            tolerance: options.link_tolerance.relative(mean_b, mean_e),
        };
        // Every pass links with the same trees and counters, its own B and ε.
        let base = Linker {
            nodes: &nodes,
            children: &children,
            occluders,
            options,
            rho: &node_rho,
            b: &[],
            spread: &[],
            leaves: &leaves,
            epsilon: 0.0,
            counters: &counters,
        };
        let linker = Linker {
            b: &b_node,
            spread: &spread_node,
            epsilon: options.link_tolerance.epsilon(mean_b, mean_e),
            ..base
        };
        let culling = Culling::new(&nodes, &roots, &leaves);
        let first = culling.initial(&linker, progress);
        if first.links.len() as u64 > limit {
            return Err(too_many());
        }
        let (mut links, mut dropped) = (first.links, first.dropped);
        let mut passes = 1;
        let mut last_mean = mean_b;
        let accuracy = options.estimator.row_sum_accuracy();
        let no_masks = Masks::none(nodes.len());
        while passes < options.passes {
            // A coarse solve with the current links, then re-examine them with its B.
            // Without masks: B only steers refinement.
            let entries = assemble(&nodes, &links, false);
            let op = View {
                n,
                nodes: &nodes,
                children: &children,
                entries: &entries,
                masks: &no_masks,
                accuracy,
            };
            // B steers refinement only: a percent is plenty, and no condition estimate.
            let coarse = IterativeOptions {
                tolerance: 1e-2,
                max_iterations: 500,
                condition: false,
                ..IterativeOptions::default()
            };
            let solution = solver::solve_iterative(&op, rho, e, &coarse)?;
            drop(entries);
            let solved: Vec<f64> = solution.b.iter().map(|v| max3(*v)).collect();
            (b_node, spread_node) = node_range(&nodes, &children, n, &solved);
            let mean = mesh
                .elements
                .iter()
                .zip(&solution.b)
                .map(|(el, b)| el.area * max3(*b))
                .sum::<f64>()
                / total_area.max(f64::MIN_POSITIVE);
            last_mean = mean;
            let linker = Linker {
                b: &b_node,
                spread: &spread_node,
                epsilon: options.link_tolerance.epsilon(mean, mean_e),
                ..base
            };
            progress(LinkProgress::Pass {
                pass: passes + 1,
                links: links.len() as u64,
            });
            // In chunks, so that progress is told once per chunk, not per link.
            let refined: Vec<Option<Vec<Link>>> = links
                .par_chunks(4096)
                .map(|chunk| {
                    let out: Vec<Option<Vec<Link>>> =
                        chunk.iter().map(|link| linker.refine_kept(link)).collect();
                    progress(LinkProgress::Links(chunk.len() as u64));
                    out
                })
                .collect::<Vec<_>>()
                .into_iter()
                .flatten()
                .collect();
            let revisited = culling.revisit(&linker, &dropped);
            dropped = revisited.dropped;
            passes += 1;
            if refined.iter().all(Option::is_none) && revisited.links.is_empty() {
                break;
            }
            let total: usize = refined
                .iter()
                .map(|r| r.as_ref().map_or(1, Vec::len))
                .sum::<usize>()
                + revisited.links.len();
            if total as u64 > limit {
                return Err(too_many());
            }
            let mut next = Vec::with_capacity(total);
            for (link, r) in links.iter().zip(refined) {
                match r {
                    Some(sub) => next.extend(sub),
                    None => next.push(*link),
                }
            }
            next.extend(revisited.links);
            links = next;
        }
        let entries = assemble(&nodes, &links, options.shadow_masks);
        let masks = Masks::build(&nodes, &children, n, &entries, occluders);
        let stats = HierarchicalStats {
            nodes: nodes.len() as u64,
            links: links.iter().filter(|l| l.g != 0.0).count() as u64,
            blocked_links: links.iter().filter(|l| l.g == 0.0).count() as u64,
            clusters_dropped: counters.clusters_dropped.load(Ordering::Relaxed),
            polygon_pairs: counters.polygon_pairs.load(Ordering::Relaxed),
            pairs_evaluated: counters.pairs_evaluated.load(Ordering::Relaxed),
            pairs_tested: counters.pairs_tested.load(Ordering::Relaxed),
            pairs_occludable: counters.pairs_occludable.load(Ordering::Relaxed),
            rays_cast: counters.rays_cast.load(Ordering::Relaxed) + masks.rays,
            masked_nodes: masks.node.len() as u64,
            mask_rays: masks.rays,
            kernel_evaluations: counters.kernel_evaluations.load(Ordering::Relaxed),
            by_method: [0, 1, 2].map(|k| counters.by_method[k].load(Ordering::Relaxed)),
            passes,
            relative_tolerance: options.link_tolerance.relative(last_mean, mean_e),
            amplification: if mean_e > 0.0 {
                last_mean / mean_e
            } else {
                0.0
            },
        };
        Ok(HierarchicalTransport {
            n,
            nodes,
            children,
            entries,
            masks,
            accuracy,
            stats,
        })
    }

    fn view(&self) -> View<'_> {
        View {
            n: self.n,
            nodes: &self.nodes,
            children: &self.children,
            entries: &self.entries,
            masks: &self.masks,
            accuracy: self.accuracy,
        }
    }

    /// Per element and band: estimates of the irradiance error its links leave with the
    /// radiosities `b` (per element), as [`LinkError`]:
    /// - `models`: what the links' linear models miss. Each link (through an ancestor or the
    ///   element itself) from source s misses up to `F (residual_r · B_s + residual_s · ΔB_s)`:
    ///   the terms of the linking criterion (module docs) without ρ, with B_s the mean and
    ///   ΔB_s the spread of `b` over s (the residuals are ranges, max − min, of the fit's
    ///   residual: at most twice the largest deviation). Measured against the exact matrix by
    ///   the test `link_error_bounds_the_coarse_links_irradiance_error` on a box: 96% of
    ///   element-bands bounded, median true/estimate 0.25 (their plain sum: 100%, 0.05; half
    ///   the ranges in quadrature: 82%, 0.50).
    /// - `visibility`: what the links' shadow rays leave, `F σ B_s` per link, σ the standard
    ///   deviation of its estimated visible fraction (`linking::visibility_sd`).
    /// - `delivered`: the links' deliveries `F B_s` in quadrature, which times the estimator's
    ///   relative accuracy is what the links' form factors may miss.
    ///
    /// The links' misses are of either sign and independent (each link's rays are seeded by
    /// its pair), so each is combined in quadrature. Times ρ they are the links' part of the
    /// error of b for one bounce; element–element links miss nothing of the kernel (it is
    /// integrated, not modelled) but may of visibility.
    pub fn link_error(&self, b: &[[f64; BANDS]]) -> LinkMisses {
        let total = self.nodes.len();
        // Per node and band: the area-weighted mean of b (what a link sends) and its spread.
        let mut mean = vec![[0.0; BANDS]; total];
        mean[..self.n].copy_from_slice(&b[..self.n]);
        for u in self.n..total {
            let node = &self.nodes[u];
            let mut sum = [0.0; BANDS];
            for &c in &self.children[node.first as usize..(node.first + node.count) as usize] {
                let area = self.nodes[c as usize].surface.area;
                for (v, m) in sum.iter_mut().zip(mean[c as usize]) {
                    *v += area * m;
                }
            }
            mean[u] = sum.map(|v| v / node.surface.area);
        }
        let spreads: Vec<Vec<f64>> = (0..BANDS)
            .map(|c| {
                let values: Vec<f64> = b.iter().map(|v| v[c]).collect();
                node_range(&self.nodes, &self.children, self.n, &values).1
            })
            .collect();
        let e = &self.entries;
        // Per node: the sums of squares of the models' misses, the visibility's, and the
        // deliveries.
        let mut error: Vec<[[f64; BANDS]; 3]> = (0..total)
            .into_par_iter()
            .map(|r| {
                let mut sum = [[0.0; BANDS]; 3];
                for k in e.offsets[r] as usize..e.offsets[r + 1] as usize {
                    let [over_r, over_s, deviation] = e.residuals[k].map(f64::from);
                    let (s, f) = (e.sources[k] as usize, e.coefficients[k]);
                    for (c, spread) in spreads.iter().enumerate() {
                        // In quadrature (above): squares here, the roots at the leaves.
                        let miss = f * (over_r * mean[s][c] + over_s * spread[s]);
                        sum[0][c] += miss * miss;
                        let noise = f * deviation * mean[s][c];
                        sum[1][c] += noise * noise;
                        let delivered = f * mean[s][c];
                        sum[2][c] += delivered * delivered;
                    }
                }
                sum
            })
            .collect();
        // Down the trees: parents (created after their children) first.
        for u in (self.n..total).rev() {
            let node = &self.nodes[u];
            let above = error[u];
            for &c in &self.children[node.first as usize..(node.first + node.count) as usize] {
                for (v, a) in error[c as usize].iter_mut().zip(above) {
                    for (x, y) in v.iter_mut().zip(a) {
                        *x += y;
                    }
                }
            }
        }
        error.truncate(self.n);
        let root = |kind: usize| -> Vec<[f64; BANDS]> {
            error.iter().map(|v| v[kind].map(f64::sqrt)).collect()
        };
        LinkMisses {
            models: root(0),
            visibility: root(1),
            delivered: root(2),
        }
    }

    /// What building it did.
    pub fn stats(&self) -> HierarchicalStats {
        self.stats
    }
}

/// Per element and band, the irradiance a hierarchical transport's links miss
/// ([`HierarchicalTransport::link_error`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinkMisses {
    /// What the links' linear models of the kernel miss.
    pub models: Vec<[f64; BANDS]>,
    /// What the links' shadow rays leave (one standard deviation).
    pub visibility: Vec<[f64; BANDS]>,
    /// The links' deliveries `F B_s` in quadrature ([`View::delivered_quadrature`]).
    pub delivered: Vec<[f64; BANDS]>,
}

impl Operator for HierarchicalTransport {
    fn n(&self) -> usize {
        self.n
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.view().apply(x, y);
    }

    fn apply_bands(&self, x: &[[f64; BANDS]], y: &mut [[f64; BANDS]]) {
        self.view().apply_bands(x, y);
    }

    fn accuracy(&self) -> f64 {
        self.accuracy
    }

    /// Elements get their ancestors' link averages: single rows may exceed 1 by the links'
    /// receiver error (area-weighted sums are exact), which is not integration error.
    fn rows_bounded(&self) -> bool {
        false
    }
}

impl crate::Transport for HierarchicalTransport {}
