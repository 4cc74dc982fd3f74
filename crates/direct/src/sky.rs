//! Sky light: each element's mean illuminance from a sky dome over the scene and a ground
//! below its horizon (the paper's §2 "fictitious surfaces" carrying the outside light,
//! without declaring them: the sky is what a ray reaches when it meets no surface at all).
//!
//! "Up" is +Y (glTF's convention). A direction ω with ω_y > 0 sees the sky's radiance
//! L(ω); one with ω_y ≤ 0 sees a ground of radiance `R E_h / π` (a diffuse ground of
//! reflectance R under the sky's unobstructed horizontal illuminance E_h).
//!
//! An element's illuminance is `E = ∫ L(ω) cos θ V(ω) dω` over its front hemisphere, V = 0
//! where any polygon — front or back face — lies along ω (alpha cut-outs let rays through
//! where a texture says the surface is not there), averaged over the element:
//! - **exact** where nothing can block: an element whose polygon has no other polygon in
//!   front of its plane ([`visibility::Occluders::any_in_front`]) gets the closed form of a
//!   plane tilted β from up ([`Sky::unobstructed`]);
//! - **rays** elsewhere: k × k stratified cosine-weighted directions from k × k stratified
//!   jittered points of the element (direction strata shuffled against point strata),
//!   `E ≈ π / N Σ L(ω_i) V_i`, seeded by the element's index: the same bytes for any thread
//!   count.

use crate::for_each_cell;
use glam::DVec3;
use mesher::ElementMesh;
use rayon::prelude::*;
use std::f64::consts::PI;
use visibility::{pair_seed, Occluders, Patch, SplitMix64};

/// Rays per element some polygon may block from the sky, when the caller has no preset:
/// 32 × 32 strata. Measured on the black-walled courtyard (10 × 10 m floor, 5 m walls, 0.5 m
/// elements; tests/end_to_end/sky.rs), the floor's error against the closed form, RMS and
/// worst element: 256 rays 2.6% and 8.5%, 1024 rays 1.1% and 4.2%, 4096 rays 0.44% and
/// 1.5%, 16384 rays 0.20% and 0.78%: about N^(-0.6), the error of a visibility edge that
/// moves across the element's own directions (points and directions are each stratified,
/// not jointly).
pub const DEFAULT_SKY_SAMPLES: u32 = 1024;

/// Most rays per element (`--sky-samples`): 128 × 128 strata.
pub const MAX_SKY_SAMPLES: u32 = 16384;

/// `--ground-reflectance` when not given: a typical outdoor ground (grass, asphalt, soil).
pub const DEFAULT_GROUND_REFLECTANCE: f64 = 0.2;

/// How the sky's radiance varies over the dome.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(tag = "model", rename_all = "lowercase")
)]
pub enum SkyModel {
    /// The same radiance L in every direction above the horizon.
    Uniform { radiance: f64 },
    /// The CIE standard overcast sky (Moon & Spencer 1942; CIE S 011/E:2003 type 1): at
    /// elevation γ, `L(γ) = Lz (1 + 2 sin γ) / 3`, the horizon a third of the zenith.
    Overcast { zenith: f64 },
}

/// A sky over the scene and the ground below its horizon.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Sky {
    #[cfg_attr(feature = "serde", serde(flatten))]
    pub model: SkyModel,
    /// The ground's reflectance R (in [0, 1]): it has radiance `R E_h / π`.
    pub ground_reflectance: f64,
}

/// A `--sky` value that is not a sky.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SkyError {
    #[error("unknown sky {0:?}: expected uniform:L or overcast:Lz")]
    Unknown(String),
    #[error("the sky's radiance must be a finite number ≥ 0, got {0:?}")]
    Radiance(String),
    #[error("the ground reflectance must be in [0, 1], got {0}")]
    GroundReflectance(f64),
}

impl std::str::FromStr for SkyModel {
    type Err = SkyError;

