//! Where the light that leaves the scene goes, estimated by rays, independently of the
//! transport (issue 31: "split the report's `escaped` into light leaving through openings and
//! light reaching back faces", and an independent check of the solver's balance).
//!
//! The solver's `escaped` is `Σ A_i b_i (1 − Σ_j F_ij)`: the light no element's front
//! receives. Here [`RAYS`] rays leave the elements' fronts, each from an element chosen by its
//! power `A_i Σ b_i`, at a uniform point, in a cosine-distributed direction (ideal diffuse
//! emission, Goral et al. 1984 §1); a ray that meets nothing left through an *opening*, one
//! that first meets a polygon from behind reached a *back face* (a one-sided surface seen
//! from its unlit side, whose form factor the transport sets to 0). The two are Monte Carlo
//! estimates of the same power, with a standard error of about `√(share / RAYS)` of the
//! power leaving: their sum should agree with the solver's `escaped` within a few of those.
//!
//! This module knows elements and occluders; it changes no value of the solution.

use crate::BANDS;
use mesher::ElementMesh;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use visibility::{cosine_direction, point_on_element, Occluders, SplitMix64};

/// Rays per estimate, whatever the scene's size (a fixed cost: a few hundredths of a second):
/// the shares' standard error is below √(share / 2¹⁴), 0.8% of the power leaving for a share
/// of 1, 0.1% for a share of 2%.
pub const RAYS: u64 = 1 << 14;

/// Rays per parallel task (each its own seeded stream, summed in task order: deterministic).
const CHUNK: u64 = 1024;

/// The light leaving the scene, by where it goes (the report's `escape`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Escape {
    /// Per band: power leaving through openings (rays that meet nothing), in the energy
    /// balance's unit (`Σ A b`).
    pub openings: [f64; BANDS],
    /// Per band: power reaching polygons from behind (one-sided surfaces' unlit sides).
    pub back_faces: [f64; BANDS],
    /// Rays cast (0 when the solver's balance says nothing escapes: no rays needed).
    pub rays: u64,
}

/// The estimate for radiosities `b` on `mesh` (elements' fronts), rays against `occluders`.
/// `escaped` is the solver's: when it is at most `1e-9` of the light leaving the surfaces,
/// nothing escapes and no ray is cast.
pub fn estimate(
    mesh: &ElementMesh,
    b: &[[f64; BANDS]],
    occluders: &Occluders,
    escaped: [f64; BANDS],
) -> Escape {
    let power: Vec<f64> = mesh
        .elements
        .iter()
        .zip(b)
        .map(|(el, v)| el.area * v.iter().map(|x| x.max(0.0)).sum::<f64>())
        .collect();
    let mut cumulative = Vec::with_capacity(power.len());
    let mut total = 0.0;
    for p in &power {
        total += p;
        cumulative.push(total);
    }
    let leaving: f64 = escaped.iter().map(|x| x.max(0.0)).sum();
    if !(total > 0.0 && total.is_finite()) || leaving <= 1e-9 * total {
        return Escape::default();
    }
    let (lo, hi) = mesh.vertices.iter().fold(
        (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY),
        |(lo, hi), v| (lo.min(*v), hi.max(*v)),
    );
    // Far past the scene: a ray that meets nothing within this has left it.
    let reach = 4.0 * (hi - lo).length().max(f64::MIN_POSITIVE);
    let lift = occluders.ray_offset();
    let per_ray = total / RAYS as f64;
    let sums: Vec<([f64; BANDS], [f64; BANDS])> = (0..RAYS / CHUNK)
        .into_par_iter()
        .map(|chunk| {
            let mut rng = SplitMix64::new(0x0e5c_a9e0_0000_0000 ^ chunk);
            let (mut open, mut back) = ([0.0; BANDS], [0.0; BANDS]);
            for _ in 0..CHUNK {
                let t = rng.next_f64() * total;
                let k = cumulative.partition_point(|&c| c <= t).min(power.len() - 1);
                let el = &mesh.elements[k];
                let sum: f64 = b[k].iter().map(|x| x.max(0.0)).sum();
                if sum <= 0.0 {
                    continue;
                }
                let from = point_on_element(mesh, k, &mut rng) + el.normal * lift;
                let dir = cosine_direction(el.normal, &mut rng);
                let hit = occluders.first_hit(from, from + dir * reach, el.polygon as usize);
                let into = match hit {
                    None => &mut open,
                    Some(h) if !h.front => &mut back,
                    Some(_) => continue,
                };
                // This ray carries `per_ray` of the power, split over the bands as b_k is.
                for (x, v) in into.iter_mut().zip(b[k]) {
                    *x += per_ray * v.max(0.0) / sum;
                }
            }
            (open, back)
        })
        .collect();
    let mut out = Escape {
        rays: RAYS,
        ..Escape::default()
    };
    for (open, back) in sums {
        for c in 0..BANDS {
            out.openings[c] += open[c];
            out.back_faces[c] += back[c];
        }
    }
    out
}
