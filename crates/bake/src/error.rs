//! An estimate of each element's error `|b_i − b̄_i|`, `b̄_i` the area average over the
//! element of the exact continuous radiosity, per band: six parts, independent sources of
//! error, combined in quadrature (their plain sum, the worst case where every part has the
//! same sign, overestimated the hierarchy's difference from the dense solve of the same mesh
//! 30–40× at the median; measured in `tests/end_to_end/hierarchical.rs`).
//!
//! - **Discretisation** (how much the light varies across the element, which a constant
//!   element cannot follow): the element's value against the linear reconstruction from its
//!   neighbours on the same polygon (a least-squares plane through their centroids, evaluated
//!   at the element's centroid); where fewer than three neighbours span the plane, half the
//!   largest difference to a neighbour. Part 2's refinement acts on this part. Its blind spot:
//!   along a polygon's edge the neighbours form two rows, which a plane fits exactly, so
//!   curvature across the edge is not seen there (adding the second ring of neighbours there
//!   bounds 98% of the cube's element-bands but overestimates 15×; measured, not adopted).
//! - **Form-factor integration**: the estimator's stated relative accuracy `τ` of each pair or
//!   link (`auto`'s tolerance, the contour integral's 1e-9), each pair's error its own, of
//!   either sign: `ρ_i τ (Σ_j (F_ij b_j)²)^½` (the deliveries in quadrature; `ρ_i τ H_i`, every
//!   error of one sign, was 10× the cube's form-factor error at `--max-error` 1e-2 and took the
//!   whole estimate's median true/estimate to 0.08), amplified by the reflections light
//!   makes: the solution's own
//!   amplification `a = B̄ / Ē` (mean radiosity over mean source, per band), at most
//!   `‖A⁻¹‖∞` (the band's condition estimate over `1 + ρ_max`), which is the worst row's.
//! - **Visibility sampling**: where shadow rays decide a pair's visible fraction, K rays
//!   stratified in the pair's 4-D domain leave about `1/(2 K^{5/8})` of it (jittered sampling
//!   of an indicator with a smooth boundary: standard deviation ∝ K^{−(1+1/d)/2}, d = 4); it is
//!   charged on the whole of `ρ_i H_i` for elements of polygons that some polygon may shadow
//!   (the dense form-factor stage keeps no per-element occludable share). On the hierarchical
//!   transport each link's own rays: `ρ_i (Σ (F σ B_s)²)^½` over the links reaching the
//!   element, σ the standard deviation of the link's estimated visible fraction
//!   (`HierarchicalTransport::link_error`): the links' rays are independent, and only the
//!   links a shadow boundary crosses carry much of it.
//! - **Solver**: the relative residual times the condition estimate, times `|b_i|`.
//! - **Links** (hierarchical transport only): what the links' linear models of the kernel leave
//!   over their nodes, `ρ_i F (residual_r B_s + residual_s ΔB_s)` of each link reaching the
//!   element through its ancestors, combined in quadrature (`HierarchicalTransport::link_error`);
//!   and, in quadrature with it, what reflection brings of the other elements' misses (models
//!   and visibility), `ρ_i a (F ρ δH)_i` (the first reflection through the transport
//!   itself, with every miss of one sign; the later ones by the solution's own amplification
//!   `a = B̄ / Ē`, at most `‖A⁻¹‖∞`). Amplifying each
//!   element's own miss by `‖A⁻¹‖∞` instead made the estimate 15× the Cornell box's true
//!   difference from the dense solve at the median. The dense transport integrates every
//!   element pair: 0 there.
//!
//! - **Sky sampling**: where rays decide an element's sky illuminance E, their standard
//!   error σ_E (`direct::sky::SkyLight::deviation`) becomes `ρ_i σ_E / π` of its b (the
//!   first reflection; the other elements' errors are independent and of either sign, and
//!   cancel in what they reflect). 0 where E is a closed form.
//!
//! This module looks at a solved bake (mesh, b, ρ, e and the solver's diagnostics); it
//! integrates nothing and changes no value of `b`.

use mesher::ElementMesh;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use solver::BANDS;