    /// `uniform:L` or `overcast:Lz`.
    fn from_str(text: &str) -> Result<SkyModel, SkyError> {
        let (name, value) = text
            .split_once(':')
            .ok_or_else(|| SkyError::Unknown(text.to_string()))?;
        let radiance: f64 = value
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && *v >= 0.0)
            .ok_or_else(|| SkyError::Radiance(value.to_string()))?;
        match name.trim() {
            "uniform" => Ok(SkyModel::Uniform { radiance }),
            "overcast" => Ok(SkyModel::Overcast { zenith: radiance }),
            _ => Err(SkyError::Unknown(text.to_string())),
        }
    }
}

impl SkyModel {
    /// The radiance toward elevation `sin_elevation` = ω_y (> 0).
    pub fn radiance(&self, sin_elevation: f64) -> f64 {
        match *self {
            SkyModel::Uniform { radiance } => radiance,
            SkyModel::Overcast { zenith } => zenith * (1.0 + 2.0 * sin_elevation) / 3.0,
        }
    }

    /// The unobstructed horizontal illuminance E_h = ∫ L(ω) ω_y dω over the upper
    /// hemisphere: uniform π L; overcast 7π Lz / 9 (= Lz/3 (π + 2 · 2π/3)).
    pub fn horizontal_illuminance(&self) -> f64 {
        match *self {
            SkyModel::Uniform { radiance } => PI * radiance,
            SkyModel::Overcast { zenith } => 7.0 * PI * zenith / 9.0,
        }
    }

    /// The sky's part of an unobstructed plane's illuminance, its normal at `cos_tilt` = n_y
    /// (β = acos n_y from up). The upper hemisphere's share of the plane's cosine-weighted
    /// hemisphere is `∫ cos θ dω = π (1 + cos β) / 2`; the overcast sky's `sin γ` term adds
    /// `∫ ω_y (ω · n) dω = (2/3) ((π − β) cos β + sin β)` over the same lune (checked
    /// against a quadrature in this module's tests).
    pub fn unobstructed(&self, cos_tilt: f64) -> f64 {
        let c = cos_tilt.clamp(-1.0, 1.0);
        let upper = PI * (1.0 + c) / 2.0;
        match *self {
            SkyModel::Uniform { radiance } => radiance * upper,
            SkyModel::Overcast { zenith } => {
                let beta = c.acos();
                let moment = 2.0 / 3.0 * ((PI - beta) * c + beta.sin());
                zenith / 3.0 * (upper + 2.0 * moment)
            }
        }
    }
}

impl Sky {
    /// The ground's radiance `R E_h / π`.
    pub fn ground_radiance(&self) -> f64 {
        self.ground_reflectance * self.model.horizontal_illuminance() / PI
    }

    /// What a ray along the unit direction `d` that meets no surface sees.
    pub fn radiance(&self, d: DVec3) -> f64 {
        if d.y > 0.0 {
            self.model.radiance(d.y)
        } else {
            self.ground_radiance()
        }
    }

    /// The illuminance of an unobstructed plane whose unit normal has `cos_tilt` = n_y: the
    /// sky's part ([`SkyModel::unobstructed`]) and the ground's `π L_g (1 − cos β) / 2`.
    pub fn unobstructed(&self, cos_tilt: f64) -> f64 {
        let c = cos_tilt.clamp(-1.0, 1.0);
        self.model.unobstructed(c) + PI * self.ground_radiance() * (1.0 - c) / 2.0
    }

    /// Checks the values a user's options control.
    pub fn check(&self) -> Result<(), SkyError> {
        let r = match self.model {
            SkyModel::Uniform { radiance } => radiance,
            SkyModel::Overcast { zenith } => zenith,
        };
        if !(r.is_finite() && r >= 0.0) {
            return Err(SkyError::Radiance(r.to_string()));
        }
        let g = self.ground_reflectance;
        if !(g.is_finite() && (0.0..=1.0).contains(&g)) {
            return Err(SkyError::GroundReflectance(g));
        }
        Ok(())
    }
}

/// What the sky pass did (the report's `sky` object; `flux` enters it as `delivered`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SkyStats {
    /// `Σ_i A_i E_i`: lumens (the energy unit × π).
    #[cfg_attr(feature = "serde", serde(skip))]
    pub flux: f64,
    /// Rays cast.
    pub rays_cast: u64,
    /// Elements receiving some light from the sky or the ground.
    pub elements_lit: u64,
    /// Elements nothing can block from the sky: the closed form, no rays.
    pub elements_exact: u64,
    /// Elements some polygon may block: sampled by rays.
    pub elements_sampled: u64,
}

