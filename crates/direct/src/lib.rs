//! Direct light from punctual lights (glTF `KHR_lights_punctual`: point, spot, directional).
//!
//! The paper (Goral et al. 1984, §2) lights enclosures with "a variety of light sources": the
//! surfaces a directional source or spotlight illuminates are found, and their first reflection
//! is a diffuse emission term E(j). This crate finds, for every element, its **mean
//! illuminance** E (lux, per colour band) from every light, shadows included; the bake turns it
//! into the source term `ρ E / π` of the radiosity system (eq. 7).
//!
//! Exact where a closed form exists:
//! - a point light (and a spot over an element wholly inside its inner cone) of intensity I
//!   gives a planar element the mean illuminance `I Ω / A`, Ω the element's solid angle seen
//!   from the light (∫ cos θ / r² dA = Ω), per triangle by Van Oosterom & Strackee (1983);
//! - a directional light of illuminance E⊥ gives `E⊥ cos θ` times the element's lit share,
//!   which is found exactly: the occluders are projected along the light onto the element's
//!   plane, clipped to it, and the area of their union (`clip::union_area`) is subtracted;
//!   an element whose candidate occluders include one with alpha cut-outs is sampled by
//!   stratified shadow rays instead (a cut-out has no exact shadow polygon).
//!
//! Sampled where none does: elements a spot's cone edge crosses, or inside a light's `range`
//! window, are cut into k × k sub-cells of exact solid angle weighted by the falloff at their
//! centre; elements some polygon may shadow from a point or spot light get one shadow ray per
//! sub-cell (k = round(√samples), jittered, seeded by element and light: the same bytes for
//! any thread count). Rays are cast only where [`visibility::Occluders::can_shadow`] finds a
//! possible occluder, first per polygon, then per element; elements outside a spot's outer
//! cone, behind a light, or beyond its range get exactly 0 and no rays.
//!
//! It is not the radiosity solver and knows nothing of form factors, links or presets.

pub mod envmap;
pub mod sky;

use glam::{DVec2, DVec3};
use mesher::ElementMesh;
use rayon::prelude::*;
use scene::{Light, LightKind};
use visibility::{pair_seed, strata, Occluders, Patch, SplitMix64};

/// Shadow rays per element some polygon may shadow from a point or spot light
/// (`--light-samples`), when the caller has no preset: 4 × 4 strata.
pub const DEFAULT_SAMPLES: u32 = 16;

/// Sub-cells per side where only a spot's falloff or a range window varies over an element
/// (no shadows): 8 × 8 cells of exact solid angle, the falloff at each centre.
pub const FALLOFF_STRATA: usize = 8;

/// How to sample what has no closed form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Shadow rays per element (rounded to a square of strata, 1 ..= 1024).
    pub samples: u32,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            samples: DEFAULT_SAMPLES,
        }
    }
}

/// What one light's direct-light pass did (the bake report's per-light counts; `flux` enters
/// the report as `delivered`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct LightStats {
    /// `Σ_i A_i E_i / I`: the elements' area-weighted illuminance per unit intensity (m² for a
    /// directional light's lux, sr·… for candela: m² · lux / cd), so the light delivered
    /// `flux × I` lumens, `flux × I / π` in the report's energy unit.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub flux: f64,
    /// Elements receiving some light from it.
    pub elements_lit: u64,
    /// Elements facing it that some polygon may shadow (rays or clipping decided them).
    pub elements_shadowed: u64,
    /// Shadow rays cast (point and spot lights).
    pub rays_cast: u64,
    /// Elements whose falloff (spot edge, range) was integrated over sub-cells.
    pub elements_sampled: u64,
    /// Elements whose lit share was found by exact clipping (directional lights).
    pub elements_clipped: u64,
}

impl LightStats {
    fn add(&mut self, o: &LightStats) {
        self.flux += o.flux;
        self.elements_lit += o.elements_lit;
        self.elements_shadowed += o.elements_shadowed;
        self.rays_cast += o.rays_cast;
        self.elements_sampled += o.elements_sampled;
        self.elements_clipped += o.elements_clipped;
    }
}

