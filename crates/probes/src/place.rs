//! Where probes go: a regular grid over the scene's bounds, each point checked by rays against
//! the scene's polygons, moved within its cell when it is inside geometry or too close to it,
//! and flagged invalid when no place in its cell will do.

use crate::{Grid, ProbeError, MAX_PROBES};
use glam::DVec3;
use visibility::Occluders;

/// Rays each check casts (a spherical Fibonacci set: the same directions for every probe).
pub const CHECK_RAYS: usize = 64;

/// A point is inside geometry when more than this share of its check rays first meets a
/// polygon's back (single-sided surfaces face the empty space they bound).
pub const BACK_SHARE: f64 = 0.1;

/// A point is too close to geometry when a check ray meets a surface nearer than this
/// fraction of the spacing.
pub const CLEARANCE: f64 = 0.25;

/// Candidate offsets per axis when a probe is moved: (2k/STEPS − 1) × spacing/2 for
/// k = 0..=STEPS, so a moved probe stays in its own cell.
const STEPS: i32 = 4;

/// The grid of spacing `spacing` over the box `lo..hi`: `ceil(extent / spacing)` points per
/// axis (at least 1), centred on the box.
pub fn grid(lo: DVec3, hi: DVec3, spacing: f64) -> Result<Grid, ProbeError> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(ProbeError::Spacing(spacing.to_string()));
    }
    let extent = hi - lo;
    if !extent.is_finite() {
        return Err(ProbeError::Spacing(format!(
            "{spacing} over an empty scene"
        )));
    }
    let mut counts = [1u32; 3];
    let mut total = 1u64;
    for (axis, count) in counts.iter_mut().enumerate() {
        let n = (extent[axis] / spacing).ceil().max(1.0);
        if n > MAX_PROBES as f64 {
            return Err(ProbeError::TooMany(format!("more than {MAX_PROBES}")));
        }
        *count = n as u32;
        total = total.saturating_mul(u64::from(*count));
    }
    if total > MAX_PROBES {
        return Err(ProbeError::TooMany(total.to_string()));
    }
    let centre = (lo + hi) * 0.5;
    let half = DVec3::new(
        f64::from(counts[0] - 1),
        f64::from(counts[1] - 1),
        f64::from(counts[2] - 1),
    ) * (spacing * 0.5);
    Ok(Grid {
        origin: (centre - half).to_array(),
        spacing,
        counts,
    })
}

/// The check rays' directions.
pub fn directions() -> Vec<DVec3> {
    fibonacci(CHECK_RAYS)
}

/// `n` deterministic, roughly uniform unit directions (a spherical Fibonacci set, y from
/// near 1 down to near −1).
pub fn fibonacci(n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let s = (1.0 - y * y).sqrt();
            let phi = golden * i as f64;
            DVec3::new(s * phi.cos(), y, s * phi.sin())
        })
        .collect()
}

/// What the check rays found at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Check {
    /// Rays whose first surface showed its back.
    pub back: usize,
    /// The nearest surface any ray met (infinite when none).
    pub nearest: f64,
}

impl Check {
    pub fn clear(&self, clearance: f64) -> bool {
        (self.back as f64) <= BACK_SHARE * CHECK_RAYS as f64 && self.nearest >= clearance
    }
}

/// Casts the check rays from `p`; stops early (returning what it has) once the point cannot
/// be clear for `clearance`.
pub fn check(p: DVec3, occluders: &Occluders, dirs: &[DVec3], clearance: f64) -> Check {
    let reach = 4.0 * occluders.scene_scale() + 4.0 * clearance;
    let mut out = Check {
        back: 0,
        nearest: f64::INFINITY,
    };
    for &d in dirs {
        if let Some(hit) = occluders.first_hit(p, p + d * reach, usize::MAX) {
            out.nearest = out.nearest.min(hit.t * reach);
            if !hit.front {
                out.back += 1;
            }
            if !out.clear(clearance) {
                return out;
            }
        }
    }
    out
}

/// Where a probe ended up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placed {
    pub position: DVec3,
    pub moved: bool,
    pub valid: bool,
}

/// A grid point: kept when clear, else moved to the nearest clear candidate of its cell
/// (offsets on a 5 × 5 × 5 lattice of the cell, nearest first, ties in lattice order), else
/// kept and flagged invalid.
pub fn settle(p: DVec3, spacing: f64, occluders: &Occluders, dirs: &[DVec3]) -> Placed {
    let clearance = CLEARANCE * spacing;
    if check(p, occluders, dirs, clearance).clear(clearance) {
        return Placed {
            position: p,
            moved: false,
            valid: true,
        };
    }
    let mut offsets = Vec::with_capacity(((STEPS + 1) * (STEPS + 1) * (STEPS + 1)) as usize);
    for i in 0..=STEPS {
        for j in 0..=STEPS {
            for k in 0..=STEPS {
                let o = [i, j, k].map(|c| 2 * c - STEPS);
                if o != [0, 0, 0] {
                    offsets.push(o);
                }
            }
        }
    }
    let length = |o: &[i32; 3]| o.iter().map(|c| c * c).sum::<i32>();
    offsets.sort_by_key(|o| (length(o), *o));
    let unit = spacing * 0.5 / f64::from(STEPS);
    for o in offsets {
        let q = p + DVec3::new(f64::from(o[0]), f64::from(o[1]), f64::from(o[2])) * unit;
        if check(q, occluders, dirs, clearance).clear(clearance) {
            return Placed {
                position: q,
                moved: true,
                valid: true,
            };
        }
    }
    Placed {
        position: p,
        moved: false,
        valid: false,
    }
}
