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

mod links_file;
pub use links_file::LinksFileError;

/// Settings of [`HierarchicalTransport::build`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HierarchicalOptions {
    /// `ε / B̄`: the largest estimated error of one link's contribution to its receiver,
    /// relative to the scene's mean radiosity.
    pub link_tolerance: f64,
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
}

/// Memory per kept link: the link itself while refining (72 bytes) and two operator entries
/// (source index, coefficient and two gradients, 36 bytes each, plus offsets).
pub const BYTES_PER_LINK: u64 = 160;

impl Default for HierarchicalOptions {
    fn default() -> Self {
        HierarchicalOptions {
            link_tolerance: 0.01,
            samples: 25,
            estimator: Estimator::Auto { tolerance: 1e-3 },
            contour: ContourOptions::default(),
            passes: 4,
            max_links: u64::MAX,
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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
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
    pub rays_cast: u64,
    pub kernel_evaluations: u64,
    /// Evaluated pairs by estimator: contour, point-to-polygon, point-to-point.
    pub by_method: [u64; 3],
    /// Linking passes run.
    pub passes: u32,
}

/// Why the hierarchy could not be built.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error(
        "the hierarchy needs more than {limit} links (about {gib:.1} GiB) at --link-tolerance \
         {tolerance}; raise --link-tolerance or use a larger --max-element-size"
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

/// A node of a polygon's tree.
#[derive(Clone, Copy, Debug)]
struct Node {
    surface: Surface,
    polygon: u32,
    /// Children: `children[first..first + count]`; no children for a leaf.
    first: u32,
    count: u32,
}

/// Links whose whole unoccluded error contribution is below this × ε get one shadow ray.
const FAINT: f64 = 1.0 / 16.0;

/// The uncertainty of the visible fraction of a pair whose every one of `rays` shadow rays
/// was blocked: the open share the rays can have missed, by the "rule of three" (with n rays
/// all blocked, a visible share above 3/n would have been seen with 95% probability; the rays
/// are stratified, so the bound is conservative).
fn blocked_uncertainty(rays: u32) -> f64 {
    (3.0 / f64::from(rays.max(1))).min(1.0)
}

/// A kept link between nodes p and q.
#[derive(Clone, Copy, Debug)]
struct Link {
    p: u32,
    q: u32,
    /// `A_p F_pq`, visible part.
    g: f64,
    /// `G₀ · uncertainty` (the visibility's share of the BF criterion's error factor, the same
    /// for both receivers; the fit's share is computed from `g` and `residual`).
    k: f64,
    /// Whether some polygon can come between p and q (children must test again).
    occludable: bool,
    /// Unoccluded `A_p F_pq`, for recomputing `g` and `k` once the shadow rays are cast.
    g0: f64,
    /// Per node (p, then q): the relative variation of the kernel over it that the link
    /// cannot represent (the linear fit's residual; 0 for an element).
    residual: [f32; 2],
    /// Per receiver (p, then q): the gradient of the unoccluded point-to-node kernel over it
    /// (world units, in its plane), the linear part of what the link delivers.
    gradient: [[f32; 3]; 2],
    clipped: bool,
    /// Whether every shadow ray of the pair was blocked when it was screened (its visible
    /// fraction is 0 and no more rays are cast for it).
    blocked: bool,
    /// Whether `g` is the estimator's value with its visible fraction (only links that are
    /// kept are integrated and get rays; until then `g0` is the screen's rough value).
    final_value: bool,
}

/// The scene's light transport as links between nodes of per-polygon hierarchies.
pub struct HierarchicalTransport {
    /// Elements (leaves): nodes `0..n` are elements `0..n`.
    n: usize,
    nodes: Vec<Node>,
    children: Vec<u32>,
    entries: Entries,
    accuracy: f64,
    stats: HierarchicalStats,
}

/// Operator entries by receiver node: `sources[offsets[r]..offsets[r + 1]]` with the
/// coefficients `F_rs` in `coefficients`.
struct Entries {
    offsets: Vec<u64>,
    sources: Vec<u32>,
    coefficients: Vec<f64>,
    /// Per entry, the visible part of: `∇F_{dx→s}` over the receiver r (the linear part of
    /// the irradiance it delivers, pushed down as a linear function), and `∇F_{dy→r}` over
    /// the source s (dotted with the first moment of the source's radiosity and divided by
    /// `A_r`: the kernel's linear variation over the source, HSA91's constant source made
    /// linear). The same f32 values serve both directions of a link, so the operator stays
    /// exactly reciprocal.
    gradients: Vec<[[f32; 3]; 2]>,
}

/// The operator over borrowed trees and entries: the final transport and the coarse solves
/// between linking passes share it.
struct View<'a> {
    n: usize,
    nodes: &'a [Node],
    children: &'a [u32],
    entries: &'a Entries,
    accuracy: f64,
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

/// What the linking of one pass needs.
struct Linker<'a> {
    nodes: &'a [Node],
    children: &'a [u32],
    occluders: &'a Occluders,
    options: &'a HierarchicalOptions,
    /// Per node: max over bands of ρ, and of the current radiosity estimate.
    rho: &'a [f64],
    b: &'a [f64],
    /// Per node: how much that estimate varies over it (max − min over its elements).
    spread: &'a [f64],
    /// Per node: its elements (leaves), for deciding which pairs are worth a parallel task.
    leaves: &'a [u64],
    epsilon: f64,
    counters: &'a Counters,
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
        let (mut emitted, mut absorbing) = (0.0, 0.0);
        for (k, el) in mesh.elements.iter().enumerate() {
            emitted += el.area * max3(e[k]);
            absorbing += el.area * (1.0 - max3(rho[k])).max(1e-3);
        }
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
            tolerance: options.link_tolerance,
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
            epsilon: options.link_tolerance * mean_b,
            ..base
        };
        let culling = Culling::new(&nodes, &roots, &leaves);
        let first = culling.initial(&linker, progress);
        if first.links.len() as u64 > limit {
            return Err(too_many());
        }
        let (mut links, mut dropped) = (first.links, first.dropped);
        let total_area: f64 = mesh.elements.iter().map(|el| el.area).sum();
        let mut passes = 1;
        let accuracy = options.estimator.row_sum_accuracy();
        while passes < options.passes {
            // A coarse solve with the current links, then re-examine them with its B.
            let entries = assemble(&nodes, &links);
            let op = View {
                n,
                nodes: &nodes,
                children: &children,
                entries: &entries,
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
            let linker = Linker {
                b: &b_node,
                spread: &spread_node,
                epsilon: options.link_tolerance * mean,
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
        let stats = HierarchicalStats {
            nodes: nodes.len() as u64,
            links: links.iter().filter(|l| l.g != 0.0).count() as u64,
            blocked_links: links.iter().filter(|l| l.g == 0.0).count() as u64,
            clusters_dropped: counters.clusters_dropped.load(Ordering::Relaxed),
            polygon_pairs: counters.polygon_pairs.load(Ordering::Relaxed),
            pairs_evaluated: counters.pairs_evaluated.load(Ordering::Relaxed),
            pairs_tested: counters.pairs_tested.load(Ordering::Relaxed),
            pairs_occludable: counters.pairs_occludable.load(Ordering::Relaxed),
            rays_cast: counters.rays_cast.load(Ordering::Relaxed),
            kernel_evaluations: counters.kernel_evaluations.load(Ordering::Relaxed),
            by_method: [0, 1, 2].map(|k| counters.by_method[k].load(Ordering::Relaxed)),
            passes,
        };
        let entries = assemble(&nodes, &links);
        Ok(HierarchicalTransport {
            n,
            nodes,
            children,
            entries,
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
            accuracy: self.accuracy,
        }
    }

    /// What building it did.
    pub fn stats(&self) -> HierarchicalStats {
        self.stats
    }
}

impl View<'_> {
    /// `y = F x` for `B` bands at once (B = 1 or 3), the same bits per band either way.
    fn apply_generic<const B: usize>(&self, x: &[[f64; B]], y: &mut [[f64; B]]) {
        let total = self.nodes.len();
        // Pull: leaves are the elements; interior nodes (created after their children) are
        // area-weighted means of their children, with the first moment `∫ x (y − c) dy` of
        // the piecewise-constant x about the node's centroid c (0 for an element).
        let mut xn = vec![[0.0; B]; total];
        let mut moment = vec![[DVec3::ZERO; B]; total];
        xn[..self.n].copy_from_slice(&x[..self.n]);
        for u in self.n..total {
            let node = &self.nodes[u];
            let mut sum = [0.0; B];
            let mut m = [DVec3::ZERO; B];
            for &c in &self.children[node.first as usize..(node.first + node.count) as usize] {
                let child = &self.nodes[c as usize].surface;
                let offset = child.centroid - node.surface.centroid;
                for band in 0..B {
                    let power = child.area * xn[c as usize][band];
                    sum[band] += power;
                    m[band] += moment[c as usize][band] + offset * power;
                }
            }
            for band in 0..B {
                xn[u][band] = sum[band] / node.surface.area;
            }
            moment[u] = m;
        }
        // Gather over links, each receiver summed in its fixed entry order: the mean
        // irradiance over the node and its gradient (a linear function over the node).
        let mut g = vec![Delivered::<B>::default(); total];
        g.par_chunks_mut(1024).enumerate().for_each(|(chunk, out)| {
            for (k, gr) in out.iter_mut().enumerate() {
                let r = chunk * 1024 + k;
                let (lo, hi) = (
                    self.entries.offsets[r] as usize,
                    self.entries.offsets[r + 1] as usize,
                );
                let mut d = Delivered::<B>::default();
                // An element's irradiance gradient is never pushed further, and an element
                // as a source has no first moment: the common element–element entries
                // take the constant term alone.
                let receiver_is_leaf = r < self.n;
                let inverse_area = 1.0 / self.nodes[r].surface.area;
                for ((&s, &f), grad) in self.entries.sources[lo..hi]
                    .iter()
                    .zip(&self.entries.coefficients[lo..hi])
                    .zip(&self.entries.gradients[lo..hi])
                {
                    let s = s as usize;
                    let xs = &xn[s];
                    for (mean, x) in d.mean.iter_mut().zip(xs) {
                        *mean += f * x;
                    }
                    if s >= self.n {
                        let source = vec3(grad[1]) * inverse_area;
                        for (mean, m) in d.mean.iter_mut().zip(&moment[s]) {
                            *mean += source.dot(*m);
                        }
                    }
                    if !receiver_is_leaf {
                        let receiver = vec3(grad[0]);
                        for (gradient, x) in d.gradient.iter_mut().zip(xs) {
                            *gradient += receiver * *x;
                        }
                    }
                }
                *gr = d;
            }
        });
        // Push: parents before children (reverse creation order). A child receives the
        // parent's linear function averaged over itself, i.e. its value at the child's area
        // centroid; the children's area-weighted mean is the parent's mean exactly (their
        // centroids average to the parent's), so energy is unchanged.
        for u in (self.n..total).rev() {
            let node = self.nodes[u];
            let gu = g[u];
            for &c in &self.children[node.first as usize..(node.first + node.count) as usize] {
                let offset = self.nodes[c as usize].surface.centroid - node.surface.centroid;
                let gc = &mut g[c as usize];
                for band in 0..B {
                    gc.mean[band] += gu.mean[band] + gu.gradient[band].dot(offset);
                    gc.gradient[band] += gu.gradient[band];
                }
            }
        }
        for (yk, gk) in y[..self.n].iter_mut().zip(&g[..self.n]) {
            *yk = gk.mean;
        }
    }
}

fn vec3(v: [f32; 3]) -> DVec3 {
    DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
}

/// What the links deliver to one node: mean irradiance and its gradient per band.
#[derive(Clone, Copy, Debug)]
struct Delivered<const B: usize> {
    mean: [f64; B],
    gradient: [DVec3; B],
}

impl<const B: usize> Default for Delivered<B> {
    fn default() -> Self {
        Delivered {
            mean: [0.0; B],
            gradient: [DVec3::ZERO; B],
        }
    }
}

impl Operator for View<'_> {
    fn n(&self) -> usize {
        self.n
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let xs: Vec<[f64; 1]> = x.iter().map(|&v| [v]).collect();
        let mut ys = vec![[0.0; 1]; self.n];
        self.apply_generic(&xs, &mut ys);
        for (yi, v) in y.iter_mut().zip(ys) {
            *yi = v[0];
        }
    }

    fn apply_bands(&self, x: &[[f64; BANDS]], y: &mut [[f64; BANDS]]) {
        self.apply_generic(x, y);
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

impl Linker<'_> {
    /// Links nodes p and q (a candidate pair not yet evaluated): appends the kept links of
    /// the pair and, where it refines, of its children. `occludable`: whether the parent pair
    /// could be occluded (children of an unoccludable pair cannot be).
    fn link(&self, p: u32, q: u32, occludable: bool, out: &mut Vec<Link>) {
        let (np, nq) = (&self.nodes[p as usize], &self.nodes[q as usize]);
        if np.polygon == nq.polygon {
            return;
        }
        // An element's own variation does not matter: it receives the exact average over
        // itself, and as a source its radiosity is constant. (The screen is made here and
        // borrowed below: it holds the clipped pair, too large to move around per pair.)
        let Some(screen) = surface_screen(&np.surface, &nq.surface, [np.count > 0, nq.count > 0])
        else {
            return;
        };
        let link = self.evaluate(p, q, occludable, &screen);
        // Kept if it meets the tolerance or cannot be split, else its split is linked.
        match self.split(&link) {
            None => out.push(self.finalize(link, &screen)),
            Some(split) => self.link_split(&link, split, out),
        }
    }

    /// Links the children of the split node with the other node of `link`.
    fn link_split(
        &self,
        link: &Link,
        (parent, other, parent_is_p): (u32, u32, bool),
        out: &mut Vec<Link>,
    ) {
        let node = &self.nodes[parent as usize];
        let kids = &self.children[node.first as usize..(node.first + node.count) as usize];
        let pair = |c: u32| if parent_is_p { (c, other) } else { (other, c) };
        // A large pair (two big polygons facing each other) is worth parallel tasks: each
        // half into its own list, appended in order, so the links do not depend on threads.
        let work = self.leaves[parent as usize] * self.leaves[other as usize];
        if work > PARALLEL_ELEMENT_PAIRS && kids.len() >= 2 {
            let (first, rest) = kids.split_at(kids.len() / 2);
            let run = |part: &[u32], o: &mut Vec<Link>| {
                for &c in part {
                    let (a, b) = pair(c);
                    self.link(a, b, link.occludable, o);
                }
            };
            // The first half straight into `out`: only the second half's links are moved.
            let ((), mut y) = rayon::join(
                || run(first, out),
                || {
                    let mut o = Vec::new();
                    run(rest, &mut o);
                    o
                },
            );
            out.append(&mut y);
            return;
        }
        for &c in kids {
            let (a, b) = pair(c);
            self.link(a, b, link.occludable, out);
        }
    }

    /// `link` with its value from the form-factor estimator and, if it is occludable, its
    /// visible fraction from shadow rays (done once, when a link is first kept). Links whose
    /// whole unoccluded contribution is within a quarter of the tolerance get at most 9 rays,
    /// within [`FAINT`] of it one: their visibility hardly matters.
    fn finalize(&self, mut link: Link, screen: &PairScreen) -> Link {
        if link.final_value {
            return link;
        }
        let (np, nq) = (&self.nodes[link.p as usize], &self.nodes[link.q as usize]);
        let options = self.options;
        let c = self.counters;
        {
            let pair = screened_pair(
                screen,
                &np.surface,
                &nq.surface,
                &options.contour,
                options.estimator,
            );
            c.kernel_evaluations
                .fetch_add(pair.evaluations, Ordering::Relaxed);
            let method = match pair.method {
                Method::Contour => 0,
                Method::PointPolygon => 1,
                Method::PointPoint => 2,
            };
            c.by_method[method].fetch_add(1, Ordering::Relaxed);
            if link.blocked && link.g0 > 0.0 {
                // k was the screen's rough value times the rays' uncertainty.
                link.k *= pair.value / link.g0;
            }
            link.g0 = pair.value;
        }
        let mut fraction = 1.0;
        if link.blocked {
            fraction = 0.0;
        } else if link.occludable {
            let importance = (self.rho[link.p as usize] * self.b[link.q as usize]
                / np.surface.area)
                .max(self.rho[link.q as usize] * self.b[link.p as usize] / nq.surface.area)
                * link.g0;
            if importance < FAINT * self.epsilon {
                // A faint link (most pairs of distant rooms): one ray between the centroids,
                // lifted off both surfaces, decides all or nothing.
                let lift = self.occluders.ray_offset();
                let (a, b) = (np.surface, nq.surface);
                let blocked = self.occluders.segment_blocked(
                    a.centroid + a.normal * lift,
                    b.centroid + b.normal * lift,
                    [np.polygon as usize, nq.polygon as usize],
                );
                c.rays_cast.fetch_add(1, Ordering::Relaxed);
                fraction = if blocked { 0.0 } else { 1.0 };
            } else {
                let samples = if importance < 0.25 * self.epsilon {
                    options.samples.min(9)
                } else {
                    options.samples
                };
                let v = self.occluders.visibility(
                    &patch(np),
                    &patch(nq),
                    samples,
                    pair_seed(link.p as usize, link.q as usize),
                );
                c.rays_cast.fetch_add(u64::from(v.rays), Ordering::Relaxed);
                fraction = v.fraction;
            }
        }
        link.g = link.g0 * fraction;
        // Occludable: a shadow boundary may cross the pair even where every ray of the
        // sample arrived (a few rays per node miss small occluders).
        if !link.blocked {
            let uncertainty = if link.occludable || link.clipped {
                1.0
            } else {
                0.0
            };
            link.k = link.g0 * uncertainty;
        }
        link.final_value = true;
        link
    }

    /// A kept link re-examined with new radiosities: `None` if it stays, else its refinement.
    fn refine_kept(&self, link: &Link) -> Option<Vec<Link>> {
        let split = self.split(link)?;
        let mut out = Vec::new();
        self.link_split(link, split, &mut out);
        Some(out)
    }

    /// The BF error of a link between p and q of value `g`, visibility error factor `k` and
    /// kernel residuals `residual` (over p, over q): the larger over its two receivers r
    /// (source s) of `ρ_r (B_s (g residual_r + k) + ΔB_s g residual_s) / A_r`.
    fn error(&self, p: u32, q: u32, g: f64, k: f64, residual: [f32; 2]) -> f64 {
        let (p, q) = (p as usize, q as usize);
        let [rp, rq] = residual.map(f64::from);
        let at = |r: usize, s: usize, rr: f64, rs: f64| {
            self.rho[r] * (self.b[s] * (g * rr + k) + self.spread[s] * g * rs)
                / self.nodes[r].surface.area
        };
        at(p, q, rp, rq).max(at(q, p, rq, rp))
    }

    /// Whether both receivers' error is within ε.
    fn acceptable(&self, link: &Link) -> bool {
        let error = self.error(link.p, link.q, link.g, link.k, link.residual);
        error <= self.epsilon || error.is_nan()
    }

    /// Which node to split (HSA91: the larger), with the other and whether the split one is
    /// `p`; `None` when the link meets the tolerance or both ends are elements.
    fn split(&self, link: &Link) -> Option<(u32, u32, bool)> {
        let (np, nq) = (&self.nodes[link.p as usize], &self.nodes[link.q as usize]);
        if self.acceptable(link) {
            return None;
        }
        let (split_p, split_q) = (np.count > 0, nq.count > 0);
        match (split_p, split_q) {
            (false, false) => None,
            (true, false) => Some((link.p, link.q, true)),
            (false, true) => Some((link.q, link.p, false)),
            (true, true) if np.surface.area >= nq.surface.area => Some((link.p, link.q, true)),
            (true, true) => Some((link.q, link.p, false)),
        }
    }

    /// The pair's rough value, error factor and visibility from its `screen` (the pair can
    /// exchange light: [`Linker::link`] checked); occludable pairs that only visibility would
    /// refine get their shadow rays here and become blocked links when every ray is stopped.
    fn evaluate(&self, p: u32, q: u32, parent_occludable: bool, screen: &PairScreen) -> Link {
        let (np, nq) = (&self.nodes[p as usize], &self.nodes[q as usize]);
        let c = self.counters;
        c.pairs_evaluated.fetch_add(1, Ordering::Relaxed);
        // A node straddling the other's plane was clipped to its front part, but the link
        // pushes its light to all of the node: as uncertain as a shadow boundary.
        let clipped = screen.kind == PairKind::Clipped;
        let mut occludable = false;
        // A pair that would be kept even if it were fully uncertain gets rays without the
        // occludability test: the test would only save its few rays, and far pairs (most of
        // the polygon pairs of a large scene) are nearly always occludable.
        // For both receivers: what a linear model of the kernel misses over the receiver and over
        // the source (B may vary over the source as much as B itself: the conservative
        // assumption).
        let [sp, sq] = screen.sides;
        let residual = [sp.residual as f32, sq.residual as f32];
        let g = screen.rough;
        let worst = self.error(p, q, g, g, residual);
        if parent_occludable && worst <= self.epsilon {
            occludable = true;
        } else if parent_occludable {
            c.pairs_tested.fetch_add(1, Ordering::Relaxed);
            if self.occluders.can_occlude(&patch(np), &patch(nq)) {
                occludable = true;
                c.pairs_occludable.fetch_add(1, Ordering::Relaxed);
            }
        }
        // Until rays say otherwise (they are cast only if the link is kept), an occludable
        // link is fully visible and fully uncertain: the largest error it can have.
        let uncertainty = if clipped || occludable { 1.0 } else { 0.0 };
        let gradient = [sp.gradient, sq.gradient].map(|v| v.as_vec3().to_array());
        let mut link = Link {
            p,
            q,
            g,
            k: g * uncertainty,
            occludable,
            clipped,
            blocked: false,
            g0: g,
            residual,
            gradient,
            final_value: false,
        };
        // A pair that the uncertainty of its visibility alone would refine gets its shadow
        // rays now: when every ray is blocked (two rooms with a wall between them) its visible
        // fraction is 0 and what the rays can have missed is small, so it is kept as a
        // blocked link instead of being refined down to elements.
        if occludable
            && !clipped
            && !self.acceptable(&link)
            && self.error(p, q, g, 0.0, residual) <= self.epsilon
        {
            let v = self.occluders.visibility(
                &patch(np),
                &patch(nq),
                self.options.samples,
                pair_seed(p as usize, q as usize),
            );
            c.rays_cast.fetch_add(u64::from(v.rays), Ordering::Relaxed);
            // Kept at value 0 only when what the rays can have missed is negligible (within
            // FAINT × ε, as a faint link's single ray): a pair is kept blocked exactly when
            // all its rays are stopped, and refined (its children find the gaps) when one
            // arrives, so a blocked link's missed light is a one-sided loss, and within ε
            // per link it summed to 0.39% of the emitted power on a 2 × 2 office floor
            // (docs/accuracy.md). Otherwise the pair stays fully uncertain and refines.
            let k = g * blocked_uncertainty(v.rays);
            if v.fraction == 0.0
                && v.rays > 0
                && self.error(p, q, 0.0, k, residual) <= FAINT * self.epsilon
            {
                link.blocked = true;
                link.g = 0.0;
                link.k = k;
            }
        }
        link
    }
}

/// The cluster tree over the polygon roots and what its descent needs per pass.
struct Culling<'a> {
    clusters: Clusters,
    roots: &'a [u32],
    /// Per polygon: its root's surface and its index among the occluders.
    surfaces: Vec<Surface>,
    polygon: Vec<u32>,
    /// Per cluster: the elements of its polygons.
    elements: Vec<u64>,
}

/// A cluster pair dropped because every shadow ray between it was blocked, with the rays it
/// was tested with (into `a`, into `b`).
#[derive(Clone, Copy, Debug)]
struct Dropped {
    a: u32,
    b: u32,
    rays: [u32; 2],
}

/// What a descent produced.
#[derive(Default)]
struct Descent {
    links: Vec<Link>,
    dropped: Vec<Dropped>,
}

impl Descent {
    fn append(&mut self, mut other: Descent) {
        self.links.append(&mut other.links);
        self.dropped.append(&mut other.dropped);
    }
}

/// Runs `first` then `second` into `out`: in parallel (each into its own part, appended in
/// order, so the result does not depend on the thread count) when `parallel`.
fn both<F, G>(parallel: bool, out: &mut Descent, first: F, second: G)
where
    F: FnOnce(&mut Descent) + Send,
    G: FnOnce(&mut Descent) + Send,
{
    if parallel {
        // The first part straight into `out`: only the second part's links are moved.
        let ((), y) = rayon::join(
            || first(out),
            || {
                let mut o = Descent::default();
                second(&mut o);
                o
            },
        );
        out.append(y);
    } else {
        first(out);
        second(out);
    }
}

/// Cluster pairs with more polygons than this (product of the two counts) are descended in
/// parallel.
const PARALLEL_PAIRS: u64 = 4096;

/// Node pairs spanning more element pairs than this are refined in parallel tasks (a task
/// of this size takes milliseconds, far above rayon's cost per task; larger tasks would
/// move fewer links between lists but balance worse on two polygons).
const PARALLEL_ELEMENT_PAIRS: u64 = 1 << 16;

impl<'a> Culling<'a> {
    fn new(nodes: &[Node], roots: &'a [u32], leaves: &[u64]) -> Culling<'a> {
        let surfaces: Vec<Surface> = roots.iter().map(|&r| nodes[r as usize].surface).collect();
        let polygon = roots.iter().map(|&r| nodes[r as usize].polygon).collect();
        let clusters = Clusters::new(&surfaces);
        let elements = clusters
            .nodes
            .iter()
            .map(|c| {
                clusters.order[c.first as usize..(c.first + c.count) as usize]
                    .iter()
                    .map(|&k| leaves[roots[k as usize] as usize])
                    .sum()
            })
            .collect();
        Culling {
            clusters,
            roots,
            surfaces,
            polygon,
            elements,
        }
    }

    fn weights(&self, linker: &Linker) -> Weights {
        let b: Vec<f64> = self.roots.iter().map(|&r| linker.b[r as usize]).collect();
        let rho: Vec<f64> = self.roots.iter().map(|&r| linker.rho[r as usize]).collect();
        Weights::new(&self.clusters, &self.surfaces, &b, &rho)
    }

    /// Whether every ray of the pair (`rays` per direction) is blocked.
    fn blocked(&self, linker: &Linker, weights: &Weights, a: u32, b: u32, rays: [u32; 2]) -> bool {
        for (k, (receiver, source)) in [(a, b), (b, a)].into_iter().enumerate() {
            if rays[k] == 0 {
                continue;
            }
            let (blocked, cast) = clusters::all_blocked(
                &self.clusters,
                weights,
                &self.surfaces,
                &self.polygon,
                linker.occluders,
                receiver,
                source,
                rays[k],
                k as u64,
            );
            linker
                .counters
                .rays_cast
                .fetch_add(u64::from(cast), Ordering::Relaxed);
            if !blocked {
                return false;
            }
        }
        true
    }

    /// Links cluster `a` with cluster `b` (`a == b`: the cluster with itself) into `out`.
    fn descend(
        &self,
        linker: &Linker,
        weights: &Weights,
        a: u32,
        b: u32,
        progress: &(dyn Fn(LinkProgress) + Sync),
        out: &mut Descent,
    ) {
        let nodes = &self.clusters.nodes;
        let (ca, cb) = (nodes[a as usize], nodes[b as usize]);
        let large = u64::from(ca.count) * u64::from(cb.count) > PARALLEL_PAIRS
            || self.elements[a as usize] * self.elements[b as usize] > PARALLEL_ELEMENT_PAIRS;
        if a == b {
            let Some([l, r]) = ca.children else {
                progress(LinkProgress::Polygons(1));
                return;
            };
            both(
                large,
                out,
                |o| {
                    self.descend(linker, weights, l, l, progress, o);
                    self.descend(linker, weights, r, r, progress, o);
                },
                |o| self.descend(linker, weights, l, r, progress, o),
            );
            return;
        }
        let Some((split, other)) = self.split(a, b) else {
            // Two polygons: linked as HSA91 links them.
            let order = &self.clusters.order;
            let (p, q) = (order[ca.first as usize], order[cb.first as usize]);
            let (p, q) = (p.min(q), p.max(q));
            linker
                .counters
                .polygon_pairs
                .fetch_add(1, Ordering::Relaxed);
            linker.link(
                self.roots[p as usize],
                self.roots[q as usize],
                true,
                &mut out.links,
            );
            return;
        };
        let distance = clusters::box_distance(&ca, &cb);
        if let Some(rays) = clusters::rays_needed(weights, a, b, distance, linker.epsilon) {
            if self.blocked(linker, weights, a, b, rays) {
                linker
                    .counters
                    .clusters_dropped
                    .fetch_add(1, Ordering::Relaxed);
                out.dropped.push(Dropped { a, b, rays });
                return;
            }
        }
        let [l, r] = split;
        both(
            large,
            out,
            |o| self.descend(linker, weights, l, other, progress, o),
            |o| self.descend(linker, weights, r, other, progress, o),
        );
    }

    /// Which cluster of a disjoint pair to split (the one with the larger box, of those with
    /// children) and the other; `None` for two single polygons.
    fn split(&self, a: u32, b: u32) -> Option<([u32; 2], u32)> {
        let (ca, cb) = (
            &self.clusters.nodes[a as usize],
            &self.clusters.nodes[b as usize],
        );
        match (ca.children, cb.children) {
            (None, None) => None,
            (Some(x), None) => Some((x, b)),
            (None, Some(y)) => Some((y, a)),
            (Some(x), Some(y)) => {
                if (ca.hi - ca.lo).length_squared() >= (cb.hi - cb.lo).length_squared() {
                    Some((x, b))
                } else {
                    Some((y, a))
                }
            }
        }
    }

    /// The first pass: the root cluster with itself.
    fn initial(&self, linker: &Linker, progress: &(dyn Fn(LinkProgress) + Sync)) -> Descent {
        let mut out = Descent::default();
        if !self.clusters.nodes.is_empty() {
            let weights = self.weights(linker);
            self.descend(linker, &weights, 0, 0, progress, &mut out);
        }
        out
    }

    /// A later pass: the dropped pairs whose missed light, with this pass's radiosities,
    /// needs more rays than they were tested with are tested again and, if a ray arrives,
    /// descended. Returns the pairs still dropped and the new links.
    fn revisit(&self, linker: &Linker, dropped: &[Dropped]) -> Descent {
        let weights = self.weights(linker);
        let nodes = &self.clusters.nodes;
        let none = |_: LinkProgress| {};
        let parts: Vec<Descent> = dropped
            .par_iter()
            .map(|d| {
                let (ca, cb) = (nodes[d.a as usize], nodes[d.b as usize]);
                let distance = clusters::box_distance(&ca, &cb);
                let mut out = Descent::default();
                match clusters::rays_needed(&weights, d.a, d.b, distance, linker.epsilon) {
                    Some(rays) if rays[0] <= d.rays[0] && rays[1] <= d.rays[1] => {
                        out.dropped.push(*d);
                    }
                    Some(rays) if self.blocked(linker, &weights, d.a, d.b, rays) => {
                        out.dropped.push(Dropped { rays, ..*d });
                    }
                    _ => {
                        // Only pairs with a cluster of several polygons are dropped.
                        if let Some((split, other)) = self.split(d.a, d.b) {
                            for c in split {
                                self.descend(linker, &weights, c, other, &none, &mut out);
                            }
                        }
                    }
                }
                out
            })
            .collect();
        let mut out = Descent::default();
        for p in parts {
            out.append(p);
        }
        out
    }
}

fn patch(node: &Node) -> Patch {
    let s = &node.surface;
    // Sides are 3 or 4 by construction.
    Patch::new(s.corners(), s.normal, node.polygon as usize)
        .unwrap_or_else(|| unreachable!("hierarchy nodes are triangles or quads"))
}

fn max3(v: [f64; BANDS]) -> f64 {
    v[0].max(v[1]).max(v[2])
}

/// Per node: the largest of `values` (one per element) over its elements, and that maximum
/// minus the smallest.
fn node_range(nodes: &[Node], children: &[u32], n: usize, values: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut hi = vec![0.0; nodes.len()];
    let mut lo = vec![0.0; nodes.len()];
    hi[..n].copy_from_slice(&values[..n]);
    lo[..n].copy_from_slice(&values[..n]);
    for u in n..nodes.len() {
        let node = &nodes[u];
        let (mut h, mut l) = (f64::NEG_INFINITY, f64::INFINITY);
        for &c in &children[node.first as usize..(node.first + node.count) as usize] {
            h = h.max(hi[c as usize]);
            l = l.min(lo[c as usize]);
        }
        (hi[u], lo[u]) = if h >= l { (h, l) } else { (0.0, 0.0) };
    }
    let spread = hi.iter().zip(&lo).map(|(h, l)| h - l).collect();
    (hi, spread)
}

/// Per node: how many elements (leaves) lie below it.
fn leaf_counts(nodes: &[Node], children: &[u32], n: usize) -> Vec<u64> {
    let mut out = vec![1u64; nodes.len()];
    for u in n..nodes.len() {
        let node = &nodes[u];
        out[u] = children[node.first as usize..(node.first + node.count) as usize]
            .iter()
            .map(|&c| out[c as usize])
            .sum();
    }
    out
}

/// Per node: the largest band of `values` (per element), maxed over each node's leaves.
fn node_max(nodes: &[Node], children: &[u32], n: usize, values: &[[f64; BANDS]]) -> Vec<f64> {
    let mut out = vec![0.0; nodes.len()];
    for (o, v) in out.iter_mut().zip(values).take(n) {
        *o = max3(*v);
    }
    for u in n..nodes.len() {
        let node = &nodes[u];
        let mut m = 0.0f64;
        for &c in &children[node.first as usize..(node.first + node.count) as usize] {
            m = m.max(out[c as usize]);
        }
        out[u] = m;
    }
    out
}

/// The operator's receiver-ordered entries from the links (both directions of each).
fn assemble(nodes: &[Node], links: &[Link]) -> Entries {
    let total = nodes.len();
    let mut counts = vec![0u64; total + 1];
    // Blocked links (every ray stopped) carry nothing: they stay in the link list, where a
    // later pass may refine them, but not in the operator.
    let links = || links.iter().filter(|l| l.g != 0.0);
    for l in links() {
        counts[l.p as usize + 1] += 1;
        counts[l.q as usize + 1] += 1;
    }
    for k in 0..total {
        counts[k + 1] += counts[k];
    }
    let offsets = counts;
    let entries = offsets[total] as usize;
    let mut fill: Vec<u64> = offsets[..total].to_vec();
    let mut sources = vec![0u32; entries];
    let mut coefficients = vec![0.0f64; entries];
    let mut gradients = vec![[[0.0f32; 3]; 2]; entries];
    for l in links() {
        // The gradient was fitted to the unoccluded kernel: scale it by the visible fraction.
        let visible = if l.g0 > 0.0 { (l.g / l.g0) as f32 } else { 0.0 };
        for (side, (r, s)) in [(l.p, l.q), (l.q, l.p)].into_iter().enumerate() {
            let k = fill[r as usize] as usize;
            let area = nodes[r as usize].surface.area;
            sources[k] = s;
            coefficients[k] = l.g / area;
            gradients[k] = [
                l.gradient[side].map(|v| v * visible),
                l.gradient[1 - side].map(|v| v * visible),
            ];
            fill[r as usize] += 1;
        }
    }
    Entries {
        offsets,
        sources,
        coefficients,
        gradients,
    }
}

/// Nodes, child lists and per-polygon roots.
type Trees = (Vec<Node>, Vec<u32>, Vec<u32>);

/// The trees: nodes (elements first, then interior nodes, each after its children), the
/// child lists, and each polygon's root.
fn build_trees(polygons: &[Polygon], mesh: &ElementMesh) -> Result<Trees, LinkError> {
    let n = mesh.elements.len();
    let mut nodes: Vec<Node> = (0..n)
        .map(|i| Node {
            surface: Surface::element(mesh, i),
            polygon: mesh.elements[i].polygon,
            first: 0,
            count: 0,
        })
        .collect();
    let mut children = Vec::new();
    let mut roots = Vec::with_capacity(polygons.len());
    for (k, (polygon, grid)) in polygons.iter().zip(&mesh.patches).enumerate() {
        if grid.elements.is_empty() {
            return Err(LinkError::Mesh(k));
        }
        let mut tree = Tree {
            mesh,
            nodes: &mut nodes,
            children: &mut children,
            polygon: k as u32,
            normal: polygon.normal,
            e0: grid.elements.start,
            v0: grid.vertices.start,
            cells: Vec::new(),
        };
        // A refined mesh: each grid element is its own subtree of quarters.
        if !mesh.levels.is_empty() {
            tree.refined_cells(grid.elements.clone())?;
        }
        let count = tree.cell_count(grid.elements.len() as u32);
        let root = if polygon.vertices.len() == 4 {
            // Row-major nu × nv grid: element k < nu of the first row starts at vertex k, the
            // first element of the second row at vertex nu + 1 (on a refined mesh: the first
            // quarter of grid element k starts at its corner 0).
            let nu = (0..count)
                .find(|&k| {
                    mesh.elements[tree.first_element(k) as usize].corners[0]
                        != grid.vertices.start + k
                })
                .unwrap_or(count);
            let nv = count / nu;
            let (lu, lv) = (
                polygon.vertices[0].distance(polygon.vertices[1]),
                polygon.vertices[0].distance(polygon.vertices[3]),
            );
            tree.quad(nu, [0, nu, 0, nv], lu / nu as f64, lv / nv as f64)
        } else {
            let side = (count as f64).sqrt().round() as u32;
            tree.up(side, 0, 0, side)
        };
        roots.push(root);
    }
    Ok((nodes, children, roots))
}

/// Builds one polygon's tree.
struct Tree<'a> {
    mesh: &'a ElementMesh,
    nodes: &'a mut Vec<Node>,
    children: &'a mut Vec<u32>,
    polygon: u32,
    normal: DVec3,
    e0: u32,
    v0: u32,
    /// On a refined mesh, per grid element (in grid order): its node (the element itself, or
    /// the root of the quarters it was split into) and its first element. Empty on the grids,
    /// where grid element k is element `e0 + k`.
    cells: Vec<(u32, u32)>,
}

impl Tree<'_> {
    /// How many grid elements the polygon has (`elements` on the grids).
    fn cell_count(&self, elements: u32) -> u32 {
        if self.cells.is_empty() {
            elements
        } else {
            self.cells.len() as u32
        }
    }

