//! A probe's incident radiance from the elements it sees, projected on SH L2.
//!
//! Each element j is a planar convex polygon of constant radiance `b_j / π` on its front
//! side. Its contribution to coefficient k is `b_j / π ∫ Y_k(ω) dω` over the part of its
//! solid angle the probe sees; the solid-angle integral is taken over the element's area,
//! `∫ Y_k(ω(x)) cos θ_x / r² dA`, by 2 × 2 Gauss–Legendre points on an m × m split of the
//! element (bilinear map; a triangle as a quad with two equal corners), m growing with the
//! element's size over its distance ([`SPLIT`], at most [`MAX_SPLIT`]).
//!
//! Visibility, cheapest test first:
//! - nothing is cast for a polygon no other polygon can come between it and the probe
//!   (`Occluders::can_shadow`);
//! - a polygon, a block of about [`BLOCK`] × [`BLOCK`] of its elements (the rectangle
//!   bounding them in its plane), or an element whose corners all project, from the probe,
//!   into one convex occluder is wholly hidden (the occluders found this way are tried first
//!   for what follows: a room's walls hide most of the rooms beyond);
//! - *screening*: one shadow ray to each corner (shared by the elements that meet there) and
//!   one to the centre of a block whose solid angle is at most [`MIN_CELL`], else of each
//!   element; when all agree, it is taken as wholly seen (integrated without rays) or
//!   wholly hidden. An element of at most [`MIN_CELL`] sr whose rays disagree gets their
//!   seen share (the quadrature would not split it either);
//! - a larger element whose rays disagree: each quadrature point gets one shadow ray (and
//!   its cell's corners one each), and a cell whose rays disagree is split in four, down to
//!   [`MAX_DEPTH`] levels or a cell of [`MIN_CELL`] sr, whichever comes first.
//!
//! The solid angle of the cells and elements left mixed bounds the error
//! ([`Gathered::unresolved`]); measured against gathers resolved 100 times finer, the
//! irradiance is within about 1 % (docs/probes.md). An occluder that slips between the
//! screening rays of a block or element is missed: it is smaller than the rays' spacing,
//! at most about [`MIN_CELL`] sr.

use crate::sh::{basis, Sh, COEFFICIENTS};
use glam::DVec3;
use mesher::ElementMesh;
use std::collections::HashMap;
use std::f64::consts::PI;
use visibility::{Occluders, Patch};

/// Sub-cells per element side per (element diameter / distance): m = ceil(SPLIT × d / r).
pub const SPLIT: f64 = 4.0;

/// The most sub-cells per element side.
pub const MAX_SPLIT: usize = 64;

/// 2-point Gauss–Legendre on [0, 1].
const GAUSS: [f64; 2] = [0.5 - 0.288_675_134_594_812_9, 0.5 + 0.288_675_134_594_812_9];

/// What gathering at one probe gives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Gathered {
    pub sh: Sh,
    /// `∫ L² dω` per band (for the truncation bound).
    pub square: [f64; 3],
    /// Shadow rays cast.
    pub rays: u64,
    /// Elements that contributed.
    pub elements: u64,
    /// Per band, `Σ Ω L` over the cells whose shadow rays disagreed but were too small to
    /// split ([`MIN_CELL`]): no coefficient is off by more than this × max |Y_k| (≤ 0.63),
    /// nor any irradiance by more than this, for want of resolving shadow edges.
    pub unresolved: [f64; 3],
}

/// The scene a probe gathers from ([`Sources::new`]).
pub struct Sources<'a> {
    pub mesh: &'a ElementMesh,
    /// Per element, its radiosity b (the radiance is b / π).
    pub radiosity: &'a [[f64; 3]],
    pub occluders: &'a Occluders,
    /// Each polygon's elements in blocks of about [`BLOCK`] × [`BLOCK`].
    blocks: Blocks,
    /// What a ray that meets no surface sees ([`Sources::with_sky`]), and the directions
    /// it is sampled in.
    sky: Option<(&'a Sky<'a>, Vec<DVec3>)>,
}

/// The radiance (per band, in the unit of b / π) that a ray along a unit direction sees when
/// it leaves the scene: the sky and the ground below its horizon.
pub type Sky<'a> = dyn Fn(DVec3) -> [f64; 3] + Sync + 'a;

