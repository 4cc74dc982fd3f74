//! Occlusion for form factors: which element pairs can be hidden from each other at all, and
//! for those, the visible fraction estimated with shadow rays.
//!
//! The contour integral (Goral et al. 1984, eq. 13) assumes every point of one element sees
//! every point of the other. With occluders, F_ij = F_ij(unoccluded) × (visible fraction) is
//! used: unoccludable pairs keep the exact contour value, fully hidden pairs get exactly 0.
//!
//! Public API:
//! - [`Occluders::new`] builds a BVH (obvhs CWBVH) over the scene's polygons;
//! - [`Occluders::occludable_pairs`] decides once per *polygon* pair whether any other polygon
//!   can come between them ([`OccludablePairs`]; a convex enclosure such as the paper's cube
//!   has none), with [`OccludablePairs::effects`] saying why;
//! - [`Occluders::element_pair`] is the per-element-pair entry point: a cheap conservative
//!   test first (only against the polygon pair's candidate occluders), rays only when it fails;
//! - [`Occluders::can_occlude`] and [`Occluders::visibility`] are its two halves, for any
//!   [`Patch`]es; [`Counters`] sums what the calls did, for the bake report;
//! - [`Occluders::with_cutouts`] gives polygons alpha cut-outs: a [`Cutout`] per polygon says
//!   whether it is there at a point, and rays pass where it is not. The caller builds them
//!   (bake-core, from `alphaMode` `MASK` textures): this crate knows no textures.
//! - [`Occluders::with_transmission`] makes polygons thin glass: a ray crossing polygon k is
//!   multiplied by its transmission t_k (straight through, no refraction);
//!   [`Occluders::segment_transmittance`] is the product over the polygons a segment meets
//!   (0 at an opaque one), and every visible fraction ([`Occluders::visibility`]) averages it
//!   instead of 0/1. The conservative tests still count glass as an occluder, so rays are
//!   cast wherever glass may come between.
//!
//! Robustness (all tolerances scale with the scene's bounding-box diagonal `s`):
//! - points within [`PLANE_TOLERANCE`] × s of a plane count as on it: coplanar neighbours are
//!   never occluders of each other, a convex solid never occludes its own faces;
//! - shadow rays run between sample points lifted [`RAY_OFFSET`] × s along each surface's own
//!   normal (not along the ray): a ray from a floor point beside a block starts above the floor
//!   but below the block's lowest edge, so nothing slips through the contact line;
//! - hits are confirmed in f64 against the exact polygon, edges included, on both sides (thin
//!   single-sided walls block from behind); the f32 BVH only proposes candidates
//!   conservatively;
//! - results do not depend on the thread count: every pair's samples come from its own seed
//!   ([`pair_seed`]) and "is anything hit" does not depend on the BVH's shape.

mod bvh;
mod geometry;
mod sampling;

pub use geometry::Patch;
pub use sampling::{
    cosine_direction, pair_seed, point_on_element, rays_for, strata, Pattern, SplitMix64,
};

use bvh::{Slabs, Tree};
use geometry::{facing, may_block, may_block_light, Piece};
use glam::DVec3;
use mesher::ElementMesh;
use rayon::prelude::*;
use sampling::Generator;
use scene::Polygon;

/// Default shadow rays per occludable element pair (`--visibility-samples`): 17 × 17.
///
/// Measured on ~200 partly hidden element pairs of the Cornell box (100 mm elements) against
/// a brute-force reference (`tests/cornell.rs`, `measure_estimators`; two runs with different
/// seeds): with 49 / 121 / 289 / 529 / 961 rays the rms error of the visible fraction is
/// 0.030 / 0.016 / 0.0095 / 0.007 / 0.0052, of F itself 12–16 / 6–8 / 4–5 / 3–3.5 / 2–3 %.
/// 289 is past the knee, at about 50 µs per occludable pair on one core; pairs that cannot be
/// occluded cost no rays at all.
pub const DEFAULT_SAMPLES: u32 = 289;

/// At most this many glass polygons along one ray ([`Occluders::segment_transmittance`]);
/// a ray through more counts as blocked (each pane keeps at most its t: 16 panes of the
/// clearest glass, t = 0.9, keep 0.185).
pub const MAX_PANES: usize = 16;