    /// The node of grid element k.
    fn cell(&self, k: u32) -> u32 {
        self.cells.get(k as usize).map_or(self.e0 + k, |c| c.0)
    }

    /// The first element of grid element k.
    fn first_element(&self, k: u32) -> u32 {
        self.cells.get(k as usize).map_or(self.e0 + k, |c| c.1)
    }

    /// The subtrees of a refined polygon's elements `range`: `ElementMesh::refine` keeps each
    /// element in place or replaces it by its four quarters (corner k of the parent is corner
    /// k of quarter k), so the elements are the grid's in order, each followed depth-first by
    /// its quarters, and their levels are enough to rebuild the splits.
    fn refined_cells(&mut self, range: std::ops::Range<u32>) -> Result<(), LinkError> {
        let mut at = range.start;
        while at < range.end {
            let first = at;
            let node = self.quarters(&mut at, range.end, 0)?;
            self.cells.push((node, first));
        }
        Ok(())
    }

    /// The node of the element, or split element, at `at` of level `depth`.
    fn quarters(&mut self, at: &mut u32, end: u32, depth: u8) -> Result<u32, LinkError> {
        let i = *at;
        let malformed = LinkError::Refinement(self.polygon as usize);
        if i >= end {
            return Err(malformed);
        }
        let level = self.mesh.level(i as usize);
        if level == depth {
            *at += 1;
            return Ok(i);
        }
        if level < depth || depth >= u8::MAX - 1 {
            return Err(malformed);
        }
        let sides = usize::from(self.mesh.elements[i as usize].sides);
        let mut kids = [0u32; 4];
        for kid in &mut kids {
            *kid = self.quarters(at, end, depth + 1)?;
        }
        // Corner k of the split element is corner k of its k-th quarter.
        let corners: Vec<DVec3> = (0..sides)
            .map(|k| self.nodes[kids[k] as usize].surface.corners[k])
            .collect();
        Ok(self.interior(&corners, &kids))
    }

