//! Sky light: each element's mean illuminance from a sky dome over the scene and a ground
//! below its horizon (the paper's §2 "fictitious surfaces" carrying the outside light,
//! without declaring them: the sky is what a ray reaches when it meets no surface at all).
//!
//! "Up" is +Y (glTF's convention). A direction ω with ω_y > 0 sees the sky's radiance
//! L(ω); one with ω_y ≤ 0 sees a ground of radiance `R E_h / π` (a diffuse ground of
//! reflectance R under the sky's unobstructed horizontal illuminance E_h). A map sky
//! (`SkyModel::Map`, [`crate::envmap`]) gives every direction its texel's radiance, per band:
//! its lower half is the ground.
//!
//! An element's illuminance is `E = ∫ L(ω) cos θ V(ω) dω` over its front hemisphere, V = 0
//! where any opaque polygon — front or back face — lies along ω (alpha cut-outs let rays
//! through where a texture says the surface is not there), else the product of the
//! transmissions of the glass along ω (`Occluders::segment_transmittance`: a window passes
//! the sky × t), averaged over the element:
//! - **exact** where nothing can block: an element whose polygon has no other polygon in
//!   front of its plane ([`visibility::Occluders::any_in_front`]) gets the closed form of a
//!   plane tilted β from up ([`Sky::unobstructed`]);
//! - **rays** elsewhere, N = k × k per element in two stages (docs/lights.md, "Sky"):
//!   (k/4)² cosine-weighted **probe** rays per element mark, on a grid over each face of the
//!   scene's bounding box, where rays that met no surface left the box (`Portals`: the
//!   openings, found, not declared); then the other rays, cosine-weighted ones and ones
//!   **aimed** at the open cells (drawn by the projected solid angle each subtends from the
//!   element), combined by the balance heuristic: `E ≈ Σ L V cos θ / (n_c p_c + n_a p_a)`,
//!   unbiased whatever the probes found. Elements whose probes mostly escaped use cosine
//!   rays alone, `π / n_c Σ L V`. Under a map a quarter of the rays are drawn from the
//!   map's own distribution and join the same heuristic. Seeded by the element's index: the same bytes for any
//!   thread count.

use crate::envmap::EnvironmentMap;
use crate::for_each_cell;
use glam::DVec3;
use mesher::ElementMesh;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::path::PathBuf;
use std::sync::Arc;
use visibility::{pair_seed, Occluders, Patch, SplitMix64};

/// Rays per element some polygon may block from the sky, when the caller has no preset:
/// 32 × 32. Measured (tests/end_to_end/sky.rs), RMS and worst element against independent
/// references: the black-walled courtyard's floor (10 × 10 m, 5 m walls, 0.5 m elements)
/// 256 rays 2.0% and 5.9%, 1024 rays 0.56% and 2.2%, 4096 rays 0.21% and 0.98%; the daylight
/// factors of a black-walled 4 × 3 × 4 m room's floor through one 2 × 1.5 m window under the
/// overcast sky 256 rays 3.4% and 9.5%, 1024 rays 1.5% and 3.7%, 4096 rays 0.89% and 2.9%.
pub const DEFAULT_SKY_SAMPLES: u32 = 1024;

/// Most rays per element (`--sky-samples`): 128 × 128 strata.
pub const MAX_SKY_SAMPLES: u32 = 16384;

/// `--ground-reflectance` when not given: a typical outdoor ground (grass, asphalt, soil).
pub const DEFAULT_GROUND_REFLECTANCE: f64 = 0.2;

/// How the sky's radiance varies over the dome.
#[derive(Clone, Debug, PartialEq)]
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
    /// An equirectangular environment map (`.hdr` or `.exr`; orientation in
    /// [`crate::envmap`]) over the whole sphere: its lower half is the ground. `map` is
    /// `None` until the job loads the file ([`Sky::check`] refuses it then).
    Map {
        file: PathBuf,
        #[cfg_attr(feature = "serde", serde(skip))]
        map: Option<Arc<EnvironmentMap>>,
    },
    /// The CIE standard clear sky (CIE S 011/E:2003 and ISO 15469 type 12: gradation
    /// a = −1, b = −0.32; indicatrix c = 10, d = −3, e = 0.45; [`clear_sky`]) of zenith
    /// luminance Lz with the sun toward `sun` (unit, above the horizon). Once the sun is
    /// known (the scene's directional light, or `--sun-direction`) it is rendered into an
    /// equirectangular map ([`clear_sky_map`], whose lower half is the ground R E_h / π) and
    /// then lights the scene as a map does. The sun's own disc is not in it: that is the
    /// directional light.
    Clear {
        zenith: f64,
        sun: Option<[f64; 3]>,
        #[cfg_attr(feature = "serde", serde(skip))]
        map: Option<Arc<EnvironmentMap>>,
    },
}

/// Gradation and indicatrix parameters of the CIE standard clear sky (type 12).
const CLEAR: (f64, f64, f64, f64, f64) = (-1.0, -0.32, 10.0, -3.0, 0.45);

