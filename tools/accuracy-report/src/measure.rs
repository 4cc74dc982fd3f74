//! One setting of the sweep, baked in-process stage by stage (mesh → visibility → form factors
//! → solve, as `bake` does), timed, with its peak heap; and the fields and errors that compare a
//! solution against a reference solution on another mesh of the same polygons.

use crate::peak;
use anyhow::{anyhow, Context, Result};
use form_factor::{ContourOptions, Estimator};
use glam::DVec3;
use importer::Polygon;
use mesher::{ElementMesh, Subdivision};
use solver::{DenseMatrix, IterativeOptions};
use std::time::Instant;

/// A loaded scene: its polygons and per-polygon ρ and e.
pub struct Scene {
    pub name: &'static str,
    /// The imported scene, as the bake library takes it.
    pub source: importer::Scene,
    pub polygons: Vec<Polygon>,
    pub rho: Vec<[f64; 3]>,
    pub emission: Vec<[f64; 3]>,
}

impl Scene {
    pub fn load(name: &'static str, path: &std::path::Path) -> Result<Scene> {
        let scene = importer::load(path).with_context(|| format!("{}", path.display()))?;
        let (rho, emission) = scene
            .polygons
            .iter()
            .map(|p| {
                let m = &scene.materials[p.material];
                (m.rho, m.emission)
            })
            .unzip();
        Ok(Scene {
            name,
            polygons: scene.polygons.clone(),
            source: scene,
            rho,
            emission,
        })
    }

    /// Per-element ρ and e of `mesh`.
    pub fn element_values(&self, mesh: &ElementMesh) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        mesh.elements
            .iter()
            .map(|e| {
                let p = e.polygon as usize;
                (self.rho[p], self.emission[p])
            })
            .unzip()
    }
}

/// How to solve `(I − ρF) b = e`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Solve {
    Direct,
    /// The truncated series: direct light plus this many interreflections.
    Bounces(u32),
}

/// One point of the sweep.
#[derive(Clone, Debug)]
pub struct Setting {
    /// The knob this row varies (a plot legend group).
    pub group: String,
    pub label: String,
    pub subdivision: Subdivision,
    pub estimator: Estimator,
    pub contour: ContourOptions,
    pub samples: u32,
    pub solve: Solve,
    /// A preset's target error of b: `auto`'s tolerance is then derived from it and ρ_max as
    /// `--quality` does (`None`: the estimator as given).
    pub max_error: Option<f64>,
    /// Refinement below the grid with this element budget (`--refine on --max-elements N`,
    /// the target from `max_error` or the preset's); `None`: `--refine off`, the uniform mesh.
    pub refine: Option<u64>,
    /// With `refine`: split elements at most this many times (`None`: the library's limit).
    pub refine_levels: Option<u8>,
}

/// A finished bake and what it cost.
pub struct Run {
    pub mesh: ElementMesh,
    pub b: Vec<[f64; 3]>,
    /// Wall time of the library's bake: mesh + visibility + form factors + solve + energy
    /// balance (the fastest of the repeats).
    pub time_s: f64,
    pub ff_s: f64,
    pub solve_s: f64,
    pub peak_bytes: usize,
    pub counts: bake_core::Counts,
}

/// Bakes `setting` (repeated while it takes under 0.2 s, up to 3 times, keeping the fastest).
pub fn bake(scene: &Scene, setting: &Setting) -> Result<Run> {
    let mut best: Option<Run> = None;
    for _ in 0..3 {
        let run = bake_once(scene, setting)?;
        let fast = run.time_s < 0.2;
        if best.as_ref().is_none_or(|b| run.time_s < b.time_s) {
            best = Some(run);
        }
        if !fast {
            break;
        }
    }
    best.ok_or_else(|| anyhow!("no run"))
}

/// The library's one bake with this setting's knobs, on the dense transport the sweep
/// measures: each estimator and tolerance as given, except a preset's (`max_error`), whose
/// tolerance `--max-error` derives, as `--quality` does.
fn request(setting: &Setting) -> bake_core::Request {
    use bake_core::EstimatorKind;
    let (ff_estimator, ff_tolerance, ff_points) = match setting.estimator {
        Estimator::Contour => (EstimatorKind::Contour, None, None),
        Estimator::PointPolygon(rule) => (EstimatorKind::PointPolygon, None, Some(rule.points())),
        Estimator::PointPoint => (EstimatorKind::PointPoint, None, None),
        Estimator::Auto { .. } if setting.max_error.is_some() => (EstimatorKind::Auto, None, None),
        Estimator::Auto { tolerance } => (EstimatorKind::Auto, Some(tolerance), None),
    };
    let default = bake_core::Request::default();
    bake_core::Request {
        subdivision: Some(setting.subdivision),
        transport: bake_core::TransportKind::Dense,
        refine: Some(setting.refine.is_some()),
        max_elements: setting.refine,
        refine_levels: setting.refine_levels,
        ff_estimator: Some(ff_estimator),
        ff_tolerance,
        ff_points: ff_points.unwrap_or(default.ff_points),
        max_error: setting.max_error,
        contour: setting.contour,
        visibility_samples: Some(setting.samples),
        bounces: match setting.solve {
            Solve::Direct => None,
            Solve::Bounces(k) => Some(k),
        },
        ..default
    }
}