/// What the error estimate needs besides the mesh and the solution.
pub struct Inputs<'a> {
    pub mesh: &'a ElementMesh,
    pub b: &'a [[f64; BANDS]],
    pub rho: &'a [[f64; BANDS]],
    /// The source term the solver saw (emission plus the lights' first reflection).
    pub source: &'a [[f64; BANDS]],
    /// The row-sum accuracy the form factors state.
    pub row_sum_accuracy: f64,
    /// Per element: what its pairs or links deliver, `(Σ_j (F_ij b_j)²)^½`
    /// (`transport::View::delivered_quadrature`).
    pub delivered: &'a [[f64; BANDS]],
    /// Per band: the solver's condition estimate (1 where the band was not solved as a system).
    pub condition: [f64; BANDS],
    /// The largest reflectance (`‖A‖∞ = 1 + ρ_max` for a closed scene).
    pub rho_max: f64,
    /// Per band: the solver's relative residual (0 where exact).
    pub residual: [f64; BANDS],
    /// Per element: whether some polygon may shadow it (shadow rays decided part of `H_i`).
    pub sampled: &'a [bool],
    /// Shadow rays per sampled pair.
    pub samples: u32,
    /// What the links' models miss (hierarchical transport only).
    pub link_error: Option<LinkMisses<'a>>,
    /// Per element: the standard error of the source the sky's rays gave it (`ρ σ_E / π`;
    /// empty without a sky).
    pub source_noise: &'a [[f64; BANDS]],
}

/// Per element and band, what a hierarchical transport's links miss of the irradiance: their
/// models' own (`local`, δH), their shadow rays' (`visibility`, one standard deviation), and
/// the other elements' misses of both kinds after one reflection (`carried`, `F (ρ δH)`: the
/// misses taken with one sign, the worst case, through the transport itself).
#[derive(Clone, Copy)]
pub struct LinkMisses<'a> {
    pub local: &'a [[f64; BANDS]],
    pub carried: &'a [[f64; BANDS]],
    pub visibility: &'a [[f64; BANDS]],
}

/// The per-element error estimates of a bake, per band: largest, area-weighted RMS, where the
/// largest is, and the largest of each part (the report's `accuracy.error`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorSummary {
    pub max: [f64; BANDS],
    pub rms: [f64; BANDS],
    /// Per band: the element with the largest estimate and its centroid.
    pub max_element: [usize; BANDS],
    pub max_centroid: [[f64; 3]; BANDS],
    /// Per band: the largest discretisation, form-factor, visibility and solver part.
    pub max_discretisation: [f64; BANDS],
    pub max_form_factors: [f64; BANDS],
    pub max_visibility: [f64; BANDS],
    pub max_solver: [f64; BANDS],
    /// Per band: the largest links part (0 on the dense transport; absent from reports of
    /// bakes before it existed).
    #[serde(default)]
    pub max_links: [f64; BANDS],
    /// Per band: the largest sky-sampling part (0 without a sky or where it is exact; absent
    /// from reports of bakes before it existed).
    #[serde(default)]
    pub max_sky: [f64; BANDS],
}

/// The summary of the estimates `parts`, one per element of `mesh` (RMS weighted by area, in
/// element order).
pub fn summary(mesh: &ElementMesh, parts: &[Parts]) -> ErrorSummary {
    let mut s = ErrorSummary {
        max: [0.0; BANDS],
        rms: [0.0; BANDS],
        max_element: [0; BANDS],
        max_centroid: [[0.0; 3]; BANDS],
        max_discretisation: [0.0; BANDS],
        max_form_factors: [0.0; BANDS],
        max_visibility: [0.0; BANDS],
        max_solver: [0.0; BANDS],
        max_links: [0.0; BANDS],
        max_sky: [0.0; BANDS],
    };
    let mut area = 0.0;
    for (i, (element, p)) in mesh.elements.iter().zip(parts).enumerate() {
        let total = p.total();
        area += element.area;
        for (c, &t) in total.iter().enumerate() {
            if t > s.max[c] {
                s.max[c] = t;
                s.max_element[c] = i;
                s.max_centroid[c] = element.centroid.to_array();
            }
            s.rms[c] += element.area * t * t;
            s.max_discretisation[c] = s.max_discretisation[c].max(p.discretisation[c]);
            s.max_form_factors[c] = s.max_form_factors[c].max(p.form_factors[c]);
            s.max_visibility[c] = s.max_visibility[c].max(p.visibility[c]);
            s.max_solver[c] = s.max_solver[c].max(p.solver[c]);
            s.max_links[c] = s.max_links[c].max(p.links[c]);
            s.max_sky[c] = s.max_sky[c].max(p.sky[c]);
        }
    }
    if area > 0.0 {
        s.rms = s.rms.map(|x| (x / area).sqrt());
    }
    s
}