/// The direct light of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct DirectLight {
    /// Per element: mean illuminance E per band (lux: the lights' colour × intensity).
    pub illuminance: Vec<[f64; 3]>,
    /// Per light, in the order given.
    pub stats: Vec<LightStats>,
    /// Per element: some light's shadow covers part of it but not all (a sun's exact lit
    /// share, or the share of a point or spot light's shadow rays that reach it, strictly
    /// between 0 and 1): a shadow edge crosses it.
    pub partly_lit: Vec<bool>,
    /// Per element: a key of how shadows fall on it, light by light (lit, in shadow, or
    /// partly); elements with the same key are on the same side of every shadow edge, so
    /// smoothing may blend them. Unshadowed elements count as lit (a spot's cone edge is not
    /// a shadow: its falloff is continuous).
    pub shadow_class: Vec<u64>,
}

/// How a light's shadows fall on one element.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shade {
    /// No shadow on it (or nothing could shadow it).
    Lit,
    /// Wholly in shadow.
    Dark,
    /// A shadow edge crosses it.
    Partial,
}

/// Lit shares within this of 0 or 1 are whole: rounding of the clipped areas, or a shadow
/// edge along the element's edge, is not a shadow edge across it.
pub const SHARE_TOLERANCE: f64 = 1e-9;

impl Shade {
    /// The shade of a lit share in [0, 1].
    pub fn of_share(share: f64) -> Shade {
        if share <= SHARE_TOLERANCE {
            Shade::Dark
        } else if share >= 1.0 - SHARE_TOLERANCE {
            Shade::Lit
        } else {
            Shade::Partial
        }
    }
}

/// The mean illuminance of every element of `mesh` from `lights` (see the crate docs).
/// `occluders` must be built from the polygons `mesh` was made from.
pub fn illuminate(
    lights: &[Light],
    mesh: &ElementMesh,
    occluders: &Occluders,
    options: &Options,
) -> DirectLight {
    let mut illuminance = vec![[0.0; 3]; mesh.elements.len()];
    let mut partly_lit = vec![false; mesh.elements.len()];
    let mut shadow_class = vec![0xcbf2_9ce4_8422_2325u64; mesh.elements.len()];
    let mut stats = Vec::with_capacity(lights.len());
    for (l, light) in lights.iter().enumerate() {
        let pass = LightPass::new(light, l, occluders, options);
        // Which polygons some other polygon may shadow from this light: elements of the others
        // need no per-element test at all.
        let polygon_shadowed: Vec<bool> = (0..occluders.len())
            .into_par_iter()
            .map(|k| pass.may_shadow(&occluders.polygon(k)))
            .collect();
        let per_element: Vec<(f64, LightStats, Shade)> = (0..mesh.elements.len())
            .into_par_iter()
            .map_init(Scratch::default, |scratch, i| {
                let shadowed = polygon_shadowed[mesh.elements[i].polygon as usize];
                pass.element(mesh, i, shadowed, scratch)
            })
            .collect();
        let band = light.band_intensity();
        let mut total = LightStats::default();
        for (i, (e, (g, s, shade))) in illuminance.iter_mut().zip(&per_element).enumerate() {
            for c in 0..3 {
                e[c] += g * band[c];
            }
            total.add(s);
            partly_lit[i] |= *shade == Shade::Partial;
            // FNV-1a over the shades, light by light.
            shadow_class[i] ^= *shade as u64 + 1;
            shadow_class[i] = shadow_class[i].wrapping_mul(0x0100_0000_01b3);
        }
        stats.push(total);
    }
    DirectLight {
        illuminance,
        stats,
        partly_lit,
        shadow_class,
    }
}

/// Buffers reused across the elements one thread handles (no allocation per element).
#[derive(Default)]
struct Scratch {
    candidates: Vec<usize>,
    clipped: Vec<Vec<DVec2>>,
    out: Vec<DVec2>,
    tmp: Vec<DVec2>,
}

/// One light, prepared for its pass over the elements.
struct LightPass<'a> {
    light: &'a Light,
    index: usize,
    occluders: &'a Occluders,
    cone: Option<Cone>,
    strata: usize,
    /// How far directional shadow segments reach toward the light: past the whole scene.
    reach: f64,
    /// Points closer than this to a plane are on it (the visibility crate's tolerance).
    tol: f64,
}