/// Points closer than this × the scene size to a plane are on it.
pub const PLANE_TOLERANCE: f64 = 1e-6;

/// Shadow-ray end points are lifted this × the scene size off their surfaces, along the
/// surface normal. Above [`PLANE_TOLERANCE`], so a ray never starts inside the band of
/// polygons that count as coplanar with its surface.
pub const RAY_OFFSET: f64 = 1e-5;

/// What went wrong building [`Occluders`].
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VisibilityError {
    #[error("polygon {polygon} has {sides} vertices; occluders are triangles and quads")]
    UnsupportedPolygon { polygon: usize, sides: usize },
    #[error("polygon {polygon} has a non-finite vertex or normal")]
    NonFinite { polygon: usize },
}

/// How the visible fraction of a pair is estimated from its shadow rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Estimator {
    /// Each ray weighted by the point-to-point kernel cos θi cos θj / r² (times the area
    /// density of its sample points): Σ w·v / Σ w, the visible share of the form factor itself.
    #[default]
    KernelWeighted,
    /// The plain share of visible rays (area-uniform point pairs). Biased wherever visibility
    /// and the kernel vary together (a shadow over the near part of a pair).
    Uniform,
}

/// The visibility of one pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Visibility {
    /// In [0, 1]: exactly 1 when the pair cannot be occluded or every ray arrived, exactly 0
    /// when every ray was blocked; a ray through glass counts its transmittance. Multiply
    /// the unoccluded form factor by it.
    pub fraction: f64,
    /// Whether the conservative test found a possible occluder (rays were needed).
    pub occludable: bool,
    /// Shadow rays cast.
    pub rays: u32,
}

impl Visibility {
    /// A pair nothing can come between.
    pub const UNOCCLUDED: Visibility = Visibility {
        fraction: 1.0,
        occludable: false,
        rays: 0,
    };
}

/// Work counters for the bake report: sum them over all pairs ([`Counters::add`] or
/// [`Counters::merge`]; sums of integers, so any order gives the same totals).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Element pairs whose visibility was decided.
    pub pairs_tested: u64,
    /// Of those, pairs some polygon may come between (rays were cast for them).
    pub pairs_occludable: u64,
    /// Shadow rays cast.
    pub rays_cast: u64,
}

impl Counters {
    pub fn add(&mut self, v: &Visibility) {
        self.pairs_tested += 1;
        self.pairs_occludable += u64::from(v.occludable);
        self.rays_cast += u64::from(v.rays);
    }

    pub fn merge(mut self, other: Counters) -> Counters {
        self.pairs_tested += other.pairs_tested;
        self.pairs_occludable += other.pairs_occludable;
        self.rays_cast += other.rays_cast;
        self
    }
}

/// The volume a receiver's light segments sweep (the convex hull of its corners and the far
/// points, see [`Occluders::can_shadow`]) for the tree query: tested along x, y, z, the
/// receiver's normal and the plane through each receiver edge and its corner's far point —
/// the hull's own faces (a sun's prism sides `edge × d`, a point light's pyramid sides), the
/// planes [`may_block_light`]'s side test uses, so the query drops nothing it would keep.
fn light_slabs(receiver: &Patch, far: &[DVec3]) -> Slabs {
    let c = receiver.corners();
    let mut points = [DVec3::ZERO; 8];
    let mut axes = [DVec3::ZERO; 5];
    let (mut n, mut m) = (0, 0);
    for &p in c.iter().chain(far).take(points.len()) {
        points[n] = p;
        n += 1;
    }
    axes[m] = receiver.normal();
    m += 1;
    if !far.is_empty() {
        for (e, &p) in c.iter().enumerate().take(axes.len() - 1) {
            let q = c[(e + 1) % c.len()];
            axes[m] = (q - p).cross(far[e % far.len()] - p);
            m += 1;
        }
    }
    Slabs::new(&points[..n], &axes[..m])
}

/// One occludable pair of a polygon p: (q, candidate occluders).
type OccludableRow = (u32, Vec<u32>);

/// Every scene polygon as a potential occluder, in a BVH.
pub struct Occluders {
    pieces: Vec<Piece>,
    tree: Option<Tree>,
    scale: f64,
    /// Per polygon, when it has cut-outs: whether it is there (blocks light) at a point.
    cutouts: Vec<Option<Cutout>>,
    /// Per polygon, the share of light a segment crossing it keeps (0: opaque); empty when
    /// every polygon is opaque.
    transmission: Vec<f64>,
    /// [`Occluders::any_can_occlude`], once asked.
    any_occludable: std::sync::OnceLock<bool>,
}

