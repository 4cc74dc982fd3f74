//! Refinement on and off (issue 16), error against time on three scenes:
//! - the paper's cube, element errors against the exact solution of a 24 × 24-per-wall mesh
//!   (closed-form rectangle form factors);
//! - the Cornell box, element errors against a converged solution (diagonal/24, contour
//!   integral, 961 rays);
//! - a 10 × 10 m floor (ρ = 0.5) under a vertical 1000 lux sun and a black 2 × 2 m square 2 m
//!   above it, where every element's value is exact (the sun's lit share is clipped exactly)
//!   and what refinement changes is the displayed field: the smoothed vertex values
//!   interpolated over the output triangles, against the closed form ρE/π lit and 0 in the
//!   shadow at a 200 × 200 grid of points farther than 5 cm from the shadow's edge.
//!
//! Off: the uniform mesh at several element sizes. On: `--refine on` from a few base sizes at a
//! few element budgets (the preset's target, `--max-error` 1e-3 of the mean radiosity).

use crate::measure::{self, Field, Run, Scene, Setting};
use crate::plot;
use anyhow::{Context, Result};
use form_factor::Estimator;
use mesher::{ElementMesh, Subdivision};
use std::fmt::Write;
use std::path::Path;

/// One bake of the refinement sweep.
pub struct RefineRow {
    pub scene: &'static str,
    pub label: String,
    pub refine: bool,
    pub elements: usize,
    pub time_s: f64,
    /// RMS relative error (cube, Cornell: of element radiosity; floor: of the displayed field,
    /// relative to the lit value).
    pub error: f64,
    /// Floor: the share of points within 2% of the lit value.
    pub within: Option<f64>,
}

const RHO: f64 = 0.5;
const SUN: f64 = 1000.0;

fn base(label: String, subdivision: Subdivision, refine: Option<u64>) -> Setting {
    Setting {
        group: if refine.is_some() {
            "refine on".into()
        } else {
            "refine off".into()
        },
        label,
        subdivision,
        estimator: Estimator::Auto { tolerance: 1e-3 },
        contour: form_factor::ContourOptions::default(),
        samples: 121,
        solve: measure::Solve::Direct,
        max_error: Some(1e-3),
        refine,
        refine_levels: None,
    }
}

/// The most splits that keep every refined element at least as large as the reference's
/// elements (`ratio` = base element size / reference element size), so that the reference
/// resolves what it is compared with.
fn levels_within(ratio: f64) -> u8 {
    ratio.log2().floor().clamp(0.0, 8.0) as u8
}

/// The sun-lit floor and its blocker as a glTF (+ .bin) in `dir`.
pub fn write_floor(dir: &Path) -> Result<std::path::PathBuf> {
    let quads: [[[f32; 3]; 4]; 2] = [
        [
            [-5.0, 0.0, -5.0],
            [-5.0, 0.0, 5.0],
            [5.0, 0.0, 5.0],
            [5.0, 0.0, -5.0],
        ],
        [
            [-1.0, 2.0, -1.0],
            [1.0, 2.0, -1.0],
            [1.0, 2.0, 1.0],
            [-1.0, 2.0, 1.0],
        ],
    ];
    let mut bytes = Vec::new();
    for q in &quads {
        for k in [0, 1, 2, 0, 2, 3] {
            for v in q[k] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    std::fs::write(dir.join("sun-floor.bin"), &bytes)?;
    // The light looks along its local −Z: rotate −Z onto −Y (90° about +X).
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},
"extensionsUsed":["KHR_lights_punctual"],
"extensions":{{"KHR_lights_punctual":{{"lights":[{{"type":"directional","intensity":{SUN}}}]}}}},
"scene":0,"scenes":[{{"nodes":[0,1,2]}}],
"nodes":[{{"mesh":0}},{{"mesh":1}},{{"rotation":[-{h},0,0,{h}],"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"material":0}}]}},{{"primitives":[{{"attributes":{{"POSITION":1}},"material":1}}]}}],
"materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[{RHO},{RHO},{RHO},1],"metallicFactor":0}}}},{{"pbrMetallicRoughness":{{"baseColorFactor":[0,0,0,1],"metallicFactor":0}}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":6,"type":"VEC3","min":[-5,0,-5],"max":[5,0,5]}},{{"bufferView":1,"componentType":5126,"count":6,"type":"VEC3","min":[-1,2,-1],"max":[1,2,1]}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":72}},{{"buffer":0,"byteOffset":72,"byteLength":72}}],
"buffers":[{{"byteLength":144,"uri":"sun-floor.bin"}}]}}"#
    );
    let path = dir.join("sun-floor.gltf");
    std::fs::write(&path, gltf)?;
    Ok(path)
}

