//! One bake from files to files: the library entry the `bake` binary calls.
//!
//! [`run`] takes a [`Job`] (the input, the outputs and every option) and does, in order:
//! check the options and plan the output set (every file writable, none an input), import,
//! run `bake_core`'s one bake (mesh, visibility, transport, solve, refinement), build the
//! lightmap, stage the vertex and lightmap glTF, the links file and the report, and commit the
//! set (renamed into place together, OUT last). Failures carry their exit code ([`Failure`]).
//!
//! What it is not: a command line (the binary parses options into a [`Job`] and shows
//! progress through [`Events`]), and no stage of its own — every computation is in the
//! pipeline crates, which this crate only calls in order. The option enums a command line
//! needs are defined once, in the crates that use them, and re-exported here; the `clap`
//! feature derives `clap::ValueEnum` on all of them.

mod outputs;
pub mod report;
mod summary;

use anyhow::{anyhow, Context};
pub use outputs::check_preview_output;
use outputs::Plan;
use std::path::PathBuf;
use std::time::Instant;

pub use bake_core::presets::Quality;
pub use bake_core::{
    EstimatorKind, Progress, Request, Sky, SkyModel, SolverKind, TransportKind,
    DEFAULT_GROUND_REFLECTANCE, DEFAULT_MAX_REFLECTANCE, DEFAULT_SKY_SAMPLES, MAX_BOUNCES,
    MAX_SKY_SAMPLES,
};
pub use form_factor::ContourOptions;
pub use lightmap::{UvMode, DEFAULT_MAX_ATLASES, DEFAULT_MAX_SIZE};
pub use mesher::{Shading, Subdivision};
/// The software rasterizer behind `bake preview`.
pub use preview;
pub use probes::Probes;
pub use report::ElementsIncluded;

/// Above this many elements a report lists no elements unless `--report-elements all` asks
/// (each costs about 400 bytes of JSON).
pub const REPORT_ELEMENTS_LIMIT: usize = 100_000;

/// Which bakes are written (`--target`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Target {
    /// The vertex bake only, as OUT.
    Vertex,
    /// The lightmap bake only, as OUT.
    Lightmap,
    /// The vertex bake as OUT and the lightmap bake beside it.
    Both,
    /// The baked-texture bake only, as OUT: the lightmap bake's polygons with unlit
    /// materials whose base-colour texture (`TEXCOORD_1`) is ρ × H + e per texel.
    BakedTexture,
}

/// `--exposure`: `auto`, a number (checked to be finite and ≥ 0 before the bake), or
/// `ev100:N`, a camera's exposure value at ISO 100.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exposure {
    Auto,
    Value(f64),
    /// Exposure value N at ISO 100: the luminance `1.2 × 2^N` cd/m² maps to 1 (the
    /// saturation-based sensor model of ISO 12232 with the 78/65 ≈ 1.2 factor; sunny 16 is
    /// N ≈ 15, an overcast day N ≈ 12, an office interior N ≈ 7).
    Ev100(f64),
}

impl Exposure {
    /// The multiplier: a given value, or `1 / (1.2 × 2^N)` for `ev100:N`; `None` for `auto`.
    pub fn factor(&self) -> Option<f64> {
        match *self {
            Exposure::Auto => None,
            Exposure::Value(x) => Some(x),
            Exposure::Ev100(n) => Some(1.0 / (1.2 * n.exp2())),
        }
    }
}

impl std::str::FromStr for Exposure {
    type Err = String;

    fn from_str(text: &str) -> Result<Exposure, String> {
        if text.eq_ignore_ascii_case("auto") {
            return Ok(Exposure::Auto);
        }
        if let Some(n) = text.strip_prefix("ev100:") {
            return match n.trim().parse::<f64>() {
                Ok(n) if n.is_finite() && n.abs() <= 64.0 => Ok(Exposure::Ev100(n)),
                Ok(n) => Err(format!("ev100:N needs N in [−64, 64], got {n}")),
                Err(e) => Err(format!("{e} (expected ev100:N, N a number)")),
            };
        }
        text.parse::<f64>()
            .map(Exposure::Value)
            .map_err(|e| format!("{e} (expected a number, `auto` or `ev100:N`)"))
    }
}

