//! `accuracy-report [--quick] [--out DIR] [--doc FILE]`: what accuracy costs in time.
//!
//! Sweeps the knobs of a bake — subdivision, form-factor estimator and tolerance, contour
//! segments and quadrature order, shadow rays, direct solve vs K bounces, flat vs smoothed
//! display, and the `--quality` presets — over the reference scenes:
//! - the paper's cube, against the exact solution of a 24 × 24-per-wall mesh built from
//!   closed-form rectangle form factors (`bake-reference`), and per row against the exact
//!   solution of its own mesh (the form-factor and solver error alone);
//! - the Cornell box, against a converged solution (finest mesh, contour integral, 961 rays),
//!   whose own convergence is measured the same way.
//!
//! For each setting it measures wall time, peak heap, kernel evaluations and rays, and the
//! max/RMS relative error of element radiosity and of the flat and smoothed radiance along a
//! scanline; it writes `accuracy.csv`, error-versus-time plots with the Pareto front marked,
//! RGB scanline plots of the cube like the paper's Figures 6 and 7, and `docs/accuracy.md`.
//! `--quick` runs a small sweep (seconds; for tests).

mod doc;
mod measure;
mod pareto;
mod peak;
mod plot;
mod presets;
mod refinement;

use anyhow::{bail, Context, Result};
use bake_core::presets::Quality;
use form_factor::{ContourOptions, Estimator, TriangleRule};
use measure::{Errors, Field, Run, Scanline, Scene, Setting, Solve};
use mesher::Subdivision;
use std::path::{Path, PathBuf};

#[global_allocator]
static ALLOCATOR: peak::Counting = peak::Counting;

/// One measured row of the report.
pub struct Row {
    pub scene: &'static str,
    pub setting: Setting,
    pub elements: usize,
    pub time_s: f64,
    pub ff_s: f64,
    pub solve_s: f64,
    pub peak_mb: f64,
    pub evaluations: u64,
    pub rays: u64,
    pub by_method: [u64; 3],
    pub element: Errors,
    pub same_mesh: Option<Errors>,
    /// Cube: max relative error of each wall's mean radiosity against the Richardson
    /// extrapolation of the exact solutions at the reference size and half of it.
    pub wall_mean: Option<f64>,
    pub scan_flat: Option<Errors>,
    pub scan_smooth: Option<Errors>,
}

struct Options {
    quick: bool,
    /// Also sweep the Cornell box (the slow part: shadow rays).
    cornell: bool,
    /// Elements per wall of the cube's exact reference.
    cube_reference: u32,
    out: PathBuf,
    doc: Option<PathBuf>,
    /// Only the refinement on/off sweep (its section of the doc).
    refinement: bool,
    /// Only the presets against the uniform front (their section of the doc).
    presets: bool,
    /// Only the Pareto front of every knob on both transports (its section of the doc).
    pareto: bool,
}

fn main() -> Result<()> {
    run(&parse_args()?)
}