    fn vertex(&self, k: u32) -> DVec3 {
        self.mesh.vertices[(self.v0 + k) as usize]
    }

    /// An interior node over `kids` with these corners (area = the children's sum).
    fn interior(&mut self, corners: &[DVec3], kids: &[u32]) -> u32 {
        let area: f64 = kids
            .iter()
            .map(|&c| self.nodes[c as usize].surface.area)
            .sum();
        let mut surface = Surface::new(corners, self.normal).unwrap_or_else(|| {
            // A sliver whose fan area rounds to 0: keep the children's area and centroid.
            let c = self.nodes[kids[0] as usize].surface;
            Surface { area, ..c }
        });
        surface.area = area;
        // The children's area-weighted centroid (equal to the corners' up to rounding), so that
        // pushing a linear function to the children keeps its mean exactly.
        surface.centroid = kids
            .iter()
            .map(|&c| {
                let s = &self.nodes[c as usize].surface;
                s.centroid * s.area
            })
            .sum::<DVec3>()
            / area;
        let first = self.children.len() as u32;
        self.children.extend_from_slice(kids);
        self.nodes.push(Node {
            surface,
            polygon: self.polygon,
            first,
            count: kids.len() as u32,
        });
        (self.nodes.len() - 1) as u32
    }

    /// Elements `[i0, i1) × [j0, j1)` of an nu-column quad grid, halved along the longer side
    /// (world lengths `du`, `dv` per column and row).
    fn quad(&mut self, nu: u32, [i0, i1, j0, j1]: [u32; 4], du: f64, dv: f64) -> u32 {
        if i1 - i0 == 1 && j1 - j0 == 1 {
            return self.cell(j0 * nu + i0);
        }
        let split_i =
            j1 - j0 == 1 || (i1 - i0 > 1 && (i1 - i0) as f64 * du >= (j1 - j0) as f64 * dv);
        let (a, b) = if split_i {
            let m = (i0 + i1) / 2;
            (
                self.quad(nu, [i0, m, j0, j1], du, dv),
                self.quad(nu, [m, i1, j0, j1], du, dv),
            )
        } else {
            let m = (j0 + j1) / 2;
            (
                self.quad(nu, [i0, i1, j0, m], du, dv),
                self.quad(nu, [i0, i1, m, j1], du, dv),
            )
        };
        let id = |i: u32, j: u32| j * (nu + 1) + i;
        let corners = [
            self.vertex(id(i0, j0)),
            self.vertex(id(i1, j0)),
            self.vertex(id(i1, j1)),
            self.vertex(id(i0, j1)),
        ];
        self.interior(&corners, &[a, b])
    }