/// The lightmap's options (`--lightmap-*`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightmapOptions {
    /// Texel size in scene units; `None`: from the scene's size.
    pub texel: Option<f64>,
    /// Largest atlas side in texels.
    pub max_size: u32,
    /// Most atlases.
    pub atlases: u32,
    /// Where the charts come from.
    pub uv: UvMode,
}

/// One bake: what to read, what to write, and how.
#[derive(Clone, Debug)]
pub struct Job {
    pub input: PathBuf,
    pub output: PathBuf,
    /// The bake's options as `bake_core` takes them. `irradiance` and `save_links` are set by
    /// [`run`] from the target, the scene's textures and [`Job::save_links`].
    pub request: Request,
    pub target: Target,
    pub shading: Shading,
    pub exposure: Exposure,
    pub lightmap: LightmapOptions,
    /// Keep the input's punctual lights in the lightmap bake.
    pub keep_lights: bool,
    pub report: Option<PathBuf>,
    /// `None`: every element up to [`REPORT_ELEMENTS_LIMIT`], the summary above it.
    pub report_elements: Option<ElementsIncluded>,
    pub save_links: Option<PathBuf>,
    /// Let the input name files outside its own directory.
    pub allow_outside_paths: bool,
    /// Light probes (`--probes`): none, or a grid whose probes are written as the
    /// `BAKE_irradiance_probes` extension of every glTF output (docs/probes.md).
    pub probes: Probes,
}

/// What a bake tells its caller while it runs: progress (bars) and warnings as they arise.
pub trait Events: Progress {
    /// One warning line (without a `warning:` prefix), shown as it arises: a bake refused or
    /// killed later still showed it.
    fn warn(&self, line: &str);
}

/// A failure with the exit code it maps to (1 bad input, 2 an output is an input or another
/// output, 3 internal or output error, [`EXIT_TOO_LARGE`] too large for this machine).
#[derive(Debug)]
pub struct Failure {
    pub code: u8,
    pub error: anyhow::Error,
}

impl Failure {
    /// The error and its causes on one line, `: `-separated. A cause whose text the line already
    /// holds is left out: the crates' messages often embed their source (`cannot read X: {io}`).
    pub fn line(&self) -> String {
        let mut line = String::new();
        for cause in self.error.chain() {
            let text = cause.to_string();
            let text = text.split_whitespace().collect::<Vec<_>>().join(" ");
            if line.contains(&text) {
                continue;
            }
            if !line.is_empty() {
                line.push_str(": ");
            }
            line.push_str(&text);
        }
        line
    }
}

/// The exit code of a bake refused only for the memory this machine has available (a
/// memory estimate or total past `MemAvailable`): a build system may run it on a larger
/// machine. Refusals by fixed limits (the mesher's element limit, the importer's face limit)
/// are bad input (1): they fail the same everywhere.
pub const EXIT_TOO_LARGE: u8 = 4;

pub(crate) fn bad_input(error: anyhow::Error) -> Failure {
    Failure { code: 1, error }
}

/// Bad input (1), or too large for this machine ([`EXIT_TOO_LARGE`]) when `too_large`.
fn input_or_too_large(too_large: bool, error: anyhow::Error) -> Failure {
    Failure {
        code: if too_large { EXIT_TOO_LARGE } else { 1 },
        error,
    }
}

pub(crate) fn internal(error: anyhow::Error) -> Failure {
    Failure { code: 3, error }
}

/// Makes an interrupted bake (SIGINT, i.e. Ctrl-C, or SIGTERM) remove its temporaries
/// before it exits with 128 + the signal (130, 143): the output sets' temporaries are
/// removed (a commit in progress is let finish first, so the set is all previous or all
/// new), targets and the previous set are never touched, and `say` gets one line to show.
/// Without it a killed bake's temporaries stay until the next bake into the same folder
/// removes them ([`exporter::remove_stale_temporaries`]).
#[cfg(unix)]
pub fn exit_cleanly_on_interrupt(say: impl Fn(&str) + Send + 'static) -> std::io::Result<()> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM])?;
    std::thread::Builder::new()
        .name("interrupt".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                let abandoned = exporter::abandon_temporaries();
                let name = if signal == SIGINT {
                    "SIGINT"
                } else {
                    "SIGTERM"
                };
                say(&format!(
                    "interrupted by {name}: {} temporary file(s) removed",
                    abandoned.removed
                ));
                std::process::exit(128 + signal);
            }
        })?;
    Ok(())
}