/// The CIE standard clear sky's relative luminance `L / Lz` (CIE S 011/E:2003, type 12)
/// toward a sky element at zenith angle `z`, `chi` from the sun, the sun at zenith angle
/// `zs`: `f(χ) φ(Z) / (f(Zs) φ(0))` with the gradation `φ(Z) = 1 + a e^(b / cos Z)` (1 at the
/// horizon) and the indicatrix `f(χ) = 1 + c (e^(dχ) − e^(dπ/2)) + e cos²χ`.
pub fn clear_sky(z: f64, chi: f64, zs: f64) -> f64 {
    let (a, b, c, d, e) = CLEAR;
    let phi = |z: f64| {
        let cos = z.cos();
        if cos <= 0.0 {
            1.0
        } else {
            1.0 + a * (b / cos).exp()
        }
    };
    let f = |x: f64| 1.0 + c * ((d * x).exp() - (d * PI / 2.0).exp()) + e * x.cos().powi(2);
    f(chi) * phi(z) / (f(zs) * phi(0.0))
}

/// Columns of the map a clear sky is rendered into (half as many rows): a texel spans
/// 0.35°, against the circumsolar peak's e-folding width of 19° (1/|d| radians).
pub const CLEAR_SKY_COLUMNS: usize = 1024;

/// The clear sky of zenith luminance `zenith`, the sun toward the unit `sun` (y > 0),
/// rendered at texel centres into a [`CLEAR_SKY_COLUMNS`]-wide equirectangular map; its
/// lower half is the ground, of radiance `ground_reflectance × E_h / π` with `E_h` the
/// rendered upper half's exact horizontal illuminance.
pub fn clear_sky_map(
    zenith: f64,
    sun: DVec3,
    ground_reflectance: f64,
) -> Result<EnvironmentMap, crate::envmap::MapError> {
    let (w, h) = (CLEAR_SKY_COLUMNS, CLEAR_SKY_COLUMNS / 2);
    let zs = sun.y.clamp(-1.0, 1.0).acos();
    // Rows above the middle look above the horizon (the rows are symmetric about it).
    let sky = |k: usize| {
        let d = EnvironmentMap::direction(
            ((k % w) as f64 + 0.5) / w as f64,
            ((k / w) as f64 + 0.5) / h as f64,
        );
        let chi = d.dot(sun).clamp(-1.0, 1.0).acos();
        (zenith * clear_sky(d.y.clamp(-1.0, 1.0).acos(), chi, zs)) as f32
    };
    let upper = w * h / 2;
    let mut texels: Vec<[f32; 3]> = (0..w * h)
        .map(|k| [if k < upper { sky(k) } else { 0.0 }; 3])
        .collect();
    let dome = EnvironmentMap::from_texels("the clear sky", w, h, texels.clone())?;
    let ground = (ground_reflectance * dome.unobstructed(DVec3::Y)[0] / PI) as f32;
    texels[upper..].fill([ground; 3]);
    EnvironmentMap::from_texels("the clear sky", w, h, texels)
}

/// A sky over the scene and the ground below its horizon.
#[derive(Clone, Debug, PartialEq)]
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
    #[error("unknown sky {0:?}: expected uniform:L, overcast:Lz, clear:Lz or map:FILE")]
    Unknown(String),
    #[error("the clear sky needs the sun's direction above the horizon: a directional light (KHR_lights_punctual) in the scene, or --sun-direction x,y,z")]
    NoSun,
    #[error("the sky map {0} was not loaded")]
    NotLoaded(String),
    #[error("the sky's radiance must be a finite number ≥ 0, got {0:?}")]
    Radiance(String),
    #[error("the ground reflectance must be in [0, 1], got {0}")]
    GroundReflectance(f64),
}

impl std::str::FromStr for SkyModel {
    type Err = SkyError;

    /// `uniform:L`, `overcast:Lz`, `clear:Lz` or `map:FILE` (the file is read, and the clear
    /// sky rendered, later, by the job).
    fn from_str(text: &str) -> Result<SkyModel, SkyError> {
        let (name, value) = text
            .split_once(':')
            .ok_or_else(|| SkyError::Unknown(text.to_string()))?;
        if name.trim() == "map" && !value.is_empty() {
            return Ok(SkyModel::Map {
                file: PathBuf::from(value),
                map: None,
            });
        }
        let radiance: f64 = value
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && *v >= 0.0)
            .ok_or_else(|| SkyError::Radiance(value.to_string()))?;
        match name.trim() {
            "uniform" => Ok(SkyModel::Uniform { radiance }),
            "overcast" => Ok(SkyModel::Overcast { zenith: radiance }),
            "clear" => Ok(SkyModel::Clear {
                zenith: radiance,
                sun: None,
                map: None,
            }),
            _ => Err(SkyError::Unknown(text.to_string())),
        }
    }
}