    /// Vertex (i, k) of an n-split triangle grid (row k holds n − k + 1 vertices).
    fn tri_vertex(&self, n: u32, i: u32, k: u32) -> DVec3 {
        let row = k * (n + 1) - k * (k.saturating_sub(1)) / 2;
        // Σ_{k' < k} (n − k' + 1) = k (n + 1) − k (k − 1) / 2.
        self.vertex(row + i)
    }

    /// Element index of the upward (`down = false`) or downward triangle of cell (i, k).
    fn tri_element(&self, n: u32, i: u32, k: u32, down: bool) -> u32 {
        // Row k holds 2 (n − k) − 1 elements: Σ_{k' < k} = 2 n k − k².
        self.cell(2 * n * k - k * k + 2 * i + u32::from(down))
    }

    /// The upward triangle of side m with corner cell (i0, k0).
    fn up(&mut self, n: u32, i0: u32, k0: u32, m: u32) -> u32 {
        if m == 1 {
            return self.tri_element(n, i0, k0, false);
        }
        let kids = if m.is_multiple_of(2) {
            let h = m / 2;
            vec![
                self.up(n, i0, k0, h),
                self.up(n, i0 + h, k0, h),
                self.up(n, i0, k0 + h, h),
                self.down(n, i0, k0, h),
            ]
        } else {
            let mut kids = Vec::with_capacity((m * m) as usize);
            for r in 0..m {
                let k = k0 + r;
                for i in i0..i0 + (m - r) {
                    kids.push(self.tri_element(n, i, k, false));
                    if i + 1 < i0 + (m - r) {
                        kids.push(self.tri_element(n, i, k, true));
                    }
                }
            }
            kids
        };
        let corners = [
            self.tri_vertex(n, i0, k0),
            self.tri_vertex(n, i0 + m, k0),
            self.tri_vertex(n, i0, k0 + m),
        ];
        self.interior(&corners, &kids)
    }

