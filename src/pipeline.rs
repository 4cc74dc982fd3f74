//! Wires the stages together, times them, reports progress, and maps failures to exit codes.

use crate::{Cli, EstimatorArg, Shading, SolverKind, Target};
use anyhow::{anyhow, Context};
use exporter::report::{self, Effects, EnergyInfo, Report, SolverInfo, SolverMethod};
use form_factor::{ContourOptions, Estimator, FormFactors, Occluders, Occlusion, TriangleRule};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use mesher::Subdivision;
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::time::Instant;

/// A failure with the exit code it maps to (1 bad input, 3 internal or output error).
pub struct Failure {
    pub code: u8,
    pub error: anyhow::Error,
}

fn bad_input(error: anyhow::Error) -> Failure {
    Failure { code: 1, error }
}

fn internal(error: anyhow::Error) -> Failure {
    Failure { code: 3, error }
}

/// The dense path keeps an n×n matrix per distinct reflectance band plus F itself: refuse
/// meshes that could not fit rather than die mid-bake.
const MAX_DENSE_ELEMENTS: usize = 20_000;

pub fn run(cli: &Cli) -> Result<(), Failure> {
    let started = Instant::now();
    if let Some(threads) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads as usize)
            .build_global()
            .map_err(|e| internal(anyhow!("cannot start {threads} worker threads: {e}")))?;
    }
    if !(cli.exposure.is_finite() && cli.exposure >= 0.0) {
        return Err(bad_input(anyhow!(
            "--exposure must be a finite number ≥ 0, got {}",
            cli.exposure
        )));
    }
    if let Some(l) = cli.lightmap_texel {
        if !(l.is_finite() && l > 0.0) {
            return Err(bad_input(anyhow!(
                "--lightmap-texel must be a positive number, got {l}"
            )));
        }
    }
    // Fail before the bake, not after it: a missing report directory would otherwise fail
    // only once OUT has been written.
    for path in std::iter::once(&cli.output).chain(&cli.report) {
        let dir = match path.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir,
            _ => std::path::Path::new("."),
        };
        if !dir.is_dir() {
            return Err(internal(anyhow!(
                "cannot write {}: {} is not an existing directory",
                path.display(),
                dir.display()
            )));
        }
    }
    let mut timings = BTreeMap::new();
    let mut lap = Instant::now();
    let mut stage = |name: &str, lap: &mut Instant| {
        timings.insert(name.to_string(), lap.elapsed().as_secs_f64());
        *lap = Instant::now();
    };
    let input = &cli.input;

    // 1. Import.
    let scene = importer::load(input)
        .with_context(|| format!("{}", input.display()))
        .map_err(bad_input)?;
    stage("import", &mut lap);
    let mut warnings = scene.warnings.clone();

    // 2. Mesh.
    let preset = cli.quality.quality().preset();
    let subdivision = match (cli.subdiv, cli.max_element_size) {
        (Some(n), _) => Subdivision::Count(n),
        (None, Some(l)) => Subdivision::MaxSize(l),
        (None, None) => Subdivision::MaxSize(preset.max_element_size(&scene.polygons)),
    };
    let mesh = mesher::mesh(&scene.polygons, subdivision)
        .with_context(|| format!("{}: cannot subdivide", input.display()))
        .map_err(bad_input)?;
    let n = mesh.elements.len();
    if n > MAX_DENSE_ELEMENTS {
        return Err(bad_input(anyhow!(
            "{}: {n} elements is more than the dense solver's limit of {MAX_DENSE_ELEMENTS}; \
             use a larger --max-element-size or a smaller --subdiv",
            input.display()
        )));
    }
    stage("mesh", &mut lap);

    // 3. Form factors (geometry only: computed once for every band).
    let contour = ContourOptions {
        segments: cli.ff_segments,
        order: cli.ff_order,
        auto_order: !cli.ff_fixed_order,
        near_ratio: cli.ff_near_ratio,
    };
    // Occlusion only where the scene calls for it: polygon pairs a third polygon can come
    // between get shadow rays, all others keep the exact contour value.
    let occluders = Occluders::new(&scene.polygons)
        .with_context(|| format!("{}: cannot build the occlusion structure", input.display()))
        .map_err(bad_input)?;
    let occludable = occluders.occludable_pairs();
    let effects = occludable.effects();
    stage("visibility_setup", &mut lap);
    let estimator = estimator(cli, preset);
    let samples = cli.visibility_samples.unwrap_or(preset.visibility_samples);
    let mut form_factors = FormFactors::new(&mesh, contour).with_estimator(estimator);
    if effects.occlusion {
        form_factors = form_factors.with_occlusion(Occlusion {
            occluders: &occluders,
            pairs: &occludable,
            samples,
        });
    }
    let bar = progress_bar(cli.quiet, n as u64, "form factors");
    let matrix = form_factors.dense_with_progress(&|rows| bar.inc(rows));
    bar.finish_and_clear();
    stage("form_factors", &mut lap);

    // 4. Solve (I − ρF) b = e per band.
    let (rho, e): (Vec<[f64; 3]>, Vec<[f64; 3]>) = mesh
        .elements
        .iter()
        .map(|el| {
            let m = &scene.materials[scene.polygons[el.polygon as usize].material];
            (m.rho, m.emission)
        })
        .unzip();
    if e.iter().all(|x| x.iter().all(|&v| v == 0.0)) {
        warnings.push("the scene has no emitters: every radiosity is 0".to_string());
    }
    let f = solver::DenseMatrix::new(n, &matrix.data)
        .map_err(|err| internal(err.into()))?
        .with_accuracy(estimator.row_sum_accuracy());
    let method = solver_method(cli);
    let solution = match method {
        SolverMethod::Direct => solver::solve_direct(&f, &rho, &e),
        SolverMethod::Iterative => solver::solve_iterative(&f, &rho, &e, &iterative_options(cli)),
        SolverMethod::Bounces => solver::solve_bounces(&f, &rho, &e, cli.bounces.unwrap_or(0)),
    }
    .with_context(|| format!("{}: no solution", input.display()))
    .map_err(bad_input)?;
    stage("solve", &mut lap);

    // 5. Lightmap: irradiance H = F b per element (ρ = 0 elements receive light too).
    let lightmap = if cli.target == Target::Vertex {
        None
    } else {
        let mut h = vec![[0.0; 3]; n];
        solver::Operator::apply_bands(&f, &solution.b, &mut h);
        let options = lightmap::Options {
            texel_size: cli
                .lightmap_texel
                .unwrap_or_else(|| lightmap::default_texel_size(&scene.polygons)),
            max_size: cli.lightmap_max,
        };
        let built = lightmap::build(&scene.polygons, &mesh, &h, &options)
            .with_context(|| format!("{}: cannot build the lightmap", input.display()))
            .map_err(internal)?;
        if built.stats.reductions > 0 {
            warnings.push(format!(
                "lightmap texel size raised from {:.6} to {:.6} to fit a {} atlas",
                built.requested_texel_size, built.texel_size, cli.lightmap_max
            ));
        }
        stage("lightmap", &mut lap);
        Some(built)
    };

    // 6. Export.
    let shading = match cli.shading {
        Shading::Smooth => exporter::Shading::Smooth,
        Shading::Flat => exporter::Shading::Flat,
    };
    let bake = exporter::Bake {
        scene: &scene,
        mesh: &mesh,
        radiosity: &solution.b,
        shading,
        exposure: cli.exposure,
    };
    if cli.target != Target::Lightmap {
        exporter::write_gltf(&cli.output, &bake)
            .with_context(|| format!("cannot write {}", cli.output.display()))
            .map_err(internal)?;
    }
    if let Some(built) = &lightmap {
        let paths = match cli.target {
            Target::Both => exporter::LightmapPaths::beside(&cli.output),
            _ => exporter::LightmapPaths::alone(&cli.output),
        }
        .with_context(|| format!("cannot write {}", cli.output.display()))
        .map_err(internal)?;
        let lightmap_bake = exporter::LightmapBake {
            scene: &scene,
            lightmap: built,
        };
        exporter::write_lightmap_gltf(&paths, &lightmap_bake)
            .with_context(|| format!("cannot write {}", paths.gltf.display()))
            .map_err(internal)?;
    }
    stage("export", &mut lap);

    if !cli.quiet {
        for w in &warnings {
            eprintln!("bake: warning: {w}");
        }
    }

    if let Some(path) = &cli.report {
        let info = SolverInfo {
            method,
            bounces: cli.bounces,
            residual: solution.residual,
            residual_relative: solution.residual_relative,
            factorizations: solution.factorizations as u32,
            condition: solution.condition,
            iterations: solution.iterations,
        };
        // Emitted = absorbed + escaped (conservation of energy), per band.
        let areas: Vec<f64> = mesh.elements.iter().map(|el| el.area).collect();
        let energy = solver::energy_balance(&f, &areas, &rho, &e, &solution.b)
            .map_err(|err| internal(err.into()))?;
        let mut report = Report::new(input, &scene, &mesh, &solution.b, info)
            .with_context(|| format!("cannot build the report {}", path.display()))
            .map_err(internal)?;
        report.options = options_json(cli, subdivision, contour, estimator, samples, &scene);
        report.counts.pairs_evaluated = matrix.stats.pairs_integrated;
        report.counts.pairs_tested = matrix.stats.visibility.pairs_tested;
        report.counts.pairs_occludable = matrix.stats.visibility.pairs_occludable;
        report.counts.rays_cast = matrix.stats.visibility.rays_cast;
        report.counts.kernel_evaluations = matrix.stats.evaluations;
        report.counts.pairs_contour = matrix.stats.pairs_by_method.contour;
        report.counts.pairs_point_polygon = matrix.stats.pairs_by_method.point_polygon;
        report.counts.pairs_point_point = matrix.stats.pairs_by_method.point_point;
        report.effects = Effects {
            occlusion: effects.occlusion,
            occlusion_reason: effects.reason.clone(),
        };
        report.energy = Some(EnergyInfo {
            emitted: energy.emitted,
            absorbed: energy.absorbed,
            escaped: energy.escaped,
            imbalance: energy.imbalance,
            imbalance_relative: energy.imbalance_relative,
        });
        report.warnings = warnings.clone();
        timings.insert("total".to_string(), started.elapsed().as_secs_f64());
        report.timings = timings;
        report::write_report(path, &report)
            .with_context(|| format!("cannot write {}", path.display()))
            .map_err(internal)?;
    }

    if !cli.quiet {
        let r = solution.residual;
        // The hardest band's condition number and, for GMRES, its iteration count.
        let mut hardness = String::new();
        if let Some(cond) = solution
            .condition
            .iter()
            .flatten()
            .copied()
            .reduce(f64::max)
        {
            hardness += &format!(", cond {cond:.1e}");
        }
        if method == SolverMethod::Iterative {
            let iterations = solution.iterations.iter().max().copied().unwrap_or(0);
            hardness += &format!(", {iterations} iterations");
        }
        if matrix.stats.visibility.rays_cast > 0 {
            hardness += &format!(", {} shadow rays", matrix.stats.visibility.rays_cast);
        }
        if let Some(built) = &lightmap {
            hardness += &format!(
                ", lightmap {}×{} (texel {:.6}, {:.1}% occupied)",
                built.width,
                built.height,
                built.texel_size,
                100.0 * built.stats.occupancy
            );
        }
        eprintln!(
            "bake: {} → {}: {} polygons, {n} elements, {} pairs integrated, residual {:.1e}/{:.1e}/{:.1e}{hardness}, {:.2} s",
            input.display(),
            cli.output.display(),
            scene.polygons.len(),
            matrix.stats.pairs_integrated,
            r[0],
            r[1],
            r[2],
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// `--bounces` (which conflicts with `--solver`) or `--solver`.
fn solver_method(cli: &Cli) -> SolverMethod {
    match (cli.bounces, cli.solver) {
        (Some(_), _) => SolverMethod::Bounces,
        (None, SolverKind::Direct) => SolverMethod::Direct,
        (None, SolverKind::Iterative) => SolverMethod::Iterative,
    }
}

/// The iterative solver's settings: `--tolerance` and `--max-iterations` over the defaults.
fn iterative_options(cli: &Cli) -> solver::IterativeOptions {
    let default = solver::IterativeOptions::default();
    solver::IterativeOptions {
        tolerance: cli.tolerance.unwrap_or(default.tolerance),
        max_iterations: cli.max_iterations.unwrap_or(default.max_iterations),
        ..default
    }
}

fn progress_bar(quiet: bool, len: u64, what: &str) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::hidden());
    }
    let bar = ProgressBar::new(len);
    if let Ok(style) =
        ProgressStyle::with_template("{msg:>13} [{bar:40}] {pos}/{len} rows, {eta} left")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_string());
    bar
}

