//! The CSV and `docs/accuracy.md`, written from the measured rows.

use crate::measure::{Errors, Solve};
use crate::{plot, CornellSummary, CubeSummary, Row};
use form_factor::Estimator;
use mesher::Subdivision;
use std::fmt::Write;
use std::path::Path;

pub fn csv(rows: &[Row]) -> String {
    let mut out = String::from(
        "scene,group,label,elements,subdivision,estimator,tolerance,segments,order,auto_order,\
         samples,solve,time_s,ff_s,solve_s,peak_mb,kernel_evaluations,rays,pairs_contour,\
         pairs_point_polygon,pairs_point_point,element_max,element_rms,same_mesh_max,\
         same_mesh_rms,wall_mean_max,scan_flat_max,scan_flat_rms,scan_smooth_max,scan_smooth_rms\n",
    );
    let opt = |e: Option<Errors>| match e {
        Some(e) => (format!("{:.6e}", e.max), format!("{:.6e}", e.rms)),
        None => (String::new(), String::new()),
    };
    for r in rows {
        let s = &r.setting;
        let subdivision = match s.subdivision {
            Subdivision::Count(n) => format!("count {n}"),
            Subdivision::MaxSize(l) => format!("max size {l:.6}"),
        };
        let (estimator, tolerance) = match s.estimator {
            Estimator::Contour => ("contour".to_string(), String::new()),
            Estimator::PointPolygon(rule) => {
                (format!("point-polygon-{}", rule.points()), String::new())
            }
            Estimator::PointPoint => ("point-point".to_string(), String::new()),
            Estimator::Auto { tolerance } => ("auto".to_string(), format!("{tolerance:e}")),
        };
        let solve = match s.solve {
            Solve::Direct => "direct".to_string(),
            Solve::Bounces(k) => format!("bounces {k}"),
        };
        let (sm_max, sm_rms) = opt(r.same_mesh);
        let wall = r.wall_mean.map_or(String::new(), |w| format!("{w:.6e}"));
        let (sf_max, sf_rms) = opt(r.scan_flat);
        let (ss_max, ss_rms) = opt(r.scan_smooth);
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{},{},{},{:.6},{:.6},{:.6},{:.3},{},{},{},{},{},{:.6e},{:.6e},{},{},{},{},{},{},{}",
            r.scene,
            quote(&s.group),
            quote(&s.label),
            r.elements,
            subdivision,
            estimator,
            tolerance,
            s.contour.segments,
            s.contour.order,
            s.contour.auto_order,
            s.samples,
            solve,
            r.time_s,
            r.ff_s,
            r.solve_s,
            r.peak_mb,
            r.evaluations,
            r.rays,
            r.by_method[0],
            r.by_method[1],
            r.by_method[2],
            r.element.max,
            r.element.rms,
            sm_max,
            sm_rms,
            wall,
            sf_max,
            sf_rms,
            ss_max,
            ss_rms,
        );
    }
    out
}

/// A CSV text field: quoted, quotes doubled (RFC 4180).
fn quote(text: &str) -> String {
    format!("\"{}\"", text.replace('"', "\"\""))
}

fn pct(x: f64) -> String {
    if x >= 0.01 {
        format!("{:.1}%", 100.0 * x)
    } else {
        format!("{x:.1e}")
    }
}

fn seconds(t: f64) -> String {
    if t >= 1.0 {
        format!("{t:.2} s")
    } else {
        format!("{:.1} ms", 1e3 * t)
    }
}