pub fn bake_once(scene: &Scene, setting: &Setting) -> Result<Run> {
    let base = peak::reset();
    let start = Instant::now();
    let settings = bake_core::Settings::resolve(&request(setting), &scene.polygons)?;
    let bake = bake_core::run(&scene.source, &settings, &bake_core::Silent)?;
    let time_s = start.elapsed().as_secs_f64();
    let stage = |name: &str| {
        bake.timings
            .iter()
            .filter(|(n, _)| *n == name)
            .map(|(_, t)| t)
            .sum::<f64>()
    };
    Ok(Run {
        ff_s: stage("form_factors"),
        solve_s: stage("solve"),
        time_s,
        peak_bytes: peak::peak().saturating_sub(base),
        counts: bake.counts,
        mesh: bake.mesh,
        b: bake.solution.b,
    })
}

/// The exact solution of `mesh` from closed-form rectangle form factors (the paper's cube:
/// every element an axis-aligned rectangle), solved by GMRES to a residual of 1e-13.
pub fn closed_form_solution(scene: &Scene, mesh: &ElementMesh) -> Result<Vec<[f64; 3]>> {
    let data = reference::dense_form_factors(mesh).ok_or_else(|| {
        anyhow!(
            "{}: not every element is an axis-aligned rectangle",
            scene.name
        )
    })?;
    let (rho, e) = scene.element_values(mesh);
    let f = DenseMatrix::new(mesh.elements.len(), &data)?;
    let options = IterativeOptions {
        tolerance: 1e-13,
        max_iterations: 10_000,
        ..IterativeOptions::default()
    };
    Ok(solver::solve_iterative(&f, &rho, &e, &options)?.b)
}

/// A solution as a function on the scene's surfaces: flat (each element's value) or smoothed
/// (the paper's vertex averages, interpolated bilinearly over quads and linearly over
/// triangles).
pub struct Field<'a> {
    pub mesh: &'a ElementMesh,
    pub b: &'a [[f64; 3]],
    smoothed: Vec<[f64; 3]>,
}

impl<'a> Field<'a> {
    pub fn new(mesh: &'a ElementMesh, b: &'a [[f64; 3]]) -> Field<'a> {
        Field {
            mesh,
            b,
            smoothed: mesh.smooth(b),
        }
    }

    /// The element of `polygon` containing `p` and p's parameters in it.
    fn locate(&self, polygon: usize, p: DVec3) -> Option<(usize, [f64; 4])> {
        let patch = self.mesh.patches.get(polygon)?;
        let mut best: Option<(usize, [f64; 4], f64)> = None;
        for k in patch.elements.clone() {
            let k = k as usize;
            let e = &self.mesh.elements[k];
            let corners = corners(self.mesh, k);
            let c = &corners[..e.sides as usize];
            // Cheap rejection before the inverse map: farther than every corner.
            let reach = c.iter().map(|x| x.distance(e.centroid)).fold(0.0, f64::max);
            if p.distance(e.centroid) > reach * (1.0 + 1e-6) {
                continue;
            }
            let (weights, outside) = weights(c, e.normal, p);
            if outside <= 1e-9 {
                return Some((k, weights));
            }
            if best.as_ref().is_none_or(|b| outside < b.2) {
                best = Some((k, weights, outside));
            }
        }
        // On an edge between elements rounding may put p a hair outside every one of them.
        best.filter(|b| b.2 < 1e-6).map(|b| (b.0, b.1))
    }

    pub fn flat(&self, polygon: usize, p: DVec3) -> Option<[f64; 3]> {
        self.locate(polygon, p).map(|(k, _)| self.b[k])
    }

    pub fn smooth(&self, polygon: usize, p: DVec3) -> Option<[f64; 3]> {
        let (k, w) = self.locate(polygon, p)?;
        let mut v = [0.0; 3];
        for (corner, weight) in self.mesh.elements[k].corner_indices().iter().zip(w) {
            for (band, value) in v.iter_mut().enumerate() {
                *value += weight * self.smoothed[*corner as usize][band];
            }
        }
        Some(v)
    }
}