/// The six parts of one element's estimate, per band.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Parts {
    pub discretisation: [f64; BANDS],
    pub form_factors: [f64; BANDS],
    pub visibility: [f64; BANDS],
    pub solver: [f64; BANDS],
    pub links: [f64; BANDS],
    pub sky: [f64; BANDS],
}

impl Parts {
    /// The estimate: the parts in quadrature (module docs).
    pub fn total(&self) -> [f64; BANDS] {
        [0, 1, 2].map(|c| {
            (self.discretisation[c].powi(2)
                + self.form_factors[c].powi(2)
                + self.visibility[c].powi(2)
                + self.solver[c].powi(2)
                + self.links[c].powi(2)
                + self.sky[c].powi(2))
            .sqrt()
        })
    }
}

/// Each element's estimate, in element order.
pub fn estimate(inputs: &Inputs) -> Vec<Parts> {
    let mesh = inputs.mesh;
    let neighbours = neighbours(mesh);
    // ‖A⁻¹‖∞ = cond∞ / ‖A‖∞, with ‖A‖∞ = 1 + ρ_max for a closed scene (an open one's is
    // smaller, and so this is at most 1 + ρ_max times low there).
    let inverse_norm = inputs
        .condition
        .map(|k| (k / (1.0 + inputs.rho_max)).max(1.0));
    // What the other elements' misses become after their later reflections: the
    // amplification this solution has, mean radiosity over mean source (`B̄ / Ē`, per band,
    // area-weighted), at most ‖A⁻¹‖∞. A miss spread over the reflecting surfaces is amplified
    // like the light itself, not like the worst row of A⁻¹ (which overestimated the Cornell
    // box's difference from the dense solve 1.5× more).
    let mut power = [[0.0f64; 2]; BANDS];
    for ((element, b), source) in mesh.elements.iter().zip(inputs.b).zip(inputs.source) {
        for (p, (b, e)) in power.iter_mut().zip(b.iter().zip(source)) {
            p[0] += element.area * b;
            p[1] += element.area * e;
        }
    }
    let amplification: [f64; BANDS] = [0, 1, 2].map(|c| {
        let a = power[c][0] / power[c][1];
        if a.is_finite() {
            a.clamp(1.0, inverse_norm[c])
        } else {
            inverse_norm[c]
        }
    });
    (0..mesh.elements.len())
        .into_par_iter()
        .map(|i| {
            let b = inputs.b[i];
            let discretisation = discretisation(mesh, inputs.b, i, &neighbours[i]);
            let mut parts = Parts {
                discretisation,
                sky: inputs.source_noise.get(i).copied().unwrap_or([0.0; BANDS]),
                ..Parts::default()
            };
            for c in 0..BANDS {
                // ρ H = b − e (the reflected part), never negative in a physical solution.
                let reflected = (b[c] - inputs.source[i][c]).max(0.0);
                parts.form_factors[c] = amplification[c]
                    * inputs.row_sum_accuracy
                    * inputs.rho[i][c]
                    * inputs.delivered[i][c];
                parts.solver[c] = inputs.residual[c] * inputs.condition[c] * b[c].abs();
                if let Some(links) = &inputs.link_error {
                    let rho = inputs.rho[i][c];
                    parts.links[c] =
                        rho * links.local[i][c].hypot(amplification[c] * links.carried[i][c]);
                    parts.visibility[c] = rho * links.visibility[i][c];
                } else if inputs.sampled[i] && inputs.samples > 0 {
                    parts.visibility[c] = reflected / (2.0 * f64::from(inputs.samples).powf(0.625));
                }
            }
            parts
        })
        .collect()
}

/// Per element: the other elements of its polygon that share a vertex of its outline (its
/// corners, and on a refined mesh the hanging vertices on its edges) with it, in index order.
pub fn neighbours(mesh: &ElementMesh) -> Vec<Vec<u32>> {
    neighbours_where(mesh, |_, _| true)
}