/// Elsewhere the default handling stays (temporaries are removed by the next bake).
#[cfg(not(unix))]
pub fn exit_cleanly_on_interrupt(_say: impl Fn(&str) + Send + 'static) -> std::io::Result<()> {
    Ok(())
}

/// What a finished bake says of itself: the one-line summary the binary prints.
#[derive(Clone, Debug)]
pub struct Done {
    pub summary: String,
}

/// Runs `job` to the end: every output written, or none (the previous set stays). A bake
/// that fails in the import, the bake or the lightmap still writes its report when `--report`
/// asks ([`report::FailedReport`]: the error, the stage, the exit code, what was measured).
/// A failure while the outputs are written or renamed writes none: the previous set, its
/// report included, stays byte for byte (and the output location is what failed).
pub fn run<E: Events>(job: &Job, events: &E) -> Result<Done, Failure> {
    let started = Instant::now();
    let with_map;
    let job = match load_sky_map(job)? {
        Some(loaded) => {
            with_map = loaded;
            &with_map
        }
        None => job,
    };
    check_options(job)?;
    let plan = Plan::new(job)?;
    recover_interrupted_outputs(&plan.files, events)?;
    let tracked = Tracked {
        events,
        step: std::sync::Mutex::new(None),
    };
    let mut so_far = SoFar {
        stage: "import",
        counts: None,
        stages: report::Stages::default(),
        warnings: Vec::new(),
    };
    let done = bake_and_write(job, plan, &tracked, &mut so_far, started);
    let before_outputs = matches!(so_far.stage, "import" | "bake" | "lightmap");
    if let (Err(failure), Some(path), true) = (&done, &job.report, before_outputs) {
        let stage = match (so_far.stage, tracked.step()) {
            ("bake", Some(step)) => format!("bake: {step}"),
            (stage, _) => stage.to_string(),
        };
        let entry = report::FailureEntry {
            error: failure.line(),
            stage,
            exit_code: failure.code,
        };
        let mut failed = report::FailedReport::new(&job.input, entry);
        failed.counts = so_far.counts;
        (failed.timings, failed.peak_rss_mib) = so_far.stages.into_maps(started);
        failed.warnings = so_far.warnings;
        if let Err(e) = report::write_failed_report(path, &failed) {
            events.warn(&format!("cannot write the failed bake's report: {e}"));
        }
    }
    done
}

/// Before any work: puts back the previous set where a bake killed in its renames (kill -9,
/// power loss) left its outputs half replaced ([`exporter::recover_interrupted_commits`],
/// journals of dead processes beside `files`), with one warning line saying so. Refuses the
/// bake (exit 3, naming each file that could not be put back and where its previous version
/// is) when the rollback fails in part: baking on would remove those previous versions, whose
/// names are stale temporaries' ([`exporter::remove_stale_temporaries`], at the export).
fn recover_interrupted_outputs<E: Events>(files: &[PathBuf], events: &E) -> Result<(), Failure> {
    let recovered = exporter::recover_interrupted_commits(files)
        .map_err(|e| internal(anyhow!(e).context("refusing to bake")))?;
    if recovered.journals > 0 {
        events.warn(&format!(
            "a bake killed while it replaced its outputs had left them half replaced: the \
             previous set is back ({} file(s) restored, {} new file(s) removed)",
            recovered.restored, recovered.removed
        ));
    }
    Ok(())
}

/// What a bake knew when it stopped: the stage it was in, the scene's counts once imported,
/// the stages that finished, the warnings shown.
struct SoFar {
    stage: &'static str,
    counts: Option<bake_core::Counts>,
    stages: report::Stages,
    warnings: Vec<String>,
}

/// The caller's [`Events`], remembering the last step the bake began (for a failed bake's
/// report).
struct Tracked<'a, E: Events> {
    events: &'a E,
    step: std::sync::Mutex<Option<String>>,
}

impl<E: Events> Tracked<'_, E> {
    fn step(&self) -> Option<String> {
        self.step
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }
}

impl<E: Events> Progress for Tracked<'_, E> {
    fn start(&self, stage: &str, total: u64) {
        *self
            .step
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(stage.to_string());
        self.events.start(stage, total);
    }
    fn advance(&self, steps: u64) {
        self.events.advance(steps);
    }
    fn finish(&self) {
        self.events.finish();
    }
}

impl<E: Events> Events for Tracked<'_, E> {
    fn warn(&self, line: &str) {
        self.events.warn(line);
    }
}

