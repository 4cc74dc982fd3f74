//! Light probes: points in a scene's empty space that record the light arriving there, for a
//! renderer to light moving objects with.
//!
//! What it is: **placement** (a regular grid over the scene's bounds, [`place`]; each point is
//! checked with rays against the scene's polygons, moved within its cell out of geometry or
//! away from a surface nearer than a quarter of the spacing, or flagged invalid when no place
//! in its cell will do; plus any positions the caller adds, checked but never moved) and, per
//! valid probe, the **incident radiance projected on real spherical harmonics up to L2**
//! ([`sh`]: nine RGB coefficients in three.js's `SphericalHarmonics3` order and basis) from
//! every element of a solved bake ([`gather`]: each element a convex polygon of constant
//! radiance, integrated over its solid angle with shadow rays only where an occluder may
//! exist).
//!
//! Units: an element of radiosity b has radiance `b / π`; the coefficients are those of that
//! radiance, so the irradiance they reconstruct (`sh::irradiance`, three.js's
//! `shGetIrradianceAt`) is in the unit of the bake's H, where `b = e + ρ H`: a probe inside a
//! closed box of uniform b reconstructs H = b in every direction, as the box's elements have.
//! Punctual lights and the sky are not in the coefficients: they are left to the renderer,
//! which draws them directly (see docs/probes.md).
//!
//! What it is not: it knows no transport, no solver, no presets and no file format; it gets
//! the element mesh, each element's b and the scene's occluders. Same bytes for any thread
//! count: every probe is computed by the same sequential code, elements summed in index order.

pub mod gather;
pub mod place;
pub mod sh;

use glam::DVec3;
use mesher::ElementMesh;
use rayon::prelude::*;
use sh::Sh;
use std::str::FromStr;
use visibility::Occluders;

/// The most probes one bake places (grid points plus added ones).
pub const MAX_PROBES: u64 = 1 << 20;

/// The automatic spacing: the scene's bounding-box diagonal over this.
pub const AUTO_PER_DIAGONAL: f64 = 16.0;

#[derive(Debug, thiserror::Error)]
pub enum ProbeError {
    #[error("invalid probe spacing {0}: a finite length above 0 is needed")]
    Spacing(String),
    #[error("{0} probes are more than the limit of {MAX_PROBES}")]
    TooMany(String),
    #[error("invalid --probes value {0:?}: expected auto, off or grid:SPACING")]
    Option(String),
    #[error("{0} radiosity values for {1} elements")]
    Radiosity(usize, usize),
}

/// `--probes`: where probes go.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Probes {
    /// No probes (the default).
    #[default]
    Off,
    /// A grid at the scene's diagonal / [`AUTO_PER_DIAGONAL`].
    Auto,
    /// A grid at this spacing (world units).
    Grid(f64),
}

impl FromStr for Probes {
    type Err = ProbeError;

    fn from_str(text: &str) -> Result<Probes, ProbeError> {
        match text.trim() {
            "off" => Ok(Probes::Off),
            "auto" => Ok(Probes::Auto),
            other => {
                let spacing = other
                    .strip_prefix("grid:")
                    .ok_or_else(|| ProbeError::Option(text.to_string()))?;
                let value: f64 = spacing
                    .trim()
                    .parse()
                    .map_err(|_| ProbeError::Spacing(spacing.to_string()))?;
                if value.is_finite() && value > 0.0 {
                    Ok(Probes::Grid(value))
                } else {
                    Err(ProbeError::Spacing(spacing.to_string()))
                }
            }
        }
    }
}

/// A regular grid: point (i, j, k) is at `origin + spacing (i, j, k)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    pub origin: [f64; 3],
    pub spacing: f64,
    pub counts: [u32; 3],
}

impl Grid {
    pub fn len(&self) -> usize {
        self.counts.iter().map(|&c| c as usize).product()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Point `index` in x-fastest order (index = i + nx (j + ny k)).
    pub fn point(&self, index: usize) -> DVec3 {
        let [nx, ny, _] = self.counts.map(|c| c as usize);
        let (i, j, k) = (index % nx, (index / nx) % ny, index / (nx * ny));
        DVec3::from_array(self.origin) + DVec3::new(i as f64, j as f64, k as f64) * self.spacing
    }
}

/// One probe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    pub position: DVec3,
    /// Moved off its grid point (out of geometry, or away from a surface too close).
    pub moved: bool,
    /// False when no place in its cell was clear: its coefficients are 0.
    pub valid: bool,
    /// Incident radiance on SH L2 (0 when invalid).
    pub sh: Sh,
    /// Per band, the bound on the irradiance the L2 truncation misses in any direction
    /// ([`sh::truncation_bound`]).
    pub truncation: [f64; 3],
    /// Per band, the bound on the irradiance that shadow edges left unresolved may add or
    /// take away in any direction ([`gather::Gathered::unresolved`]).
    pub shadow_bound: [f64; 3],
}