impl SkyModel {
    /// The radiance toward elevation `sin_elevation` = ω_y (> 0) of an analytic sky (0 for
    /// a map: see [`Sky::radiance`]).
    pub fn radiance(&self, sin_elevation: f64) -> f64 {
        match *self {
            SkyModel::Uniform { radiance } => radiance,
            SkyModel::Overcast { zenith } => zenith * (1.0 + 2.0 * sin_elevation) / 3.0,
            SkyModel::Map { .. } | SkyModel::Clear { .. } => 0.0,
        }
    }

    /// The unobstructed horizontal illuminance E_h = ∫ L(ω) ω_y dω over the upper
    /// hemisphere: uniform π L; overcast 7π Lz / 9 (= Lz/3 (π + 2 · 2π/3)); a map's
    /// luminance (Rec. 709) summed exactly (a pass over its texels).
    pub fn horizontal_illuminance(&self) -> f64 {
        match self {
            SkyModel::Uniform { radiance } => PI * radiance,
            SkyModel::Overcast { zenith } => 7.0 * PI * zenith / 9.0,
            SkyModel::Map { map, .. } | SkyModel::Clear { map, .. } => {
                map.as_ref().map_or(0.0, |m| {
                    let e = m.unobstructed(DVec3::Y);
                    0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2]
                })
            }
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
            SkyModel::Map { .. } | SkyModel::Clear { .. } => 0.0,
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
    /// The loaded map of a `map:` sky.
    pub fn map(&self) -> Option<&EnvironmentMap> {
        match &self.model {
            SkyModel::Map { map, .. } | SkyModel::Clear { map, .. } => map.as_deref(),
            _ => None,
        }
    }

    /// The ground's radiance `R E_h / π` (0 for a map, whose lower half is the ground).
    pub fn ground_radiance(&self) -> f64 {
        if self.map().is_some() {
            return 0.0;
        }
        self.ground_reflectance * self.model.horizontal_illuminance() / PI
    }

    /// What a ray along the unit direction `d` that meets no surface sees, per band.
    pub fn radiance(&self, d: DVec3) -> [f64; 3] {
        if let Some(map) = self.map() {
            return map.radiance(d);
        }
        [if d.y > 0.0 {
            self.model.radiance(d.y)
        } else {
            self.ground_radiance()
        }; 3]
    }

    /// The illuminance of an unobstructed plane of unit normal `n`, per band: a map's exact
    /// sum ([`EnvironmentMap::unobstructed`], a pass over its texels), else the sky's part
    /// ([`SkyModel::unobstructed`]) and the ground's `π L_g (1 − cos β) / 2`.
    pub fn unobstructed(&self, n: DVec3) -> [f64; 3] {
        if let Some(map) = self.map() {
            return map.unobstructed(n);
        }
        let c = n.y.clamp(-1.0, 1.0);
        [self.model.unobstructed(c) + PI * self.ground_radiance() * (1.0 - c) / 2.0; 3]
    }

    /// Checks the values a user's options control (a map must have been loaded).
    pub fn check(&self) -> Result<(), SkyError> {
        let r = match &self.model {
            SkyModel::Uniform { radiance } => *radiance,
            SkyModel::Overcast { zenith } => *zenith,
            SkyModel::Map { file, map } => {
                if map.is_none() {
                    return Err(SkyError::NotLoaded(file.display().to_string()));
                }
                0.0
            }
            SkyModel::Clear { zenith, map, .. } => {
                if map.is_none() {
                    return Err(SkyError::NoSun);
                }
                *zenith
            }
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
    /// `Σ_i A_i E_i` per band: lumens (the energy unit × π).
    #[cfg_attr(feature = "serde", serde(skip))]
    pub flux: [f64; 3],
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
        for b in 0..3 {
            self.flux[b] += o.flux[b];
        }
        self.rays_cast += o.rays_cast;
        self.elements_lit += o.elements_lit;
        self.elements_exact += o.elements_exact;
        self.elements_sampled += o.elements_sampled;
    }
}

/// The sky light of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SkyLight {
    /// Per element and band: mean illuminance E (the analytic skies are grey: the same in
    /// every band; a map has colour).
    pub illuminance: Vec<[f64; 3]>,
    /// Per element and band: the standard error of E from its rays (0 where E is a closed
    /// form): the pooled rays' sample deviation over √N, as if they were independent draws
    /// from the balance heuristic's mixture density — stratification only makes the true
    /// error smaller.
    pub deviation: Vec<[f64; 3]>,
    pub stats: SkyStats,
}

/// Stream constant of the sky's per-element seeds (apart from the lights' streams).
const SKY_STREAM: u64 = 0x736b_795f_6c69_6768;
/// Stream constant of the sky's probe rays.
const PROBE_STREAM: u64 = 0x736b_795f_7072_6f62;

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
    // The closed form of each polygon nothing can block, once per distinct normal (a map's
    // is a pass over its texels; a scene's floors and walls share a few normals).
    let key = |p: usize| occluders.polygon(p).normal().to_array().map(f64::to_bits);
    let mut normals: Vec<[u64; 3]> = (0..occluders.len())
        .filter(|&p| !exposed[p])
        .map(key)
        .collect();
    normals.sort_unstable();
    normals.dedup();
    let forms: Vec<[f64; 3]> = normals
        .par_iter()
        .map(|n| sky.unobstructed(DVec3::from_array(n.map(f64::from_bits))))
        .collect();
    let closed: Vec<[f64; 3]> = (0..occluders.len())
        .map(|p| match exposed[p] {
            true => [0.0; 3],
            false => normals
                .binary_search(&key(p))
                .map_or([0.0; 3], |k| forms[k]),
        })
        .collect();
    let blockable = |i: usize| exposed.get(mesh.elements[i].polygon as usize) != Some(&false);
    let mut pass = Pass {
        sky,
        occluders,
        k,
        probes: if k >= 4 { k / 4 } else { 0 },
        reach: 2.0 * occluders.scene_scale(),
        portals: Portals::around(occluders),
        closed: &closed,
    };
    // Stage 1: probe rays from every sampled element mark where the sky is reached (an OR
    // of marks: the same map for any thread count), and count, per element, how many met no
    // surface.
    let mut escaped = vec![0u32; mesh.elements.len()];
    if pass.probes > 0 {
        let cells = pass.portals.slot.len();
        let marks = escaped
            .par_iter_mut()
            .enumerate()
            .filter(|(i, _)| blockable(*i) && mesh.elements[*i].area > 0.0)
            .fold(
                || vec![false; cells],
                |mut marks, (i, out)| {
                    *out = pass.probe(mesh, i, &mut marks);
                    marks
                },
            )
            .reduce(
                || vec![false; cells],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x |= *y);
                    a
                },
            );
        pass.portals.open_where(&marks);
    }
    let pass = pass;
    let per_element: Vec<([f64; 3], [f64; 3], SkyStats)> = (0..mesh.elements.len())
        .into_par_iter()
        .map_init(Scratch::default, |scratch, i| {
            pass.element(mesh, i, blockable(i).then_some(escaped[i]), scratch)
        })
        .collect();
    let mut stats = SkyStats::default();
    let mut deviation = Vec::with_capacity(per_element.len());
    let illuminance = per_element
        .iter()
        .map(|(e, d, s)| {
            stats.add(s);
            deviation.push(*d);
            *e
        })
        .collect();
    SkyLight {
        illuminance,
        deviation,
        stats,
    }
}