/// [`run`] from the import on; `so_far` says how far it got.
fn bake_and_write<E: Events>(
    job: &Job,
    plan: Plan,
    events: &E,
    so_far: &mut SoFar,
    started: Instant,
) -> Result<Done, Failure> {
    // 1. Import.
    let lap = Instant::now();
    let options = importer::Options {
        allow_outside_paths: job.allow_outside_paths,
    };
    let scene = importer::load_with(&job.input, &options).map_err(|e| {
        let too_large = e.is_too_large();
        input_or_too_large(
            too_large,
            anyhow!(e).context(job.input.display().to_string()),
        )
    })?;
    so_far.stages.record("import", lap);
    so_far.counts = Some(bake_core::Counts::default().with_scene(&scene, &Default::default()));
    plan.check_scene_inputs(&scene)?;
    let authored_uv = authored_uv(job, &scene)?;
    let mut warnings = Warnings::new(events, &mut so_far.warnings);
    warnings.extend(&scene.warnings);

    // 2.–4. Mesh, visibility, transport, solve: one bake, as every caller runs it.
    so_far.stage = "bake";
    let mut request = job.request.clone();
    render_clear_sky(&mut request, &scene)?;
    request.irradiance = job.target != Target::Vertex || exporter::keeps_textures(&scene);
    request.save_links = job.save_links.is_some();
    let settings = bake_core::Settings::resolve(&request, &scene.polygons)
        .map_err(|e| bad_input(anyhow!(e)))?;
    let bake = bake_core::run(&scene, &settings, events).map_err(|e| {
        let (input, too_large) = (e.is_input(), e.is_too_large());
        let error = anyhow!(e).context(job.input.display().to_string());
        match input {
            true => input_or_too_large(too_large, error),
            false => internal(error),
        }
    })?;
    so_far.stages.extend(&bake);
    warnings.extend(&bake.warnings);

    // 4b. Light probes from the solved b (`--probes`).
    let lap = Instant::now();
    if job.probes == Probes::Off && !scene.probe_points.is_empty() {
        warnings.push(format!(
            "{} node(s) marked \"bake_probe\" not baked: --probes is off (give --probes auto or grid:S)",
            scene.probe_points.len()
        ));
    }
    let probe_set = bake_probes(job, &scene, &bake, request.sky.as_ref(), events)?;
    if probe_set.is_some() {
        so_far.stages.record("probes", lap);
    }

    // 5. Lightmap: irradiance H = F b per element (ρ = 0 elements receive light too).
    so_far.stage = "lightmap";
    let mut lap = Instant::now();
    let lightmap = match job.target {
        Target::Vertex => None,
        _ => {
            let built = build_lightmap(job, &scene, &bake, &authored_uv, events)?;
            warnings.extend(&built.warnings);
            if built.stats.reductions > 0 {
                warnings.push(format!(
                    "lightmap texel size raised from {:.6} to {:.6} to fit a {} atlas",
                    built.requested_texel_size, built.texel_size, job.lightmap.max_size
                ));
            }
            so_far.stages.record("lightmap", lap);
            lap = Instant::now();
            Some(built)
        }
    };
    let plan = plan.with_atlases(job, lightmap.as_ref(), &scene)?;

    // 6. Export: every file of the set is staged (written to a temporary beside it) before
    // any is renamed into place: the links and the report first, the lightmap, OUT last.
    so_far.stage = "export";
    let exposure = exposure(job, &bake);
    exporter::remove_stale_temporaries(&plan.files);
    events.start("writing", 0);
    let probe_arrays = probe_set.as_ref().map(outputs::ProbeArrays::of);
    let probe_grid = probe_arrays.as_ref().map(|a| a.grid(exposure));
    let staged = outputs::stage_bakes(
        job,
        &scene,
        &bake,
        lightmap.as_ref(),
        exposure,
        probe_grid.as_ref(),
    );
    events.finish();
    let (vertex_files, lightmap_files) = staged?;
    so_far.stages.record("export", lap);

    let mut set = exporter::OutputSet::new();
    if let (Some(path), Some(saved)) = (&job.save_links, &bake.saved_links) {
        set.stage_with(path, |w| saved.write(w))
            .with_context(|| format!("cannot write {}", path.display()))
            .map_err(internal)?;
    }
    if let Some(path) = &job.report {
        so_far.stage = "report";
        let baked = report::Baked {
            job,
            scene: &scene,
            bake: &bake,
            lightmap: lightmap.as_ref(),
            exposure,
            probes: probe_set.as_ref().map(|p| &p.summary),
        };
        let stages = std::mem::take(&mut so_far.stages);
        let report = baked.report(path, &mut warnings, stages, started)?;
        report::stage_report(&mut set, path, &report)
            .with_context(|| format!("cannot write {}", path.display()))
            .map_err(internal)?;
    }
    so_far.stage = "commit";
    set.append(lightmap_files);
    set.append(vertex_files);
    set.commit()
        .context("cannot write the outputs")
        .map_err(internal)?;
    let summary = summary::line(job, &scene, &bake, lightmap.as_ref(), exposure, started);
    Ok(Done { summary })
}