impl<'a> LightPass<'a> {
    fn new(light: &'a Light, index: usize, occluders: &'a Occluders, options: &Options) -> Self {
        let cone = match light.kind {
            LightKind::Spot { inner, outer } => Some(Cone::new(light.direction, inner, outer)),
            _ => None,
        };
        LightPass {
            light,
            index,
            occluders,
            cone,
            strata: strata(options.samples),
            reach: 2.0 * occluders.scene_scale(),
            tol: visibility::PLANE_TOLERANCE * occluders.scene_scale(),
        }
    }

    /// The far ends of the receiver's light segments (see `Occluders::can_shadow`).
    fn far_points(&self, receiver: &Patch) -> ([DVec3; 4], usize) {
        match self.light.kind {
            LightKind::Directional => {
                let mut far = [DVec3::ZERO; 4];
                let c = receiver.corners();
                for (f, &p) in far.iter_mut().zip(c) {
                    *f = p - self.light.direction * self.reach;
                }
                (far, c.len())
            }
            _ => ([self.light.position; 4], 1),
        }
    }

    /// Whether the patch faces the light and some polygon may shadow part of it.
    fn may_shadow(&self, receiver: &Patch) -> bool {
        if !self.faces(receiver) {
            return false;
        }
        let (far, n) = self.far_points(receiver);
        self.occluders.can_shadow(receiver, &far[..n])
    }

    /// Some corner of the patch sees the light from its front.
    fn faces(&self, receiver: &Patch) -> bool {
        let n = receiver.normal();
        match self.light.kind {
            LightKind::Directional => -self.light.direction.dot(n) > 0.0,
            _ => receiver
                .corners()
                .iter()
                .any(|&c| (self.light.position - c).dot(n) > self.tol),
        }
    }

    /// Element `i`: its illuminance per unit light intensity, what it took, and how the
    /// light's shadows fall on it.
    fn element(
        &self,
        mesh: &ElementMesh,
        i: usize,
        polygon_shadowed: bool,
        scratch: &mut Scratch,
    ) -> (f64, LightStats, Shade) {
        let patch = Patch::element(mesh, i);
        let area = mesh.elements[i].area;
        let mut stats = LightStats::default();
        if area <= 0.0 || area.is_nan() {
            return (0.0, stats, Shade::Lit);
        }
        let mut shade = Shade::Lit;
        let g = match self.light.kind {
            LightKind::Directional => {
                self.directional(&patch, i, polygon_shadowed, scratch, &mut stats, &mut shade)
            }
            _ => self.point(&patch, i, area, polygon_shadowed, &mut stats, &mut shade),
        };
        if g > 0.0 {
            stats.elements_lit = 1;
            stats.flux = g * area;
        }
        (g, stats, shade)
    }

    /// Point and spot lights: (1/A) ∫ falloff · visibility · cos θ / r² dA.
    fn point(
        &self,
        patch: &Patch,
        i: usize,
        area: f64,
        polygon_shadowed: bool,
        stats: &mut LightStats,
        shade: &mut Shade,
    ) -> f64 {
        let l = self.light.position;
        let n = patch.normal();
        let corners = patch.corners();
        // The light must be in front of the element's plane (it is planar: one test).
        if (l - corners[0]).dot(n) <= self.tol {
            return 0.0;
        }
        let mut uniform = true;
        if let Some(cone) = &self.cone {
            let (lowest, highest) = cone.cos_range(l, corners);
            if highest <= cone.cos_outer {
                return 0.0; // wholly outside the outer cone: exactly dark, no rays
            }
            uniform &= lowest >= cone.cos_full;
        }
        if let Some(range) = self.light.range {
            if nearest_distance(l, corners) >= range {
                return 0.0;
            }
            uniform = false;
        }
        let shadowed = polygon_shadowed && self.occluders.can_shadow(patch, &[l]);
        if uniform && !shadowed {
            return solid_angle(l, corners) / area;
        }
        stats.elements_shadowed = u64::from(shadowed);
        stats.elements_sampled = u64::from(!uniform);
        let k = if shadowed {
            self.strata
        } else {
            FALLOFF_STRATA
        };
        let mut rng = SplitMix64::new(pair_seed(i, self.index) ^ 0x6c69_6768_7473);
        let lift = n * self.occluders.ray_offset();
        let polygon = patch.polygon();
        let mut sum = 0.0;
        let (mut rays, mut blocked, mut clear) = (0u32, 0u32, 0u32);
        for_each_cell(corners, k, |cell, centre, jitter| {
            let w = self.falloff(centre - l);
            if w == 0.0 {
                return;
            }
            let mut passed = 1.0;
            if shadowed {
                let p = jitter([rng.next_f64(), rng.next_f64()]) + lift;
                // The ray stops just short of the light, so a lamp mounted on a ceiling is not
                // shadowed by the ceiling it touches.
                let to_light = l - p;
                let end = l - to_light.normalize_or_zero() * self.occluders.ray_offset();
                stats.rays_cast += 1;
                rays += 1;
                // Glass passes its transmission of the light.
                passed = self
                    .occluders
                    .segment_transmittance(p, end, [polygon, polygon]);
                if passed <= 0.0 {
                    blocked += 1;
                    return;
                }
                clear += u32::from(passed >= 1.0);
            }
            sum += w * passed * solid_angle(l, cell);
        });
        if rays > 0 {
            *shade = if clear == rays {
                Shade::Lit
            } else if blocked == rays {
                Shade::Dark
            } else {
                Shade::Partial
            };
        }
        sum / area
    }