/// An element's corner positions (a triangle repeats its third corner), without allocating.
fn corners(mesh: &ElementMesh, element: usize) -> [DVec3; 4] {
    mesh.elements[element]
        .corners
        .map(|i| mesh.vertices[i as usize])
}

/// Interpolation weights of `p` at the corners `c` (bilinear for a quad by Newton's method on
/// the inverse map, barycentric for a triangle), and how far outside the element p lies in
/// parameter units (≤ 0 inside).
fn weights(c: &[DVec3], normal: DVec3, p: DVec3) -> ([f64; 4], f64) {
    let e1 = (c[1] - c[0]).normalize_or_zero();
    let e2 = normal.cross(e1);
    let to2 = |x: DVec3| glam::DVec2::new((x - c[0]).dot(e1), (x - c[0]).dot(e2));
    let q = to2(p);
    if c.len() == 3 {
        let (a, b) = (to2(c[1]), to2(c[2]));
        let det = a.perp_dot(b);
        let l1 = q.perp_dot(b) / det;
        let l2 = a.perp_dot(q) / det;
        let l0 = 1.0 - l1 - l2;
        let outside = (-l0).max(-l1).max(-l2);
        return ([l0, l1, l2, 0.0], outside);
    }
    let (u, v) = inverse_bilinear(c, normal, p);
    let outside = (-u).max(u - 1.0).max(-v).max(v - 1.0);
    (
        [(1.0 - u) * (1.0 - v), u * (1.0 - v), u * v, (1.0 - u) * v],
        outside,
    )
}

/// Parameters (u, v) of `p` in the bilinear quad `c` (u along c0→c1, v along c0→c3), by
/// Newton's method in the quad's plane.
fn inverse_bilinear(c: &[DVec3], normal: DVec3, p: DVec3) -> (f64, f64) {
    let e1 = (c[1] - c[0]).normalize_or_zero();
    let e2 = normal.cross(e1);
    let to2 = |x: DVec3| glam::DVec2::new((x - c[0]).dot(e1), (x - c[0]).dot(e2));
    let q = to2(p);
    let (a, b, d) = (to2(c[1]), to2(c[2]), to2(c[3]));
    // P(u, v) = u a + v d + u v (b − a − d), corner 0 at the origin.
    let k = b - a - d;
    let (mut u, mut v) = (0.5, 0.5);
    for _ in 0..20 {
        let r = a * u + d * v + k * (u * v) - q;
        let (du, dv) = (a + k * v, d + k * u);
        let det = du.perp_dot(dv);
        if det.abs() < 1e-300 {
            break;
        }
        let step_u = r.perp_dot(dv) / det;
        let step_v = du.perp_dot(r) / det;
        u -= step_u;
        v -= step_v;
        if step_u.abs() + step_v.abs() < 1e-15 {
            break;
        }
    }
    (u, v)
}