/// `--sky map:FILE`: reads the map before any other work (a missing or unreadable file is
/// refused in one line naming it) and returns the job with it loaded; `None` for any other
/// sky.
fn load_sky_map(job: &Job) -> Result<Option<Job>, Failure> {
    let Some(Sky {
        model: SkyModel::Map { file, map: None },
        ground_reflectance,
    }) = &job.request.sky
    else {
        return Ok(None);
    };
    let image = importer::load_sky_map(file).map_err(|e| bad_input(anyhow!(e)))?;
    let map = bake_core::EnvironmentMap::from_texels(
        &file.display().to_string(),
        image.width,
        image.height,
        image.texels,
    )
    .map_err(|e| bad_input(anyhow!(e)))?;
    let mut loaded = job.clone();
    loaded.request.sky = Some(Sky {
        model: SkyModel::Map {
            file: file.clone(),
            map: Some(std::sync::Arc::new(map)),
        },
        ground_reflectance: *ground_reflectance,
    });
    Ok(Some(loaded))
}

/// `--sky clear:Lz`: renders the clear sky around its sun — `--sun-direction`, else opposite
/// the scene's first directional light — into the map it lights the scene with; refused in
/// one line when there is no sun or it is not above the horizon.
fn render_clear_sky(
    request: &mut bake_core::Request,
    scene: &importer::Scene,
) -> Result<(), Failure> {
    let Some(Sky {
        model:
            SkyModel::Clear {
                zenith,
                sun,
                map: None,
            },
        ground_reflectance,
    }) = &request.sky
    else {
        return Ok(());
    };
    let toward = sun.map(glam::DVec3::from_array).or_else(|| {
        scene
            .lights
            .iter()
            .find(|l| l.kind == scene::LightKind::Directional)
            .map(|l| -l.direction)
    });
    let Some(toward) = toward.and_then(|d| d.try_normalize()).filter(|d| d.y > 0.0) else {
        return Err(bad_input(anyhow!(bake_core::SkyError::NoSun)));
    };
    let map = bake_core::clear_sky_map(*zenith, toward, *ground_reflectance)
        .map_err(|e| internal(anyhow!(e)))?;
    request.sky = Some(Sky {
        model: SkyModel::Clear {
            zenith: *zenith,
            sun: Some(toward.to_array()),
            map: Some(std::sync::Arc::new(map)),
        },
        ground_reflectance: *ground_reflectance,
    });
    Ok(())
}