/// Every probe of a bake: the grid's points first (x fastest), then the added ones.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeSet {
    pub grid: Grid,
    pub probes: Vec<Probe>,
    pub summary: Summary,
}

/// What probing did, for the report.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Summary {
    pub count: u64,
    pub valid: u64,
    pub moved: u64,
    pub spacing: f64,
    /// Shadow rays the gather cast.
    pub rays: u64,
    /// The largest [`Probe::shadow_bound`] over probes and bands, relative to that probe's
    /// mean irradiance in the band (`π c₀ Y₀₀`): how much unresolved shadow edges may change
    /// a probe's light.
    pub shadow_bound_max: f64,
    /// Seconds placing, and gathering.
    pub place_seconds: f64,
    pub gather_seconds: f64,
}

/// `bound` over the mean irradiance `π c₀ Y₀₀` (0 where that is 0).
fn relative(bound: f64, c0: f64) -> f64 {
    let mean = c0 * 0.5 * std::f64::consts::PI.sqrt();
    if mean > 0.0 {
        bound / mean
    } else {
        0.0
    }
}

/// Places probes (the grid `probes` asks for over the polygons' bounds, then `extra` points)
/// and gathers each valid one's light from `radiosity` (per element of `mesh`). `None` for
/// [`Probes::Off`].
pub fn bake(
    probes: Probes,
    extra: &[DVec3],
    mesh: &ElementMesh,
    radiosity: &[[f64; 3]],
    occluders: &Occluders,
    bounds: (DVec3, DVec3),
    sky: Option<&gather::Sky<'_>>,
) -> Result<Option<ProbeSet>, ProbeError> {
    let diagonal = (bounds.1 - bounds.0).length();
    let spacing = match probes {
        Probes::Off => return Ok(None),
        Probes::Auto => diagonal / AUTO_PER_DIAGONAL,
        Probes::Grid(s) => s,
    };
    if radiosity.len() != mesh.elements.len() {
        return Err(ProbeError::Radiosity(radiosity.len(), mesh.elements.len()));
    }
    let grid = place::grid(bounds.0, bounds.1, spacing)?;
    let total = grid.len() as u64 + extra.len() as u64;
    if total > MAX_PROBES {
        return Err(ProbeError::TooMany(total.to_string()));
    }
    let start = std::time::Instant::now();
    let dirs = place::directions();
    let placed: Vec<place::Placed> = (0..grid.len() + extra.len())
        .into_par_iter()
        .map(|i| match i.checked_sub(grid.len()) {
            None => place::settle(grid.point(i), spacing, occluders, &dirs),
            Some(e) => {
                let clearance = place::CLEARANCE * spacing;
                let c = place::check(extra[e], occluders, &dirs, clearance);
                place::Placed {
                    position: extra[e],
                    moved: false,
                    valid: c.clear(clearance),
                }
            }
        })
        .collect();
    let place_seconds = start.elapsed().as_secs_f64();
    let start = std::time::Instant::now();
    let mut sources = gather::Sources::new(mesh, radiosity, occluders);
    if let Some(sky) = sky {
        sources = sources.with_sky(sky);
    }
    let gathered: Vec<(Probe, u64)> = placed
        .par_iter()
        .map(|p| {
            if !p.valid {
                let probe = Probe {
                    position: p.position,
                    moved: p.moved,
                    valid: false,
                    sh: [[0.0; 3]; sh::COEFFICIENTS],
                    truncation: [0.0; 3],
                    shadow_bound: [0.0; 3],
                };
                return (probe, 0);
            }
            let g = gather::gather(p.position, &sources);
            let probe = Probe {
                position: p.position,
                moved: p.moved,
                valid: true,
                sh: g.sh,
                truncation: sh::truncation_bound(&g.sh, g.square),
                shadow_bound: g.unresolved,
            };
            (probe, g.rays)
        })
        .collect();
    let gather_seconds = start.elapsed().as_secs_f64();
    let rays = gathered.iter().map(|g| g.1).sum();
    let probes: Vec<Probe> = gathered.into_iter().map(|g| g.0).collect();
    let summary = Summary {
        count: probes.len() as u64,
        valid: probes.iter().filter(|p| p.valid).count() as u64,
        moved: probes.iter().filter(|p| p.moved).count() as u64,
        spacing,
        rays,
        shadow_bound_max: probes
            .iter()
            .flat_map(|p| (0..3).map(move |b| relative(p.shadow_bound[b], p.sh[0][b])))
            .fold(0.0, f64::max),
        place_seconds,
        gather_seconds,
    };
    Ok(Some(ProbeSet {
        grid,
        probes,
        summary,
    }))
}