/// Cells per side of each face of [`Portals`]' box.
const PORTAL_CELLS: usize = 16;

/// Where rays from inside the scene's bounding box leave it toward the sky: each of the box's
/// six faces cut into [`PORTAL_CELLS`]² cells, a cell open where some probe ray that met no
/// surface left the box through it or through a neighbouring cell of the same face. Every
/// direction from a point inside the box leaves it through exactly one point, so picking a
/// point of an open cell is picking a direction, with the solid-angle density
/// `P(cell) / A_cell × r² / |cos θ_face|`.
struct Portals {
    lo: DVec3,
    hi: DVec3,
    /// Per cell (face-major: face f = 2 × axis + (1 on the high side), then row, column):
    /// its place in `cells`, `u32::MAX` where closed.
    slot: Vec<u32>,
    /// The open cells.
    cells: Vec<u32>,
}

impl Portals {
    /// The box around every polygon, grown by a hair so that lifted ray origins lie inside.
    fn around(occluders: &Occluders) -> Portals {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in 0..occluders.len() {
            for &c in occluders.polygon(p).corners() {
                lo = lo.min(c);
                hi = hi.max(c);
            }
        }
        let grow = DVec3::splat(1e-3 * occluders.scene_scale());
        Portals {
            lo: lo - grow,
            hi: hi + grow,
            slot: vec![u32::MAX; 6 * PORTAL_CELLS * PORTAL_CELLS],
            cells: Vec::new(),
        }
    }

    /// Face f's two in-face axes (column, row).
    fn axes(face: usize) -> (usize, usize) {
        let a = face / 2;
        ((a + 1) % 3, (a + 2) % 3)
    }

    /// The cell the ray from `p` (inside the box) along `d` leaves the box through, and the
    /// distance to that point.
    fn exit(&self, p: DVec3, d: DVec3) -> Option<(usize, f64)> {
        let (mut best, mut face) = (f64::INFINITY, usize::MAX);
        for a in 0..3 {
            let t = if d[a] > 0.0 {
                (self.hi[a] - p[a]) / d[a]
            } else if d[a] < 0.0 {
                (self.lo[a] - p[a]) / d[a]
            } else {
                continue;
            };
            if t < best {
                (best, face) = (t, 2 * a + usize::from(d[a] > 0.0));
            }
        }
        if face == usize::MAX || !best.is_finite() {
            return None;
        }
        let x = p + d * best;
        let (u, v) = Self::axes(face);
        let g = PORTAL_CELLS;
        let at = |b: usize| {
            let s = (x[b] - self.lo[b]) / (self.hi[b] - self.lo[b]);
            ((s * g as f64).floor().max(0.0) as usize).min(g - 1)
        };
        Some(((face * g + at(v)) * g + at(u), best.max(0.0)))
    }