/// Like [`neighbours`], keeping only the pairs `keep(i, j)` accepts (e.g. on the same side of
/// every shadow edge).
pub fn neighbours_where(
    mesh: &ElementMesh,
    keep: impl Fn(usize, usize) -> bool + Sync,
) -> Vec<Vec<u32>> {
    let mut at_vertex: Vec<Vec<u32>> = vec![Vec::new(); mesh.vertices.len()];
    for i in 0..mesh.elements.len() {
        for &v in mesh.outline(i) {
            if let Some(list) = at_vertex.get_mut(v as usize) {
                list.push(i as u32);
            }
        }
    }
    mesh.elements
        .par_iter()
        .enumerate()
        .map(|(i, e)| {
            let mut list: Vec<u32> = mesh
                .outline(i)
                .iter()
                .filter_map(|&v| at_vertex.get(v as usize))
                .flatten()
                .copied()
                .filter(|&j| {
                    j as usize != i
                        && mesh.elements[j as usize].polygon == e.polygon
                        && keep(i, j as usize)
                })
                .collect();
            list.sort_unstable();
            list.dedup();
            list
        })
        .collect()
}

/// `|b_i − L(c_i)|` per band, `L` the least-squares plane through the neighbours' values at
/// their centroids (in the element's plane); half the largest neighbour difference where the
/// neighbours do not span a plane.
pub fn discretisation(
    mesh: &ElementMesh,
    b: &[[f64; BANDS]],
    i: usize,
    neighbours: &[u32],
) -> [f64; BANDS] {
    let e = &mesh.elements[i];
    let half_spread = || {
        let mut d = [0.0f64; BANDS];
        for &j in neighbours {
            for c in 0..BANDS {
                d[c] = d[c].max((b[j as usize][c] - b[i][c]).abs() / 2.0);
            }
        }
        d
    };
    if neighbours.len() < 3 {
        return half_spread();
    }
    let t = e.normal.any_orthonormal_vector();
    let s = e.normal.cross(t);
    // Normal equations of v ≈ a + g_t x + g_s y, x, y relative to the element's centroid.
    let mut m = [[0.0f64; 3]; 3];
    let mut r = [[0.0f64; 3]; BANDS];
    for &j in neighbours {
        let d = mesh.elements[j as usize].centroid - e.centroid;
        let row = [1.0, d.dot(t), d.dot(s)];
        for p in 0..3 {
            for q in 0..3 {
                m[p][q] += row[p] * row[q];
            }
            for c in 0..BANDS {
                r[c][p] += row[p] * b[j as usize][c];
            }
        }
    }
    let Some(a) = solve3(m, r) else {
        return half_spread();
    };
    [0, 1, 2].map(|c| (b[i][c] - a[c]).abs())
}