/// Directions each probe samples the sky in (a spherical Fibonacci set): the sky seen
/// through openings is summed over those that leave the scene, each weighing 4π / this.
pub const SKY_RAYS: usize = 4096;

impl<'a> Sources<'a> {
    /// The sources, with each polygon's elements grouped into blocks once for every probe.
    pub fn new(
        mesh: &'a ElementMesh,
        radiosity: &'a [[f64; 3]],
        occluders: &'a Occluders,
    ) -> Sources<'a> {
        Sources {
            mesh,
            radiosity,
            occluders,
            blocks: Blocks::new(mesh, occluders),
            sky: None,
        }
    }

    /// The same sources with a sky: each probe adds the sky's radiance along the
    /// [`SKY_RAYS`] directions that meet no surface.
    pub fn with_sky(mut self, sky: &'a Sky<'a>) -> Sources<'a> {
        self.sky = Some((sky, crate::place::fibonacci(SKY_RAYS)));
        self
    }
}

/// Elements per side of a block: a polygon's elements are tested block by block first, and
/// a block that one occluder hides (most of a room beyond a wall) is skipped as a whole.
pub const BLOCK: f64 = 4.0;

/// Per polygon, its elements grouped by position in its plane.
struct Blocks {
    /// Per polygon, its blocks' range in `blocks`.
    ranges: Vec<std::ops::Range<u32>>,
    /// A block: the rectangle in its polygon's plane that bounds its elements (whatever
    /// hides all of it hides each of them), and its elements `order[first..first + count]`.
    /// Whether the rectangle is exactly the elements (its area theirs): only then is it
    /// screened by rays as a whole.
    blocks: Vec<(Patch, u32, u32, bool)>,
    order: Vec<u32>,
}

impl Blocks {
    fn new(mesh: &ElementMesh, occ: &Occluders) -> Blocks {
        let mut out = Blocks {
            ranges: Vec::with_capacity(mesh.patches.len()),
            blocks: Vec::new(),
            order: Vec::with_capacity(mesh.elements.len()),
        };
        let mut keyed: Vec<(u64, u32)> = Vec::new();
        for (k, grid) in mesh.patches.iter().enumerate() {
            let first_block = out.blocks.len() as u32;
            if grid.elements.is_empty() || k >= occ.len() {
                out.ranges.push(first_block..first_block);
                continue;
            }
            let polygon = occ.polygon(k);
            let (origin, u, v) = plane_frame(&polygon);
            let range = grid.elements.start as usize..grid.elements.end as usize;
            let area: f64 = range.clone().map(|i| mesh.elements[i].area).sum();
            let side = BLOCK * (area / range.len() as f64).sqrt();
            // A cell index per axis, offset to stay positive; the clamp keeps a degenerate
            // polygon's NaN or huge coordinates in range.
            let cell = |x: f64| ((x / side).floor().clamp(-1e9, 1e9) as i64 + (1 << 31)) as u64;
            keyed.clear();
            for i in range {
                let d = mesh.elements[i].centroid - origin;
                keyed.push(((cell(d.dot(u)) << 32) | cell(d.dot(v)), i as u32));
            }
            keyed.sort_unstable();
            for run in keyed.chunk_by(|a, b| a.0 == b.0) {
                let first = out.order.len() as u32;
                out.order.extend(run.iter().map(|r| r.1));
                let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
                for &(_, i) in run {
                    for &c in mesh.convex(i as usize).corners() {
                        let d = c - origin;
                        let (a, b) = (d.dot(u), d.dot(v));
                        lo = [lo[0].min(a), lo[1].min(b)];
                        hi = [hi[0].max(a), hi[1].max(b)];
                    }
                }
                let at = |a: f64, b: f64| origin + u * a + v * b;
                let rectangle = [
                    at(lo[0], lo[1]),
                    at(hi[0], lo[1]),
                    at(hi[0], hi[1]),
                    at(lo[0], hi[1]),
                ];
                // A degenerate rectangle (no area) is its first element.
                let patch = Patch::new(&rectangle, polygon.normal, k)
                    .unwrap_or_else(|| Patch::element(mesh, run[0].1 as usize));
                let covered: f64 = run.iter().map(|r| mesh.elements[r.1 as usize].area).sum();
                let exact = ((hi[0] - lo[0]) * (hi[1] - lo[1]) - covered).abs() <= 1e-9 * covered;
                out.blocks.push((patch, first, run.len() as u32, exact));
            }
            out.ranges.push(first_block..out.blocks.len() as u32);
        }
        out
    }
}