    /// Opens the cells `marks` says probes left through, and their neighbours on the same
    /// face.
    fn open_where(&mut self, marks: &[bool]) {
        let g = PORTAL_CELLS as isize;
        self.cells.clear();
        for c in 0..self.slot.len() {
            let (face, row, col) = (c as isize / (g * g), (c as isize / g) % g, c as isize % g);
            let open = (-1..=1).any(|dr| {
                (-1..=1).any(|dc| {
                    let (r, q) = (row + dr, col + dc);
                    (0..g).contains(&r)
                        && (0..g).contains(&q)
                        && marks[((face * g + r) * g + q) as usize]
                })
            });
            self.slot[c] = if open {
                self.cells.push(c as u32);
                (self.cells.len() - 1) as u32
            } else {
                u32::MAX
            };
        }
    }

    fn cell_area(&self, face: usize) -> f64 {
        let (u, v) = Self::axes(face);
        let g = PORTAL_CELLS as f64;
        (self.hi[u] - self.lo[u]) * (self.hi[v] - self.lo[v]) / (g * g)
    }

    /// The point of cell `c` at (s, t) in [0, 1)² of its column and row axes.
    fn at(&self, c: usize, s: f64, t: f64) -> DVec3 {
        let g = PORTAL_CELLS;
        let face = c / (g * g);
        let (row, col) = ((c / g) % g, c % g);
        let (u, v) = Self::axes(face);
        let axis = face / 2;
        let mut p = DVec3::ZERO;
        p[axis] = if face % 2 == 1 {
            self.hi[axis]
        } else {
            self.lo[axis]
        };
        p[u] = self.lo[u] + (self.hi[u] - self.lo[u]) * (col as f64 + s) / g as f64;
        p[v] = self.lo[v] + (self.hi[v] - self.lo[v]) * (row as f64 + t) / g as f64;
        p
    }

    /// An element's probabilities of the open cells, as the running sum of their weights into
    /// `cdf` (cleared; returns the total): each cell's projected solid angle seen from `x`
    /// (normal `n`), `A cos θ_x cos θ_face / r²` at its centre, 0 behind the element.
    fn weigh(&self, x: DVec3, n: DVec3, cdf: &mut Vec<f64>) -> f64 {
        cdf.clear();
        let mut total = 0.0;
        for &c in &self.cells {
            let c = c as usize;
            let face = c / (PORTAL_CELLS * PORTAL_CELLS);
            let to = self.at(c, 0.5, 0.5) - x;
            let r2 = to.length_squared();
            let cos_x = to.dot(n);
            if cos_x > 0.0 && r2 > 0.0 {
                total += self.cell_area(face) * cos_x * to[face / 2].abs() / (r2 * r2);
            }
            cdf.push(total);
        }
        total
    }

    /// A point of an open cell: the cell drawn from `cdf` (of [`Portals::weigh`], `total`
    /// its last value) by `x` in [0, 1), uniform inside it by what is left of `x` along the
    /// cell's columns and `y` along its rows.
    fn point(&self, cdf: &[f64], total: f64, x: f64, y: f64) -> DVec3 {
        let target = x * total;
        let n = cdf.partition_point(|&sum| sum <= target).min(cdf.len() - 1);
        let start = if n == 0 { 0.0 } else { cdf[n - 1] };
        let s = ((target - start) / (cdf[n] - start)).clamp(0.0, 1.0);
        self.at(self.cells[n] as usize, s, y)
    }

    /// The solid-angle density with which [`Portals::point`] picks direction `d` from `p`:
    /// `P(cell) / A_cell × r² / |cos θ_face|` where `d` leaves through an open cell, else 0.
    fn density(&self, cdf: &[f64], total: f64, p: DVec3, d: DVec3) -> f64 {
        let Some((c, r)) = self.exit(p, d) else {
            return 0.0;
        };
        let n = self.slot[c];
        if n == u32::MAX {
            return 0.0;
        }
        let n = n as usize;
        let weight = cdf[n] - if n == 0 { 0.0 } else { cdf[n - 1] };
        let face = c / (PORTAL_CELLS * PORTAL_CELLS);
        let cos = d[face / 2].abs();
        if weight > 0.0 && cos > 0.0 {
            weight / total / self.cell_area(face) * r * r / cos
        } else {
            0.0
        }
    }
}