    /// The spot's angular falloff and the range window toward `offset` (from the light).
    fn falloff(&self, offset: DVec3) -> f64 {
        let r = offset.length();
        if r <= 0.0 || r.is_nan() {
            return 0.0;
        }
        let mut w = 1.0;
        if let Some(cone) = &self.cone {
            w *= cone.falloff(offset / r);
        }
        if let Some(range) = self.light.range {
            // KHR_lights_punctual, "Range Property" (recommended):
            // "attenuation = max( min( 1.0 - ( current_distance / range )^4, 1 ), 0 ) /
            //  current_distance^2" — the 1/r² is in the solid angle.
            w *= (1.0 - (r / range).powi(4)).clamp(0.0, 1.0);
        }
        w
    }

    /// Directional lights: E⊥ cos θ × the element's exact lit share.
    fn directional(
        &self,
        patch: &Patch,
        i: usize,
        polygon_shadowed: bool,
        scratch: &mut Scratch,
        stats: &mut LightStats,
        shade: &mut Shade,
    ) -> f64 {
        let n = patch.normal();
        let d = self.light.direction;
        let cos = -d.dot(n);
        if cos <= 0.0 || cos.is_nan() {
            return 0.0;
        }
        if !polygon_shadowed {
            return cos;
        }
        let (far, count) = self.far_points(patch);
        self.occluders
            .shadow_candidates(patch, &far[..count], &mut scratch.candidates);
        if scratch.candidates.is_empty() {
            return cos;
        }
        stats.elements_shadowed = 1;
        let panes = scratch
            .candidates
            .iter()
            .filter(|&&k| {
                let t = self.occluders.transmission(k);
                t > 0.0 && t < 1.0
            })
            .count();
        if panes > 1
            || scratch
                .candidates
                .iter()
                .any(|&k| self.occluders.has_cutouts(k))
        {
            // An occluder with alpha cut-outs has no exact shadow polygon, nor have two
            // glass panes a simple exact product: rays.
            let share = self.sampled_share(patch, i, stats);
            *shade = Shade::of_share(share);
            return cos * share;
        }
        stats.elements_clipped = 1;
        let lit = self.lit_share(patch, cos, scratch);
        *shade = Shade::of_share(lit);
        cos * lit
    }