/// Where a segment first meets a polygon ([`Occluders::first_hit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub polygon: usize,
    /// Along the segment, 0 at its start and 1 at its end.
    pub t: f64,
    /// Whether the segment meets the polygon's front (the side its normal points to).
    pub front: bool,
}

/// Whether a polygon with alpha cut-outs is there at a world point of its plane (false: the
/// segment passes through). Built by the caller, which knows textures; visibility only asks.
pub type Cutout = std::sync::Arc<dyn Fn(DVec3) -> bool + Send + Sync>;

impl Occluders {
    /// A BVH over `polygons` (3 or 4 finite vertices each, as the importer makes them; polygon
    /// k keeps index k). The scene size is the diagonal of their bounding box.
    pub fn new(polygons: &[Polygon]) -> Result<Occluders, VisibilityError> {
        let mut pieces = Vec::with_capacity(polygons.len());
        for (k, p) in polygons.iter().enumerate() {
            let patch = Patch::new(&p.vertices, p.normal, k).ok_or(
                VisibilityError::UnsupportedPolygon {
                    polygon: k,
                    sides: p.vertices.len(),
                },
            )?;
            if !(p.vertices.iter().all(|v| v.is_finite()) && p.normal.is_finite()) {
                return Err(VisibilityError::NonFinite { polygon: k });
            }
            pieces.push(Piece::new(patch));
        }
        let (lo, hi) = scene::bounds(polygons);
        let diagonal = (hi - lo).length();
        let scale = if diagonal.is_finite() && diagonal > 0.0 {
            diagonal
        } else {
            1.0
        };
        let centre = if polygons.is_empty() {
            DVec3::ZERO
        } else {
            (lo + hi) * 0.5
        };
        let tree = Tree::new(&pieces, centre, scale);
        Ok(Occluders {
            pieces,
            tree,
            scale,
            cutouts: Vec::new(),
            transmission: Vec::new(),
            any_occludable: std::sync::OnceLock::new(),
        })
    }

    /// The same occluders, polygon k blocking a segment only where `cutouts[k]` (if any) says
    /// it is there (alpha cut-outs). The conservative tests (`can_occlude`, `can_shadow`)
    /// still count such polygons as occluders; only rays look through them.
    pub fn with_cutouts(mut self, cutouts: Vec<Option<Cutout>>) -> Occluders {
        self.cutouts = cutouts;
        self
    }

    /// The same occluders, polygon k keeping `transmission[k]` ∈ [0, 1] of the light of a
    /// segment that crosses it (thin glass; 0 opaque, 1 as if absent; missing entries are
    /// 0). Only rays see it ([`Occluders::segment_transmittance`]); the conservative tests
    /// still count every polygon as an occluder. Values outside [0, 1] are clamped, NaN is 0.
    pub fn with_transmission(mut self, transmission: Vec<f64>) -> Occluders {
        self.transmission = if transmission.iter().any(|&t| t > 0.0) {
            transmission
                .into_iter()
                .map(|t| if t > 0.0 { t.min(1.0) } else { 0.0 })
                .collect()
        } else {
            Vec::new()
        };
        self
    }

    /// The share of light polygon `k` lets through (0: opaque).
    pub fn transmission(&self, k: usize) -> f64 {
        self.transmission.get(k).copied().unwrap_or(0.0)
    }

    /// Whether some polygon lets light through ([`Occluders::with_transmission`]).
    pub fn has_transmission(&self) -> bool {
        !self.transmission.is_empty()
    }

    /// Whether polygon `k` has cut-outs.
    pub fn has_cutouts(&self, k: usize) -> bool {
        self.cutouts.get(k).is_some_and(Option::is_some)
    }

    /// Number of polygons.
    pub fn len(&self) -> usize {
        self.pieces.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pieces.is_empty()
    }

    /// The scene size: the diagonal of the polygons' bounding box (1 for an empty scene).
    pub fn scene_scale(&self) -> f64 {
        self.scale
    }