    /// The downward triangle of side m with corners (i0 + m, k0), (i0 + m, k0 + m),
    /// (i0, k0 + m) in vertex coordinates.
    fn down(&mut self, n: u32, i0: u32, k0: u32, m: u32) -> u32 {
        if m == 1 {
            return self.tri_element(n, i0, k0, true);
        }
        let kids = if m.is_multiple_of(2) {
            let h = m / 2;
            vec![
                self.down(n, i0 + h, k0, h),
                self.down(n, i0, k0 + h, h),
                self.down(n, i0 + h, k0 + h, h),
                self.up(n, i0 + h, k0 + h, h),
            ]
        } else {
            let mut kids = Vec::with_capacity((m * m) as usize);
            for r in 0..m {
                let k = k0 + r;
                // r + 1 downward cells ending at column i0 + m − 1, r upward ones between.
                for i in (i0 + m - 1 - r)..(i0 + m) {
                    kids.push(self.tri_element(n, i, k, true));
                    if i + 1 < i0 + m {
                        kids.push(self.tri_element(n, i + 1, k, false));
                    }
                }
            }
            kids
        };
        let corners = [
            self.tri_vertex(n, i0 + m, k0),
            self.tri_vertex(n, i0 + m, k0 + m),
            self.tri_vertex(n, i0, k0 + m),
        ];
        self.interior(&corners, &kids)
    }
}