/// The closed form of the floor's radiosity at (x, 0, z): ρE/π lit, 0 in the blocker's
/// shadow; `None` within 5 cm of the shadow's edge (no mesh shows the step exactly).
pub(crate) fn floor_exact(x: f64, z: f64) -> Option<f64> {
    let (dx, dz) = (x.abs() - 1.0, z.abs() - 1.0);
    let inside = dx < 0.0 && dz < 0.0;
    let edge = if inside {
        -dx.max(dz)
    } else {
        dx.max(0.0).hypot(dz.max(0.0))
    };
    (edge > 0.05).then_some(if inside {
        0.0
    } else {
        RHO * SUN / std::f64::consts::PI
    })
}

/// The displayed field's RMS error relative to the lit value and the share of points within
/// 2%, over the 200 × 200 grid of floor points farther than 5 cm from the shadow's edge.
pub fn displayed_errors(mesh: &ElementMesh, b: &[[f64; 3]]) -> (f64, f64) {
    let lit = RHO * SUN / std::f64::consts::PI;
    let smoothed = mesh.smooth(b);
    let cells = 100usize;
    let cell =
        |x: f64| (((x + 5.0) / 10.0 * cells as f64).floor().max(0.0) as usize).min(cells - 1);
    let mut tris: Vec<[([f64; 2], f64); 3]> = Vec::new();
    let mut buckets = vec![Vec::new(); cells * cells];
    let mut scratch = Vec::new();
    for (i, e) in mesh.elements.iter().enumerate() {
        if e.normal.y < 0.5 || e.centroid.y.abs() > 1e-9 {
            continue;
        }
        mesh.triangles(i, &mut scratch);
        for t in &scratch {
            let tri = t.map(|v| {
                let p = mesh.vertices[v as usize];
                ([p.x, p.z], smoothed[v as usize][0])
            });
            let (x0, x1) = tri.iter().fold((f64::MAX, f64::MIN), |(a, b), (p, _)| {
                (a.min(p[0]), b.max(p[0]))
            });
            let (z0, z1) = tri.iter().fold((f64::MAX, f64::MIN), |(a, b), (p, _)| {
                (a.min(p[1]), b.max(p[1]))
            });
            for j in cell(z0)..=cell(z1) {
                for k in cell(x0)..=cell(x1) {
                    buckets[j * cells + k].push(tris.len());
                }
            }
            tris.push(tri);
        }
    }
    let (mut squares, mut good, mut total) = (0.0, 0usize, 0usize);
    for j in 0..200 {
        for i in 0..200 {
            let (x, z) = (
                -5.0 + (i as f64 + 0.5) * 0.05,
                -5.0 + (j as f64 + 0.5) * 0.05,
            );
            let Some(expected) = floor_exact(x, z) else {
                continue;
            };
            let value = buckets[cell(z) * cells + cell(x)].iter().find_map(|&k| {
                let [(a, va), (b, vb), (c, vc)] = tris[k];
                let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
                let u = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (z - a[1])) / det;
                let v = ((b[0] - a[0]) * (z - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
                let w = 1.0 - u - v;
                (w >= -1e-9 && u >= -1e-9 && v >= -1e-9).then_some(w * va + u * vb + v * vc)
            });
            let error = value.map_or(1.0, |v| (v - expected).abs() / lit);
            total += 1;
            squares += error * error;
            good += usize::from(error <= 0.02);
        }
    }
    (
        (squares / total.max(1) as f64).sqrt(),
        good as f64 / total.max(1) as f64,
    )
}

fn push(
    rows: &mut Vec<RefineRow>,
    scene: &'static str,
    s: &Setting,
    run: &Run,
    error: f64,
    within: Option<f64>,
) {
    eprintln!(
        "refinement {scene}: {} {}: {} elements, {:.2} s, rms {error:.3e}",
        s.group,
        s.label,
        run.mesh.elements.len(),
        run.time_s
    );
    rows.push(RefineRow {
        scene,
        label: s.label.clone(),
        refine: s.refine.is_some(),
        elements: run.mesh.elements.len(),
        time_s: run.time_s,
        error,
        within,
    });
}

/// The sweep; `quick` leaves out the Cornell box and the largest meshes.
pub fn sweep(root: &Path, out: &Path, quick: bool) -> Result<Vec<RefineRow>> {
    let mut rows = Vec::new();
    // Cube: exact reference.
    let cube = Scene::load("cube", &root.join("fixtures/cube.gltf"))?;
    let reference_mesh = mesher::mesh(&cube.polygons, Subdivision::Count(24))?;
    let reference_b = measure::closed_form_solution(&cube, &reference_mesh)?;
    let reference = Field::new(&reference_mesh, &reference_b);
    let mut settings = Vec::new();
    for n in [4, 6, 8, 10, 12] {
        settings.push(base(format!("{n}×{n}"), Subdivision::Count(n), None));
    }
    for (n, budget) in [(4, 300), (4, 600), (6, 600), (6, 1200)] {
        let mut s = base(
            format!("{n}×{n} ≤ {budget}"),
            Subdivision::Count(n),
            Some(budget),
        );
        s.refine_levels = Some(levels_within(24.0 / f64::from(n)));
        settings.push(s);
    }
    for s in &settings {
        let run = measure::bake(&cube, s)?;
        let e = measure::element_errors(&Field::new(&run.mesh, &run.b), &reference, &cube);
        push(&mut rows, "cube", s, &run, e.rms, None);
    }
    // Cornell box: converged reference.
    if !quick {
        let cornell = Scene::load("cornell", &root.join("fixtures/cornell.gltf"))?;
        let size = |d: f64| Subdivision::MaxSize(mesher::max_element_size(&cornell.polygons, d));
        let mut fine = base("reference".into(), size(24.0), None);
        fine.estimator = Estimator::Contour;
        fine.samples = 961;
        fine.max_error = None;
        eprintln!("refinement cornell: reference ...");
        let reference_run = measure::bake_once(&cornell, &fine)?;
        let reference = Field::new(&reference_run.mesh, &reference_run.b);
        let mut settings = Vec::new();
        for d in [6.0, 8.0, 12.0, 16.0] {
            settings.push(base(format!("diag/{d}"), size(d), None));
        }
        for (d, budget) in [(6.0, 400), (6.0, 700), (12.0, 900), (12.0, 1300)] {
            let mut s = base(format!("diag/{d} ≤ {budget}"), size(d), Some(budget));
            s.refine_levels = Some(levels_within(24.0 / d));
            settings.push(s);
        }
        for s in &settings {
            let run = measure::bake(&cornell, s)?;
            let e = measure::element_errors(&Field::new(&run.mesh, &run.b), &reference, &cornell);
            push(&mut rows, "cornell", s, &run, e.rms, None);
        }
    }
    // The sun-lit floor: the closed form of the displayed field.
    let path = write_floor(out)?;
    let floor = Scene::load("sun floor", &path)?;
    let size = |d: f64| Subdivision::MaxSize(mesher::max_element_size(&floor.polygons, d));
    let mut settings = Vec::new();
    let uniform: &[f64] = if quick {
        &[16.0, 32.0]
    } else {
        &[16.0, 32.0, 48.0, 64.0, 96.0]
    };
    for &d in uniform {
        settings.push(base(format!("diag/{d}"), size(d), None));
    }
    for (d, budget) in [(8.0, 2000), (16.0, 600), (16.0, 2000)] {
        settings.push(base(format!("diag/{d} ≤ {budget}"), size(d), Some(budget)));
    }
    for s in &settings {
        let run = measure::bake(&floor, s)?;
        let (rms, within) = displayed_errors(&run.mesh, &run.b);
        push(&mut rows, "sun floor", s, &run, rms, Some(within));
    }
    for scene in ["cube", "cornell", "sun floor"] {
        let points: Vec<plot::Point> = rows
            .iter()
            .filter(|r| r.scene == scene)
            .map(|r| plot::Point {
                label: r.label.clone(),
                group: if r.refine { "refine on" } else { "refine off" }.into(),
                time_s: r.time_s,
                error: r.error,
            })
            .collect();
        if points.is_empty() {
            continue;
        }
        let file = out.join(format!("refine-{}.png", scene.replace(' ', "-")));
        plot::error_vs_time(
            &file,
            &format!("{scene}: refinement on vs off"),
            "time (s, 2 cores)",
            if scene == "sun floor" {
                "RMS error of the displayed field / lit value"
            } else {
                "RMS relative error of element radiosity"
            },
            &points,
        )
        .with_context(|| format!("{}", file.display()))?;
        eprintln!("wrote {}", file.display());
    }
    Ok(rows)
}

/// The lowest error each of on and off reaches within `time` seconds (the Pareto front read at
/// that time).
fn best_within(rows: &[&RefineRow], refine: bool, time: f64) -> Option<f64> {
    rows.iter()
        .filter(|r| r.refine == refine && r.time_s <= time)
        .map(|r| r.error)
        .fold(None, |m: Option<f64>, e| Some(m.map_or(e, |m| m.min(e))))
}

/// The markdown section for `docs/accuracy.md`.
pub fn markdown(rows: &[RefineRow]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{BEGIN}\n## Refinement on and off (issue 16)\n");
    let _ = writeln!(
        s,
        "`--refine on` (the default) splits elements whose discretisation estimate exceeds \
         `--max-error` × the mean radiosity, or that a light's shadow edge crosses, and solves \
         again (`bake_core::refine`); `off` is the uniform mesh. Measured by \
         `accuracy-report --refinement` (regenerates this section only). Cube and Cornell box: \
         RMS relative error of element radiosity against the exact 24 × 24-per-wall solution \
         and the converged diagonal/24 solution (contour, 961 rays); sun floor (10 × 10 m, \
         ρ = 0.5, vertical 1000 lux sun, black 2 × 2 m square 2 m above): the displayed field \
         (smoothed vertex values over the output triangles) against ρE/π lit and 0 in shadow, \
         at the 200 × 200 points farther than 5 cm from the shadow's edge, relative to the lit \
         value; \"within 2%\" is the share of those points within 2%. On the cube and the Cornell \
         box refinement stops at the reference's element size (`Settings::refine_levels`: a \
         refined element smaller than the reference's would be compared with the mean of a \
         reference element straddling what it resolves); on the floor it runs to the library's \
         5 levels. Times are wall seconds on 2 shared cores (the fastest of up to 3 runs under \
         0.2 s).\n"
    );
    for scene in ["cube", "cornell", "sun floor"] {
        let here: Vec<&RefineRow> = rows.iter().filter(|r| r.scene == scene).collect();
        if here.is_empty() {
            continue;
        }
        let _ = writeln!(
            s,
            "### {scene}\n\n![{scene}](accuracy/refine-{}.png)\n",
            scene.replace(' ', "-")
        );
        let _ = writeln!(
            s,
            "| refine | mesh | elements | time (s) | RMS error | within 2% |"
        );
        let _ = writeln!(s, "| --- | --- | ---: | ---: | ---: | ---: |");
        for r in &here {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.2} | {:.2e} | {} |",
                if r.refine { "on" } else { "off" },
                r.label,
                r.elements,
                r.time_s,
                r.error,
                r.within.map_or("".into(), |w| format!("{:.2}%", 100.0 * w))
            );
        }
        // Equal time: each refined bake against the best uniform one no slower; equal error:
        // the cheapest uniform bake at least as accurate.
        let _ = writeln!(s);
        let ratio = |off: f64, on: f64| {
            if on < 1e-12 {
                "exact to rounding".to_string()
            } else {
                format!("off/on = {:.1}", off / on)
            }
        };
        for r in here.iter().filter(|r| r.refine) {
            let time = match best_within(&here, false, r.time_s) {
                Some(off) => format!(
                    "{:.2e} vs {:.2e} for the best uniform mesh within that time ({})",
                    r.error,
                    off,
                    ratio(off, r.error)
                ),
                None => format!("{:.2e}; every uniform mesh measured took longer", r.error),
            };
            let equal = here
                .iter()
                .filter(|u| !u.refine && u.error <= r.error)
                .min_by(|a, b| a.time_s.total_cmp(&b.time_s));
            let error = match equal {
                Some(u) => format!(
                    "the uniform mesh reaching that error: {} ({} elements, {:.2} s)",
                    u.label, u.elements, u.time_s
                ),
                None => "no uniform mesh measured reaches that error".to_string(),
            };
            let _ = writeln!(
                s,
                "- {} ({} elements, {:.2} s): {time}; {error}.",
                r.label, r.elements, r.time_s
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "{END}");
    s
}

pub const BEGIN: &str = "<!-- refinement: written by accuracy-report --refinement -->";
pub const END: &str = "<!-- /refinement -->";

/// `doc` with its refinement section replaced by `section` (appended when it has none).
pub fn splice(doc: &str, section: &str) -> String {
    splice_between(doc, BEGIN, END, section)
}

/// `doc` with the part from `begin` to `end` replaced by `section` (appended when it has none).
pub fn splice_between(doc: &str, begin: &str, end: &str, section: &str) -> String {
    match (doc.find(begin), doc.find(end)) {
        (Some(a), Some(b)) if b > a => {
            format!(
                "{}{}{}",
                &doc[..a],
                section.trim_end(),
                &doc[b + end.len()..]
            )
        }
        _ => format!("{}\n\n{}", doc.trim_end(), section),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The section replaces its old self and nothing else, or is appended once.
    #[test]
    fn splicing_replaces_only_the_section() {
        let section = format!("{BEGIN}\nnew\n{END}\n");
        let doc = format!("# A\n\ntext\n\n{BEGIN}\nold\n{END}\n\n## B\n");
        let out = splice(&doc, &section);
        assert_eq!(out, format!("# A\n\ntext\n\n{BEGIN}\nnew\n{END}\n\n## B\n"));
        let appended = splice("# A\n", &section);
        assert_eq!(appended, format!("# A\n\n{section}"));
        assert_eq!(splice(&appended, &section), appended);
    }

    /// The displayed-field error is 0 for the exact field on a grid whose lines lie on the
    /// shadow's edges (flat values, copies at the edges) and not for a blurred one.
    #[test]
    fn displayed_errors_read_the_closed_form() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_floor(dir.path()).unwrap();
        let scene = importer::load(&path).unwrap();
        // 10 × 10 one-metre elements: the shadow's edges at ±1 are grid lines.
        let mesh = mesher::mesh(&scene.polygons, Subdivision::Count(10)).unwrap();
        let lit = RHO * SUN / std::f64::consts::PI;
        let shadowed = |e: &mesher::Element| {
            e.centroid.y == 0.0 && e.centroid.x.abs() < 1.0 && e.centroid.z.abs() < 1.0
        };
        let b: Vec<[f64; 3]> = mesh
            .elements
            .iter()
            .map(|e| {
                if shadowed(e) || e.centroid.y != 0.0 {
                    [0.0; 3]
                } else {
                    [lit; 3]
                }
            })
            .collect();
        let (rms, within) = displayed_errors(&mesh, &b);
        assert!(
            rms > 0.05 && within < 0.99,
            "smoothed across the edge: {rms} {within}"
        );
        let class: Vec<u64> = mesh
            .elements
            .iter()
            .map(|e| u64::from(shadowed(e)))
            .collect();
        let split = mesh.split_at_discontinuities(&class);
        let (rms, within) = displayed_errors(&split, &b);
        assert!(rms < 1e-12 && within == 1.0, "{rms} {within}");
    }
}