    /// How far shadow-ray end points are lifted off their surfaces: [`RAY_OFFSET`] × scene size.
    pub fn ray_offset(&self) -> f64 {
        RAY_OFFSET * self.scale
    }

    fn tol(&self) -> f64 {
        PLANE_TOLERANCE * self.scale
    }

    /// Polygon `k` as a patch.
    pub fn polygon(&self, k: usize) -> Patch {
        self.pieces[k].patch
    }

    /// The polygon a patch lies on, or the patch itself if its polygon is not in the scene.
    fn parent(&self, p: &Patch) -> Patch {
        self.pieces.get(p.polygon()).map_or(*p, |piece| piece.patch)
    }

    /// Conservative: `false` only when `a` and `b` cannot exchange light (neither is in front
    /// of the other) or no polygon other than theirs can block a segment between a point of
    /// `a` and a point of `b` (see [`OccludablePairs`] for the tests). Finds candidates in
    /// the BVH; gives the same answer as [`OccludablePairs::can_occlude`].
    pub fn can_occlude(&self, a: &Patch, b: &Patch) -> bool {
        let tol = self.tol();
        let Some(tree) = &self.tree else { return false };
        if !facing(a, b, tol) {
            return false;
        }
        let (pa, pb) = (self.parent(a), self.parent(b));
        let (alo, ahi) = a
            .corners()
            .iter()
            .chain(b.corners())
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        tree.any_in_box(alo, ahi, |k| {
            if k == a.polygon() || k == b.polygon() {
                return false;
            }
            let piece = &self.pieces[k];
            may_block(piece, a, b, tol) && may_block(piece, &pa, &pb, tol)
        })
    }

    /// Whether some polygon can come between two others ([`Occluders::can_occlude`] of some
    /// polygon pair; cut-outs play no part: they only open what could be blocked). Stops at
    /// the first such pair; computed once, then remembered (a refining bake asks per solve).
    pub fn any_can_occlude(&self) -> bool {
        *self.any_occludable.get_or_init(|| {
            let p = self.len();
            (0..p).any(|i| {
                let a = self.polygon(i);
                (i + 1..p).any(|j| self.can_occlude(&a, &self.polygon(j)))
            })
        })
    }

    /// Which polygon pairs some third polygon can come between, with those candidate
    /// occluders; computed in parallel, the same whatever the thread count.
    pub fn occludable_pairs(&self) -> OccludablePairs {
        self.occludable_pairs_with_progress(&|_| {})
    }

    /// [`Occluders::occludable_pairs`], calling `progress(1)` after each of the polygons' rows
    /// (from any thread), for a progress bar over [`Occluders::len`] steps.
    pub fn occludable_pairs_with_progress(
        &self,
        progress: &(dyn Fn(u64) + Sync),
    ) -> OccludablePairs {
        let n = self.pieces.len();
        let rows: Vec<(u64, Vec<OccludableRow>)> = (0..n)
            .into_par_iter()
            .map(|p| {
                let row = self.occludable_row(p);
                progress(1);
                row
            })
            .collect();
        let mut out = OccludablePairs {
            pairs: Vec::new(),
            offsets: vec![0],
            candidates: Vec::new(),
            facing_pairs: 0,
            polygons: n,
        };
        for (p, (facing_pairs, row)) in rows.into_iter().enumerate() {
            out.facing_pairs += facing_pairs;
            for (q, candidates) in row {
                out.pairs.push((p as u32, q));
                out.candidates.extend(candidates);
                out.offsets.push(out.candidates.len() as u32);
            }
        }
        out
    }

    /// Pairs (p, q > p): how many face each other, and the occludable ones with their sorted
    /// candidate occluders.
    fn occludable_row(&self, p: usize) -> (u64, Vec<OccludableRow>) {
        let tol = self.tol();
        let mut facing_pairs = 0;
        let mut row = Vec::new();
        let Some(tree) = &self.tree else {
            return (0, row);
        };
        let a = &self.pieces[p];
        for q in p + 1..self.pieces.len() {
            let b = &self.pieces[q];
            if !facing(&a.patch, &b.patch, tol) {
                continue;
            }
            facing_pairs += 1;
            let mut candidates = Vec::new();
            tree.for_each_in_box(a.lo.min(b.lo), a.hi.max(b.hi), |k| {
                if k != p && k != q && may_block(&self.pieces[k], &a.patch, &b.patch, tol) {
                    candidates.push(k as u32);
                }
            });
            if !candidates.is_empty() {
                candidates.sort_unstable();
                candidates.dedup();
                row.push((q as u32, candidates));
            }
        }
        (facing_pairs, row)
    }

