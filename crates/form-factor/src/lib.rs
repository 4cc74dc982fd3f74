//! Element-to-element form factors by the contour integral (Goral et al. 1984, eq. 13):
//!
//! ```text
//!   F_ij = 1/(2π A_i) ∮_{C_i} ∮_{C_j} [ln r dx_i dx_j + ln r dy_i dy_j + ln r dz_i dz_j]
//! ```
//!
//! F_ij is the fraction of the light leaving element i that reaches element j (eq. 12), so the
//! radiosity system reads `b_i = e_i + ρ_i Σ_j F_ij b_j`.
//!
//! Public API: [`FormFactors`] over an [`ElementMesh`]: a single pair ([`FormFactors::pair`]),
//! one row on demand ([`FormFactors::row`]), or every pair at once ([`FormFactors::dense`],
//! computing each unordered pair once and using reciprocity, eq. 14). Callers that cannot
//! afford an N×N matrix use rows or pairs; the dense matrix is one user of them.
//!
//! Invariants: F ≥ 0; `A_i F_ij = A_j F_ji` (the double contour integral is symmetric, and the
//! dense path computes it once per pair); `F_ii = 0` (a plane does not see itself, eq. 16);
//! back-facing and coplanar pairs are exactly 0; rows are never renormalised.

mod contour;
mod polygon;

pub use contour::{ContourOptions, MAX_ORDER};
use glam::DVec3;
use mesher::ElementMesh;
use polygon::Poly;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Normals with `n_i · n_j ≥ 1 − PARALLEL` count as parallel (angle ≤ 1.4e-7 rad). Two
/// elements tilted by θ see each other with F ~ 0.1 θ² at most (e.g. 0.078 θ² for unit squares
/// sharing an edge), so the pairs this culls have F ≲ 2e-15; rounding of normals from world
/// coordinates of magnitude X on polygons of size S is ~ε X / S rad (1e-9 at X / S = 1e7).
const PARALLEL: f64 = 1e-14;

/// How one pair was classified before integrating.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PairKind {
    /// The same element, parallel planes facing the same way (coplanar neighbours included),
    /// or either element lies wholly behind (or in) the other's plane.
    Culled,
    /// Both face each other wholly: the contour integral of the elements as they are.
    Facing,
    /// One element straddles the other's plane and was clipped to the part in front.
    Clipped,
}

/// Work counters of a form-factor computation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Unordered element pairs considered.
    pub pairs: u64,
    /// Pairs whose contour integral was evaluated (not culled).
    pub pairs_integrated: u64,
    /// Of those, pairs that needed clipping.
    pub pairs_clipped: u64,
    /// Kernel evaluations (ln r, or one closed-form segment integral).
    pub evaluations: u64,
}

/// Form factors between the elements of one mesh.
pub struct FormFactors<'a> {
    mesh: &'a ElementMesh,
    options: ContourOptions,
}

impl<'a> FormFactors<'a> {
    pub fn new(mesh: &'a ElementMesh, options: ContourOptions) -> Self {
        FormFactors { mesh, options }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.mesh.elements.len()
    }

    pub fn is_empty(&self) -> bool {
        self.mesh.elements.is_empty()
    }

    /// `A_i F_ij` (= `A_j F_ji`): the symmetric double contour integral over 2π.
    pub fn area_weighted(&self, i: usize, j: usize) -> (f64, PairKind, u64) {
        if i == j {
            return (0.0, PairKind::Culled, 0);
        }
        let (ni, nj) = (self.mesh.elements[i].normal, self.mesh.elements[j].normal);
        // Parallel planes facing the same way never see each other: each lies behind or in the
        // other's plane. Deciding it from the normals makes coplanar neighbours exactly 0 even
        // where their vertices are only known to the rounding of large world coordinates
        // (a scene far from the origin), which the clip tolerance below cannot resolve.
        if ni.dot(nj) >= 1.0 - PARALLEL {
            return (0.0, PairKind::Culled, 0);
        }
        let (pi, pj) = (self.poly(i), self.poly(j));
        // Work relative to the pair's own frame: origin between the centroids, unit = their
        // distance. ln r then stays near 0 and the result is independent of where the scene
        // sits and of its scale (the contour integral of a constant vanishes on closed loops).
        let (ci, cj) = (
            self.mesh.elements[i].centroid,
            self.mesh.elements[j].centroid,
        );
        let origin = (ci + cj) * 0.5;
        let unit = ci.distance(cj).max(pi.extent().max(pj.extent()) * 1e-3);
        let (pi, pj) = (pi.in_frame(origin, unit), pj.in_frame(origin, unit));
        // Clip each element to the half-space in front of the other (eq. 13 assumes both
        // surfaces see each other wholly). Tolerance relative to the pair's size.
        let tol = 1e-11 * (pi.extent().max(pj.extent())).max(1.0);
        let (ci_, clipped_i) = match pi.clip_front(pj.vertex(0), nj, tol) {
            Some(c) => c,
            None => return (0.0, PairKind::Culled, 0),
        };
        let (cj_, clipped_j) = match pj.clip_front(pi.vertex(0), ni, tol) {
            Some(c) => c,
            None => return (0.0, PairKind::Culled, 0),
        };
        let mut evaluations = 0;
        let mut sum = 0.0;
        for a in 0..ci_.len() {
            let (p0, p1) = (ci_.vertex(a), ci_.vertex((a + 1) % ci_.len()));
            for b in 0..cj_.len() {
                let (q0, q1) = (cj_.vertex(b), cj_.vertex((b + 1) % cj_.len()));
                sum += contour::edge_pair(p0, p1, q0, q1, &self.options, &mut evaluations);
            }
        }
        // Eq. 13 with both contours counter-clockwise about their own normals. Quadrature
        // noise can leave a tiny negative value for a pair that barely sees itself: F ≥ 0.
        let g = (sum / (2.0 * std::f64::consts::PI)).max(0.0) * unit * unit;
        let kind = if clipped_i || clipped_j {
            PairKind::Clipped
        } else {
            PairKind::Facing
        };
        (g, kind, evaluations)
    }