/// The parameter rectangle `[u0, u1] × [v0, v1]` an element covers in its quad polygon's
/// bilinear map (mesher grids are uniform in these parameters).
fn parameter_rect(polygon: &Polygon, mesh: &ElementMesh, element: usize) -> [f64; 4] {
    let e = &mesh.elements[element];
    let mut r = [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for &i in e.corner_indices() {
        let (u, v) = inverse_bilinear(&polygon.vertices, polygon.normal, mesh.vertices[i as usize]);
        r = [r[0].min(u), r[1].max(u), r[2].min(v), r[3].max(v)];
    }
    r
}

/// `sum += w · v`, band by band.
fn add(sum: &mut [f64; 3], w: f64, v: &[f64; 3]) {
    for (s, x) in sum.iter_mut().zip(v) {
        *s += w * x;
    }
}

/// Max and area-weighted RMS relative error over elements and bands.
#[derive(Clone, Copy, Debug, Default)]
pub struct Errors {
    pub max: f64,
    pub rms: f64,
}

/// Running max and weighted sum of squares of relative errors.
#[derive(Default)]
struct Accumulator {
    max: f64,
    squares: f64,
    weight: f64,
}

impl Accumulator {
    fn add(&mut self, error: f64, weight: f64) {
        self.max = self.max.max(error);
        self.squares += weight * error * error;
        self.weight += weight;
    }

    fn finish(self) -> Errors {
        Errors {
            max: self.max,
            rms: if self.weight > 0.0 {
                (self.squares / self.weight).sqrt()
            } else {
                0.0
            },
        }
    }
}

/// Sub-samples per reference element side on triangles for [`element_errors`].
const SUBSAMPLES: usize = 4;

/// Relative error of each element of `coarse` against the area average of the reference over
/// it. On quads the overlap of every coarse and reference element is exact in the polygon's
/// bilinear parameters (exact area for parallelograms, like every quad of the cube and the
/// Cornell box); on triangles each reference element is cut into 4 × 4 pieces credited to the
/// element containing their centres.
pub fn element_errors(coarse: &Field, reference: &Field, scene: &Scene) -> Errors {
    let means = reference_means(coarse, reference, scene);
    let floor = dark_floor(reference, scene);
    let mut errors = Accumulator::default();
    for (c, e) in coarse.mesh.elements.iter().enumerate() {
        let Some(r) = means[c] else {
            continue;
        };
        for band in 0..3 {
            let err = (coarse.b[c][band] - r[band]).abs() / r[band].max(floor[band]);
            if err.is_finite() {
                errors.add(err, e.area);
            }
        }
    }
    errors.finish()
}

/// The field a viewer shows (vertex-interpolated, [`Field::smooth`]) of `shown`, sampled at the
/// centroid of every element of the finer `reference` (≥ 32 × 32 points per face for the
/// references used here), against the reference element's value, relative to the reference's
/// area-weighted mean over non-emitting elements (per band): RMS weighted by the reference
/// elements' areas, and the worst point. Unlike [`element_errors`], elements of `shown` finer
/// than the reference's are not compared with an average they do not resolve, and dark
/// regions count by their absolute error.
pub fn displayed_errors(shown: &Field, reference: &Field, scene: &Scene) -> Errors {
    let lit = |k: usize| {
        let p = reference.mesh.elements[k].polygon as usize;
        scene
            .emission
            .get(p)
            .is_some_and(|e| e.iter().all(|&v| v == 0.0))
    };
    let (mut mean, mut area) = ([0.0; 3], 0.0);
    for (k, e) in reference.mesh.elements.iter().enumerate() {
        if lit(k) {
            add(&mut mean, e.area, &reference.b[k]);
            area += e.area;
        }
    }
    if area <= 0.0 {
        return Errors { max: 0.0, rms: 0.0 };
    }
    let mean = mean.map(|m| m / area);
    let mut errors = Accumulator::default();
    for (k, e) in reference.mesh.elements.iter().enumerate() {
        if !lit(k) {
            continue;
        }
        let polygon = e.polygon as usize;
        let Some(v) = shown
            .smooth(polygon, e.centroid)
            .or_else(|| shown.flat(polygon, e.centroid))
        else {
            continue;
        };
        for band in 0..3 {
            if mean[band] > 0.0 {
                errors.add((v[band] - reference.b[k][band]).abs() / mean[band], e.area);
            }
        }
    }
    errors.finish()
}

/// Per element of `coarse`: the area average of the reference over it, as
/// [`element_errors`] computes it (`None` where no reference element overlaps it).
pub fn reference_means(coarse: &Field, reference: &Field, scene: &Scene) -> Vec<Option<[f64; 3]>> {
    let polygons = &scene.polygons;
    let n = coarse.mesh.elements.len();
    let mut sum = vec![[0.0f64; 3]; n];
    let mut area = vec![0.0f64; n];
    for (p, polygon) in polygons.iter().enumerate() {
        let (Some(cp), Some(rp)) = (coarse.mesh.patches.get(p), reference.mesh.patches.get(p))
        else {
            continue;
        };
        if polygon.vertices.len() == 4 {
            let rects: Vec<(usize, [f64; 4])> = cp
                .elements
                .clone()
                .map(|c| (c as usize, parameter_rect(polygon, coarse.mesh, c as usize)))
                .collect();
            for k in rp.elements.clone() {
                let k = k as usize;
                let r = parameter_rect(polygon, reference.mesh, k);
                let whole = (r[1] - r[0]) * (r[3] - r[2]);
                if whole <= 0.0 {
                    continue;
                }
                for &(c, q) in &rects {
                    let du = r[1].min(q[1]) - r[0].max(q[0]);
                    let dv = r[3].min(q[3]) - r[2].max(q[2]);
                    if du > 0.0 && dv > 0.0 {
                        let w = reference.mesh.elements[k].area * (du * dv / whole);
                        area[c] += w;
                        add(&mut sum[c], w, &reference.b[k]);
                    }
                }
            }
            continue;
        }
        for k in rp.elements.clone() {
            let k = k as usize;
            let e = &reference.mesh.elements[k];
            let c = corners(reference.mesh, k);
            let m = SUBSAMPLES;
            let w = e.area / (m * m) as f64;
            // The m² sub-triangles' centroids of the regular split (upright and inverted).
            let mut pieces = Vec::with_capacity(m * m);
            for i in 0..m {
                for j in 0..m - i {
                    let at = |a: f64, b: f64| {
                        c[0] + (c[1] - c[0]) * (a / m as f64) + (c[2] - c[0]) * (b / m as f64)
                    };
                    pieces.push(at(i as f64 + 1.0 / 3.0, j as f64 + 1.0 / 3.0));
                    if i + j + 1 < m {
                        pieces.push(at(i as f64 + 2.0 / 3.0, j as f64 + 2.0 / 3.0));
                    }
                }
            }
            for x in pieces {
                if let Some((c, _)) = coarse.locate(p, x) {
                    area[c] += w;
                    add(&mut sum[c], w, &reference.b[k]);
                }
            }
        }
    }
    (0..n)
        .map(|c| (area[c] > 0.0).then(|| sum[c].map(|s| s / area[c])))
        .collect()
}

/// Per band, 5% of the area-weighted mean radiosity of the reference's non-emitting elements:
/// errors are relative to the reference value but never to less than this, so elements in full
/// shadow (b ≈ 0, e.g. the floor under the Cornell box's blocks) count by their absolute error
/// instead of turning a difference of 1e-4 into 100%.
pub fn dark_floor(field: &Field, scene: &Scene) -> [f64; 3] {
    let mut sum = [0.0; 3];
    let mut area = 0.0;
    for (e, b) in field.mesh.elements.iter().zip(field.b) {
        if scene.emission[e.polygon as usize].iter().any(|&x| x > 0.0) {
            continue;
        }
        area += e.area;
        for band in 0..3 {
            sum[band] += e.area * b[band];
        }
    }
    sum.map(|s| if area > 0.0 { 0.05 * s / area } else { 0.0 })
}

/// The area-weighted mean of `b` over each polygon (the power each wall sends out, over its
/// area): a quantity every mesh of the same polygons can be compared on directly.
pub fn polygon_means(mesh: &ElementMesh, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut sum = vec![[0.0; 3]; mesh.patches.len()];
    let mut area = vec![0.0; mesh.patches.len()];
    for (e, v) in mesh.elements.iter().zip(b) {
        let p = e.polygon as usize;
        area[p] += e.area;
        add(&mut sum[p], e.area, v);
    }
    sum.iter()
        .zip(&area)
        .map(|(s, &a)| s.map(|x| if a > 0.0 { x / a } else { 0.0 }))
        .collect()
}

/// Largest relative difference over polygons and bands.
pub fn max_relative(values: &[[f64; 3]], reference: &[[f64; 3]]) -> f64 {
    let mut worst = 0.0f64;
    for (v, r) in values.iter().zip(reference) {
        for band in 0..3 {
            if r[band] > 0.0 {
                worst = worst.max((v[band] - r[band]).abs() / r[band]);
            }
        }
    }
    worst
}

/// Relative error of same-mesh solutions, element by element.
pub fn same_mesh_errors(mesh: &ElementMesh, b: &[[f64; 3]], exact: &[[f64; 3]]) -> Errors {
    let mut errors = Accumulator::default();
    for ((e, x), r) in mesh.elements.iter().zip(b).zip(exact) {
        for band in 0..3 {
            if r[band] > 0.0 {
                errors.add((x[band] - r[band]).abs() / r[band], e.area);
            }
        }
    }
    errors.finish()
}

/// A scanline across the scene: points on polygons, at positions along the line.
pub struct Scanline {
    pub points: Vec<(f64, usize, DVec3)>,
    /// Positions where the line moves to the next wall.
    pub breaks: Vec<f64>,
}

impl Scanline {
    /// The paper's cube seen from the emitter (z = 1) towards the back wall (z = 0): a
    /// horizontal line at height y = 0.43 (off every element edge of the swept grids) across
    /// the red wall (x = 0) from front to back, the back wall left to right, and the blue wall
    /// (x = 1) back to front. Position 0…3 is arc length.
    pub fn cube(scene: &Scene, samples: usize) -> Result<Scanline> {
        let find = |normal: DVec3| {
            scene
                .polygons
                .iter()
                .position(|p| p.normal.dot(normal) > 0.999)
                .ok_or_else(|| anyhow!("cube: no wall facing {normal}"))
        };
        let (red, back, blue) = (find(DVec3::X)?, find(DVec3::Z)?, find(-DVec3::X)?);
        let y = 0.43;
        let mut points = Vec::new();
        for k in 0..samples {
            let s = 3.0 * (k as f64 + 0.5) / samples as f64;
            let (polygon, p) = if s < 1.0 {
                (red, DVec3::new(0.0, y, 1.0 - s))
            } else if s < 2.0 {
                (back, DVec3::new(s - 1.0, y, 0.0))
            } else {
                (blue, DVec3::new(1.0, y, s - 2.0))
            };
            points.push((s, polygon, p));
        }
        Ok(Scanline {
            points,
            breaks: vec![1.0, 2.0],
        })
    }

    /// The field along the line.
    pub fn sample(&self, field: &Field, smooth: bool) -> Vec<[f64; 3]> {
        self.points
            .iter()
            .map(|&(_, polygon, p)| {
                let v = if smooth {
                    field.smooth(polygon, p)
                } else {
                    field.flat(polygon, p)
                };
                v.unwrap_or([f64::NAN; 3])
            })
            .collect()
    }

    pub fn positions(&self) -> Vec<f64> {
        self.points.iter().map(|p| p.0).collect()
    }
}

/// Max and RMS relative error of `values` against `reference` along a scanline.
pub fn scanline_errors(values: &[[f64; 3]], reference: &[[f64; 3]]) -> Errors {
    let mut errors = Accumulator::default();
    for (v, r) in values.iter().zip(reference) {
        for band in 0..3 {
            if r[band] > 0.0 && v[band].is_finite() {
                errors.add((v[band] - r[band]).abs() / r[band], 1.0);
            }
        }
    }
    errors.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// User + system CPU seconds of this process so far (Linux `/proc/self/stat`, 100 ticks
    /// per second), to compare bakes on a machine that other work shares.
    fn cpu_seconds() -> f64 {
        let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
        let fields: Vec<&str> = stat
            .rsplit(')')
            .next()
            .unwrap_or("")
            .split_whitespace()
            .collect();
        let ticks = |k: usize| {
            fields
                .get(k)
                .and_then(|f| f.parse::<f64>().ok())
                .unwrap_or(0.0)
        };
        // After the ")": state is field 0, utime field 11, stime field 12.
        (ticks(11) + ticks(12)) / 100.0
    }

    /// The cube at `--subdiv 28`, dense and hierarchical (each link tolerance), against the
    /// continuous solution (the exact closed-form solve at 48 × 48 per wall, averaged over each
    /// element). Prints the errors and wall and CPU times; asserts that the hierarchical error
    /// falls as the link tolerance does and is within 1.2× dense's at the last one (issue 11;
    /// speed is a benchmark, not a test).
    #[test]
    #[ignore = "a 13 824-element closed-form reference: minutes in a release build"]
    fn cube_28_hierarchical_and_dense_against_the_continuous_solution() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/cube.gltf");
        let cube = Scene::load("cube", &path).expect("cube");
        let ref_mesh = mesher::mesh(&cube.polygons, Subdivision::Count(48)).expect("mesh");
        let ref_b = closed_form_solution(&cube, &ref_mesh).expect("reference");
        let reference = Field::new(&ref_mesh, &ref_b);
        let bake = |transport, link_tolerance| {
            let request = bake_core::Request {
                subdivision: Some(Subdivision::Count(28)),
                transport,
                link_tolerance,
                refine: Some(false),
                ..bake_core::Request::default()
            };
            let settings =
                bake_core::Settings::resolve(&request, &cube.polygons).expect("settings");
            let (start, cpu) = (Instant::now(), cpu_seconds());
            let b = bake_core::run(&cube.source, &settings, &bake_core::Silent).expect("bake");
            let s = start.elapsed().as_secs_f64();
            println!("  ({s:.2} s wall, {:.2} s cpu)", cpu_seconds() - cpu);
            (b, s)
        };
        let (dense, dense_s) = bake(bake_core::TransportKind::Dense, None);
        let dense_error = element_errors(
            &Field::new(&dense.mesh, &dense.solution.b),
            &reference,
            &cube,
        );
        println!(
            "dense: {dense_s:.2} s, rms {:.5}, max {:.5}",
            dense_error.rms, dense_error.max
        );
        let mut previous = f64::INFINITY;
        for t in [1e-3, 1e-4, 5e-5, 3e-5, 2.2e-5] {
            let (h, s) = bake(bake_core::TransportKind::Hierarchical, Some(t));
            let e = element_errors(&Field::new(&h.mesh, &h.solution.b), &reference, &cube);
            println!(
                "hierarchical {t}: {s:.2} s ({:.1}x faster), {} links, rms {:.5} ({:.2}x dense), max {:.5}",
                dense_s / s,
                h.counts.links,
                e.rms,
                e.rms / dense_error.rms,
                e.max
            );
            assert!(e.rms < previous);
            previous = e.rms;
        }
        // Issue 11: the tolerance the README's speed comparison uses is within 1.2× of the
        // dense transport's error against the continuous solution.
        assert!(
            previous <= 1.2 * dense_error.rms,
            "{previous} vs dense {}",
            dense_error.rms
        );
    }

    /// Issue 14: the per-element error estimate (`bake_core::error`) on the cube at
    /// `--subdiv 7` (default options) against the continuous solution (the exact closed-form
    /// solve at 48 × 48 per wall, averaged over each element). Prints the table; asserts that
    /// at least 90% of element-bands are bounded and the median true/estimate is ≥ 0.1.
    #[test]
    #[ignore = "a 13 824-element closed-form reference: a minute in a release build"]
    fn cube_7_error_estimate_bounds_the_true_error() {
        let (bounded, median) = cube_7_error_estimate(48);
        assert!(bounded >= 0.9, "{bounded}");
        assert!(median >= 0.1, "{median}");
    }

    /// The same on the Cornell box: the default options at elements of diagonal/8 against
    /// the accuracy report's converged reference (diagonal/24, contour, 961 rays, dense). A
    /// benchmark: prints the table, asserts nothing (the reference's own error, ~3% RMS at
    /// diagonal/12 against it, is of the size being measured).
    #[test]
    #[ignore = "the Cornell box reference: 30 s and more in a release build"]
    fn cornell_error_estimate_against_the_converged_reference() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/cornell.gltf");
        let cornell = Scene::load("cornell", &path).expect("cornell");
        let size = |d| Subdivision::MaxSize(mesher::max_element_size(&cornell.polygons, d));
        let run = |request: bake_core::Request| {
            let settings =
                bake_core::Settings::resolve(&request, &cornell.polygons).expect("settings");
            bake_core::run(&cornell.source, &settings, &bake_core::Silent).expect("bake")
        };
        let fine = run(bake_core::Request {
            subdivision: Some(size(24.0)),
            ff_estimator: Some(bake_core::EstimatorKind::Contour),
            visibility_samples: Some(961),
            transport: bake_core::TransportKind::Dense,
            refine: Some(false),
            ..bake_core::Request::default()
        });
        let reference = Field::new(&fine.mesh, &fine.solution.b);
        for d in [8.0, 12.0] {
            let bake = run(bake_core::Request {
                subdivision: Some(size(d)),
                refine: Some(false),
                ..bake_core::Request::default()
            });
            let coarse = Field::new(&bake.mesh, &bake.solution.b);
            let means = reference_means(&coarse, &reference, &cornell);
            println!(
                "cornell diagonal/{d} ({} elements) against diagonal/24 ({} elements):\n{}",
                bake.mesh.elements.len(),
                fine.mesh.elements.len(),
                estimate_table(&bake, &means)
            );
        }
    }

    /// The cube at `--subdiv 7` against the closed-form solve at `n × n` per wall averaged over
    /// each element: the bounded fraction and the median true/estimate (and the table, printed).
    fn cube_7_error_estimate(n: u32) -> (f64, f64) {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/cube.gltf");
        let cube = Scene::load("cube", &path).expect("cube");
        let ref_mesh = mesher::mesh(&cube.polygons, Subdivision::Count(n)).expect("mesh");
        let ref_b = closed_form_solution(&cube, &ref_mesh).expect("reference");
        let reference = Field::new(&ref_mesh, &ref_b);
        let request = bake_core::Request {
            subdivision: Some(Subdivision::Count(7)),
            refine: Some(false),
            ..bake_core::Request::default()
        };
        let settings = bake_core::Settings::resolve(&request, &cube.polygons).expect("settings");
        let bake = bake_core::run(&cube.source, &settings, &bake_core::Silent).expect("bake");
        let coarse = Field::new(&bake.mesh, &bake.solution.b);
        let means = reference_means(&coarse, &reference, &cube);
        let table = estimate_table(&bake, &means);
        println!(
            "cube --subdiv 7 ({} elements) against {n} x {n}:\n{table}",
            bake.mesh.elements.len()
        );
        bounded_and_median(&bake, &means, |p| p.total())
    }

    #[test]
    fn bilinear_weights_reproduce_the_point_and_flag_outside() {
        let c = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.5, 1.0, 0.0),
            DVec3::new(0.0, 1.5, 0.0),
        ];
        for p in [DVec3::new(1.0, 0.5, 0.0), DVec3::new(0.1, 1.2, 0.0)] {
            let (w, outside) = weights(&c, DVec3::Z, p);
            let back: DVec3 = c.iter().zip(w).map(|(x, w)| *x * w).sum();
            assert!(back.distance(p) < 1e-12, "{back} vs {p}");
            assert!(outside <= 0.0);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        let (_, outside) = weights(&c, DVec3::Z, DVec3::new(3.0, 0.5, 0.0));
        assert!(outside > 0.1);
        let tri = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let (w, outside) = weights(&tri, DVec3::Z, DVec3::new(0.25, 0.25, 0.0));
        assert!((w[0] - 0.5).abs() < 1e-15 && (w[1] - 0.25).abs() < 1e-15 && outside <= 0.0);
    }

    #[test]
    fn errors_are_relative_and_area_weighted() {
        let e = scanline_errors(&[[1.1, 2.0, 3.0], [1.0, 2.0, 3.3]], &[[1.0, 2.0, 3.0]; 2]);
        assert!((e.max - 0.1).abs() < 1e-12);
        assert!((e.rms - (0.02f64 / 6.0).sqrt()).abs() < 1e-12);
    }

    /// Fraction of element-bands with |b − reference| ≤ estimate, and the median of
    /// |b − reference| / estimate over those with an estimate > 0.
    fn bounded_and_median(
        bake: &bake_core::Bake,
        means: &[Option<[f64; 3]>],
        estimate: impl Fn(&bake_core::error::Parts) -> [f64; 3],
    ) -> (f64, f64) {
        let (mut bounded, mut total, mut ratios) = (0usize, 0usize, Vec::new());
        for (i, parts) in bake.error.iter().enumerate() {
            let Some(r) = means[i] else { continue };
            let est = estimate(parts);
            for c in 0..3 {
                let truth = (bake.solution.b[i][c] - r[c]).abs();
                total += 1;
                if truth <= est[c] {
                    bounded += 1;
                }
                if est[c] > 0.0 {
                    ratios.push(truth / est[c]);
                }
            }
        }
        ratios.sort_by(f64::total_cmp);
        let median = ratios.get(ratios.len() / 2).copied().unwrap_or(0.0);
        (bounded as f64 / total.max(1) as f64, median)
    }

    /// The estimate and each of its parts alone: bounded fraction, median and 10th/90th
    /// percentiles of true/estimate, and the largest true error and estimate.
    fn estimate_table(bake: &bake_core::Bake, means: &[Option<[f64; 3]>]) -> String {
        type Pick = fn(&bake_core::error::Parts) -> [f64; 3];
        let rows: [(&str, Pick); 5] = [
            ("total", |p| p.total()),
            ("discretisation", |p| p.discretisation),
            ("form factors", |p| p.form_factors),
            ("visibility", |p| p.visibility),
            ("solver", |p| p.solver),
        ];
        let mut out = String::from(
            "| estimate | bounded | median true/est | p10 | p90 | max true | max est |\n|---|---|---|---|---|---|---|\n",
        );
        for (name, pick) in rows {
            let (mut ratios, mut max_true, mut max_est) = (Vec::new(), 0.0f64, 0.0f64);
            for (i, parts) in bake.error.iter().enumerate() {
                let Some(r) = means[i] else { continue };
                let est = pick(parts);
                for c in 0..3 {
                    let truth = (bake.solution.b[i][c] - r[c]).abs();
                    max_true = max_true.max(truth);
                    max_est = max_est.max(est[c]);
                    if est[c] > 0.0 {
                        ratios.push(truth / est[c]);
                    }
                }
            }
            ratios.sort_by(f64::total_cmp);
            let q = |f: f64| {
                ratios
                    .get(((ratios.len() as f64 * f) as usize).min(ratios.len().saturating_sub(1)))
                    .copied()
                    .unwrap_or(f64::NAN)
            };
            let (bounded, median) = bounded_and_median(bake, means, pick);
            out += &format!(
                "| {name} | {:.1}% | {median:.3} | {:.3} | {:.3} | {max_true:.3e} | {max_est:.3e} |\n",
                bounded * 100.0,
                q(0.1),
                q(0.9)
            );
        }
        out
    }
}