impl SkyStats {
    fn add(&mut self, o: &SkyStats) {
        self.flux += o.flux;
        self.rays_cast += o.rays_cast;
        self.elements_lit += o.elements_lit;
        self.elements_exact += o.elements_exact;
        self.elements_sampled += o.elements_sampled;
    }
}

/// The sky light of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SkyLight {
    /// Per element: mean illuminance E (the sky is grey: the same in every band).
    pub illuminance: Vec<f64>,
    pub stats: SkyStats,
}

/// Stream constant of the sky's per-element seeds (apart from the lights' streams).
const SKY_STREAM: u64 = 0x736b_795f_6c69_6768;

/// The mean sky illuminance of every element of `mesh` (see the module docs), with
/// `samples` rays (rounded to a square of strata, 1 ..= [`MAX_SKY_SAMPLES`]) per element some
/// polygon may block. `occluders` must be built from the polygons `mesh` was made from.
pub fn illuminate(sky: &Sky, mesh: &ElementMesh, occluders: &Occluders, samples: u32) -> SkyLight {
    let k = ((samples.clamp(1, MAX_SKY_SAMPLES) as f64).sqrt().round() as usize).max(1);
    // Which polygons have something in front of their plane: only their elements cast rays.
    let exposed: Vec<bool> = (0..occluders.len())
        .into_par_iter()
        .map(|p| occluders.any_in_front(&occluders.polygon(p)))
        .collect();
    let pass = Pass {
        sky,
        occluders,
        k,
        reach: 2.0 * occluders.scene_scale(),
    };
    let per_element: Vec<(f64, SkyStats)> = (0..mesh.elements.len())
        .into_par_iter()
        .map_init(Vec::new, |order, i| {
            let polygon = mesh.elements[i].polygon as usize;
            pass.element(mesh, i, exposed.get(polygon) != Some(&false), order)
        })
        .collect();
    let mut stats = SkyStats::default();
    let illuminance = per_element
        .iter()
        .map(|(e, s)| {
            stats.add(s);
            *e
        })
        .collect();
    SkyLight { illuminance, stats }
}

/// The sky, prepared for its pass over the elements.
struct Pass<'a> {
    sky: &'a Sky,
    occluders: &'a Occluders,
    /// Strata per side.
    k: usize,
    /// How far rays reach: past the whole scene from any point of it.
    reach: f64,
}

impl Pass<'_> {
    /// Element `i`'s mean illuminance and what it took; `blockable`: its polygon has some
    /// polygon in front of it. `order` is reused across elements (the direction strata's
    /// shuffle).
    fn element(
        &self,
        mesh: &ElementMesh,
        i: usize,
        blockable: bool,
        order: &mut Vec<u32>,
    ) -> (f64, SkyStats) {
        let mut stats = SkyStats::default();
        let area = mesh.elements[i].area;
        if area <= 0.0 || area.is_nan() {
            return (0.0, stats);
        }
        let patch = Patch::element(mesh, i);
        let n = patch.normal();
        let e = if blockable {
            stats.elements_sampled = 1;
            self.sampled(&patch, i, order, &mut stats)
        } else {
            stats.elements_exact = 1;
            self.sky.unobstructed(n.y)
        };
        if e > 0.0 {
            stats.elements_lit = 1;
            stats.flux = e * area;
        }
        (e, stats)
    }

    /// `π / N Σ L(ω_i) V_i` over N = k² rays: point stratum j of the element paired with
    /// cosine-weighted direction stratum `order[j]` (a per-element shuffle), both jittered.
    fn sampled(&self, patch: &Patch, i: usize, order: &mut Vec<u32>, stats: &mut SkyStats) -> f64 {
        let k = self.k;
        let n = patch.normal();
        let (t, b) = n.any_orthonormal_pair();
        let mut rng = SplitMix64::new(pair_seed(i, 0) ^ SKY_STREAM);
        let count = k * k;
        order.clear();
        order.extend(0..count as u32);
        for j in (1..count).rev() {
            order.swap(j, rng.below(j + 1));
        }
        let lift = n * self.occluders.ray_offset();
        let polygon = patch.polygon();
        let kf = k as f64;
        let (mut sum, mut next) = (0.0, 0);
        for_each_cell(patch.corners(), k, |_, _, jitter| {
            let p = jitter([rng.next_f64(), rng.next_f64()]) + lift;
            let s = order[next] as usize;
            next += 1;
            // Malley's method: a uniform point of the unit disc lifted to the hemisphere is
            // cosine-distributed; the disc point by Shirley and Chiu's concentric map, which
            // keeps strata compact (a shadow's outline crosses fewer of them than with polar
            // coordinates).
            let u = ((s % k) as f64 + rng.next_f64()) / kf;
            let v = ((s / k) as f64 + rng.next_f64()) / kf;
            let [x, y] = concentric(u, v);
            let up = (1.0 - x * x - y * y).max(0.0).sqrt();
            let d = t * x + b * y + n * up;
            stats.rays_cast += 1;
            if !self
                .occluders
                .segment_blocked(p, p + d * self.reach, [polygon, polygon])
            {
                sum += self.sky.radiance(d);
            }
        });
        PI * sum / count as f64
    }
}