/// The sky, prepared for its pass over the elements.
struct Pass<'a> {
    sky: &'a Sky,
    occluders: &'a Occluders,
    /// Strata per side.
    k: usize,
    /// Probe rays per sampled element, per side (0: no probes, no portals).
    probes: usize,
    /// How far rays reach: past the whole scene from any point of it.
    reach: f64,
    portals: Portals,
    /// Per polygon: the closed form of one nothing can block.
    closed: &'a [[f64; 3]],
}

/// A sampled element's buffers, reused across the elements a thread takes (nothing is
/// allocated per element once they have grown).
#[derive(Default)]
struct Scratch {
    /// The rays' start points.
    points: Vec<DVec3>,
    /// The running sum of the open portal cells' weights seen from the element.
    cdf: Vec<f64>,
}

/// Of the rays after the probes, the share drawn cosine-weighted over the hemisphere (the
/// rest aim at the open portal cells): what finds an opening the probes missed, and the
/// better strategy where the sky fills most of the hemisphere.
const COSINE_SHARE: f64 = 0.25;

/// Rays aim at the portals only from elements whose probes met no surface less often than
/// this: where the sky fills much of the hemisphere, cosine-weighted rays alone do better
/// (a wall facing an open landscape: the portals are then most of the box).
const AIM_BELOW: f64 = 0.5;

/// Under a map, the share of an element's rays drawn from the map's own distribution (its
/// bright texels: a sun in a photographed sky).
const MAP_SHARE: f64 = 0.25;