/// The probes `job.probes` asks for (the grid, then the nodes the input marks), from the
/// bake's b, with a progress step; `None` when off.
fn bake_probes<E: Events>(
    job: &Job,
    scene: &importer::Scene,
    bake: &bake_core::Bake,
    sky: Option<&Sky>,
    events: &E,
) -> Result<Option<probes::ProbeSet>, Failure> {
    if job.probes == Probes::Off {
        return Ok(None);
    }
    events.start("probes", 0);
    let occluders = bake_core::occluders(scene).map_err(|e| internal(anyhow!(e)))?;
    // The sky's radiance L in the probes' unit b / π: it lights a surface to H = E / π.
    let sky_radiance =
        sky.map(|sky| move |d: glam::DVec3| sky.radiance(d).map(|l| l / std::f64::consts::PI));
    let placed = probes::bake(
        job.probes,
        &scene.probe_points,
        &bake.mesh,
        &bake.solution.b,
        &occluders,
        scene::bounds(&scene.polygons),
        sky_radiance.as_ref().map(|f| f as &probes::gather::Sky<'_>),
    );
    events.finish();
    placed.map_err(|e| match e {
        probes::ProbeError::Radiosity(..) => internal(anyhow!(e)),
        _ => bad_input(anyhow!(e)),
    })
}

/// The options no parser checks: refused before any work.
fn check_options(job: &Job) -> Result<(), Failure> {
    if let Exposure::Value(x) = job.exposure {
        if !(x.is_finite() && x >= 0.0) {
            return Err(bad_input(anyhow!(
                "--exposure must be a finite number ≥ 0 or `auto`, got {x}"
            )));
        }
    }
    if let Some(l) = job.lightmap.texel {
        if !(l.is_finite() && l > 0.0) {
            return Err(bad_input(anyhow!(
                "--lightmap-texel must be a positive number, got {l}"
            )));
        }
    }
    Ok(())
}

/// The lightmap options for `scene`.
fn lightmap_options(job: &Job, scene: &importer::Scene) -> lightmap::Options {
    lightmap::Options {
        texel_size: job
            .lightmap
            .texel
            .unwrap_or_else(|| lightmap::default_texel_size(&scene.polygons)),
        max_size: job.lightmap.max_size,
        shading: job.shading,
        max_atlases: job.lightmap.atlases,
    }
}

/// The input's own lightmap UVs, when the lightmap may keep them; `--lightmap-uv keep` with
/// an unusable TEXCOORD_1 is refused here, before the bake.
fn authored_uv(job: &Job, scene: &importer::Scene) -> Result<lightmap::AuthoredUv, Failure> {
    if job.target == Target::Vertex || job.lightmap.uv == UvMode::Generate {
        return Ok(lightmap::AuthoredUv::none(scene.polygons.len()));
    }
    let authored = lightmap::AuthoredUv::from_scene(scene);
    if job.lightmap.uv == UvMode::Keep {
        lightmap::plan_uv(
            &scene.polygons,
            &authored,
            UvMode::Keep,
            &lightmap_options(job, scene),
        )
        .with_context(|| format!("{}", job.input.display()))
        .map_err(bad_input)?;
    }
    Ok(authored)
}

/// The lightmap of the bake's irradiance.
fn build_lightmap<E: Events>(
    job: &Job,
    scene: &importer::Scene,
    bake: &bake_core::Bake,
    authored_uv: &lightmap::AuthoredUv,
    events: &E,
) -> Result<lightmap::Lightmap, Failure> {
    let h = bake
        .irradiance
        .as_ref()
        .ok_or_else(|| internal(anyhow!("the bake computed no irradiance for the lightmap")))?;
    events.start("lightmap", 0);
    let built = lightmap::build_with(
        &scene.polygons,
        &bake.mesh,
        h,
        &lightmap_options(job, scene),
        authored_uv,
        job.lightmap.uv,
    );
    events.finish();
    built.map_err(|e| {
        // Too many charts for the atlas limits is the input's (exit 1, with what to change),
        // not an internal error; more memory would not help (not exit 4).
        let hint = match e {
            lightmap::LightmapError::TooLarge { .. } => {
                " (raise --lightmap-max or --lightmap-atlases, or bake --target vertex)"
            }
            _ => "",
        };
        let input = e.is_input();
        let error = anyhow!(e).context(format!(
            "{}: cannot build the lightmap{hint}",
            job.input.display()
        ));
        match input {
            true => bad_input(error),
            false => internal(error),
        }
    })
}

/// The exposure the vertex bake uses (`auto`: from the elements' radiosities).
fn exposure(job: &Job, bake: &bake_core::Bake) -> f64 {
    job.exposure.factor().unwrap_or_else(|| {
        let areas: Vec<f64> = bake.mesh.elements.iter().map(|e| e.area).collect();
        exporter::auto_exposure(&areas, &bake.solution.b)
    })
}

/// The bake's warnings: shown through [`Events::warn`] as they arise and kept for the report
/// (a failed bake's too).
pub(crate) struct Warnings<'a, E: Events> {
    events: &'a E,
    pub lines: &'a mut Vec<String>,
}

impl<'a, E: Events> Warnings<'a, E> {
    fn new(events: &'a E, lines: &'a mut Vec<String>) -> Self {
        Warnings { events, lines }
    }

    pub fn push(&mut self, line: String) {
        self.events.warn(&line);
        self.lines.push(line);
    }

    fn extend(&mut self, lines: &[String]) {
        for line in lines {
            self.push(line.clone());
        }
    }
}
