//! A probe's incident radiance from the elements it sees, projected on SH L2.
//!
//! Each element j is a planar convex polygon of constant radiance `b_j / π` on its front
//! side. Its contribution to coefficient k is `b_j / π ∫ Y_k(ω) dω` over the part of its
//! solid angle the probe sees; the solid-angle integral is taken over the element's area,
//! `∫ Y_k(ω(x)) cos θ_x / r² dA`, by 2 × 2 Gauss–Legendre points on an m × m split of the
//! element (bilinear map; a triangle as a quad with two equal corners), m growing with the
//! element's size over its distance ([`SPLIT`], at most [`MAX_SPLIT`]). Visibility: nothing
//! is cast for a polygon no other polygon can come between it and the probe
//! (`Occluders::can_shadow`); a polygon or element whose corners all project, from the
//! probe, into one convex occluder is wholly hidden; elsewhere each quadrature point gets
//! one shadow ray (and its corners one each), and a cell whose rays disagree is split in four, down to [`MAX_DEPTH`]
//! levels or a cell of [`MIN_CELL`] sr, whichever comes first; the solid angle of the
//! mixed cells left bounds the error ([`Gathered::unresolved`]).

use crate::sh::{basis, Sh, COEFFICIENTS};
use glam::DVec3;
use mesher::ElementMesh;
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

/// The scene a probe gathers from.
pub struct Sources<'a> {
    pub mesh: &'a ElementMesh,
    /// Per element, its radiosity b (the radiance is b / π).
    pub radiosity: &'a [[f64; 3]],
    pub occluders: &'a Occluders,
}

/// Gathers at `p` (a point in empty space: not on any polygon).
pub fn gather(p: DVec3, sources: &Sources) -> Gathered {
    let mut out = Gathered::default();
    let occ = sources.occluders;
    let tol = visibility::PLANE_TOLERANCE * occ.scene_scale();
    // Polygons that hid something from `p`: most of what a room hides, its walls hide.
    let mut blockers: Vec<usize> = Vec::new();
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
            || hidden_by_known(p, &polygon, occ, &blockers)
        {
            continue;
        }
        let shadowable = occ.can_shadow(&polygon, &[p]);
        if shadowable && hidden(p, &polygon, occ, &mut blockers) {
            continue;
        }
        for i in range {
            let b = sources.radiosity[i];
            if b.iter().all(|&v| v == 0.0) {
                continue;
            }
            let patch = Patch::element(sources.mesh, i);
            if shadowable && hidden_by_known(p, &patch, occ, &blockers) {
                continue;
            }
            let rays = shadowable && occ.can_shadow(&patch, &[p]);
            if rays && hidden(p, &patch, occ, &mut blockers) {
                continue;
            }
            let radiance = b.map(|v| v / PI);
            integrate(p, &patch, radiance, rays.then_some(occ), &mut out);
        }
    }
    out
}

/// Whether one of `blockers` hides all of `patch` from `p` ([`covers`]).
fn hidden_by_known(p: DVec3, patch: &Patch, occ: &Occluders, blockers: &[usize]) -> bool {
    blockers.iter().any(|&b| covers(p, patch, occ, b))
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
fn integrate(
    p: DVec3,
    patch: &Patch,
    radiance: [f64; 3],
    occluders: Option<&Occluders>,
    out: &mut Gathered,
) {
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
        return;
    }
    out.elements += 1;
    for (c, a) in out.sh.iter_mut().zip(acc) {
        for (band, value) in c.iter_mut().enumerate() {
            *value += radiance[band] * a;
        }
    }
    for (s, l) in out.square.iter_mut().zip(radiance) {
        *s += l * l * solid;
    }
}

/// Sub-cells a shadowed cell is split into, at most this many times over, where its points'
/// shadow rays disagree (so a shadow's edge is found 2^MAX_DEPTH times finer).
pub const MAX_DEPTH: u32 = 6;

/// A cell whose rays disagree is not split once its solid angle (sr) is below this: about
/// 0.6° × 0.6°. What is left unresolved is bounded ([`Gathered::unresolved`]).
pub const MIN_CELL: f64 = 1e-3;

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
        let mut points = [(DVec3::ZERO, 0.0, true); 4];
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
            let mut seen = w > 0.0;
            let mut w = w;
            if let (Some(occ), true) = (self.occluders, seen) {
                self.rays += 1;
                // Glass passes its transmission; a cell partly behind it is split like a
                // shadow edge.
                let passed =
                    occ.segment_transmittance(self.p, x + n * self.lift, [self.patch.polygon(); 2]);
                if passed < 1.0 {
                    seen = passed > 0.0;
                    w *= passed;
                    blocked += 1;
                }
            }
            *slot = (d, w, seen);
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
        for (d, w, seen) in points {
            if !seen {
                continue;
            }
            let y = basis(d.normalize());
            for (a, yk) in self.acc.iter_mut().zip(y) {
                *a += yk * w;
            }
            self.solid += w;
        }
    }
}