/// A frame of a polygon's plane: a corner and two orthonormal vectors in it.
fn plane_frame(polygon: &Patch) -> (DVec3, DVec3, DVec3) {
    let n = polygon.normal;
    let origin = polygon.corners[0];
    let u = (polygon.corners[1] - origin).normalize_or_zero();
    (origin, u, n.cross(u))
}

/// Gathers at `p` (a point in empty space: not on any polygon).
pub fn gather(p: DVec3, sources: &Sources) -> Gathered {
    let mut out = Gathered::default();
    let occ = sources.occluders;
    let tol = visibility::PLANE_TOLERANCE * occ.scene_scale();
    // Polygons that hid something from `p`: most of what a room hides, its walls hide.
    let mut blockers: Vec<usize> = Vec::new();
    // The current polygon's element corners already tested: shared by up to four elements.
    let mut corners: HashMap<[u64; 3], f64> = HashMap::new();
    let blocks = &sources.blocks;
    for (k, grid) in sources.mesh.patches.iter().enumerate() {
        if grid.elements.is_empty() || k >= occ.len() {
            continue;
        }
        let range = grid.elements.start as usize..grid.elements.end as usize;
        if range
            .clone()
            .all(|i| sources.radiosity[i].iter().all(|&b| b == 0.0))
        {
            continue;
        }
        let polygon = occ.polygon(k);
        if (p - polygon.corners[0]).dot(polygon.normal) <= tol
            || hidden_by_known(p, &polygon, occ, &mut blockers)
        {
            continue;
        }
        let shadowable = occ.can_shadow(&polygon, &[p]);
        if shadowable && hidden(p, &polygon, occ, &mut blockers) {
            continue;
        }
        corners.clear();
        let centre = {
            let c = polygon.corners();
            c.iter().copied().sum::<DVec3>() / c.len() as f64
        };
        let own = blocks.ranges[k].start as usize..blocks.ranges[k].end as usize;
        for &(block, first, count, exact) in &blocks.blocks[own] {
            if shadowable
                && (hidden_by_known(p, &block, occ, &mut blockers)
                    || hidden(p, &block, occ, &mut blockers))
            {
                continue;
            }
            // A block no larger than a cell the quadrature would not split is screened as
            // one: its elements are then all seen or all hidden, or else screened each.
            let mut block_seen = false;
            if shadowable && exact && solid_angle(p, &block) <= MIN_CELL {
                match screen(p, &block, centre, occ, &mut corners, &mut out) {
                    Screened::Seen => block_seen = true,
                    Screened::Hidden => continue,
                    Screened::Mixed(_) => {}
                }
            }
            for &i in &blocks.order[first as usize..(first + count) as usize] {
                let i = i as usize;
                let b = sources.radiosity[i];
                if b.iter().all(|&v| v == 0.0) {
                    continue;
                }
                let patch = Patch::element(sources.mesh, i);
                let rays = shadowable && !block_seen;
                let radiance = b.map(|v| v / PI);
                let rays = rays
                    && match screen(p, &patch, centre, occ, &mut corners, &mut out) {
                        Screened::Seen => false,
                        Screened::Hidden => continue,
                        // An element too small for the quadrature to split gets the
                        // screening rays' seen share (what its own unsplit cell would do with
                        // its own rays), and counts as unresolved.
                        Screened::Mixed(share) if solid_angle(p, &patch) <= MIN_CELL => {
                            let solid = integrate(p, &patch, radiance, share, None, &mut out);
                            for (u, l) in out.unresolved.iter_mut().zip(radiance) {
                                *u += solid * l;
                            }
                            continue;
                        }
                        Screened::Mixed(_) => true,
                    };
                integrate(p, &patch, radiance, 1.0, rays.then_some(occ), &mut out);
            }
        }
    }
    if let Some((sky, directions)) = &sources.sky {
        gather_sky(p, sky, directions, occ, &mut out);
    }
    out
}