    /// Conservative, for punctual lights: `false` only when no polygon other than the
    /// receiver's can block a segment from a point of `receiver` to one of the `far` points
    /// (a point light's position; for a directional light, the receiver's corners moved
    /// toward the light by the scene size). Finds candidates in the BVH, stops at the first.
    pub fn can_shadow(&self, receiver: &Patch, far: &[DVec3]) -> bool {
        let Some(tree) = &self.tree else { return false };
        let tol = self.tol();
        tree.any_in_slabs(&light_slabs(receiver, far), |k| {
            k != receiver.polygon() && may_block_light(&self.pieces[k], receiver, far, tol)
        })
    }

    /// Conservative, for light from a whole hemisphere (a sky): `false` only when no polygon
    /// other than the receiver's has a corner more than the plane tolerance in front of the
    /// receiver's plane, so that no ray leaving the receiver's front can meet one. Finds
    /// candidates in the BVH, stops at the first.
    pub fn any_in_front(&self, receiver: &Patch) -> bool {
        let Some(tree) = &self.tree else { return false };
        let tol = self.tol();
        let n = receiver.normal();
        let d = n.dot(receiver.corners()[0]) + tol;
        tree.any_in_front(n, d, |k| {
            k != receiver.polygon()
                && self.pieces[k]
                    .patch
                    .corners()
                    .iter()
                    .any(|&x| receiver.height(x) > tol)
        })
    }

    /// Every polygon [`Occluders::can_shadow`] would find, sorted, into `out` (cleared).
    pub fn shadow_candidates(&self, receiver: &Patch, far: &[DVec3], out: &mut Vec<usize>) {
        out.clear();
        let Some(tree) = &self.tree else { return };
        let tol = self.tol();
        tree.for_each_in_slabs(&light_slabs(receiver, far), |k| {
            if k != receiver.polygon() && may_block_light(&self.pieces[k], receiver, far, tol) {
                out.push(k);
            }
        });
        out.sort_unstable();
        out.dedup();
    }

    /// Whether the segment p–q is blocked by a polygon other than those in `skip` (exact f64
    /// test, polygon edges included, either side of a polygon; a polygon with cut-outs only
    /// where it is there). Glass ([`Occluders::with_transmission`]) blocks here like any
    /// polygon: callers that average light use [`Occluders::segment_transmittance`].
    pub fn segment_blocked(&self, p: DVec3, q: DVec3, skip: [usize; 2]) -> bool {
        let Some(tree) = &self.tree else { return false };
        let edge_tol = 1e-9 * self.scale;
        tree.any_on_segment(p, q, |k| self.meets(k, p, q, skip, edge_tol))
    }

    /// Whether the segment p–q meets polygon `k` (not in `skip`) where it is there.
    #[inline]
    fn meets(&self, k: usize, p: DVec3, q: DVec3, skip: [usize; 2], edge_tol: f64) -> bool {
        k != skip[0]
            && k != skip[1]
            && self.pieces[k].hits_segment(p, q, edge_tol)
            && self
                .cutouts
                .get(k)
                .and_then(Option::as_ref)
                .is_none_or(|there| {
                    // Where the segment crosses the polygon's plane.
                    let piece = &self.pieces[k];
                    let n = piece.patch.normal();
                    let (dp, dq) = (n.dot(p) - piece.offset, n.dot(q) - piece.offset);
                    let t: f64 = if dp == dq { 0.0 } else { dp / (dp - dq) };
                    there(p + (q - p) * t.clamp(0.0, 1.0))
                })
    }