/// The rows of one scene, Pareto-optimal ones (RMS element error vs time) marked.
fn table(rows: &[&Row], with_cube_columns: bool) -> String {
    let points: Vec<plot::Point> = rows
        .iter()
        .map(|r| plot::Point {
            label: r.setting.label.clone(),
            group: r.setting.group.clone(),
            time_s: r.time_s,
            error: r.element.rms,
        })
        .collect();
    let front = plot::pareto_front(&points);
    let mut out = String::new();
    if with_cube_columns {
        out.push_str(
            "| | knob | setting | elements | time | peak heap | kernel evals | element error max / RMS | same-mesh error max | wall-mean error | scanline flat RMS | scanline smoothed RMS |\n\
             |---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
    } else {
        out.push_str(
            "| | knob | setting | elements | time | peak heap | kernel evals | rays | element error max / RMS | wall-mean error |\n\
             |---|---|---|---:|---:|---:|---:|---:|---:|---:|\n",
        );
    }
    for (k, r) in rows.iter().enumerate() {
        let star = if front.contains(&k) { "★" } else { "" };
        let common = format!(
            "| {star} | {} | {} | {} | {} | {:.1} MB | {:.3e} |",
            r.setting.group,
            r.setting.label,
            r.elements,
            seconds(r.time_s),
            r.peak_mb,
            r.evaluations as f64,
        );
        if with_cube_columns {
            let _ = writeln!(
                out,
                "{common} {} / {} | {} | {} | {} | {} |",
                pct(r.element.max),
                pct(r.element.rms),
                r.same_mesh.map_or(String::new(), |e| pct(e.max)),
                r.wall_mean.map_or(String::new(), pct),
                r.scan_flat.map_or(String::new(), |e| pct(e.rms)),
                r.scan_smooth.map_or(String::new(), |e| pct(e.rms)),
            );
        } else {
            let _ = writeln!(
                out,
                "{common} {:.3e} | {} / {} | {} |",
                r.rays as f64,
                pct(r.element.max),
                pct(r.element.rms),
                r.wall_mean.map_or(String::new(), pct),
            );
        }
    }
    out
}

/// For each `auto` tolerance at the focus mesh: the fastest contour setting whose same-mesh
/// error is no larger, and the ratio of their form-factor times.
fn speedups(rows: &[&Row]) -> String {
    let contour: Vec<&&Row> = rows
        .iter()
        .filter(|r| {
            r.setting.estimator == Estimator::Contour
                && (r.setting.group.contains("contour quadrature")
                    || r.setting.group.starts_with("estimator"))
        })
        .collect();
    let mut out = String::from(
        "| auto tolerance | same-mesh error max | form-factor time | cheapest contour setting with no larger error | its time | speed-up |\n|---|---:|---:|---|---:|---:|\n",
    );
    for r in rows.iter().filter(|r| {
        r.setting.group.starts_with("estimator")
            && matches!(r.setting.estimator, Estimator::Auto { .. })
    }) {
        let Some(err) = r.same_mesh.map(|e| e.max) else {
            continue;
        };
        let best = contour
            .iter()
            .filter(|c| c.same_mesh.is_some_and(|e| e.max <= err))
            .min_by(|a, b| a.ff_s.total_cmp(&b.ff_s));
        match best {
            Some(c) => {
                let _ = writeln!(
                    out,
                    "| {} | {} | {} | {} | {} | {:.1}× |",
                    r.setting.label,
                    pct(err),
                    seconds(r.ff_s),
                    c.setting.label,
                    seconds(c.ff_s),
                    c.ff_s / r.ff_s
                );
            }
            None => {
                let _ = writeln!(
                    out,
                    "| {} | {} | {} | none reaches it | | |",
                    r.setting.label,
                    pct(err),
                    seconds(r.ff_s)
                );
            }
        }
    }
    out
}

/// `auto 1e-3` against the exact contour integral on the same meshes (the subdivision sweeps):
/// equal element error, and the ratio of whole-bake times.
fn subdivision_speedups(rows: &[&Row]) -> String {
    let mut out = String::from(
        "| elements | exact contour: time | element RMS | auto 1e-3: time | element RMS | speed-up |\n|---:|---:|---:|---:|---:|---:|\n",
    );
    for exact in rows
        .iter()
        .filter(|r| r.setting.group == "subdivision, contour")
    {
        let Some(auto) = rows.iter().find(|r| {
            r.setting.group == "subdivision, auto 1e-3"
                && r.setting.subdivision == exact.setting.subdivision
        }) else {
            continue;
        };
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.1}× |",
            exact.elements,
            seconds(exact.time_s),
            pct(exact.element.rms),
            seconds(auto.time_s),
            pct(auto.element.rms),
            exact.time_s / auto.time_s
        );
    }
    out
}