impl Pass<'_> {
    /// Element `i`'s probe rays: cosine-weighted, stratified; each that meets no surface
    /// marks the portal cell it leaves the box through. Returns how many met no surface.
    fn probe(&self, mesh: &ElementMesh, i: usize, marks: &mut [bool]) -> u32 {
        let patch = Patch::element(mesh, i);
        let n = patch.normal();
        let frame = Frame::new(n);
        let mut rng = SplitMix64::new(pair_seed(i, 0) ^ PROBE_STREAM);
        let lift = n * self.occluders.ray_offset();
        let polygon = patch.polygon();
        let m = self.probes;
        let (mut next, mut escaped) = (0, 0);
        for_each_cell(patch.corners(), m, |_, _, jitter| {
            let p = jitter([rng.next_f64(), rng.next_f64()]) + lift;
            // Direction strata in the order of the point strata, transposed, so that the
            // pairing is not the identity.
            let s = next;
            next += 1;
            let u = ((s / m) as f64 + rng.next_f64()) / m as f64;
            let v = ((s % m) as f64 + rng.next_f64()) / m as f64;
            let d = frame.cosine(u, v);
            // A probe through glass finds an opening too (the sky behind it, dimmed).
            if self
                .occluders
                .segment_transmittance(p, p + d * self.reach, [polygon, polygon])
                > 0.0
            {
                escaped += 1;
                if let Some((c, _)) = self.portals.exit(p, d) {
                    marks[c] = true;
                }
            }
        });
        escaped
    }

    /// Element `i`'s mean illuminance, its standard error ([`SkyLight::deviation`]) and what
    /// it took; `escaped`: `None` where its polygon has no polygon in front of it (the closed
    /// form), else how many of its probe rays met no surface. `scratch` is reused across
    /// elements.
    fn element(
        &self,
        mesh: &ElementMesh,
        i: usize,
        escaped: Option<u32>,
        scratch: &mut Scratch,
    ) -> ([f64; 3], [f64; 3], SkyStats) {
        let mut stats = SkyStats::default();
        let area = mesh.elements[i].area;
        if area <= 0.0 || area.is_nan() {
            return ([0.0; 3], [0.0; 3], stats);
        }
        let patch = Patch::element(mesh, i);
        let mut deviation = [0.0; 3];
        let e = if let Some(escaped) = escaped {
            stats.elements_sampled = 1;
            stats.rays_cast = (self.probes * self.probes) as u64;
            let aim = !self.portals.cells.is_empty()
                && (escaped as f64) < AIM_BELOW * (self.probes * self.probes) as f64;
            let (e, d) = self.sampled(&patch, i, aim, scratch, &mut stats);
            deviation = d;
            e
        } else {
            stats.elements_exact = 1;
            self.closed
                .get(patch.polygon())
                .copied()
                .unwrap_or([0.0; 3])
        };
        if e.iter().any(|&v| v > 0.0) {
            stats.elements_lit = 1;
            stats.flux = e.map(|v| v * area);
        }
        (e, deviation, stats)
    }

    /// The rays after the probes (k² − probes²): `n_c` cosine-weighted, `n_a` aimed at the
    /// open portal cells, combined by the balance heuristic (Veach 1997, §9.2):
    /// `E ≈ Σ L V cos θ / (n_c p_c + n_a p_a)` over all of them, `p_c = cos θ / π` and `p_a`
    /// the portals' solid-angle density ([`Portals::density`], the cells drawn by the
    /// projected solid angle they subtend from the element's centre), both at the ray's own
    /// start point. Unbiased for any portal map (the cosine rays cover the whole
    /// hemisphere); without aiming it is `π / n_c Σ L V`. Under a map, a third set of n_m
    /// rays is drawn from the map's own distribution ([`EnvironmentMap::sample`], density
    /// `p_m`), and `n_m p_m` joins the denominator.
    fn sampled(
        &self,
        patch: &Patch,
        i: usize,
        aim: bool,
        scratch: &mut Scratch,
        stats: &mut SkyStats,
    ) -> ([f64; 3], [f64; 3]) {
        let Scratch { points, cdf } = scratch;
        let k = self.k;
        let n = patch.normal();
        let corners = patch.corners();
        let centre = corners.iter().copied().sum::<DVec3>() / corners.len() as f64;
        let cells_total = if aim {
            self.portals.weigh(centre, n, cdf)
        } else {
            0.0
        };
        let aim = aim && cells_total > 0.0;
        let frame = Frame::new(n);
        let mut rng = SplitMix64::new(pair_seed(i, 0) ^ SKY_STREAM);
        let lift = n * self.occluders.ray_offset();
        let polygon = patch.polygon();
        let map = self.sky.map().filter(|m| !m.is_dark());
        // Under a map: k_m × k_m rays drawn from it, from the k_m × k_m point strata.
        let k_m = match map {
            Some(_) => ((MAP_SHARE * (k * k) as f64).sqrt().round() as usize).min(k - 1),
            None => 0,
        };
        let n_m = k_m * k_m;
        let total = k * k - self.probes * self.probes - n_m;
        // The rays aimed at portals: k_a × k_a of them, from the k_a × k_a point strata.
        let k_a = if aim {
            (((1.0 - COSINE_SHARE) * total as f64).sqrt().round() as usize).min(k - 1)
        } else {
            0
        };
        let n_a = k_a * k_a;
        // The cosine-weighted rays: the rest, a rows × cols grid of direction strata (rows ×
        // cols = n_c exactly, so that every stratum is drawn once), from a random n_c of the
        // k_c × k_c point strata.
        let n_c = total - n_a;
        let mut rows = ((n_c as f64).sqrt().floor() as usize).max(1);
        while !n_c.is_multiple_of(rows) {
            rows -= 1;
        }
        let cols = n_c / rows;
        let k_c = (n_c as f64).sqrt().ceil() as usize;
        // The start points, each set shuffled (a random pairing with the direction strata).
        points.clear();
        for (side, count) in [(k_c, n_c), (k_a, n_a), (k_m, n_m)] {
            let from = points.len();
            for_each_cell(patch.corners(), side, |_, _, jitter| {
                points.push(jitter([rng.next_f64(), rng.next_f64()]) + lift);
            });
            let set = &mut points[from..];
            for j in (1..set.len()).rev() {
                set.swap(j, rng.below(j + 1));
            }
            points.truncate(from + count);
        }
        let (nc, na, nm) = (n_c as f64, n_a as f64, n_m as f64);
        let weight = |p: DVec3, d: DVec3| {
            let cos = d.dot(n);
            let mut density = nc * cos / PI;
            if n_a > 0 {
                density += na * self.portals.density(cdf, cells_total, p, d);
            }
            if let Some(map) = map {
                density += nm * map.density(d);
            }
            cos / density
        };
        let (mut sum, mut squares) = ([0.0; 3], [0.0; 3]);
        let mut add = |value: [f64; 3], w: f64| {
            for b in 0..3 {
                sum[b] += value[b] * w;
                squares[b] += (value[b] * w).powi(2);
            }
        };
        for (j, &p) in points.iter().take(n_c).enumerate() {
            let u = ((j % cols) as f64 + rng.next_f64()) / cols as f64;
            let v = ((j / cols) as f64 + rng.next_f64()) / rows as f64;
            let d = frame.cosine(u, v);
            let value = self.trace(p, d, polygon, stats);
            if value.iter().any(|&v| v > 0.0) {
                add(value, weight(p, d));
            }
        }
        // Rays aimed at the portals: stratified by the running sum of the cells' weights.
        for (j, &p) in points.iter().skip(n_c).take(n_a).enumerate() {
            let target = self.portals.point(
                cdf,
                cells_total,
                (j as f64 + rng.next_f64()) / na,
                rng.next_f64(),
            );
            let d = (target - p).normalize_or_zero();
            if d.dot(n) <= 0.0 {
                continue;
            }
            let value = self.trace(p, d, polygon, stats);
            if value.iter().any(|&v| v > 0.0) {
                add(value, weight(p, d));
            }
        }
        // Rays drawn from the map: stratified by its running sums.
        if let Some(map) = map {
            for (j, &p) in points.iter().skip(n_c + n_a).take(n_m).enumerate() {
                let Some((d, _)) = map.sample((j as f64 + rng.next_f64()) / nm, rng.next_f64())
                else {
                    continue;
                };
                if d.dot(n) <= 0.0 {
                    continue;
                }
                let value = self.trace(p, d, polygon, stats);
                if value.iter().any(|&v| v > 0.0) {
                    add(value, weight(p, d));
                }
            }
        }
        // E is the mean of N terms c_j = N v_j w_j (every ray, those that brought nothing
        // included): its variance ≈ (N Σ (v w)² − E²) / (N − 1).
        let rays = (n_c + n_a + n_m) as f64;
        let deviation = [0, 1, 2].map(|b| {
            if rays > 1.0 {
                ((rays * squares[b] - sum[b] * sum[b]) / (rays - 1.0))
                    .max(0.0)
                    .sqrt()
            } else {
                sum[b]
            }
        });
        (sum, deviation)
    }

    /// The radiance a ray from `p` along `d` brings: the sky's (or the ground's) times the
    /// transmission of the glass it passes, 0 if it meets an opaque polygon but its own.
    fn trace(&self, p: DVec3, d: DVec3, polygon: usize, stats: &mut SkyStats) -> [f64; 3] {
        stats.rays_cast += 1;
        let passed =
            self.occluders
                .segment_transmittance(p, p + d * self.reach, [polygon, polygon]);
        if passed <= 0.0 {
            [0.0; 3]
        } else {
            self.sky.radiance(d).map(|l| l * passed)
        }
    }
}