/// The form-factor estimator: explicit options over the preset's.
fn estimator(cli: &Cli, preset: presets::Preset) -> Estimator {
    let preset_tolerance = match preset.estimator {
        Estimator::Auto { tolerance } => tolerance,
        _ => form_factor::MIN_TOLERANCE,
    };
    match (cli.ff_estimator, cli.ff_tolerance) {
        (None, None) => preset.estimator,
        (None | Some(EstimatorArg::Auto), Some(tolerance)) => Estimator::Auto { tolerance },
        (Some(EstimatorArg::Auto), None) => Estimator::Auto {
            tolerance: preset_tolerance,
        },
        (Some(EstimatorArg::Contour), _) => Estimator::Contour,
        (Some(EstimatorArg::PointPoint), _) => Estimator::PointPoint,
        (Some(EstimatorArg::PointPolygon), _) => Estimator::PointPolygon(
            TriangleRule::from_points(cli.ff_points).unwrap_or(TriangleRule::Three),
        ),
    }
}

/// The options as resolved for this bake (defaults filled in), for the report.
fn options_json(
    cli: &Cli,
    subdivision: Subdivision,
    contour: ContourOptions,
    estimator: Estimator,
    samples: u32,
    scene: &importer::Scene,
) -> serde_json::Value {
    let (estimator, ff_tolerance, ff_points) = match estimator {
        Estimator::Contour => ("contour", None, None),
        Estimator::PointPolygon(rule) => ("point-polygon", None, Some(rule.points())),
        Estimator::PointPoint => ("point-point", None, None),
        Estimator::Auto { tolerance } => ("auto", Some(tolerance), None),
    };
    let subdivision = match subdivision {
        Subdivision::Count(n) => serde_json::json!({ "subdiv": n }),
        Subdivision::MaxSize(l) => serde_json::json!({ "max_element_size": l }),
    };
    let iterative = (solver_method(cli) == SolverMethod::Iterative).then(|| iterative_options(cli));
    serde_json::json!({
        "subdivision": subdivision,
        "solver": solver_method(cli),
        "tolerance": iterative.map(|o| o.tolerance),
        "max_iterations": iterative.map(|o| o.max_iterations),
        "bounces": cli.bounces,
        "shading": match cli.shading { Shading::Smooth => "smooth", Shading::Flat => "flat" },
        "exposure": cli.exposure,
        "ff_segments": contour.segments,
        "ff_order": contour.order,
        "ff_auto_order": contour.auto_order,
        "quality": cli.quality.quality().name(),
        "ff_estimator": estimator,
        "ff_tolerance": ff_tolerance,
        "ff_points": ff_points,
        "visibility_samples": samples,
        "ff_near_ratio": contour.near_ratio,
        "output": cli.output.display().to_string(),
        "target": match cli.target {
            Target::Vertex => "vertex",
            Target::Lightmap => "lightmap",
            Target::Both => "both",
        },
        "lightmap_texel": cli
            .lightmap_texel
            .unwrap_or_else(|| lightmap::default_texel_size(&scene.polygons)),
        "lightmap_max": cli.lightmap_max,
    })
}