    /// The share of light the segment p–q keeps: the product of the transmissions of the
    /// polygons (other than those in `skip`) it meets, as [`Occluders::segment_blocked`]
    /// finds them; 0 at the first opaque one, 1 when it meets none. Without glass it is
    /// exactly `segment_blocked` as 0 or 1 (the same rays, the same cost). The product is
    /// taken in polygon order, so the bits do not depend on the BVH's traversal; a segment
    /// through more than [`MAX_PANES`] glass polygons counts as blocked. Allocates nothing.
    pub fn segment_transmittance(&self, p: DVec3, q: DVec3, skip: [usize; 2]) -> f64 {
        if self.transmission.is_empty() {
            return if self.segment_blocked(p, q, skip) {
                0.0
            } else {
                1.0
            };
        }
        let Some(tree) = &self.tree else { return 1.0 };
        let edge_tol = 1e-9 * self.scale;
        let mut panes = [0u32; MAX_PANES];
        let mut count = 0;
        let blocked = tree.any_on_segment(p, q, |k| {
            if !self.meets(k, p, q, skip, edge_tol) {
                return false;
            }
            let t = self.transmission(k);
            if t <= 0.0 || count == MAX_PANES {
                return true;
            }
            panes[count] = k as u32;
            count += 1;
            false
        });
        if blocked {
            return 0.0;
        }
        let panes = &mut panes[..count];
        panes.sort_unstable();
        panes
            .iter()
            .fold(1.0, |product, &k| product * self.transmission(k as usize))
    }

    /// The nearest polygon (other than `skip`) that the segment p → q meets, where, and from
    /// which side (the same edge-inclusive test and cut-outs as [`Occluders::segment_blocked`]).
    /// It visits every candidate along the segment: meant for checks and tools (an independent
    /// particle trace of where light goes), not for per-element-pair loops.
    pub fn first_hit(&self, p: DVec3, q: DVec3, skip: usize) -> Option<Hit> {
        let tree = self.tree.as_ref()?;
        let edge_tol = 1e-9 * self.scale;
        let mut best: Option<Hit> = None;
        tree.each_on_segment(p, q, |k| {
            if k == skip || !self.pieces[k].hits_segment(p, q, edge_tol) {
                return;
            }
            let piece = &self.pieces[k];
            let n = piece.patch.normal();
            let (dp, dq) = (n.dot(p) - piece.offset, n.dot(q) - piece.offset);
            let t = if dp == dq { 0.0 } else { dp / (dp - dq) }.clamp(0.0, 1.0);
            let at = p + (q - p) * t;
            if let Some(Some(there)) = self.cutouts.get(k) {
                if !there(at) {
                    return;
                }
            }
            // Nearest first; at the same distance (within rounding: a double-sided face's two
            // sides are coincident polygons) the one met from the front, then the lower index,
            // so the answer does not depend on the visiting order.
            let front = n.dot(q - p) < 0.0;
            let better = |b: &Hit| {
                if (t - b.t).abs() > 1e-12 {
                    t < b.t
                } else if front != b.front {
                    front
                } else {
                    k < b.polygon
                }
            };
            if best.as_ref().is_none_or(better) {
                best = Some(Hit {
                    polygon: k,
                    t,
                    front,
                });
            }
        });
        best
    }

    /// One shadow ray between the point at unit-square coordinates `(ua, va)` of `a` and the
    /// one at `(ub, vb)` of `b` (mapped as in [`Occluders::visibility_with`]), lifted
    /// [`Occluders::ray_offset`] along their normals and ignoring hits on their own polygons:
    /// `None` when the two points do not face each other (no light passes between them),
    /// else whether some light passes (the segment meets no opaque polygon).
    pub fn point_pair_visible(&self, a: &Patch, b: &Patch, uv: [f64; 4]) -> Option<bool> {
        self.point_pair_transmittance(a, b, uv).map(|t| t > 0.0)
    }

    /// [`Occluders::point_pair_visible`] as a share of light: `None` when the points do not
    /// face each other, else the segment's [`Occluders::segment_transmittance`].
    pub fn point_pair_transmittance(
        &self,
        a: &Patch,
        b: &Patch,
        [ua, va, ub, vb]: [f64; 4],
    ) -> Option<f64> {
        let (x, _) = a.point(ua, va);
        let (y, _) = b.point(ub, vb);
        let d = y - x;
        if !(a.normal().dot(d) > 0.0 && -b.normal().dot(d) > 0.0) {
            return None;
        }
        let lift = self.ray_offset();
        Some(self.segment_transmittance(
            x + a.normal() * lift,
            y + b.normal() * lift,
            [a.polygon(), b.polygon()],
        ))
    }