/// An element's tangent frame, for cosine-weighted directions.
struct Frame {
    t: DVec3,
    b: DVec3,
    n: DVec3,
}

impl Frame {
    fn new(n: DVec3) -> Frame {
        let (t, b) = n.any_orthonormal_pair();
        Frame { t, b, n }
    }

    /// The cosine-weighted direction of (u, v) in [0, 1)²: Malley's method (a uniform point
    /// of the unit disc lifted to the hemisphere is cosine-distributed), the disc point by
    /// Shirley and Chiu's concentric map, which keeps strata compact.
    fn cosine(&self, u: f64, v: f64) -> DVec3 {
        let [x, y] = concentric(u, v);
        let up = (1.0 - x * x - y * y).max(0.0).sqrt();
        self.t * x + self.b * y + self.n * up
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
                    sum += sky.radiance(d)[0] * cos * theta.sin() * dt * dp;
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
                model: model.clone(),
                ground_reflectance: 0.3,
            };
            for beta in [0.0f64, 0.4, 1.0, PI / 2.0, 2.0, 2.9, PI] {
                let n = DVec3::new(beta.sin(), beta.cos(), 0.0);
                let exact = sky.unobstructed(n)[0];
                let reference = quadrature(&sky, n, 1200);
                assert!(
                    (exact - reference).abs() < 2e-4 * sky.model.horizontal_illuminance(),
                    "{model:?} β = {beta}: {exact} against {reference}"
                );
            }
            // Facing up: E_h.
            let up = sky.unobstructed(DVec3::Y)[2];
            assert!((up - sky.model.horizontal_illuminance()).abs() < 1e-12 * up);
        }
    }

    /// The portals' solid-angle density integrates to 1 over the sphere (a midpoint rule in
    /// spherical coordinates), from a point inside a box with a "window" of open cells on
    /// one face and a whole open face: the area-to-direction change of measure is right.
    #[test]
    fn the_portal_density_is_a_density() {
        let mut portals = Portals {
            lo: DVec3::new(-2.0, 0.0, -2.0),
            hi: DVec3::new(2.0, 3.0, 2.0),
            slot: vec![u32::MAX; 6 * PORTAL_CELLS * PORTAL_CELLS],
            cells: Vec::new(),
        };
        let g = PORTAL_CELLS;
        let mut marks = vec![false; portals.slot.len()];
        // Face 4 (z low): a block of cells; face 3 (y high): all of it.
        for row in 6..9 {
            for col in 5..11 {
                marks[(4 * g + row) * g + col] = true;
            }
        }
        for c in 0..g * g {
            marks[3 * g * g + c] = true;
        }
        portals.open_where(&marks);
        let x = DVec3::new(0.3, 0.2, 0.7);
        let n = DVec3::new(0.0, 1.0, 0.0);
        let mut cdf = Vec::new();
        let total = portals.weigh(x, n, &mut cdf);
        assert!(total > 0.0);
        let cells = 1000;
        let (dt, dp) = (PI / cells as f64, 2.0 * PI / (2 * cells) as f64);
        let mut sum = 0.0;
        for a in 0..cells {
            let theta = (a as f64 + 0.5) * dt;
            for c in 0..2 * cells {
                let phi = (c as f64 + 0.5) * dp;
                let d = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                sum += portals.density(&cdf, total, x, d) * theta.sin() * dt * dp;
            }
        }
        assert!((sum - 1.0).abs() < 2e-3, "∫ p dω = {sum}");
        // A point it draws leaves the box through the cell it was drawn in.
        let p = portals.point(&cdf, total, 0.37, 0.61);
        let d = (p - x).normalize();
        assert!(portals.density(&cdf, total, x, d) > 0.0);
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