    /// The share of `patch` lit by the sun from stratified, per-element-seeded shadow rays
    /// (one per cell, weighted by the cell's area), for occluders with alpha cut-outs.
    fn sampled_share(&self, patch: &Patch, i: usize, stats: &mut LightStats) -> f64 {
        let n = patch.normal();
        let lift = n * self.occluders.ray_offset();
        let polygon = patch.polygon();
        let mut rng = SplitMix64::new(pair_seed(i, self.index) ^ 0x0073_756e);
        let (mut lit, mut total) = (0.0, 0.0);
        for_each_cell(patch.corners(), self.strata, |cell, _, jitter| {
            let area = if cell.len() == 4 {
                0.5 * (cell[2] - cell[0]).cross(cell[3] - cell[1]).length()
            } else {
                0.5 * (cell[1] - cell[0]).cross(cell[2] - cell[0]).length()
            };
            total += area;
            let p = jitter([rng.next_f64(), rng.next_f64()]) + lift;
            let end = p - self.light.direction * self.reach;
            stats.rays_cast += 1;
            lit += area
                * self
                    .occluders
                    .segment_transmittance(p, end, [polygon, polygon]);
        });
        if total > 0.0 {
            (lit / total).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    /// The share of `patch` no candidate occluder's shadow covers: each occluder's part in
    /// front of the patch's plane, projected along the light onto it, clipped to the patch;
    /// 1 − (area of their union) / A, exactly (up to rounding).
    fn lit_share(&self, patch: &Patch, cos: f64, scratch: &mut Scratch) -> f64 {
        let n = patch.normal();
        let d = self.light.direction;
        let corners = patch.corners();
        let origin = corners[0];
        let u = (corners[1] - origin).normalize_or_zero();
        let v = n.cross(u);
        let to_2d = |p: DVec3| DVec2::new((p - origin).dot(u), (p - origin).dot(v));
        let receiver: Vec<DVec2> = corners.iter().map(|&p| to_2d(p)).collect();
        let receiver_area = clip::signed_area(&receiver).abs();
        if receiver_area <= 0.0 || receiver_area.is_nan() {
            return 1.0;
        }
        let Scratch {
            candidates,
            clipped,
            out,
            tmp,
        } = scratch;
        let mut used = 0;
        // The one glass pane among the candidates (the caller sends two or more to rays):
        // its shadow's index in `clipped` and its transmission.
        let mut pane: Option<(usize, f64)> = None;
        for &k in candidates.iter() {
            let passes = self.occluders.transmission(k);
            if passes >= 1.0 {
                continue; // casts no shadow
            }
            let occluder = self.occluders.polygon(k);
            // The occluder's part at height ≥ 0 above the receiver's plane, projected along d.
            tmp.clear();
            let c = occluder.corners();
            for e in 0..c.len() {
                let (a, b) = (c[e], c[(e + 1) % c.len()]);
                let (ha, hb) = ((a - origin).dot(n), (b - origin).dot(n));
                if ha >= 0.0 {
                    tmp.push(to_2d(a + d * (ha / cos)));
                }
                if (ha >= 0.0) != (hb >= 0.0) {
                    let x = a + (b - a) * (ha / (ha - hb));
                    tmp.push(to_2d(x));
                }
            }
            if tmp.len() < 3 {
                continue;
            }
            if used == clipped.len() {
                clipped.push(Vec::new());
            }
            clip::clip_convex(tmp, &receiver, out, &mut clipped[used]);
            if out.len() < 3 {
                continue;
            }
            let covered = clip::signed_area(out).abs();
            if passes <= 0.0 && covered >= receiver_area * (1.0 - 1e-12) {
                return 0.0; // one opaque shadow covers it all
            }
            std::mem::swap(out, &mut clipped[used]);
            if passes > 0.0 {
                pane = Some((used, passes));
            }
            used += 1;
        }
        if used == 0 {
            return 1.0;
        }
        let shadows: Vec<&[DVec2]> = clipped[..used].iter().map(|p| p.as_slice()).collect();
        let covered = clip::union_area(&shadows);
        // Behind one pane of transmission t, the light lost is the opaque shadows' union U_o
        // and 1 − t of the rest of the union U: t U_o + (1 − t) U.
        let covered = match pane {
            None => covered,
            Some((g, t)) => {
                let opaque: Vec<&[DVec2]> = shadows
                    .iter()
                    .enumerate()
                    .filter(|&(s, _)| s != g)
                    .map(|(_, p)| *p)
                    .collect();
                let opaque = if opaque.is_empty() {
                    0.0
                } else {
                    clip::union_area(&opaque)
                };
                t * opaque + (1.0 - t) * covered
            }
        };
        // Relative to the receiver's own 2D area, so rounding of A cancels.
        (1.0 - covered / receiver_area).clamp(0.0, 1.0)
    }
}

/// A spot's cones, as the extension's recommended falloff uses them (KHR_lights_punctual,
/// "Inner and Outer Cone Angles"):
/// ```text
/// lightAngleScale = 1.0f / max(0.001f, cos(innerConeAngle) - cos(outerConeAngle));
/// lightAngleOffset = -cos(outerConeAngle) * lightAngleScale;
/// cd = dot(spotlightDir, normalizedLightVector);
/// angularAttenuation = saturate(cd * lightAngleScale + lightAngleOffset);
/// angularAttenuation *= angularAttenuation;
/// ```
#[derive(Clone, Copy, Debug)]
struct Cone {
    axis: DVec3,
    scale: f64,
    offset: f64,
    cos_outer: f64,
    /// Above this cosine the falloff is exactly 1 (cos inner, or just above cos outer when the
    /// cones nearly coincide).
    cos_full: f64,
}

impl Cone {
    fn new(axis: DVec3, inner: f64, outer: f64) -> Cone {
        let cos_outer = outer.cos();
        let width = (inner.cos() - cos_outer).max(0.001);
        Cone {
            axis,
            scale: 1.0 / width,
            offset: -cos_outer / width,
            cos_outer,
            cos_full: cos_outer + width,
        }
    }

    fn falloff(&self, direction: DVec3) -> f64 {
        let x = (self.axis.dot(direction) * self.scale + self.offset).clamp(0.0, 1.0);
        x * x
    }

    /// The least and greatest cos(angle to the axis) over the convex polygon `corners`, seen
    /// from `l`. The greatest: 1 if the axis pierces it, else the best point of an edge; the
    /// angle along a line is quasiconvex (its sublevel sets are cones), so each edge has one
    /// stationary point, where d/dt [a·(u + t d) / |u + t d|] = 0:
    /// t* = ((a·u)(u·d) − (a·d)|u|²) / ((a·d)(u·d) − (a·u)|d|²).
    /// The least is at a corner whenever it is positive (the cone {angle ≤ max} is convex and
    /// holds every corner), which is the only case a caller relies on.
    fn cos_range(&self, l: DVec3, corners: &[DVec3]) -> (f64, f64) {
        let a = self.axis;
        let cos_at = |p: DVec3| {
            let w = p - l;
            let len = w.length();
            if len > 0.0 {
                a.dot(w) / len
            } else {
                1.0
            }
        };
        let mut lowest = f64::INFINITY;
        let mut highest = f64::NEG_INFINITY;
        for (k, &p) in corners.iter().enumerate() {
            let c = cos_at(p);
            lowest = lowest.min(c);
            highest = highest.max(c);
            let q = corners[(k + 1) % corners.len()];
            let (u, d) = (p - l, q - p);
            let den = a.dot(d) * u.dot(d) - a.dot(u) * d.length_squared();
            if den != 0.0 {
                let t = (a.dot(u) * u.dot(d) - a.dot(d) * u.length_squared()) / den;
                if t.is_finite() && t > 0.0 && t < 1.0 {
                    highest = highest.max(cos_at(p + d * t));
                }
            }
        }
        if axis_pierces(l, a, corners) {
            highest = 1.0;
        }
        (lowest, highest)
    }
}

/// Whether the ray from `l` along `a` meets the convex polygon `corners` (counter-clockwise).
fn axis_pierces(l: DVec3, a: DVec3, corners: &[DVec3]) -> bool {
    let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
    let along = a.dot(n);
    if along == 0.0 {
        return false;
    }
    let t = (corners[0] - l).dot(n) / along;
    if t <= 0.0 || t.is_nan() {
        return false;
    }
    let x = l + a * t;
    (0..corners.len()).all(|k| {
        let (p, q) = (corners[k], corners[(k + 1) % corners.len()]);
        (q - p).cross(x - p).dot(n) >= 0.0
    })
}

/// The distance from `l` to the nearest point of the convex polygon `corners`.
fn nearest_distance(l: DVec3, corners: &[DVec3]) -> f64 {
    let n = (corners[1] - corners[0])
        .cross(corners[2] - corners[0])
        .normalize_or_zero();
    let h = (l - corners[0]).dot(n);
    let foot = l - n * h;
    let inside = (0..corners.len()).all(|k| {
        let (p, q) = (corners[k], corners[(k + 1) % corners.len()]);
        (q - p).cross(foot - p).dot(n) >= 0.0
    });
    if inside {
        return h.abs();
    }
    (0..corners.len())
        .map(|k| {
            let (p, q) = (corners[k], corners[(k + 1) % corners.len()]);
            let d = q - p;
            let t = ((l - p).dot(d) / d.length_squared()).clamp(0.0, 1.0);
            (l - (p + d * t)).length()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The solid angle of the planar convex polygon `corners` seen from `l` (in front of it):
/// a fan of triangles, each by Van Oosterom & Strackee (1983),
/// tan(Ω/2) = a·(b × c) / (|a||b||c| + (a·b)|c| + (a·c)|b| + (b·c)|a|).
pub fn solid_angle(l: DVec3, corners: &[DVec3]) -> f64 {
    let mut total = 0.0;
    for k in 1..corners.len() - 1 {
        let (a, b, c) = (corners[0] - l, corners[k] - l, corners[k + 1] - l);
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let numerator = a.dot(b.cross(c)).abs();
        let denominator = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
        total += 2.0 * numerator.atan2(denominator);
    }
    total
}

/// Cuts the convex polygon `corners` (3 or 4) into k × k sub-cells and calls `f(cell corners,
/// cell centre, jitter)`, `jitter` mapping [0, 1)² to a uniform point of the cell. Quads: a
/// bilinear grid (planar cells, as the quad is planar); triangles: the k² triangles of the
/// barycentric grid.
fn for_each_cell(
    corners: &[DVec3],
    k: usize,
    mut f: impl FnMut(&[DVec3], DVec3, &dyn Fn([f64; 2]) -> DVec3),
) {
    let kf = k as f64;
    if corners.len() == 4 {
        let at = |s: f64, t: f64| {
            corners[0] * ((1.0 - s) * (1.0 - t))
                + corners[1] * (s * (1.0 - t))
                + corners[2] * (s * t)
                + corners[3] * ((1.0 - s) * t)
        };
        for b in 0..k {
            for a in 0..k {
                let (s0, t0) = (a as f64 / kf, b as f64 / kf);
                let (s1, t1) = ((a + 1) as f64 / kf, (b + 1) as f64 / kf);
                let cell = [at(s0, t0), at(s1, t0), at(s1, t1), at(s0, t1)];
                let centre = at((s0 + s1) * 0.5, (t0 + t1) * 0.5);
                let jitter = |r: [f64; 2]| at(s0 + r[0] / kf, t0 + r[1] / kf);
                f(&cell, centre, &jitter);
            }
        }
    } else {
        let (o, e1, e2) = (corners[0], corners[1] - corners[0], corners[2] - corners[0]);
        let at = |i: usize, j: usize| o + e1 * (i as f64 / kf) + e2 * (j as f64 / kf);
        for j in 0..k {
            for i in 0..k - j {
                let up = [at(i, j), at(i + 1, j), at(i, j + 1)];
                triangle_cell(&up, &mut f);
                if i + j + 1 < k {
                    let down = [at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                    triangle_cell(&down, &mut f);
                }
            }
        }
    }
}

/// One triangular sub-cell: centroid, and a uniform point by the square-to-triangle map
/// (1 − √u, √u (1 − v), √u v).
fn triangle_cell(
    cell: &[DVec3; 3],
    f: &mut impl FnMut(&[DVec3], DVec3, &dyn Fn([f64; 2]) -> DVec3),
) {
    let centre = (cell[0] + cell[1] + cell[2]) / 3.0;
    let jitter = |r: [f64; 2]| {
        let s = r[0].sqrt();
        cell[0] * (1.0 - s) + cell[1] * (s * (1.0 - r[1])) + cell[2] * (s * r[1])
    };
    f(cell, centre, &jitter);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Solid angle of an axis-aligned rectangle [0, x] × [0, y] seen from height z above its
    /// corner: Ω = atan(x y / (z √(x² + y² + z²))) (a closed form independent of the fan).
    fn corner_rectangle(x: f64, y: f64, z: f64) -> f64 {
        (x * y / (z * (x * x + y * y + z * z).sqrt())).atan()
    }

    #[test]
    fn solid_angle_matches_the_rectangle_closed_form() {
        let l = DVec3::new(0.0, 0.0, 2.0);
        let quad = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(3.0, 0.0, 0.0),
            DVec3::new(3.0, 1.5, 0.0),
            DVec3::new(0.0, 1.5, 0.0),
        ];
        let exact = corner_rectangle(3.0, 1.5, 2.0);
        assert!((solid_angle(l, &quad) - exact).abs() < 1e-14 * exact);
        // The same rectangle cut into sub-cells sums to the same.
        for k in [1, 3, 8] {
            let mut sum = 0.0;
            for_each_cell(&quad, k, |cell, _, _| sum += solid_angle(l, cell));
            assert!((sum - exact).abs() < 1e-13, "k = {k}");
        }
        let tri = [quad[0], quad[1], quad[2]];
        let mut sum = 0.0;
        for_each_cell(&tri, 5, |cell, _, _| sum += solid_angle(l, cell));
        assert!((sum - solid_angle(l, &tri)).abs() < 1e-13);
        // A hemisphere: a huge square right below the light.
        let big = 1e7;
        let floor = [
            DVec3::new(-big, -big, 0.0),
            DVec3::new(big, -big, 0.0),
            DVec3::new(big, big, 0.0),
            DVec3::new(-big, big, 0.0),
        ];
        let omega = solid_angle(DVec3::new(0.0, 0.0, 1.0), &floor);
        assert!((omega - 2.0 * std::f64::consts::PI).abs() < 1e-6);
    }

    /// The spot falloff integrated over elements its cone edge crosses: FALLOFF_STRATA² cells
    /// against 256² cells, the error relative to the element's unattenuated light I Ω / A.
    #[test]
    fn falloff_quadrature_of_straddling_elements_converges() {
        let l = DVec3::new(0.0, 3.0, 0.0);
        let cone = Cone::new(DVec3::NEG_Y, 20f64.to_radians(), 30f64.to_radians());
        let integrate = |corners: &[DVec3], k: usize| {
            let mut sum = 0.0;
            for_each_cell(corners, k, |cell, centre, _| {
                sum += cone.falloff((centre - l).normalize()) * solid_angle(l, cell);
            });
            sum
        };
        let mut worst = 0.0f64;
        for i in 0..16 {
            // 0.25 m squares along x from 0.9 m to 2.0 m: across the penumbra (1.09 … 1.73 m).
            let x0 = 0.9 + 0.07 * i as f64;
            let square = [
                DVec3::new(x0, 0.0, 0.1),
                DVec3::new(x0, 0.0, 0.35),
                DVec3::new(x0 + 0.25, 0.0, 0.35),
                DVec3::new(x0 + 0.25, 0.0, 0.1),
            ];
            let reference = integrate(&square, 256);
            let coarse = integrate(&square, FALLOFF_STRATA);
            // Relative to the element's light without falloff, I Ω / A: what it would get
            // inside the inner cone.
            let error = (coarse - reference).abs() / solid_angle(l, &square);
            worst = worst.max(error);
        }
        // Measured: 5.1e-4 at worst (penumbra 0.9 … 1.7 m from the foot, 0.25 m elements).
        assert!(
            worst < 1e-3,
            "worst error {worst:.2e} of the unattenuated light"
        );
    }

    #[test]
    fn cone_range_finds_the_closest_point_of_an_edge() {
        // Light at the origin looking along −y; a segment-like thin quad crossing in front of
        // it at y = −1 from x = 1 to x = 3: closest angle at x = 1, not at a stationary point.
        let cone = Cone::new(DVec3::NEG_Y, 0.1, 0.2);
        let l = DVec3::ZERO;
        let quad = [
            DVec3::new(-1.0, -1.0, -1.0),
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(1.0, -1.0, 1.0),
            DVec3::new(-1.0, -1.0, 1.0),
        ];
        // Pierced: the axis hits the middle.
        assert_eq!(cone.cos_range(l, &quad).1, 1.0);
        // A square off to the side, y from −1: nearest direction at (1, −1, 0) on an edge's
        // interior (corners are at z = ±1).
        let side = [
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(3.0, -1.0, -1.0),
            DVec3::new(3.0, -1.0, 1.0),
            DVec3::new(1.0, -1.0, 1.0),
        ];
        let (_, highest) = cone.cos_range(l, &side);
        assert!((highest - 1.0 / 2f64.sqrt()).abs() < 1e-15);
    }
}