/// Shirley and Chiu's concentric map of the unit square onto the unit disc (area-preserving:
/// uniform in, uniform out).
fn concentric(u: f64, v: f64) -> [f64; 2] {
    let (a, b) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    if a == 0.0 && b == 0.0 {
        return [0.0, 0.0];
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, PI / 4.0 * (b / a))
    } else {
        (b, PI / 2.0 - PI / 4.0 * (a / b))
    };
    [r * phi.cos(), r * phi.sin()]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ L(ω) (ω · n) dω over n's hemisphere, L the sky above the horizon and the ground
    /// below, by a midpoint rule in (zenith angle, azimuth) about up: independent of the
    /// closed forms.
    fn quadrature(sky: &Sky, n: DVec3, cells: usize) -> f64 {
        let mut sum = 0.0;
        let (dt, dp) = (PI / cells as f64, 2.0 * PI / cells as f64);
        for a in 0..cells {
            let theta = (a as f64 + 0.5) * dt;
            for c in 0..cells {
                let phi = (c as f64 + 0.5) * dp;
                let d = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                let cos = d.dot(n);
                if cos > 0.0 {
                    sum += sky.radiance(d) * cos * theta.sin() * dt * dp;
                }
            }
        }
        sum
    }

    #[test]
    fn closed_forms_match_a_quadrature_at_every_tilt() {
        for model in [
            SkyModel::Uniform { radiance: 1.7 },
            SkyModel::Overcast { zenith: 2.3 },
        ] {
            let sky = Sky {
                model,
                ground_reflectance: 0.3,
            };
            for beta in [0.0f64, 0.4, 1.0, PI / 2.0, 2.0, 2.9, PI] {
                let n = DVec3::new(beta.sin(), beta.cos(), 0.0);
                let exact = sky.unobstructed(n.y);
                let reference = quadrature(&sky, n, 1200);
                assert!(
                    (exact - reference).abs() < 2e-4 * sky.model.horizontal_illuminance(),
                    "{model:?} β = {beta}: {exact} against {reference}"
                );
            }
            // Facing up: E_h.
            let up = sky.unobstructed(1.0);
            assert!((up - sky.model.horizontal_illuminance()).abs() < 1e-12 * up);
        }
    }

    #[test]
    fn parses_the_sky_option() {
        assert_eq!(
            "uniform:1.5".parse::<SkyModel>(),
            Ok(SkyModel::Uniform { radiance: 1.5 })
        );
        assert_eq!(
            "overcast:3000".parse::<SkyModel>(),
            Ok(SkyModel::Overcast { zenith: 3000.0 })
        );
        assert!(matches!(
            "clear".parse::<SkyModel>(),
            Err(SkyError::Unknown(_))
        ));
        assert!(matches!(
            "uniform:-1".parse::<SkyModel>(),
            Err(SkyError::Radiance(_))
        ));
        assert!(matches!(
            "uniform:nan".parse::<SkyModel>(),
            Err(SkyError::Radiance(_))
        ));
    }
}