/// Adds the sky seen from `p` along `directions` (uniform over the sphere): those that meet
/// no surface, front or back (but glass, which passes its transmission), each with weight
/// 4π / their count.
fn gather_sky(p: DVec3, sky: &Sky<'_>, directions: &[DVec3], occ: &Occluders, out: &mut Gathered) {
    let weight = 4.0 * PI / directions.len() as f64;
    // Past every polygon: twice the scene's diagonal from anywhere in its box.
    let far = 2.0 * occ.scene_scale();
    let none = [usize::MAX; 2];
    for &d in directions {
        out.rays += 1;
        // Glass on the way passes its transmission.
        let passed = occ.segment_transmittance(p, p + d * far, none);
        if passed == 0.0 {
            continue;
        }
        let radiance = sky(d).map(|l| l * passed);
        if radiance.iter().all(|&l| l == 0.0) {
            continue;
        }
        let y = basis(d);
        for (c, yk) in out.sh.iter_mut().zip(y) {
            for (value, l) in c.iter_mut().zip(radiance) {
                *value += l * yk * weight;
            }
        }
        for (s, l) in out.square.iter_mut().zip(radiance) {
            *s += l * l * weight;
        }
    }
}

/// About the solid angle `patch` subtends at `p`: area × cosine / distance² at its centroid
/// (no more than 2π).
fn solid_angle(p: DVec3, patch: &Patch) -> f64 {
    let corners = patch.corners();
    let centroid = corners.iter().copied().sum::<DVec3>() / corners.len() as f64;
    let d = centroid - p;
    let r2 = d.length_squared();
    let area: f64 = (1..corners.len() - 1)
        .map(|k| {
            0.5 * (corners[k] - corners[0])
                .cross(corners[k + 1] - corners[0])
                .length()
        })
        .sum();
    (area * d.dot(patch.normal).abs() / (r2 * r2.sqrt())).min(2.0 * PI)
}

/// What the screening rays of an element saw ([`screen`]).
enum Screened {
    Seen,
    Hidden,
    /// Some rays seen, some not: the share seen.
    Mixed(f64),
}

/// One shadow ray to each corner of an element (shared with its neighbours on the polygon
/// through `tested`, keyed by the corner's position; pulled a hair toward the polygon's
/// `centre`, so a corner on the polygon's edge is not taken for its neighbour's) and one to
/// its centroid. When all agree the element is taken as wholly seen or wholly hidden (what
/// an occluder smaller than the element's spacing of these points could hide is missed, as
/// it would be between the quadrature's own points); otherwise (a ray through glass counts
/// as its transmittance's share of a seen one) the quadrature casts its own.
fn screen(
    p: DVec3,
    patch: &Patch,
    centre: DVec3,
    occ: &Occluders,
    tested: &mut HashMap<[u64; 3], f64>,
    out: &mut Gathered,
) -> Screened {
    let lift = patch.normal * occ.ray_offset();
    let skip = [patch.polygon(); 2];
    let corners = patch.corners();
    let centroid = corners.iter().copied().sum::<DVec3>() / corners.len() as f64;
    // Each ray's transmittance: 1 seen, 0 hidden, between behind glass.
    let mut passed = [0.0; 5];
    for (slot, &c) in passed.iter_mut().zip(corners) {
        let key = [c.x.to_bits(), c.y.to_bits(), c.z.to_bits()];
        *slot = *tested.entry(key).or_insert_with(|| {
            out.rays += 1;
            let x = c + (centre - c) * 1e-4 + lift;
            if (x - p).dot(patch.normal) < 0.0 {
                occ.segment_transmittance(p, x, skip)
            } else {
                0.0
            }
        });
    }
    out.rays += 1;
    passed[corners.len()] = occ.segment_transmittance(p, centroid + lift, skip);
    let passed = &passed[..=corners.len()];
    if passed.iter().all(|&t| t == 1.0) {
        Screened::Seen
    } else if passed.iter().all(|&t| t == 0.0) {
        Screened::Hidden
    } else {
        Screened::Mixed(passed.iter().sum::<f64>() / passed.len() as f64)
    }
}

/// Whether one of `blockers` hides all of `patch` from `p` ([`covers`]). The one that does
/// moves to the front: neighbouring elements are mostly hidden by the same wall.
fn hidden_by_known(p: DVec3, patch: &Patch, occ: &Occluders, blockers: &mut [usize]) -> bool {
    match blockers.iter().position(|&b| covers(p, patch, occ, b)) {
        Some(k) => {
            blockers[..=k].rotate_right(1);
            true
        }
        None => false,
    }
}

