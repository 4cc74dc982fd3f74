//! Wires the stages together, times them, reports progress, and maps failures to exit codes.

use crate::{Cli, Exposure, LightmapUv, ReportElements, Shading, Target, REPORT_ELEMENTS_LIMIT};
use anyhow::{anyhow, Context};
use bake_core::Solve;
use exporter::report::{
    self, AccuracyInfo, Effects, ElementsIncluded, EnergyInfo, ErrorSummary, LightEntry, Report,
    SolverInfo, SolverMethod, TransportInfo,
};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::sync::Mutex;
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

/// Two paths of the bake are one file: a usage error (exit 2), refused before writing.
fn same_file(error: exporter::SameFile) -> Failure {
    Failure {
        code: 2,
        error: anyhow!(error),
    }
}

/// The lightmap bake's files for `cli.target` (`both`: beside OUT; `lightmap`: OUT itself).
fn lightmap_paths(cli: &Cli) -> anyhow::Result<exporter::LightmapPaths> {
    match cli.target {
        Target::Both => exporter::LightmapPaths::beside(&cli.output),
        _ => exporter::LightmapPaths::alone(&cli.output),
    }
    .with_context(|| format!("cannot write {}", cli.output.display()))
}

/// Every file this bake may write, in the order they are renamed into place (OUT last).
fn output_files(cli: &Cli) -> anyhow::Result<Vec<std::path::PathBuf>> {
    let mut files: Vec<std::path::PathBuf> = cli.save_links.iter().cloned().collect();
    files.extend(cli.report.iter().cloned());
    if cli.target != Target::Vertex {
        files.extend(lightmap_paths(cli)?.files()?);
    }
    if cli.target != Target::Lightmap {
        files.extend(
            exporter::gltf_files(&cli.output)
                .with_context(|| format!("cannot write {}", cli.output.display()))?,
        );
    }
    Ok(files)
}