    /// The visible fraction between `a` and `b` with the default [`Estimator`]; see
    /// [`Occluders::visibility_with`]. Always casts rays (it does not test occludability).
    pub fn visibility(&self, a: &Patch, b: &Patch, samples: u32, seed: u64) -> Visibility {
        self.visibility_with(a, b, samples, seed, Estimator::default())
    }

    /// The visible fraction between `a` and `b` from n² point pairs, n the prime nearest
    /// √`samples` (3 ≤ n ≤ 31, see [`rays_for`]): a randomised orthogonal array of strength 2
    /// in (u_a, v_a, u_b, v_b), jittered, so the points are n × n stratified on each patch and
    /// in every cross projection such as (u_a, u_b); the unit squares are mapped onto the
    /// patches (bilinear for quads, area-uniform for triangles). Pairs of points that face
    /// each other get a shadow ray between the points lifted [`Occluders::ray_offset`] along
    /// their normals, ignoring hits on `a`'s and `b`'s own polygons. All randomness comes from
    /// `seed`. If no point pair faces the other, the fraction is 1 (such a pair's unoccluded
    /// form factor is ~0 anyway).
    pub fn visibility_with(
        &self,
        a: &Patch,
        b: &Patch,
        samples: u32,
        seed: u64,
        estimator: Estimator,
    ) -> Visibility {
        self.visibility_pattern(a, b, samples, seed, estimator, Pattern::OrthogonalArray)
    }

    /// [`Occluders::visibility_with`] with a chosen point layout (for measurements).
    #[doc(hidden)]
    pub fn visibility_pattern(
        &self,
        a: &Patch,
        b: &Patch,
        samples: u32,
        seed: u64,
        estimator: Estimator,
        pattern: Pattern,
    ) -> Visibility {
        let mut points = Generator::new(pattern, samples, seed);
        let lift_a = a.normal() * self.ray_offset();
        let lift_b = b.normal() * self.ray_offset();
        let skip = [a.polygon(), b.polygon()];
        let (mut sum_w, mut sum_visible, mut rays) = (0.0, 0.0, 0u32);
        for k in 0..points.count() {
            let [ua, va, ub, vb] = points.coords(k);
            let (x, jx) = a.point(ua, va);
            let (y, jy) = b.point(ub, vb);
            let d = y - x;
            let (cos_a, cos_b) = (a.normal().dot(d), -b.normal().dot(d));
            if !(cos_a > 0.0 && cos_b > 0.0) {
                continue;
            }
            let w = match estimator {
                Estimator::KernelWeighted => {
                    let r2 = d.length_squared();
                    jx * jy * cos_a * cos_b / (r2 * r2)
                }
                Estimator::Uniform => jx * jy,
            };
            rays += 1;
            sum_w += w;
            sum_visible += w * self.segment_transmittance(x + lift_a, y + lift_b, skip);
        }
        let fraction = if sum_w > 0.0 {
            (sum_visible / sum_w).clamp(0.0, 1.0)
        } else {
            1.0
        };
        Visibility {
            fraction,
            occludable: true,
            rays,
        }
    }

    /// The per-element-pair entry point: the visibility between elements `i` and `j` of
    /// `mesh` (built from the same polygons as `self`), using `pairs` =
    /// [`Occluders::occludable_pairs`]. Unoccludable pairs (same polygon, not facing, or no
    /// candidate occluder passes [`Occluders::can_occlude`]'s tests) are
    /// [`Visibility::UNOCCLUDED`] without a ray; the rest get
    /// [`Occluders::visibility`] with `samples` and the seed [`pair_seed`]`(i, j)`.
    /// Symmetric: (i, j) and (j, i) give the same bits (rays always run from the lower index),
    /// so A_i F_ij = A_j F_ji still holds after multiplying.
    pub fn element_pair(
        &self,
        pairs: &OccludablePairs,
        mesh: &ElementMesh,
        i: usize,
        j: usize,
        samples: u32,
    ) -> Visibility {
        let (lo, hi) = if i <= j { (i, j) } else { (j, i) };
        let a = Patch::element(mesh, lo);
        let b = Patch::element(mesh, hi);
        if pairs.can_occlude(self, &a, &b) {
            self.visibility(&a, &b, samples, pair_seed(lo, hi))
        } else {
            Visibility::UNOCCLUDED
        }
    }
}