/// Whether every corner of `patch` (pulled a hair toward its centroid and lifted off it) is
/// seen from `p` through one and the same convex occluder without cut-outs (the first met
/// toward its centroid): then so is all of it (the central projection of a convex polygon
/// beyond a plane is the convex hull of its corners' projections). Remembers that occluder
/// in `blockers`.
fn hidden(p: DVec3, patch: &Patch, occ: &Occluders, blockers: &mut Vec<usize>) -> bool {
    let corners = patch.corners();
    let centroid = corners.iter().copied().sum::<DVec3>() / corners.len() as f64;
    let lift = patch.normal * occ.ray_offset();
    let Some(hit) = occ.first_hit(p, centroid + lift, patch.polygon()) else {
        return false;
    };
    if !covers(p, patch, occ, hit.polygon) {
        return false;
    }
    if !blockers.contains(&hit.polygon) {
        blockers.push(hit.polygon);
    }
    true
}

/// Whether polygon `blocker` (without cut-outs, not the patch's own) hides all of `patch`
/// from `p`: every corner's segment crosses its plane inside it.
fn covers(p: DVec3, patch: &Patch, occ: &Occluders, blocker: usize) -> bool {
    // Glass (transmission > 0) hides nothing wholly.
    if blocker == patch.polygon() || occ.has_cutouts(blocker) || occ.transmission(blocker) > 0.0 {
        return false;
    }
    let corners = patch.corners();
    let centroid = corners.iter().copied().sum::<DVec3>() / corners.len() as f64;
    let lift = patch.normal * occ.ray_offset();
    let blocker = occ.polygon(blocker);
    let n = blocker.normal;
    let base = blocker.corners[0];
    let hp = (p - base).dot(n);
    let bc = blocker.corners();
    corners.iter().all(|&c| {
        let c = c + (centroid - c) * 1e-6 + lift;
        let hc = (c - base).dot(n);
        if hp * hc >= 0.0 || hp.is_nan() || hc.is_nan() {
            return false;
        }
        let x = p + (c - p) * (hp / (hp - hc));
        (0..bc.len()).all(|e| {
            let a = bc[e];
            let b = bc[(e + 1) % bc.len()];
            (b - a).cross(x - a).dot(n) >= 0.0
        })
    })
}

/// Adds the element's projection to `out`; with `occluders`, one shadow ray per point, cells
/// split where their rays disagree.
/// `share` (1 but for an element screened as partly seen) scales what the quadrature sees.
/// Returns the solid angle it saw, before `share`.
fn integrate(
    p: DVec3,
    patch: &Patch,
    radiance: [f64; 3],
    share: f64,
    occluders: Option<&Occluders>,
    out: &mut Gathered,
) -> f64 {
    let (c0, n) = (patch.corners[0], patch.normal);
    let corners = patch.corners();
    let centroid = corners.iter().copied().sum::<DVec3>() / corners.len() as f64;
    let radius = corners
        .iter()
        .map(|&c| (c - centroid).length())
        .fold(0.0, f64::max);
    let height = (p - c0).dot(n);
    let near = ((p - centroid).length() - radius).max(height);
    let m = if near > 0.0 {
        ((SPLIT * 2.0 * radius / near).ceil() as usize).clamp(1, MAX_SPLIT)
    } else {
        MAX_SPLIT
    };
    let cell = 1.0 / m as f64;
    let mut quad = Quadrature {
        p,
        patch,
        occluders,
        lift: occluders.map_or(0.0, Occluders::ray_offset),
        acc: [0.0; COEFFICIENTS],
        solid: 0.0,
        rays: 0,
        unresolved: 0.0,
    };
    for su in 0..m {
        for sv in 0..m {
            quad.cell(su as f64 * cell, sv as f64 * cell, cell, 0);
        }
    }
    out.rays += quad.rays;
    for (u, l) in out.unresolved.iter_mut().zip(radiance) {
        *u += quad.unresolved * l;
    }
    let (acc, solid) = (quad.acc, quad.solid);
    if solid == 0.0 {
        return 0.0;
    }
    out.elements += 1;
    for (c, a) in out.sh.iter_mut().zip(acc) {
        for (band, value) in c.iter_mut().enumerate() {
            *value += radiance[band] * share * a;
        }
    }
    for (s, l) in out.square.iter_mut().zip(radiance) {
        *s += l * l * share * solid;
    }
    solid
}

/// Sub-cells a shadowed cell is split into, at most this many times over, where its points'
/// shadow rays disagree (so a shadow's edge is found 2^MAX_DEPTH times finer).
pub const MAX_DEPTH: u32 = 6;