    /// `F_ij`: the fraction of the light leaving element i that reaches element j.
    pub fn pair(&self, i: usize, j: usize) -> f64 {
        self.area_weighted(i, j).0 / self.mesh.elements[i].area
    }

    /// Row i of F into `out` (length = number of elements), computed on demand.
    pub fn row(&self, i: usize, out: &mut [f64]) -> Stats {
        let mut stats = Stats::default();
        let area = self.mesh.elements[i].area;
        for (j, f) in out.iter_mut().enumerate() {
            let (g, kind, ev) = self.area_weighted(i, j);
            *f = g / area;
            stats.count(kind, ev);
        }
        stats
    }

    /// The whole matrix, row-major (`data[i * n + j] = F_ij`). Each unordered pair is
    /// integrated once, in parallel; F_ji follows by reciprocity (eq. 14). The result does not
    /// depend on the thread count (every entry is computed by the same sequential code).
    pub fn dense(&self) -> DenseFormFactors {
        self.dense_with_progress(&|_| {})
    }

    /// [`FormFactors::dense`], calling `progress(rows_done)` as rows finish (from any thread).
    pub fn dense_with_progress(&self, progress: &(dyn Fn(u64) + Sync)) -> DenseFormFactors {
        let n = self.len();
        let mut data = vec![0.0f64; n * n];
        let pairs_integrated = AtomicU64::new(0);
        let pairs_clipped = AtomicU64::new(0);
        let evaluations = AtomicU64::new(0);
        // Upper triangle: G_ij = A_i F_ij for j > i, each row by one task.
        data.par_chunks_mut(n.max(1))
            .enumerate()
            .for_each(|(i, row)| {
                let mut local = Stats::default();
                for (j, g) in row.iter_mut().enumerate().skip(i + 1) {
                    let (value, kind, ev) = self.area_weighted(i, j);
                    *g = value;
                    local.count(kind, ev);
                }
                pairs_integrated.fetch_add(local.pairs_integrated, Ordering::Relaxed);
                pairs_clipped.fetch_add(local.pairs_clipped, Ordering::Relaxed);
                evaluations.fetch_add(local.evaluations, Ordering::Relaxed);
                progress(1);
            });
        // Reciprocity: F_ij = G_ij / A_i and F_ji = G_ij / A_j.
        let areas: Vec<f64> = self.mesh.elements.iter().map(|e| e.area).collect();
        for i in 0..n {
            for j in i + 1..n {
                let g = data[i * n + j];
                data[i * n + j] = g / areas[i];
                data[j * n + i] = g / areas[j];
            }
        }
        let stats = Stats {
            pairs: (n as u64) * (n as u64).saturating_sub(1) / 2,
            pairs_integrated: pairs_integrated.into_inner(),
            pairs_clipped: pairs_clipped.into_inner(),
            evaluations: evaluations.into_inner(),
        };
        DenseFormFactors { n, data, stats }
    }

    fn poly(&self, i: usize) -> Poly {
        let e = &self.mesh.elements[i];
        Poly::from_points(
            e.corner_indices()
                .iter()
                .map(|&c| self.mesh.vertices[c as usize]),
        )
    }
}

impl Stats {
    fn count(&mut self, kind: PairKind, evaluations: u64) {
        self.pairs += 1;
        self.evaluations += evaluations;
        match kind {
            PairKind::Culled => {}
            PairKind::Facing => self.pairs_integrated += 1,
            PairKind::Clipped => {
                self.pairs_integrated += 1;
                self.pairs_clipped += 1;
            }
        }
    }
}

/// A dense form-factor matrix, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseFormFactors {
    pub n: usize,
    /// `data[i * n + j] = F_ij`.
    pub data: Vec<f64>,
    pub stats: Stats,
}

impl DenseFormFactors {
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.n + j]
    }

    pub fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.n..(i + 1) * self.n]
    }

    /// Σ_j F_ij for every row (1 for an element inside a closed enclosure, eq. 15).
    pub fn row_sums(&self) -> Vec<f64> {
        (0..self.n).map(|i| self.row(i).iter().sum()).collect()
    }
}

/// Exact form factor between two convex planar polygons given as vertex lists
/// (counter-clockwise about their normals): for tests and tools that check the integrator
/// outside a mesh.
pub fn polygon_pair(a: &[DVec3], b: &[DVec3], options: &ContourOptions) -> f64 {
    let mesh = polygon::two_element_mesh(a, b);
    FormFactors::new(&mesh, *options).pair(0, 1)
}

/// Bound on `|Σ_j F_ij − 1|` for an element inside a closed enclosure, with the default
/// [`ContourOptions`]: measured ≤ 4e-15 on the test scenes (the cube at subdivisions 1–8,
/// random sheared boxes, a furnace box with unequal elements) and stated with a wide margin,
/// since 1:10⁴ strips and grazing pairs carry up to ~1e-7 relative error on their own (tiny)
/// values. The solver uses it to refuse
/// systems whose answer an error this size could change entirely (e.g. ρ = 1 everywhere).
pub const ROW_SUM_ACCURACY: f64 = 1e-9;