pub fn run(cli: &Cli) -> Result<(), Failure> {
    let started = Instant::now();
    if let Some(threads) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads as usize)
            .build_global()
            .map_err(|e| internal(anyhow!("cannot start {threads} worker threads: {e}")))?;
    }
    if let Exposure::Value(x) = cli.exposure {
        if !(x.is_finite() && x >= 0.0) {
            return Err(bad_input(anyhow!(
                "--exposure must be a finite number ≥ 0 or `auto`, got {x}"
            )));
        }
    }
    if let Some(l) = cli.lightmap_texel {
        if !(l.is_finite() && l > 0.0) {
            return Err(bad_input(anyhow!(
                "--lightmap-texel must be a positive number, got {l}"
            )));
        }
    }
    // Fail before the bake, not after it: every file of the set must be writable where it
    // is named (an existing directory, not itself a directory), and none may be an input.
    let planned = output_files(cli).map_err(internal)?;
    // OUT first (it is renamed last), so a missing directory is named by OUT.
    for path in planned.iter().rev() {
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
        exporter::check_target(path).map_err(|e| internal(anyhow!(e)))?;
    }
    let input = &cli.input;
    let mut inputs = vec![input.clone()];
    inputs.extend(cli.load_links.iter().cloned());
    exporter::check_distinct(&planned, &inputs).map_err(same_file)?;

    // 1. Import.
    let lap = Instant::now();
    let options = importer::Options {
        allow_outside_paths: cli.allow_outside_paths,
    };
    let scene = importer::load_with(input, &options)
        .with_context(|| format!("{}", input.display()))
        .map_err(bad_input)?;
    let mut timings = BTreeMap::new();
    timings.insert("import".to_string(), lap.elapsed().as_secs_f64());
    let mut memory = BTreeMap::new();
    if let Some(mib) = bake_core::peak_rss_mib_now() {
        memory.insert("import".to_string(), mib);
    }
    exporter::check_distinct(&planned, &scene.input_files).map_err(same_file)?;
    // `--lightmap-uv keep` with an unusable TEXCOORD_1 is refused before the bake.
    let authored_uv = if cli.target != Target::Vertex && cli.lightmap_uv != LightmapUv::Generate {
        lightmap::AuthoredUv::from_scene(&scene)
    } else {
        lightmap::AuthoredUv::none(scene.polygons.len())
    };
    if cli.target != Target::Vertex && cli.lightmap_uv == LightmapUv::Keep {
        let options = lightmap::Options {
            texel_size: cli
                .lightmap_texel
                .unwrap_or_else(|| lightmap::default_texel_size(&scene.polygons)),
            max_size: cli.lightmap_max,
            shading: lightmap_shading(cli.shading),
            max_atlases: cli.lightmap_atlases,
        };
        lightmap::plan_uv(
            &scene.polygons,
            &authored_uv,
            lightmap::UvMode::Keep,
            &options,
        )
        .with_context(|| format!("{}", input.display()))
        .map_err(bad_input)?;
    }
    // Warnings as they arise: a bake refused or killed later still showed them.
    let warn = |lines: &[String]| {
        if !cli.quiet {
            for w in lines {
                eprintln!("bake: warning: {w}");
            }
        }
    };
    warn(&scene.warnings);

    // 2.–4. Mesh, visibility, transport, solve: one bake, as every caller runs it.
    let mut request = cli.request();
    // A textured material's vertex-bake COLOR_0 is the irradiance H.
    request.irradiance |= exporter::keeps_textures(&scene);
    let settings = bake_core::Settings::resolve(&request, &scene.polygons)
        .map_err(|e| bad_input(anyhow!(e)))?;
    let bars = Bars::new(cli.quiet);
    let bake = bake_core::run(&scene, &settings, &bars).map_err(|e| {
        let code = if e.is_input() { 1 } else { 3 };
        Failure {
            code,
            error: anyhow!(e).context(format!("{}", input.display())),
        }
    })?;
    for (name, seconds) in &bake.timings {
        timings.insert(name.to_string(), *seconds);
    }
    for (name, mib) in &bake.peak_rss_mib {
        memory.insert(name.to_string(), *mib);
    }
    warn(&bake.warnings);
    let mut warnings = scene.warnings.clone();
    warnings.extend(bake.warnings.iter().cloned());
    let mesh = &bake.mesh;
    let n = mesh.elements.len();
    let mut lap = Instant::now();
    let mut stage = |name: &str, lap: &mut Instant| {
        timings.insert(name.to_string(), lap.elapsed().as_secs_f64());
        if let Some(mib) = bake_core::peak_rss_mib_now() {
            memory.insert(name.to_string(), mib);
        }
        *lap = Instant::now();
    };
    let solution = &bake.solution;

    // 5. Lightmap: irradiance H = F b per element (ρ = 0 elements receive light too).
    let lightmap = if cli.target == Target::Vertex {
        None
    } else {
        let h = bake
            .irradiance
            .as_ref()
            .ok_or_else(|| internal(anyhow!("the bake computed no irradiance for the lightmap")))?;
        let options = lightmap::Options {
            texel_size: cli
                .lightmap_texel
                .unwrap_or_else(|| lightmap::default_texel_size(&scene.polygons)),
            max_size: cli.lightmap_max,
            shading: lightmap_shading(cli.shading),
            max_atlases: cli.lightmap_atlases,
        };
        bake_core::Progress::start(&bars, "lightmap", 0);
        let built = lightmap::build_with(
            &scene.polygons,
            mesh,
            h,
            &options,
            &authored_uv,
            cli.lightmap_uv.mode(),
        );
        bake_core::Progress::finish(&bars);
        let built = built
            .with_context(|| format!("{}: cannot build the lightmap", input.display()))
            .map_err(internal)?;
        warn(&built.warnings);
        warnings.extend(built.warnings.iter().cloned());
        if built.stats.reductions > 0 {
            let line = format!(
                "lightmap texel size raised from {:.6} to {:.6} to fit a {} atlas",
                built.requested_texel_size, built.texel_size, cli.lightmap_max
            );
            warn(std::slice::from_ref(&line));
            warnings.push(line);
        }
        stage("lightmap", &mut lap);
        Some(built)
    };

    // Several atlases add files the check before the bake could not know of: they too must
    // not be an input or another output.
    let mut planned = planned;
    if let Some(built) = lightmap.as_ref().filter(|b| !b.more.is_empty()) {
        let paths = lightmap_paths(cli).map_err(internal)?;
        let with_png = paths
            .files()
            .map_err(|e| internal(anyhow!(e)))?
            .contains(&paths.png);
        for k in 1..=built.more.len() {
            planned.push(paths.atlas_exr(k).map_err(|e| internal(anyhow!(e)))?);
            if with_png {
                planned.push(paths.atlas_png(k).map_err(|e| internal(anyhow!(e)))?);
            }
        }
        let mut all_inputs = inputs.clone();
        all_inputs.extend(scene.input_files.iter().cloned());
        exporter::check_distinct(&planned, &all_inputs).map_err(same_file)?;
    }

    // 6. Export.
    let shading = match cli.shading {
        Shading::Smooth => exporter::Shading::Smooth,
        Shading::Flat => exporter::Shading::Flat,
    };
    let exposure = match cli.exposure {
        Exposure::Value(x) => x,
        Exposure::Auto => {
            let areas: Vec<f64> = mesh.elements.iter().map(|e| e.area).collect();
            exporter::auto_exposure(&areas, &solution.b)
        }
    };
    let errors: Vec<[f64; 3]> = bake.error.iter().map(|p| p.total()).collect();
    let vertex_bake = exporter::Bake {
        scene: &scene,
        mesh,
        radiosity: &solution.b,
        irradiance: bake.irradiance.as_deref(),
        error: Some(&errors),
        shading,
        exposure,
    };
    // Every file of the set is staged (written to a temporary beside it) before any is
    // renamed into place: the report first, then the lightmap, then OUT last.
    exporter::remove_stale_temporaries(&planned);
    bake_core::Progress::start(&bars, "writing", 0);
    let mut vertex_files = exporter::OutputSet::new();
    if cli.target != Target::Lightmap {
        exporter::stage_gltf(&mut vertex_files, &cli.output, &vertex_bake)
            .with_context(|| format!("cannot write {}", cli.output.display()))
            .map_err(internal)?;
    }
    let mut lightmap_files = exporter::OutputSet::new();
    if let Some(built) = &lightmap {
        let paths = lightmap_paths(cli).map_err(internal)?;
        let lightmap_bake = exporter::LightmapBake {
            scene: &scene,
            lightmap: built,
            keep_lights: cli.keep_lights,
        };
        exporter::stage_lightmap_gltf(&mut lightmap_files, &paths, &lightmap_bake)
            .with_context(|| format!("cannot write {}", paths.gltf.display()))
            .map_err(internal)?;
    }
    bake_core::Progress::finish(&bars);
    stage("export", &mut lap);

    let mut set = exporter::OutputSet::new();
    if let (Some(path), Some(saved)) = (&cli.save_links, &bake.saved_links) {
        set.stage_with(path, |w| saved.write(w))
            .with_context(|| format!("cannot write {}", path.display()))
            .map_err(internal)?;
    }
    if let Some(path) = &cli.report {
        let info = SolverInfo {
            method: match bake.solve {
                Solve::Direct => SolverMethod::Direct,
                Solve::Iterative(_) => SolverMethod::Iterative,
                Solve::Bounces(_) => SolverMethod::Bounces,
            },
            bounces: match bake.solve {
                Solve::Bounces(k) => Some(k),
                _ => None,
            },
            residual: solution.residual,
            residual_relative: solution.residual_relative,
            factorizations: solution.factorizations as u32,
            condition: solution.condition,
            iterations: solution.iterations,
        };
        let mut report = Report::new(input, &scene, mesh, &solution.b, info)
            .with_context(|| format!("cannot build the report {}", path.display()))
            .map_err(internal)?;
        report.options = options_json(cli, &bake, &settings, &scene, exposure);
        if let (Some(built), Some(map)) = (&lightmap, report.options.as_object_mut()) {
            map.insert("lightmap_layout".into(), lightmap_layout(built));
        }
        // The summary needs only area and b: drop the list before filling in what only the
        // list shows.
        let (which, warning) = report_elements(cli.report_elements, mesh.elements.len());
        if let Some(line) = warning {
            warn(std::slice::from_ref(&line));
            warnings.push(line);
        }
        report.keep_elements(which);
        for (i, entry) in report.elements.iter_mut().enumerate() {
            // ρ and e as the bake used them (textures averaged over the element).
            entry.rho = bake.rho[i];
            entry.e = bake.emission[i];
            entry.direct = bake.direct[i];
            entry.h = bake.irradiance.as_ref().map(|h| h[i]);
            entry.error = errors.get(i).copied();
        }
        report.lights = light_entries(&scene, &bake);
        let counts = &bake.counts;
        report.counts.pairs_evaluated = counts.pairs_evaluated;
        report.counts.pairs_tested = counts.pairs_tested;
        report.counts.pairs_occludable = counts.pairs_occludable;
        report.counts.rays_cast = counts.rays_cast;
        report.counts.kernel_evaluations = counts.kernel_evaluations;
        report.counts.pairs_contour = counts.pairs_contour;
        report.counts.pairs_point_polygon = counts.pairs_point_polygon;
        report.counts.pairs_point_point = counts.pairs_point_point;
        report.counts.links = counts.links;
        report.counts.nodes = counts.nodes;
        report.counts.refinement_passes = counts.passes;
        report.counts.blocked_links = counts.blocked_links;
        report.counts.polygon_pairs = counts.polygon_pairs;
        report.counts.cluster_pairs_dropped = counts.clusters_dropped;
        report.effects = Effects {
            occlusion: bake.effects.occlusion,
            occlusion_reason: bake.effects.reason.clone(),
        };
        report.transport = TransportInfo {
            kind: bake.transport.kind.name().to_string(),
            reason: bake.transport.reason.clone(),
        };
        let energy = &bake.energy;
        report.energy = Some(EnergyInfo {
            delivered: energy.delivered,
            emitted: energy.emitted,
            absorbed: energy.absorbed,
            escaped: energy.escaped,
            imbalance: energy.imbalance,
            imbalance_relative: energy.imbalance_relative,
        });
        let a = &bake.accuracy;
        report.accuracy = Some(AccuracyInfo {
            max_error: a.max_error,
            rho_max: a.rho_max,
            ff_tolerance: a.chosen_tolerance,
            row_sum_accuracy: a.row_sum_accuracy,
            condition_bound: Some(a.condition_bound).filter(|c| c.is_finite()),
            error_bound: a.error_bound.map(|b| b.filter(|b| b.is_finite())),
            row_sums: a.row_sums.map(|r| exporter::report::RowSumsInfo {
                largest_before: r.largest_before,
                largest_after: r.largest_after,
                scaled: r.scaled,
                seen_twice: r.seen_twice,
            }),
            error: Some(error_summary(mesh, &bake.error)),
        });
        let r = &bake.refinement;
        report.refinement = Some(exporter::report::RefinementInfo {
            enabled: r.enabled,
            passes: r.passes,
            elements_before: r.elements_before,
            elements_after: r.elements_after,
            budget: r.budget,
            split: r.split,
            above_target: r.above_target,
            discontinuity_vertices: r.discontinuity_vertices,
            discontinuity_edges: r.discontinuity_edges,
            stopped: r.stopped.clone(),
        });
        report.warnings = warnings.clone();
        timings.insert("total".to_string(), started.elapsed().as_secs_f64());
        report.timings = timings;
        report.peak_rss_mib = memory;
        report::stage_report(&mut set, path, &report)
            .with_context(|| format!("cannot write {}", path.display()))
            .map_err(internal)?;
    }
    set.append(lightmap_files);
    set.append(vertex_files);
    set.commit()
        .context("cannot write the outputs")
        .map_err(internal)?;

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
        if matches!(bake.solve, Solve::Iterative(_)) {
            let iterations = solution.iterations.iter().max().copied().unwrap_or(0);
            hardness += &format!(", {iterations} iterations");
        }
        if bake.counts.links > 0 {
            hardness += &format!(", {} links", bake.counts.links);
        }
        if bake.counts.rays_cast > 0 {
            hardness += &format!(", {} shadow rays", bake.counts.rays_cast);
        }
        if !scene.lights.is_empty() {
            let rays: u64 = bake.light_stats.iter().map(|s| s.rays_cast).sum();
            hardness += &format!(", {} lights ({rays} light rays)", scene.lights.len());
        }
        match cli.exposure {
            Exposure::Auto => hardness += &format!(", exposure auto = {exposure:.4e}"),
            Exposure::Value(x) if x != 1.0 => hardness += &format!(", exposure {x}"),
            Exposure::Value(_) => {}
        }
        if let Some(built) = &lightmap {
            let own = built.uv_decisions.iter().filter(|d| d.own_region).count();
            let layout = if built.uv_decisions.iter().all(|d| d.kept && !d.own_region) {
                "the input's TEXCOORD_1".to_string()
            } else if own > 0 {
                format!(
                    "{} charts + {own} primitives' own TEXCOORD_1",
                    built.stats.charts
                )
            } else {
                format!("{} charts", built.stats.charts)
            };
            let sizes: Vec<String> = built
                .atlases()
                .iter()
                .map(|a| format!("{}×{}", a.width, a.height))
                .collect();
            let atlases = match sizes.len() {
                1 => String::new(),
                n => format!("{n} atlases "),
            };
            hardness += &format!(
                ", lightmap {atlases}{} (texel {:.6}, {:.1}% occupied, {layout})",
                sizes.join(" + "),
                built.texel_size,
                100.0 * built.stats.occupancy
            );
        }
        eprintln!(
            "bake: {} → {}: {} polygons, {n} elements, {} transport, {} pairs integrated, residual {:.1e}/{:.1e}/{:.1e}{hardness}, {:.2} s",
            input.display(),
            cli.output.display(),
            scene.polygons.len(),
            bake.transport.kind.name(),
            bake.counts.pairs_evaluated,
            r[0],
            r[1],
            r[2],
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Progress bars on a terminal (none with --quiet or when stderr is not a terminal).
struct Bars {
    enabled: bool,
    bar: Mutex<Option<ProgressBar>>,
}

/// A bar still open when the bake stops early (an error return) is cleared, so the error
/// line stands alone.
impl Drop for Bars {
    fn drop(&mut self) {
        bake_core::Progress::finish(self);
    }
}

impl Bars {
    fn new(quiet: bool) -> Bars {
        Bars {
            enabled: !quiet && std::io::stderr().is_terminal(),
            bar: Mutex::new(None),
        }
    }
}

impl bake_core::Progress for Bars {
    fn start(&self, stage: &str, total: u64) {
        if !self.enabled {
            return;
        }
        let bar = if total == 0 {
            // Open-ended (an iterative solve): a count, no bar or time left.
            let bar = ProgressBar::new_spinner();
            if let Ok(style) = ProgressStyle::with_template("{msg:>13} {spinner} {elapsed}") {
                bar.set_style(style);
            }
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
            bar
        } else {
            let bar = ProgressBar::new(total);
            if let Ok(style) =
                ProgressStyle::with_template("{msg:>13} [{bar:40}] {pos}/{len}, {eta} left")
            {
                bar.set_style(style.progress_chars("=> "));
            }
            bar
        };
        bar.set_message(stage.to_string());
        if let Ok(mut slot) = self.bar.lock() {
            *slot = Some(bar);
        }
    }

    fn advance(&self, steps: u64) {
        if let Ok(slot) = self.bar.lock() {
            if let Some(bar) = slot.as_ref() {
                bar.inc(steps);
            }
        }
    }

    fn finish(&self) {
        if let Ok(mut slot) = self.bar.lock() {
            if let Some(bar) = slot.take() {
                bar.finish_and_clear();
            }
        }
    }
}

/// The options as resolved for this bake (defaults filled in), for the report: the bake's
/// settings plus the CLI's output options.
fn options_json(
    cli: &Cli,
    bake: &bake_core::Bake,
    settings: &bake_core::Settings,
    scene: &importer::Scene,
    exposure: f64,
) -> serde_json::Value {
    let mut options = bake.options_json(settings);
    let output = serde_json::json!({
        "shading": match cli.shading { Shading::Smooth => "smooth", Shading::Flat => "flat" },
        "exposure": exposure,
        "exposure_rule": match cli.exposure {
            Exposure::Auto => "auto: the 99th percentile (by area) of the elements' brightest band maps to 0.8",
            Exposure::Value(_) => "given",
        },
        "keep_lights": cli.keep_lights,
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
        "lightmap_uv": match cli.lightmap_uv {
            LightmapUv::Auto => "auto",
            LightmapUv::Keep => "keep",
            LightmapUv::Generate => "generate",
        },
    });
    if let (Some(map), serde_json::Value::Object(extra)) = (options.as_object_mut(), output) {
        map.extend(extra);
    }
    options
}

/// `--shading` for the lightmap's texels (each element's own H with `flat`).
fn lightmap_shading(shading: Shading) -> lightmap::Shading {
    match shading {
        Shading::Smooth => lightmap::Shading::Smooth,
        Shading::Flat => lightmap::Shading::Flat,
    }
}

/// The report's `options.lightmap_layout`: per primitive instance, whether the input's
/// TEXCOORD_1 was kept as the lightmap layout, and if not why.
fn lightmap_layout(built: &lightmap::Lightmap) -> serde_json::Value {
    let entries: Vec<serde_json::Value> = built
        .uv_decisions
        .iter()
        .map(|d| {
            serde_json::json!({
                "node": d.node,
                "mesh": d.mesh,
                "primitive": d.primitive,
                "polygons": d.polygons,
                "uv": if d.kept { "kept" } else { "generated" },
                "reason": d.reason,
                "own_region": d.own_region,
            })
        })
        .collect();
    serde_json::Value::Array(entries)
}

/// The report's `lights`: each light the bake used, where it is, and what it took.
fn light_entries(scene: &importer::Scene, bake: &bake_core::Bake) -> Vec<LightEntry> {
    scene
        .lights
        .iter()
        .enumerate()
        .map(|(l, light)| {
            let stats = bake.light_stats.get(l).copied().unwrap_or_default();
            let (inner, outer) = match light.kind {
                importer::LightKind::Spot { inner, outer } => (Some(inner), Some(outer)),
                _ => (None, None),
            };
            LightEntry {
                kind: light.kind.name().to_string(),
                name: light.name.clone(),
                node: light.node,
                position: light.position.to_array(),
                direction: light.direction.to_array(),
                intensity: light.intensity,
                color: light.color,
                range: light.range,
                inner_cone_angle: inner,
                outer_cone_angle: outer,
                elements_lit: stats.elements_lit,
                elements_shadowed: stats.elements_shadowed,
                rays_cast: stats.rays_cast,
                elements_sampled: stats.elements_sampled,
                elements_clipped: stats.elements_clipped,
                delivered: light
                    .band_intensity()
                    .map(|i| i * stats.flux / std::f64::consts::PI),
            }
        })
        .collect()
}

/// What a report keeps per element: the user's choice, else all up to
/// [`REPORT_ELEMENTS_LIMIT`] elements and the summary above (with a warning).
fn report_elements(
    choice: Option<ReportElements>,
    elements: usize,
) -> (ElementsIncluded, Option<String>) {
    match choice {
        Some(ReportElements::All) => (ElementsIncluded::All, None),
        Some(ReportElements::Summary) => (ElementsIncluded::Summary, None),
        Some(ReportElements::None) => (ElementsIncluded::None, None),
        None if elements > REPORT_ELEMENTS_LIMIT => (
            ElementsIncluded::Summary,
            Some(format!(
                "the report lists no elements, only their summary: {elements} elements, more \
                 than {REPORT_ELEMENTS_LIMIT} (--report-elements all lists them)"
            )),
        ),
        None => (ElementsIncluded::All, None),
    }
}

/// The report's summary of the per-element error estimates `parts` (one per element of
/// `mesh`).
fn error_summary(mesh: &mesher::ElementMesh, parts: &[bake_core::error::Parts]) -> ErrorSummary {
    let mut s = ErrorSummary {
        max: [0.0; 3],
        rms: [0.0; 3],
        max_element: [0; 3],
        max_centroid: [[0.0; 3]; 3],
        max_discretisation: [0.0; 3],
        max_form_factors: [0.0; 3],
        max_visibility: [0.0; 3],
        max_solver: [0.0; 3],
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
        }
    }
    if area > 0.0 {
        s.rms = s.rms.map(|x| (x / area).sqrt());
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_reports_keep_the_summary_unless_asked() {
        assert_eq!(
            report_elements(None, 100_000),
            (ElementsIncluded::All, None)
        );
        let (which, warning) = report_elements(None, 100_001);
        assert_eq!(which, ElementsIncluded::Summary);
        assert!(warning.is_some_and(|w| w.contains("100001 elements")));
        for (choice, which) in [
            (ReportElements::All, ElementsIncluded::All),
            (ReportElements::Summary, ElementsIncluded::Summary),
            (ReportElements::None, ElementsIncluded::None),
        ] {
            assert_eq!(report_elements(Some(choice), 5_000_000), (which, None));
            assert_eq!(report_elements(Some(choice), 1), (which, None));
        }
    }
}