/// A cell whose rays disagree is not split once its solid angle (sr) is below this: about
/// 5.7° × 5.7°, some 0.1 % of the sphere; L2 harmonics vary little over it. What is left unresolved is bounded ([`Gathered::unresolved`]).
pub const MIN_CELL: f64 = 1e-2;

/// One element's quadrature in progress.
struct Quadrature<'a> {
    p: DVec3,
    patch: &'a Patch,
    occluders: Option<&'a Occluders>,
    lift: f64,
    acc: [f64; COEFFICIENTS],
    solid: f64,
    rays: u64,
    /// Solid angle of mixed cells left unsplit.
    unresolved: f64,
}

impl Quadrature<'_> {
    /// The unit-square cell at (u0, v0) of side `size`: its four Gauss points, each with a
    /// shadow ray when there are occluders; split into four where some are blocked and some
    /// not, down to [`MAX_DEPTH`].
    fn cell(&mut self, u0: f64, v0: f64, size: f64, depth: u32) {
        let [c0, c1, c2, c3] = self.patch.corners;
        let n = self.patch.normal;
        let mut points = [(DVec3::ZERO, 0.0, 1.0); 4];
        let mut blocked = 0;
        for (slot, (gu, gv)) in points
            .iter_mut()
            .zip([(0, 0), (0, 1), (1, 0), (1, 1)].map(|(a, b)| (GAUSS[a], GAUSS[b])))
        {
            let (u, v) = (u0 + gu * size, v0 + gv * size);
            let bottom = c0.lerp(c1, u);
            let top = c3.lerp(c2, u);
            let x = bottom.lerp(top, v);
            let du = (c1 - c0).lerp(c2 - c3, v);
            let dv = top - bottom;
            let jacobian = du.cross(dv).dot(n).abs();
            let d = x - self.p;
            let r2 = d.length_squared();
            let cos = -d.dot(n) / r2.sqrt();
            let w = if cos > 0.0 {
                jacobian * cos / r2 * 0.25 * size * size
            } else {
                0.0
            };
            // The share of the point's light that arrives: 1 unless something is in the
            // way; glass passes its transmission, and a cell partly behind it is split like
            // a shadow edge.
            let mut passed = if w > 0.0 { 1.0 } else { 0.0 };
            if let (Some(occ), true) = (self.occluders, w > 0.0) {
                self.rays += 1;
                passed =
                    occ.segment_transmittance(self.p, x + n * self.lift, [self.patch.polygon(); 2]);
                if passed < 1.0 {
                    blocked += 1;
                }
            }
            *slot = (d, w, passed);
        }
        // The cell's corners (a hair inside it, off the polygon's edges) tell whether a
        // shadow edge crosses it between the Gauss points.
        let mut rays = 4;
        if let (Some(occ), true, true) = (self.occluders, depth < MAX_DEPTH, blocked % 4 == 0) {
            for (a, b) in [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)] {
                let inset = |t: f64| (t - 0.5) * (1.0 - 1e-3) + 0.5;
                let (u, v) = (u0 + inset(a) * size, v0 + inset(b) * size);
                let x = c0.lerp(c1, u).lerp(c3.lerp(c2, u), v);
                if (x - self.p).dot(n) >= 0.0 {
                    continue;
                }
                self.rays += 1;
                rays += 1;
                let passed =
                    occ.segment_transmittance(self.p, x + n * self.lift, [self.patch.polygon(); 2]);
                if passed < 1.0 {
                    blocked += 1;
                }
            }
        }
        let cell_solid: f64 = points.iter().map(|q| q.1).sum();
        let mixed = blocked > 0 && blocked < rays;
        if mixed && depth < MAX_DEPTH && cell_solid > MIN_CELL {
            let half = size * 0.5;
            for (a, b) in [(0.0, 0.0), (0.0, half), (half, 0.0), (half, half)] {
                self.cell(u0 + a, v0 + b, half, depth + 1);
            }
            return;
        }
        if mixed {
            self.unresolved += cell_solid;
        }
        for (d, w, passed) in points {
            if passed == 0.0 {
                continue;
            }
            let w = w * passed;
            let y = basis(d.normalize());
            for (a, yk) in self.acc.iter_mut().zip(y) {
                *a += yk * w;
            }
            self.solid += w;
        }
    }
}