fn run(options: &Options) -> Result<()> {
    std::fs::create_dir_all(&options.out)
        .with_context(|| format!("creating {}", options.out.display()))?;
    let root = workspace_root();
    if options.refinement {
        let rows = refinement::sweep(&root, &options.out, options.quick)?;
        if let Some(path) = &options.doc {
            let old = std::fs::read_to_string(path).unwrap_or_default();
            let text = refinement::splice(&old, &refinement::markdown(&rows));
            std::fs::write(path, text).with_context(|| format!("{}", path.display()))?;
            eprintln!("wrote {}", path.display());
        }
        return Ok(());
    }
    if options.pareto {
        let points = pareto::sweep(&root, &options.out, options.quick)?;
        let section = pareto::markdown(&points, options.quick);
        return write_section(options, pareto::BEGIN, pareto::END, &section);
    }
    if options.presets {
        let rows = presets::sweep(&root, &options.out, options.quick)?;
        let section = presets::markdown(&rows);
        return write_section(options, presets::BEGIN, presets::END, &section);
    }
    let cube = Scene::load("cube", &root.join("fixtures/cube.gltf"))?;
    let mut rows = Vec::new();
    let cube_summary = cube_sweep(&cube, options, &mut rows)?;
    let cornell_summary = if options.quick || !options.cornell {
        None
    } else {
        let cornell = Scene::load("cornell", &root.join("fixtures/cornell.gltf"))?;
        Some(cornell_sweep(&cornell, &mut rows)?)
    };
    let csv = options.out.join("accuracy.csv");
    std::fs::write(&csv, doc::csv(&rows)).with_context(|| format!("{}", csv.display()))?;
    eprintln!("wrote {}", csv.display());
    for scene in ["cube", "cornell"] {
        let points: Vec<plot::Point> = rows
            .iter()
            .filter(|r| r.scene == scene)
            .map(|r| plot::Point {
                label: r.setting.label.clone(),
                group: r.setting.group.clone(),
                time_s: r.time_s,
                error: r.element.rms,
            })
            .collect();
        if points.is_empty() {
            continue;
        }
        let path = options.out.join(format!("{scene}-pareto.png"));
        plot::error_vs_time(
            &path,
            &format!("{scene}: RMS relative error of element radiosity vs bake time"),
            "time (s, 2 cores)",
            "RMS relative error",
            &points,
        )?;
        eprintln!("wrote {}", path.display());
    }
    let curves = &cube_summary.curves;
    plot::scanline(
        &options.out.join("cube-scanline-shading.png"),
        "cube, scanline y = 0.43: flat vs smoothed (paper Figs. 6, 8)",
        "position along the scanline (red wall | back wall | blue wall)",
        &curves.shading,
        &curves.breaks,
        &["back wall", "blue wall"],
    )?;
    plot::scanline(
        &options.out.join("cube-scanline-bounces.png"),
        "cube, scanline y = 0.43: K bounces vs the full solution (paper Fig. 7)",
        "position along the scanline (red wall | back wall | blue wall)",
        &curves.bounces,
        &curves.breaks,
        &["back wall", "blue wall"],
    )?;
    if let Some(path) = &options.doc {
        let text = doc::markdown(&rows, &cube_summary, cornell_summary.as_ref(), &options.out);
        // The refinement section is measured by its own run (`--refinement`): kept.
        let old = std::fs::read_to_string(path).unwrap_or_default();
        let text = match (old.find(refinement::BEGIN), old.find(refinement::END)) {
            (Some(a), Some(b)) if b > a => {
                refinement::splice(&text, &old[a..b + refinement::END.len()])
            }
            _ => text,
        };
        // So are the presets (`--presets`) and Pareto (`--pareto`) sections.
        let mut text = text;
        for (begin, end) in [(presets::BEGIN, presets::END), (pareto::BEGIN, pareto::END)] {
            if let (Some(a), Some(b)) = (old.find(begin), old.find(end)) {
                if b > a {
                    text = refinement::splice_between(&text, begin, end, &old[a..b + end.len()]);
                }
            }
        }
        std::fs::write(path, text).with_context(|| format!("{}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// Prints `section` and puts it between `begin` and `end` in the doc (appended when it has
/// none), when there is a doc.
fn write_section(options: &Options, begin: &str, end: &str, section: &str) -> Result<()> {
    println!("{section}");
    if let Some(path) = &options.doc {
        let old = std::fs::read_to_string(path).unwrap_or_default();
        let text = refinement::splice_between(&old, begin, end, section);
        std::fs::write(path, text).with_context(|| format!("{}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

fn parse_args() -> Result<Options> {
    let root = workspace_root();
    let mut options = Options {
        quick: false,
        cornell: true,
        cube_reference: 48,
        out: root.join("docs/accuracy"),
        doc: Some(root.join("docs/accuracy.md")),
        refinement: false,
        presets: false,
        pareto: false,
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--quick" => options.quick = true,
            "--out" => options.out = args.next().context("--out needs a directory")?.into(),
            "--doc" => options.doc = Some(args.next().context("--doc needs a file")?.into()),
            "--no-doc" => options.doc = None,
            "--cube-only" => options.cornell = false,
            "--refinement" => options.refinement = true,
            "--presets" => options.presets = true,
            "--pareto" => options.pareto = true,
            "--cube-reference" => {
                options.cube_reference = args
                    .next()
                    .and_then(|n| n.parse().ok())
                    .context("--cube-reference needs a number of elements per wall")?
            }
            "-h" | "--help" => {
                println!(
                    "usage: accuracy-report [--quick] [--cube-only] [--refinement] [--presets] \
                     [--pareto] [--cube-reference N] [--out DIR] [--doc FILE | --no-doc]\n\
                     --refinement: only the refinement on/off sweep and its section of the doc\n\
                     --presets: only the presets against the uniform front and their section\n\
                     --pareto: only the Pareto front of every knob on both transports and its \
                     section\n\
                     defaults: --cube-reference 48 --out docs/accuracy --doc docs/accuracy.md \
                     (workspace root)"
                );
                std::process::exit(0);
            }
            other => bail!("unknown argument {other:?} (try --help)"),
        }
    }
    Ok(options)
}

fn workspace_root() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest
        .ancestors()
        .nth(2)
        .unwrap_or(manifest)
        .to_path_buf()
}

fn contour() -> ContourOptions {
    ContourOptions::default()
}

fn setting(group: &str, label: String, subdivision: Subdivision, estimator: Estimator) -> Setting {
    Setting {
        group: group.to_string(),
        label,
        subdivision,
        estimator,
        contour: contour(),
        samples: visibility::DEFAULT_SAMPLES,
        solve: Solve::Direct,
        max_error: None,
        refine: None,
        refine_levels: None,
    }
}

fn estimator_label(e: Estimator) -> String {
    match e {
        Estimator::Contour => "contour".into(),
        Estimator::PointPolygon(rule) => format!("point-polygon {}", rule.points()),
        Estimator::PointPoint => "point-point".into(),
        Estimator::Auto { tolerance } => format!("auto {tolerance:.0e}"),
    }
}

/// What the markdown needs beyond the rows.
pub struct CubeSummary {
    pub reference_n: u32,
    pub reference_elements: usize,
    /// Richardson estimate of the reference's own RMS error (from the n/4, n/2, n errors).
    pub reference_convergence: Vec<(u32, Errors)>,
    pub curves: Curves,
}

pub struct Curves {
    pub shading: Vec<plot::Curve>,
    pub bounces: Vec<plot::Curve>,
    pub breaks: Vec<f64>,
}

pub struct CornellSummary {
    pub reference_label: String,
    pub reference_elements: usize,
    pub reference_time_s: f64,
    /// The reference against a finer one: its own convergence.
    pub convergence: Vec<(String, usize, Errors)>,
}

fn cube_sweep(cube: &Scene, options: &Options, rows: &mut Vec<Row>) -> Result<CubeSummary> {
    let quick = options.quick;
    let reference_n = if quick { 8 } else { options.cube_reference };
    eprintln!("cube: exact reference at {reference_n} x {reference_n} per wall ...");
    let ref_mesh = mesher::mesh(&cube.polygons, Subdivision::Count(reference_n))?;
    let ref_b = measure::closed_form_solution(cube, &ref_mesh)?;
    let reference = Field::new(&ref_mesh, &ref_b);
    // Wall means converge like h² (see the presets test): extrapolate from n and n/2.
    let half_mesh = mesher::mesh(&cube.polygons, Subdivision::Count(reference_n / 2))?;
    let half_b = measure::closed_form_solution(cube, &half_mesh)?;
    let extrapolated: Vec<[f64; 3]> = measure::polygon_means(&half_mesh, &half_b)
        .iter()
        .zip(measure::polygon_means(&ref_mesh, &ref_b))
        .map(|(a, b)| [0, 1, 2].map(|k| (4.0 * b[k] - a[k]) / 3.0))
        .collect();
    let scanline = Scanline::cube(cube, 600)?;
    let ref_scan = scanline.sample(&reference, true);

    let subdivs: &[u32] = if quick {
        &[1, 2, 4]
    } else {
        &[1, 2, 3, 4, 6, 8, 12]
    };
    let focus = if quick { 4 } else { 8 };
    let mut settings = Vec::new();
    for &n in subdivs {
        settings.push(setting(
            "subdivision, contour",
            format!("n={n}"),
            Subdivision::Count(n),
            Estimator::Contour,
        ));
    }
    for &n in subdivs.iter().skip(1) {
        settings.push(setting(
            "subdivision, auto 1e-3",
            format!("n={n} auto"),
            Subdivision::Count(n),
            Estimator::Auto { tolerance: 1e-3 },
        ));
    }
    // Estimators at one mesh.
    let mut estimators = vec![
        Estimator::PointPoint,
        Estimator::PointPolygon(TriangleRule::Centroid),
        Estimator::PointPolygon(TriangleRule::Three),
        Estimator::PointPolygon(TriangleRule::Seven),
    ];
    for t in [1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8] {
        estimators.push(Estimator::Auto { tolerance: t });
    }
    for e in estimators {
        settings.push(setting(
            &format!("estimator, n={focus}"),
            estimator_label(e),
            Subdivision::Count(focus),
            e,
        ));
    }
    // Contour quadrature knobs at the same mesh.
    // (segments, order, near ratio): the paper's rule is (1, 3, 0) — Gauss everywhere but on
    // collinear segments; the default is (1, 3, 8) with the order raised automatically.
    for (segments, order, near) in [
        (1, 1, 0.0),
        (1, 2, 0.0),
        (1, 3, 0.0),
        (2, 3, 0.0),
        (4, 3, 0.0),
        (1, 3, 2.0),
        (1, 3, 4.0),
    ] {
        let mut s = setting(
            &format!("contour quadrature, n={focus}"),
            format!("contour s={segments} o={order} near={near}"),
            Subdivision::Count(focus),
            Estimator::Contour,
        );
        s.contour = ContourOptions {
            segments,
            order,
            auto_order: false,
            near_ratio: near,
        };
        settings.push(s);
    }
    // Bounces.
    for k in [0, 1, 2, 4, 8, 16] {
        let mut s = setting(
            &format!("bounces, n={focus}"),
            format!("K={k}"),
            Subdivision::Count(focus),
            Estimator::Contour,
        );
        s.solve = Solve::Bounces(k);
        settings.push(s);
    }
    // Presets.
    for q in Quality::ALL {
        let p = q.preset();
        let mut s = setting(
            "preset",
            format!("--quality {}", q.name()),
            Subdivision::MaxSize(p.max_element_size(&cube.polygons)),
            p.estimator,
        );
        s.samples = p.visibility_samples;
        s.max_error = Some(p.max_error);
        settings.push(s);
    }

    let mut curves = Curves {
        shading: vec![plot::Curve {
            label: format!("reference ({reference_n}x{reference_n}, smoothed)"),
            x: scanline.positions(),
            rgb: ref_scan.clone(),
        }],
        bounces: Vec::new(),
        breaks: scanline.breaks.clone(),
    };
    let mut exact_cache: Vec<(usize, Vec<[f64; 3]>)> = Vec::new();
    let mut full_solution: Option<Vec<[f64; 3]>> = None;
    let mut bounce_curves = Vec::new();
    for s in settings {
        eprintln!("cube: {} / {}", s.group, s.label);
        let run = measure::bake(cube, &s)?;
        let field = Field::new(&run.mesh, &run.b);
        let element = measure::element_errors(&field, &reference, cube);
        let n = run.mesh.elements.len();
        let exact = match exact_cache.iter().find(|(m, _)| *m == n) {
            Some((_, b)) => b.clone(),
            None => {
                let b = measure::closed_form_solution(cube, &run.mesh)?;
                exact_cache.push((n, b.clone()));
                b
            }
        };
        let same = measure::same_mesh_errors(&run.mesh, &run.b, &exact);
        let flat = scanline.sample(&field, false);
        let smooth = scanline.sample(&field, true);
        let scan_flat = measure::scanline_errors(&flat, &ref_scan);
        let scan_smooth = measure::scanline_errors(&smooth, &ref_scan);
        if s.group.starts_with("subdivision, contour") && s.subdivision == Subdivision::Count(focus)
        {
            curves.shading.push(plot::Curve {
                label: format!("{focus}x{focus} flat"),
                x: scanline.positions(),
                rgb: flat.clone(),
            });
            curves.shading.push(plot::Curve {
                label: format!("{focus}x{focus} smoothed"),
                x: scanline.positions(),
                rgb: smooth.clone(),
            });
            full_solution = Some(smooth.clone());
        }
        if let Solve::Bounces(k) = s.solve {
            if k <= 8 {
                bounce_curves.push(plot::Curve {
                    label: format!("{k} bounces"),
                    x: scanline.positions(),
                    rgb: smooth.clone(),
                });
            }
        }
        let mut r = row(
            cube.name,
            s,
            &run,
            element,
            Some(same),
            Some(scan_flat),
            Some(scan_smooth),
        );
        r.wall_mean = Some(measure::max_relative(
            &measure::polygon_means(&run.mesh, &run.b),
            &extrapolated,
        ));
        rows.push(r);
    }
    if let Some(full) = full_solution {
        curves.bounces.push(plot::Curve {
            label: format!("full solution ({focus}x{focus}, smoothed)"),
            x: scanline.positions(),
            rgb: full,
        });
    }
    curves.bounces.extend(bounce_curves);

    // The reference's own convergence: exact solutions at n/4 and n/2 (solved above for the
    // extrapolation) against it.
    let quarter_mesh = mesher::mesh(&cube.polygons, Subdivision::Count(reference_n / 4))?;
    let quarter_b = measure::closed_form_solution(cube, &quarter_mesh)?;
    let reference_convergence = vec![
        (
            reference_n / 4,
            measure::element_errors(&Field::new(&quarter_mesh, &quarter_b), &reference, cube),
        ),
        (
            reference_n / 2,
            measure::element_errors(&Field::new(&half_mesh, &half_b), &reference, cube),
        ),
    ];
    Ok(CubeSummary {
        reference_n,
        reference_elements: ref_mesh.elements.len(),
        reference_convergence,
        curves,
    })
}

fn row(
    scene: &'static str,
    setting: Setting,
    run: &Run,
    element: Errors,
    same_mesh: Option<Errors>,
    scan_flat: Option<Errors>,
    scan_smooth: Option<Errors>,
) -> Row {
    let c = run.counts;
    Row {
        scene,
        setting,
        elements: run.mesh.elements.len(),
        time_s: run.time_s,
        ff_s: run.ff_s,
        solve_s: run.solve_s,
        peak_mb: run.peak_bytes as f64 / 1e6,
        evaluations: c.kernel_evaluations,
        rays: c.rays_cast,
        by_method: [c.pairs_contour, c.pairs_point_polygon, c.pairs_point_point],
        element,
        same_mesh,
        wall_mean: None,
        scan_flat,
        scan_smooth,
    }
}

fn cornell_sweep(cornell: &Scene, rows: &mut Vec<Row>) -> Result<CornellSummary> {
    let size = |per_diagonal| {
        Subdivision::MaxSize(mesher::max_element_size(&cornell.polygons, per_diagonal))
    };
    let reference_setting = |per_diagonal: f64| {
        let mut s = setting(
            "reference",
            format!("diagonal/{per_diagonal}, contour, 961 rays"),
            size(per_diagonal),
            Estimator::Contour,
        );
        s.samples = 961;
        s
    };
    eprintln!("cornell: reference ...");
    let fine = reference_setting(24.0);
    let reference_run = measure::bake_once(cornell, &fine)?;
    let reference = Field::new(&reference_run.mesh, &reference_run.b);
    let reference_means = measure::polygon_means(&reference_run.mesh, &reference_run.b);
    let mut convergence = Vec::new();
    for per_diagonal in [12.0, 16.0] {
        let s = reference_setting(per_diagonal);
        let run = measure::bake_once(cornell, &s)?;
        let e = measure::element_errors(&Field::new(&run.mesh, &run.b), &reference, cornell);
        convergence.push((s.label.clone(), run.mesh.elements.len(), e));
    }

    let mut settings = Vec::new();
    for d in [4.0, 6.0, 8.0, 12.0, 16.0] {
        settings.push(setting(
            "subdivision, auto 1e-3, 289 rays",
            format!("diag/{d}"),
            size(d),
            Estimator::Auto { tolerance: 1e-3 },
        ));
    }
    for samples in [16, 49, 121, 289, 961] {
        let mut s = setting(
            "rays, diag/12",
            format!("{samples} rays"),
            size(12.0),
            Estimator::Auto { tolerance: 1e-3 },
        );
        s.samples = samples;
        settings.push(s);
    }
    for e in [
        Estimator::Contour,
        Estimator::Auto { tolerance: 1e-2 },
        Estimator::Auto { tolerance: 1e-4 },
        Estimator::PointPolygon(TriangleRule::Three),
        Estimator::PointPoint,
    ] {
        settings.push(setting(
            "estimator, diag/12, 289 rays",
            estimator_label(e),
            size(12.0),
            e,
        ));
    }
    for q in [Quality::Draft, Quality::Normal] {
        let p = q.preset();
        let mut s = setting(
            "preset",
            format!("--quality {}", q.name()),
            Subdivision::MaxSize(p.max_element_size(&cornell.polygons)),
            p.estimator,
        );
        s.samples = p.visibility_samples;
        s.max_error = Some(p.max_error);
        settings.push(s);
    }
    for s in settings {
        eprintln!("cornell: {} / {}", s.group, s.label);
        let run = measure::bake(cornell, &s)?;
        let element = measure::element_errors(&Field::new(&run.mesh, &run.b), &reference, cornell);
        let mut r = row(cornell.name, s, &run, element, None, None, None);
        r.wall_mean = Some(measure::max_relative(
            &measure::polygon_means(&run.mesh, &run.b),
            &reference_means,
        ));
        rows.push(r);
    }
    Ok(CornellSummary {
        reference_label: fine.label.clone(),
        reference_elements: reference_run.mesh.elements.len(),
        reference_time_s: reference_run.time_s,
        convergence,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The presets are ordered on the cube: draft does less work (kernel evaluations) and is
    /// less accurate than normal, and normal than high. Accuracy: each wall's mean radiosity
    /// (per band) against the Richardson extrapolation of the exact closed-form solutions at
    /// 12 and 24 elements per wall (their error falls like h²: checked here too).
    #[test]
    fn presets_are_ordered_on_the_cube() {
        let cube = Scene::load("cube", &workspace_root().join("fixtures/cube.gltf")).unwrap();
        let exact_means = |n| {
            let mesh = mesher::mesh(&cube.polygons, Subdivision::Count(n)).unwrap();
            let b = measure::closed_form_solution(&cube, &mesh).unwrap();
            measure::polygon_means(&mesh, &b)
        };
        let (m6, m12, m24) = (exact_means(6), exact_means(12), exact_means(24));
        let extrapolated: Vec<[f64; 3]> = m12
            .iter()
            .zip(&m24)
            .map(|(a, b)| [0, 1, 2].map(|k| (4.0 * b[k] - a[k]) / 3.0))
            .collect();
        // Second order: halving h divides the error by about 4.
        let (e6, e12) = (
            measure::max_relative(&m6, &extrapolated),
            measure::max_relative(&m12, &extrapolated),
        );
        eprintln!("exact 6: {e6:.3e}, exact 12: {e12:.3e}");
        assert!(e6 / e12 > 3.0 && e6 / e12 < 5.5, "{e6:e} / {e12:e}");
        let mut last: Option<(u64, f64)> = None;
        for q in Quality::ALL {
            let p = q.preset();
            let mut s = setting(
                "preset",
                q.name().into(),
                Subdivision::MaxSize(p.max_element_size(&cube.polygons)),
                p.estimator,
            );
            s.samples = p.visibility_samples;
            s.max_error = Some(p.max_error);
            let run = measure::bake_once(&cube, &s).unwrap();
            let means = measure::polygon_means(&run.mesh, &run.b);
            let error = measure::max_relative(&means, &extrapolated);
            let work = run.counts.kernel_evaluations;
            eprintln!(
                "{}: {work} evaluations, wall-mean error {error:.3e}",
                q.name()
            );
            if let Some((last_work, last_error)) = last {
                assert!(work > last_work, "{}: {work} vs {last_work}", q.name());
                assert!(
                    error < last_error,
                    "{}: {error:e} vs {last_error:e}",
                    q.name()
                );
            }
            last = Some((work, error));
        }
    }

    /// `--quick` writes the CSV (one row per setting, finite numbers), both plots and the
    /// document.
    #[test]
    fn quick_report_writes_every_file() {
        let dir = tempfile::tempdir().unwrap();
        let options = Options {
            quick: true,
            cornell: false,
            cube_reference: 8,
            out: dir.path().join("img"),
            doc: Some(dir.path().join("accuracy.md")),
            refinement: false,
            presets: false,
            pareto: false,
        };
        run(&options).unwrap();
        let csv = std::fs::read_to_string(options.out.join("accuracy.csv")).unwrap();
        let lines: Vec<&str> = csv.lines().collect();
        assert!(lines.len() > 30, "{} rows", lines.len());
        for line in &lines[1..] {
            assert!(!line.contains("NaN") && !line.contains("inf"), "{line}");
        }
        for png in [
            "cube-pareto.png",
            "cube-scanline-shading.png",
            "cube-scanline-bounces.png",
        ] {
            let image = image::open(options.out.join(png)).unwrap();
            assert!(image.width() >= 1000, "{png}");
        }
        let doc = std::fs::read_to_string(dir.path().join("accuracy.md")).unwrap();
        assert!(doc.contains("img/cube-pareto.png") && doc.contains("★"));
    }
}