pub fn markdown(
    rows: &[Row],
    cube: &CubeSummary,
    cornell: Option<&CornellSummary>,
    images: &Path,
) -> String {
    let rel = images
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "accuracy".into());
    let cube_rows: Vec<&Row> = rows.iter().filter(|r| r.scene == "cube").collect();
    let cornell_rows: Vec<&Row> = rows.iter().filter(|r| r.scene == "cornell").collect();
    let mut md = String::new();
    let _ = write!(
        md,
        "# What accuracy costs\n\n\
         Generated by `cargo run --release -p bake-accuracy-report` (this file, `{rel}/accuracy.csv` and the\n\
         pictures in `{rel}/`; about 1.5 minutes on 2 cores, most of it the Cornell box's reference). Times are wall time on the machine that ran it (the committed\n\
         numbers: 2 cores), for mesh + occlusion setup + form factors + solve, the fastest of up to\n\
         3 runs for settings under 0.2 s. Peak heap is counted by the tool's allocator per setting.\n\
         Errors are relative, per element and colour band: max, and RMS weighted by area; the\n\
         denominator is the reference value but never less than 5% of the scene's mean radiosity in\n\
         that band (elements in full shadow count by their absolute error). *Wall-mean error*: the\n\
         largest relative error of a polygon's area-weighted mean radiosity (the light it sends out).\n\n"
    );
    // Cube.
    let conv: Vec<String> = cube
        .reference_convergence
        .iter()
        .map(|(n, e)| format!("{n}×{n} per wall: RMS {}, max {}", pct(e.rms), pct(e.max)))
        .collect();
    let estimate = match cube.reference_convergence.as_slice() {
        [(_, a), (_, b)] if a.rms > 0.0 && b.rms > 0.0 && a.rms > b.rms => {
            // error(h) ≈ C h^p; e(n/4) − e(n) and e(n/2) − e(n) measured, Richardson-like.
            let p = (a.rms / b.rms).log2();
            let own = b.rms / (2f64.powf(p) - 1.0);
            format!(
                " The errors fall like h^{p:.2}, so the reference itself is within about {} RMS of the continuous solution.",
                pct(own)
            )
        }
        _ => String::new(),
    };
    let _ = write!(
        md,
        "## The paper's cube\n\n\
         Reference: the exact solution of a {n}×{n}-per-wall mesh ({e} elements) whose form factors are\n\
         the closed forms for axis-aligned rectangles (`crates/reference`, no code shared with the\n\
         integrator), solved by GMRES to a residual of 1e-13. Each row's element error compares an\n\
         element with the area average of the reference over it; the *same-mesh* error compares it\n\
         with the exact solution of its own mesh, so it is the form-factor and solver error alone.\n\
         The reference's own convergence: {conv}.{estimate}\n\n\
         ![cube: error vs time]({rel}/cube-pareto.png)\n\n{table}\n\
         ★ = on the Pareto front (no other setting is both faster and more accurate).\n\n\
         ### The automatic estimator against the contour integral at equal error\n\n\
         Against the exact contour integral (the default before estimators), mesh by mesh: the\n\
         element error is the same to the digits shown, the whole bake is faster.\n\n{subdivision}\n\
         Against every contour setting of the sweep, at one mesh: for each tolerance, the cheapest\n\
         contour setting whose same-mesh error (element radiosity against the closed-form solution\n\
         of that mesh) is no larger; times are the form-factor stage only. On the cube's\n\
         axis-aligned walls the contour integral is cheap (perpendicular edges cost nothing), so a\n\
         well-chosen fixed rule is as fast as `auto` — but only `auto` guarantees its error bound on\n\
         every pair, and it needs no tuning per scene.\n\n{speedups}\n\
         ### Flat vs smoothed, and bounces (the paper's Figures 6–8)\n\n\
         ![flat vs smoothed]({rel}/cube-scanline-shading.png)\n\n\
         ![bounces]({rel}/cube-scanline-bounces.png)\n\n",
        n = cube.reference_n,
        e = cube.reference_elements,
        conv = conv.join(", "),
        table = table(&cube_rows, true),
        speedups = speedups(&cube_rows),
        subdivision = subdivision_speedups(&cube_rows),
    );
    if let Some(c) = cornell {
        let conv: Vec<String> = c
            .convergence
            .iter()
            .map(|(label, n, e)| {
                format!(
                    "{label} ({n} elements): RMS {}, max {}",
                    pct(e.rms),
                    pct(e.max)
                )
            })
            .collect();
        let _ = write!(
            md,
            "## The Cornell box\n\n\
             Reference: a converged solution, {label} ({n} elements, {t}). Its own convergence —\n\
             coarser references against it: {conv}. Errors below that level are not resolved. The\n\
             element errors here are dominated by the elements that cross the blocks' contact lines\n\
             and shadow edges: an element has one visibility per pair, so its value is an average\n\
             over a region that is part lit, part dark, and the worst of them is off by up to 100%\n\
             (dark in one mesh, half lit in the other). Wall means converge (37% at diagonal/4, 3% at\n\
             diagonal/16); their largest errors are on the short block's darkest faces, which get\n\
             only 3 × 3 elements at diagonal/8 to /16.\n\n\
             ![Cornell box: error vs time]({rel}/cornell-pareto.png)\n\n{table}\n",
            label = c.reference_label,
            n = c.reference_elements,
            t = seconds(c.reference_time_s),
            conv = conv.join("; "),
            table = table(&cornell_rows, false),
        );
    }
    md.push_str(&presets(rows));
    md.push_str(READING);
    md
}