/// The polygon pairs some third polygon can come between, each with its candidate occluders
/// (sorted polygon indices), from [`Occluders::occludable_pairs`].
///
/// A polygon k is a candidate for the pair (a, b) when it passes every test of a conservative
/// separating-plane check against the convex hull of a ∪ b (the union of all segments
/// between them):
/// 1. k's bounding box overlaps that of a ∪ b;
/// 2. the corners of a ∪ b are not all on one closed side of k's plane (else k lies in a
///    supporting plane of the hull: no wall of a convex enclosure ever occludes);
/// 3. some part of k is strictly in front of both a's and b's planes (coplanar neighbours and
///    the other faces of a convex solid never are);
/// 4. no side face of the hull (a plane through an edge of one and a corner of the other)
///    has k wholly outside.
///
/// Elements lie inside their polygons, so an element pair can only be occluded by its polygon
/// pair's candidates; [`OccludablePairs::can_occlude`] re-runs the tests for the elements
/// against those candidates only.
#[derive(Clone, Debug, PartialEq)]
pub struct OccludablePairs {
    /// (p, q), p < q, sorted.
    pairs: Vec<(u32, u32)>,
    /// Candidates of pair k: `candidates[offsets[k]..offsets[k + 1]]`.
    offsets: Vec<u32>,
    candidates: Vec<u32>,
    facing_pairs: u64,
    polygons: usize,
}

/// Which effects a scene calls for, with the reason: the bake report's `effects` object.
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Effects {
    /// Whether some element pairs need shadow rays.
    pub occlusion: bool,
    /// One sentence saying why.
    #[cfg_attr(feature = "serde", serde(rename = "occlusion_reason"))]
    pub reason: String,
}

impl OccludablePairs {
    /// Number of occludable polygon pairs.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Polygon pairs that face each other (can exchange light): the pairs tested.
    pub fn facing_pairs(&self) -> u64 {
        self.facing_pairs
    }

    /// The occludable pairs (p < q).
    pub fn pairs(&self) -> &[(u32, u32)] {
        &self.pairs
    }

    /// The candidate occluders of polygons p and q (either order); `None` when nothing can
    /// come between them.
    pub fn candidates(&self, p: usize, q: usize) -> Option<&[u32]> {
        let key = if p <= q { (p, q) } else { (q, p) };
        let key = (u32::try_from(key.0).ok()?, u32::try_from(key.1).ok()?);
        let k = self.pairs.binary_search(&key).ok()?;
        Some(&self.candidates[self.offsets[k] as usize..self.offsets[k + 1] as usize])
    }

    /// Number of distinct polygons that are a candidate for some pair.
    pub fn occluders(&self) -> usize {
        let mut seen = vec![false; self.polygons];
        for &k in &self.candidates {
            seen[k as usize] = true;
        }
        seen.iter().filter(|&&s| s).count()
    }

    /// Element-level version of [`Occluders::can_occlude`], testing only the candidates of
    /// the patches' polygon pair (same answer, no BVH query).
    pub fn can_occlude(&self, occluders: &Occluders, a: &Patch, b: &Patch) -> bool {
        if a.polygon() == b.polygon() {
            return false;
        }
        let Some(candidates) = self.candidates(a.polygon(), b.polygon()) else {
            return false;
        };
        let tol = occluders.tol();
        facing(a, b, tol)
            && candidates
                .iter()
                .any(|&k| may_block(&occluders.pieces[k as usize], a, b, tol))
    }

    /// Whether the scene calls for shadow rays, and why.
    pub fn effects(&self) -> Effects {
        if self.pairs.is_empty() {
            Effects {
                occlusion: false,
                reason: format!(
                    "no polygon can come between any of the {} polygon pairs that face each \
                     other (every polygon lies in a supporting plane of the others' hull, as in \
                     a convex enclosure): form factors are exact, no rays are cast",
                    self.facing_pairs
                ),
            }
        } else {
            Effects {
                occlusion: true,
                reason: format!(
                    "{} of the {} polygon pairs that face each other may be partly hidden by \
                     one of {} occluding polygons: shadow rays are cast for their element \
                     pairs that fail the conservative test",
                    self.pairs.len(),
                    self.facing_pairs,
                    self.occluders()
                ),
            }
        }
    }
}