/// The first unknown (the plane's value at the centroid) of `m x = r_c` for each band, by
/// Cramer's rule; `None` when `m` is singular relative to its size.
fn solve3(m: [[f64; 3]; 3], r: [[f64; 3]; BANDS]) -> Option<[f64; BANDS]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&m);
    let scale = m[0][0] * m[1][1] * m[2][2];
    if d.is_nan() || d.abs() <= 1e-9 * scale.abs() {
        return None;
    }
    Some([0, 1, 2].map(|c| {
        let mut k = m;
        for (p, row) in k.iter_mut().enumerate() {
            row[0] = r[c][p];
        }
        det(&k) / d
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// The unit square in z = 0, as the OBJ importer reads it.
    fn square_mesh(n: u32) -> ElementMesh {
        let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
        let scene = importer::load_obj_bytes(obj.as_bytes(), None).expect("the square imports");
        mesher::mesh(&scene.polygons, mesher::Subdivision::Count(n)).expect("mesh")
    }

    fn discretisations(mesh: &ElementMesh, f: impl Fn(DVec3) -> f64) -> Vec<f64> {
        let b: Vec<[f64; BANDS]> = mesh.elements.iter().map(|e| [f(e.centroid); 3]).collect();
        let nb = neighbours(mesh);
        (0..mesh.elements.len())
            .map(|i| discretisation(mesh, &b, i, &nb[i])[0])
            .collect()
    }

    /// A linear field is reconstructed exactly from any neighbourhood (edges and corners
    /// too): no discretisation error is charged.
    #[test]
    fn linear_light_has_no_discretisation_error() {
        let mesh = square_mesh(6);
        for d in discretisations(&mesh, |p| 2.0 + 3.0 * p.x - 1.5 * p.y) {
            assert!(d < 1e-12, "{d}");
        }
    }

    /// b = x² sampled at centroids on a grid of spacing h: the least-squares plane through an
    /// interior element's 8 neighbours is their mean, x² + (6/8) h², so the estimate is
    /// 0.75 h² exactly; along the edges parallel to x it is h², along the others and at the
    /// corners 0.
    #[test]
    fn quadratic_light_gives_the_closed_form_estimate() {
        let n = 8;
        let h = 1.0 / f64::from(n);
        let mesh = square_mesh(n);
        let d = discretisations(&mesh, |p| p.x * p.x);
        let nb = neighbours(&mesh);
        for (i, e) in mesh.elements.iter().enumerate() {
            let expect = match nb[i].len() {
                8 => 0.75 * h * h,
                // Along a bottom or top edge the plane passes through the two rows' means:
                // x² + h² at the element's own row. Along a left or right edge the
                // neighbours are two columns, which a plane fits exactly: the curvature
                // across the edge goes unseen (the estimate's blind spot, as at corners,
                // whose three neighbours determine the plane).
                5 if e.centroid.y < h || e.centroid.y > 1.0 - h => h * h,
                5 => 0.0,
                3 => 0.0,
                k => panic!("{k} neighbours"),
            };
            assert!(
                (d[i] - expect).abs() < 1e-12,
                "{i}: {} at {}",
                d[i],
                e.centroid
            );
        }
        assert_eq!(nb.iter().filter(|l| l.len() == 8).count(), 36);
    }

    /// The parts other than discretisation follow their formulas: a uniform field, 2 × 2
    /// elements, ρH = b − e = 0.5, deliveries 0.4 in quadrature, ‖A⁻¹‖ = 10 / (1 + 0.5),
    /// amplification B̄ / Ē = 1.5, accuracy 1e-6, 100 rays on half of them, residual 1e-12,
    /// a sky part of 0.25 given as it is.
    #[test]
    fn the_other_parts_follow_their_formulas() {
        let mesh = square_mesh(2);
        let n = mesh.elements.len();
        let b = vec![[1.5; BANDS]; n];
        let sampled: Vec<bool> = (0..n).map(|i| i % 2 == 0).collect();
        let parts = estimate(&Inputs {
            mesh: &mesh,
            b: &b,
            rho: &vec![[0.5; BANDS]; n],
            source: &vec![[1.0; BANDS]; n],
            row_sum_accuracy: 1e-6,
            delivered: &vec![[0.4; BANDS]; n],
            condition: [10.0; BANDS],
            rho_max: 0.5,
            residual: [1e-12; BANDS],
            sampled: &sampled,
            samples: 100,
            link_error: None,
            source_noise: &vec![[0.25; BANDS]; n],
        });
        for (i, p) in parts.iter().enumerate() {
            assert_eq!(p.discretisation, [0.0; BANDS]);
            // The amplification B̄ / Ē = 1.5 (below ‖A⁻¹‖∞ = 10 / 1.5) × accuracy × ρ × the
            // deliveries in quadrature.
            let ff = 1.5 * 1e-6 * 0.5 * 0.4;
            assert!((p.form_factors[0] - ff).abs() < 1e-18, "{p:?}");
            let vis = if i % 2 == 0 {
                0.5 / (2.0 * 100f64.powf(0.625))
            } else {
                0.0
            };
            assert!((p.visibility[0] - vis).abs() < 1e-15, "{p:?}");
            assert!((p.solver[0] - 1e-12 * 10.0 * 1.5).abs() < 1e-24, "{p:?}");
            assert_eq!(p.sky, [0.25; BANDS]);
            let total = (ff * ff + vis * vis + 1.5e-11f64.powi(2) + 0.25f64.powi(2)).sqrt();
            assert!((p.total()[0] - total).abs() < 1e-15);
        }
    }
}