/// One line per `--quality` preset and scene.
fn presets(rows: &[Row]) -> String {
    let mut out = String::from(
        "\n## The presets\n\n| preset | scene | elements | time | peak heap | element error max / RMS | wall-mean error |\n|---|---|---:|---:|---:|---:|---:|\n",
    );
    for r in rows.iter().filter(|r| r.setting.group == "preset") {
        let _ = writeln!(
            out,
            "| `{}` | {} | {} | {} | {:.1} MB | {} / {} | {} |",
            r.setting.label,
            r.scene,
            r.elements,
            seconds(r.time_s),
            r.peak_mb,
            pct(r.element.max),
            pct(r.element.rms),
            r.wall_mean.map_or(String::new(), pct),
        );
    }
    out.push_str(
        "\n`--quality high` is not run on the Cornell box: its elements would be finer than the\n\
         reference's.\n",
    );
    out
}

/// The reading of the knobs (kept in the generator so the document stays one command's output;
/// the claims are about the tables above and were checked against them when written).
pub const READING: &str = "\n## What each knob buys\n\n\
- **Subdivision** dominates the error of every scene. Element radiosity is constant per element,\n  \
  so on the cube the RMS element error falls like h^1.3–1.5 (3.2% at one element per wall, 0.13%\n  \
  at 12×12) while the bake time grows like n³–n⁴ (pairs ∝ n⁴, LU ∝ n⁶ at large n). It is the\n  \
  first knob to turn, and the presets turn it first.\n\
- **Form-factor estimator.** The exact contour integral is at the rounding level (same-mesh error\n  \
  ~1e-13); `auto` at 1e-3 leaves a same-mesh error of a few 1e-6 — three orders below the\n  \
  discretisation error of any mesh here — and bakes 2–4× faster than the exact integral on the\n  \
  same mesh (50 elements and more). Point-to-point alone is off by tens of percent between neighbouring elements;\n  \
  point-to-polygon with 3 points is within 0.1% and cheap, but neither bounds its error by itself.\n\
- **Contour segments, order and near ratio** only matter when the contour integral is forced onto a\n  \
  fixed rule: the paper's 3-point rule without the semi-analytic near pairs (`--ff-near-ratio 0`)\n  \
  is within ~1e-5 on the cube, a 1-point rule 2%, and more segments converge slowly (s = 4: 1e-9\n  \
  for 2× the exact integral's time).\n\
- **Shadow rays** set the noise of partly hidden pairs. On the Cornell box the element error stops\n  \
  falling at about 121 rays per pair, where the ray noise drops below the discretisation error;\n  \
  16 rays are visibly worse.\n\
- **Bounces** converge geometrically (factor ≈ ρ per bounce): 0, 1, 2, 4, 8 bounces leave 42%,\n  \
  18%, 8%, 1.6%, 0.2% RMS on the cube. The series costs one matrix–vector product per bounce, so\n  \
  it only pays against LU for large meshes and few bounces.\n\
- **Smoothing** halves the scanline error on fine meshes (12×12: 2.1% flat, 0.9% smoothed) and\n  \
  removes the staircase of flat shading; on one element per wall it cannot help. It cannot recover\n  \
  shadows finer than an element.\n\
- **Presets** sit on the measured Pareto fronts: `draft` (diagonal/8, `auto` 1e-2, 49 rays) for\n  \
  previews, `normal` (diagonal/16, 1e-3, 121 rays) where the form factors' error is far below the\n  \
  discretisation error, `high` (diagonal/32, 1e-4, 961 rays) for final bakes. Each halves the\n  \
  element size of the one before and costs 10–20× its time.\n";
