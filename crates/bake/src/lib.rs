//! One bake: an imported scene in, the solved radiosity of its element mesh out.
//!
//! This crate owns the wiring of the pipeline (mesher → visibility → form factors / transport
//! → solver) so that the `bake` CLI, `tools/accuracy-report`, the benchmarks and the tests run
//! exactly the same bake: [`Settings::resolve`] turns a [`Request`] (the user's options) and
//! its quality preset into settings once, and [`run`] performs the stages, gathers ρ and e per
//! element, adds the punctual lights' first reflection `ρ E / π` to e (the paper's §2 E(j)),
//! chooses the transport, derives the dense transport's per-pair form-factor tolerance from
//! the target error of `b` ([`accuracy`]), solves, estimates each element's error
//! ([`error`]), and times every stage.
//!
//! It is not the importer or the exporter (the caller reads the scene and writes the outputs)
//! and knows no file formats or command-line syntax. It is the only crate that knows the
//! presets ([`presets`]).

pub mod accuracy;
pub mod advice;
pub mod cost;
pub mod error;
pub mod escape;
mod plan;
pub mod presets;
pub mod refine;
mod settings;
mod transports;

pub use settings::{
    hierarchical_solve_tolerance, EstimatorKind, Request, Settings, Solve, SolverKind,
    TransportKind, DEFAULT_MAX_REFLECTANCE, HIERARCHICAL_SOLVE_LOOSEST, HIERARCHICAL_SOLVE_SHARE,
};

pub use accuracy::Accuracy;
pub use direct::envmap::EnvironmentMap;
pub use direct::sky::{
    clear_sky_map, Sky, SkyError, SkyModel, SkyStats, DEFAULT_GROUND_REFLECTANCE,
    DEFAULT_SKY_SAMPLES, MAX_SKY_SAMPLES,
};
pub use direct::LightStats;
use form_factor::Estimator;
use mesher::ElementMesh;
pub use plan::{Plan, SceneSummary};
use scene::Scene;
use serde::{Deserialize, Serialize};
pub use solver::EnergyBalance;
use solver::{Solution, SolveError, BANDS};
use std::time::Instant;
use transport::{HierarchicalTransport, Transport};
pub use visibility::Effects;
use visibility::Occluders;

/// Why a bake failed. [`BakeError::is_input`] tells bad input (exit 1) from internal errors.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    #[error("{0}")]
    Options(String),
    #[error("cannot subdivide: {0}")]
    Mesh(#[from] mesher::MeshError),
    #[error("cannot build the occlusion structure: {0}")]
    Visibility(#[from] visibility::VisibilityError),
    /// More memory than this machine has available now (`MemAvailable`): the same bake may
    /// run on a larger machine ([`BakeError::is_too_large`]).
    #[error("too large for this machine: {0}")]
    TooLarge(String),
    /// The transport's builder found the mesh inconsistent with its trees (a bug upstream).
    #[error("internal error: {0}")]
    Transport(transport::LinkError),
    #[error("no solution: {0}")]
    Solve(SolveError),
    /// The solver's refusal with what about this scene or these options caused it.
    #[error("no solution: {error}; {hint}")]
    Unsolvable { error: SolveError, hint: String },
    #[error("internal error: {0}")]
    Internal(SolveError),
    #[error("{path}: {source}")]
    LinksFile {
        path: std::path::PathBuf,
        source: transport::LinksFileError,
    },
}

impl BakeError {
    /// Whether the input (scene or options) is at fault rather than the baker.
    pub fn is_input(&self) -> bool {
        !matches!(self, BakeError::Internal(_) | BakeError::Transport(_))
    }

    /// Whether the bake was refused only for the memory this machine has (an estimate or a
    /// link count past `MemAvailable`): it may run on a machine with more (exit code 4).
    pub fn is_too_large(&self) -> bool {
        matches!(self, BakeError::TooLarge(_))
    }
}

/// Progress of the long stages, for a progress bar; called from any thread (defined by the
/// transport, whose builders report through it).
pub use transport::Progress;

/// Reports nothing.
pub struct Silent;

impl Progress for Silent {
    fn start(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
}

/// What the bake did, for the report (its `counts` object, keys in field order) and the
/// summary line: the scene's and the mesh's sizes, the importer's statistics and the
/// transport's work.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counts {
    pub polygons: usize,
    pub elements: usize,
    /// Element pairs (dense) or node pairs (hierarchical) whose form factor was computed.
    pub pairs_evaluated: u64,
    pub degenerate_dropped: usize,
    pub quads_merged: usize,
    pub primitives_skipped: usize,
    pub ngons_split: usize,
    pub faces_read: usize,
    /// Faces dropped as duplicates of an earlier face (absent in older reports: 0).
    #[serde(default)]
    pub duplicates_dropped: usize,
    /// Polygons dropped because a polygon of another primitive or node has the same corners
    /// and facing (absent in older reports: 0).
    #[serde(default)]
    pub coincident_dropped: usize,
    /// Faces wound opposite to their neighbours, kept as authored (absent in older
    /// reports: 0).
    #[serde(default)]
    pub against_winding: usize,
    /// Pairs facing each other whose visibility was decided.
    #[serde(default)]
    pub pairs_tested: u64,
    /// Of those, pairs some polygon may come between (rays were cast).
    #[serde(default)]
    pub pairs_occludable: u64,
    /// Shadow rays cast.
    #[serde(default)]
    pub rays_cast: u64,
    /// Form-factor kernel evaluations (ln r terms of the contour integral, edge terms of
    /// point-to-polygon, centroid kernels of point-to-point).
    #[serde(default)]
    pub kernel_evaluations: u64,
    /// Integrated pairs computed by the contour integral, point-to-polygon and point-to-point.
    #[serde(default)]
    pub pairs_contour: u64,
    #[serde(default)]
    pub pairs_point_polygon: u64,
    #[serde(default)]
    pub pairs_point_point: u64,
    /// Hierarchical transport: links between nodes (0 for the dense transport).
    #[serde(default)]
    pub links: u64,
    /// Hierarchical transport: nodes of the polygons' hierarchies, leaves (elements) included.
    #[serde(default)]
    pub nodes: u64,
    /// Hierarchical transport: link refinement passes (each followed by a solve).
    #[serde(default)]
    pub refinement_passes: u32,
    /// Hierarchical transport: links whose every shadow ray was blocked (kept while linking,
    /// carrying nothing).
    #[serde(default)]
    pub blocked_links: u64,
    /// Hierarchical transport: polygon pairs the cluster descent left for linking, and the
    /// cluster pairs it dropped because every shadow ray between them was blocked.
    #[serde(default)]
    pub polygon_pairs: u64,
    #[serde(default)]
    pub cluster_pairs_dropped: u64,
    /// Hierarchical transport: nodes whose occludable links' light is spread over their
    /// elements by a shadow mask, and the shadow rays cast for the masks (in `rays_cast`).
    #[serde(default)]
    pub masked_nodes: u64,
    #[serde(default)]
    pub mask_rays: u64,
}

impl Counts {
    /// These counts with the scene's polygon count, the importer's statistics and the element
    /// count of `mesh` filled in.
    pub fn with_scene(self, scene: &Scene, mesh: &ElementMesh) -> Counts {
        let stats = &scene.stats;
        Counts {
            polygons: scene.polygons.len(),
            elements: mesh.elements.len(),
            degenerate_dropped: stats.degenerate_dropped,
            quads_merged: stats.quads_merged,
            primitives_skipped: stats.primitives_skipped,
            ngons_split: stats.ngons_split,
            faces_read: stats.faces_read,
            duplicates_dropped: stats.duplicates_dropped,
            coincident_dropped: stats.coincident_dropped,
            against_winding: stats.against_winding,
            ..self
        }
    }
}

/// The transport a bake used and why: the report's `transport` object.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TransportChoice {
    pub kind: TransportKind,
    pub reason: String,
}

/// A finished bake.
pub struct Bake {
    pub mesh: ElementMesh,
    /// Per element: reflectance and emission of its material.
    pub rho: Vec<[f64; BANDS]>,
    pub emission: Vec<[f64; BANDS]>,
    /// Per element: the punctual lights' first reflection `ρ E / π`, the part of `b` (and of
    /// the source term `e + ρ E / π` the solver saw) that comes straight from the lights.
    pub direct: Vec<[f64; BANDS]>,
    /// Per light of the scene: what its direct-light pass did.
    pub light_stats: Vec<direct::LightStats>,
    /// Per element: the sky's first reflection `ρ E_sky / π` (0 without `--sky`), the part of
    /// `b` that comes straight from the sky and the ground below it.
    pub sky: Vec<[f64; BANDS]>,
    /// What the sky pass did (`None` without `--sky`).
    pub sky_stats: Option<SkyStats>,
    /// Per element: some light's shadow edge crosses it ([`direct::DirectLight::partly_lit`]).
    pub partly_lit: Vec<bool>,
    /// Per element: which side of every shadow edge it is on
    /// ([`direct::DirectLight::shadow_class`]).
    pub shadow_class: Vec<u64>,
    /// What refinement did.
    pub refinement: refine::Refinement,
    pub solution: Solution,
    /// What the last solve planned and ran: the transport and why, the solve, the estimator.
    pub plan: Plan,
    /// `H = F b + E / π` per element (interreflected plus direct light), when
    /// [`Request::irradiance`] asked for it.
    pub irradiance: Option<Vec<[f64; BANDS]>>,
    /// Delivered + emitted = absorbed + escaped, per band.
    pub energy: EnergyBalance,
    /// Where the escaping light goes (openings, back faces), estimated by rays independently of
    /// the transport ([`escape`]).
    pub escape: escape::Escape,
    pub counts: Counts,
    pub effects: visibility::Effects,
    /// Per element: the estimated bound on `|b − b̄|` and its parts ([`error`]).
    pub error: Vec<error::Parts>,
    /// The target error of `b`, the tolerance it chose and the bound the solve leaves.
    pub accuracy: Accuracy,
    /// Seconds per stage, in pipeline order (`mesh`, `visibility_setup`, `form_factors`,
    /// `solve`, ...).
    pub timings: Vec<(&'static str, f64)>,
    /// The process's peak resident memory (MiB) at the end of each stage, where the system
    /// says (Linux: `VmHWM`); it only grows, so a stage's rise over the previous one is its
    /// own peak's excess.
    pub peak_rss_mib: Vec<(&'static str, f64)>,
    /// The hierarchical transport, when `--save-links` asked to keep it.
    pub saved_links: Option<SavedLinks>,
    pub warnings: Vec<String>,
}

/// This process's peak resident memory so far, in MiB (`VmHWM` of `/proc/self/status`);
/// `None` where that is not available.
pub fn peak_rss_mib_now() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// The most interreflections `--bounces` may ask for: each is one product with the
/// transport (a series that has not converged after 10 000 bounces is better solved
/// exactly).
pub const MAX_BOUNCES: u32 = 10_000;

/// The dense transport's default element budget ([`DEFAULT_MAX_ELEMENTS`]), and the largest
/// small scene with occluders whose hierarchical bake falls back to the dense transport when
/// it has no solution. (`--transport auto` chooses by [`cost`], not by this count.)
pub const DENSE_CROSSOVER: usize = 2_000;

/// The least default `--max-elements` of a small scene on the hierarchical transport under
/// `auto` (one with occlusion up to the crossover, any scene up to [`SMALL_SCENE_ELEMENTS`]),
/// which is refined by default: measured (docs/accuracy.md, issue 31) on `small_room.obj` and
/// the Cornell box, the hierarchy refined to 4 000 elements is more accurate than the dense
/// transport refined to 2 000, in a tenth of the time, and than a uniform grid of as many
/// elements.
pub const OCCLUDED_MAX_ELEMENTS: u64 = 4_000;

/// Scenes of up to this many elements on the hierarchical transport under `auto` are refined
/// by default (up to twice their grid's elements, at least [`OCCLUDED_MAX_ELEMENTS`], as many
/// solves as on the dense transport, [`refine::MAX_PASSES`]): each pass links the scene again,
/// which a small scene affords and a walkthrough does not. Measured on the paper's cube at `--quality high`
/// (2 166 elements) and the Cornell box (3 409): refined, they are more accurate than uniform
/// grids at the same time (issue 31, docs/accuracy.md).
pub const SMALL_SCENE_ELEMENTS: usize = 4_000;

/// The default `--max-elements` of a dense bake (the dense crossover: a small scene refines up
/// to what the dense transport takes), and the least of a hierarchical one.
pub const DEFAULT_MAX_ELEMENTS: u64 = DENSE_CROSSOVER as u64;

/// By default refinement on the hierarchical transport may add a quarter of the grid's
/// elements (where that passes [`DEFAULT_MAX_ELEMENTS`]): the time and memory of each solve
/// grow by about as much.
pub const DEFAULT_GROWTH_DIVISOR: u64 = 4;

/// Bakes `scene` with `settings`: mesh, visibility, transport, solve (and `H = F b` if asked),
/// then, with [`Settings::refine`], splits elements where the light changes and solves again
/// until the estimate meets the target ([`refine`]).
pub fn run(scene: &Scene, settings: &Settings, progress: &dyn Progress) -> Result<Bake, BakeError> {
    match run_refined(scene, settings, progress) {
        // `auto` gave a small scene with occluders the hierarchy, whose rows are not limited
        // to 1: surfaces seen twice (coincident or overlapping solids, as in
        // `graz_overlap.obj`) can leave it without a solution where the dense transport,
        // which scales such rows to 1, has one. A small scene is baked again that way.
        Err(BakeError::Solve(error)) if small_occluded_auto(scene, settings)? => {
            let dense = Settings {
                transport: TransportKind::Dense,
                ..settings.clone()
            };
            let mut bake = run_refined(scene, &dense, progress)?;
            let why = format!(
                "the hierarchical transport, chosen for a small scene with occluders, had no \
                 solution ({error}); baked with the dense transport, which scales rows that \
                 see surfaces twice"
            );
            bake.plan.fell_back(&why);
            bake.warnings.push(why);
            Ok(bake)
        }
        other => other,
    }
}

/// The scene's polygons as occluders, alpha cut-outs and glass included, as the bake's
/// stages see them: for stages after the bake that cast rays into the scene (light probes).
pub fn occluders(scene: &Scene) -> Result<Occluders, BakeError> {
    Ok(Occluders::new(&scene.polygons)?
        .with_cutouts(cutouts(scene))
        .with_transmission(transmission(scene)))
}

/// Per polygon, the share of light a ray crossing it keeps: its material's transmission
/// (`scene::Material::transmission`, thin glass). The back copy the importer adds for a
/// double-sided material passes everything (1): its front twin, at the same place, already
/// attenuates, so a double-sided pane dims a ray by t once, not t².
fn transmission(scene: &Scene) -> Vec<f64> {
    scene
        .polygons
        .iter()
        .map(|polygon| {
            let Some(m) = scene.materials.get(polygon.material) else {
                return 0.0;
            };
            if m.transmission > 0.0 && m.double_sided && polygon.origin.side == scene::Side::Back {
                1.0
            } else {
                m.transmission
            }
        })
        .collect()
}

/// [`run`] with the transport `settings` plan, no fallback.
fn run_refined(
    scene: &Scene,
    settings: &Settings,
    progress: &dyn Progress,
) -> Result<Bake, BakeError> {
    // One tree of occluders for every solve of a refining bake (the polygons do not change).
    let lap = Instant::now();
    let occluders = occluders(scene)?;
    let setup = lap.elapsed().as_secs_f64();
    // Smooth light on a small scene starts at refinement's budget instead of refining.
    let summary = scene_summary(scene, settings, None, &occluders)?;
    let finer = plan::finer_start(settings, &summary, &scene.polygons)?;
    let settings = finer.as_ref().unwrap_or(settings);
    let first = run_mesh(scene, settings, progress, None, &occluders)?;
    let mut bake = refine::refine(scene, settings, progress, first, &occluders)?;
    insert_stage(&mut bake, "visibility_setup", setup, Some("mesh"));
    // Where the escaped light goes, once, on the final mesh.
    let lap = Instant::now();
    bake.escape = escape::estimate(
        &bake.mesh,
        &bake.solution.b,
        &occluders,
        bake.energy.escaped,
    );
    if bake.escape.rays > 0 {
        insert_stage(&mut bake, "escape", lap.elapsed().as_secs_f64(), None);
    }
    bake.counts = bake.counts.with_scene(scene, &bake.mesh);
    bake.accuracy.error = Some(error::summary(&bake.mesh, &bake.error));
    Ok(bake)
}

/// Records stage `name` (`seconds`, and the peak memory now) right after stage `after` in
/// `bake`'s timings (at the end when `after` is `None` or not there).
fn insert_stage(bake: &mut Bake, name: &'static str, seconds: f64, after: Option<&str>) {
    let at = |list: &Vec<(&'static str, f64)>| {
        list.iter()
            .position(|s| Some(s.0) == after)
            .map_or(list.len(), |k| k + 1)
    };
    let k = at(&bake.timings);
    bake.timings.insert(k, (name, seconds));
    if let Some(mib) = peak_rss_mib_now() {
        let k = at(&bake.peak_rss_mib);
        bake.peak_rss_mib.insert(k, (name, mib));
    }
}

/// Whether the plan of `scene`'s grids is the hierarchy `auto` gives a small scene with
/// occluders (the plan decides, so the fallback follows its rule).
fn small_occluded_auto(scene: &Scene, settings: &Settings) -> Result<bool, BakeError> {
    let occluders = Occluders::new(&scene.polygons)?;
    let summary = scene_summary(scene, settings, None, &occluders)?;
    Ok(Plan::new(settings, &summary, &mut Vec::new())?.small_occluded())
}

/// Each stage's wall time (s) and the peak memory (MiB) when it ended, in order.
pub(crate) struct Stages {
    timings: Vec<(&'static str, f64)>,
    peak_rss_mib: Vec<(&'static str, f64)>,
    lap: Instant,
}

impl Stages {
    fn new() -> Stages {
        Stages {
            timings: Vec::new(),
            peak_rss_mib: Vec::new(),
            lap: Instant::now(),
        }
    }

    /// The stage `name` ends now; the next begins.
    pub(crate) fn record(&mut self, name: &'static str) {
        self.timings.push((name, self.lap.elapsed().as_secs_f64()));
        if let Some(mib) = peak_rss_mib_now() {
            self.peak_rss_mib.push((name, mib));
        }
        self.lap = Instant::now();
    }
}

/// One bake on the mesher's grids (`given` = `None`) or on a given (refined) element mesh,
/// which the dense transport takes as it is, with `occluders` made from `scene`'s polygons
/// (and cut-outs). Its `escape` is left empty: [`run`] estimates it once, on the final mesh.
pub(crate) fn run_mesh(
    scene: &Scene,
    settings: &Settings,
    progress: &dyn Progress,
    given: Option<ElementMesh>,
    occluders: &Occluders,
) -> Result<Bake, BakeError> {
    let mut stages = Stages::new();
    let mut warnings = Vec::new();
    let (mesh, plan) = plan_and_mesh(scene, settings, given, occluders, &mut warnings)?;
    let (mut rho, emission) = element_values(scene, &mesh);
    warnings.extend(limit_reflectance(
        scene,
        &mesh,
        &mut rho,
        settings.max_reflectance,
    ));
    let rho_max = rho.iter().flatten().copied().fold(0.0f64, f64::max);
    if scene.lights.is_empty()
        && settings.sky.is_none()
        && emission.iter().all(|x| x.iter().all(|&v| v == 0.0))
    {
        warnings.push(advice::no_light());
    }
    warnings.extend(advice::emissive_is_base_colour(scene));
    stages.record("mesh");

    let light = Light::of(
        scene,
        &mesh,
        occluders,
        (&rho, &emission),
        settings,
        progress,
        &mut stages,
    );
    warnings.extend(advice::lights_reaching_little(scene, &light.lit.stats));
    let dark = light.source.iter().all(|s| s.iter().all(|&v| v == 0.0));
    if dark && settings.save_links {
        warnings.push(
            "--save-links writes no file: nothing emits or reflects direct light, so no links \
             were built"
                .to_string(),
        );
    }
    let mut plan = plan.with_rho_max(rho_max);
    if dark {
        plan.not_built();
    }
    let problem = transports::Problem {
        scene,
        settings,
        mesh: &mesh,
        occluders,
        rho: &rho,
        emission: &emission,
        external: &light.external,
        source: &light.source,
        source_noise: &light.source_noise,
        rho_max,
        plan: &plan,
    };
    let done = if dark {
        transports::dark(&problem)?
    } else if plan.transport().kind == TransportKind::Hierarchical {
        transports::hierarchical(&problem, progress, &mut stages)?
    } else {
        transports::dense(&problem, progress, &mut stages, &mut warnings)?
    };
    stages.record("energy");

    let accuracy = accuracy_of(&plan, rho_max, &done);
    let error = estimate_error(&problem, &done);
    stages.record("error_estimate");

    let transports::Transported {
        solution,
        irradiance,
        energy,
        counts,
        effects,
        saved_links,
        ..
    } = done;
    Ok(Bake {
        error,
        mesh,
        rho,
        emission,
        direct: light.direct,
        light_stats: light.lit.stats,
        sky: light.sky,
        sky_stats: light.sky_stats,
        partly_lit: light.lit.partly_lit,
        shadow_class: light.lit.shadow_class,
        refinement: refine::Refinement::default(),
        solution,
        plan,
        irradiance,
        energy,
        escape: escape::Escape::default(),
        counts,
        effects,
        accuracy,
        timings: stages.timings,
        peak_rss_mib: stages.peak_rss_mib,
        saved_links,
        warnings,
    })
}

/// The plan of one solve on the mesher's grids (`given` = `None`) or on a given (refined)
/// mesh, and that mesh.
fn plan_and_mesh(
    scene: &Scene,
    settings: &Settings,
    given: Option<ElementMesh>,
    occluders: &Occluders,
    warnings: &mut Vec<String>,
) -> Result<(ElementMesh, Plan), BakeError> {
    let refined = given.as_ref().map(|mesh| mesh.elements.len() as u64);
    // A refined mesh is planned for like the grids: both transports take it (the hierarchical
    // one's trees continue below the grid elements into their quarters).
    let plan = Plan::new(
        settings,
        &scene_summary(scene, settings, refined, occluders)?,
        warnings,
    )?;
    let mesh = match given {
        Some(mesh) => mesh,
        None => mesher::mesh(&scene.polygons, settings.subdivision)?,
    };
    Ok((mesh, plan))
}

/// What the plan needs of `scene` on its grids, or on a refined mesh of `refined` elements.
fn scene_summary(
    scene: &Scene,
    settings: &Settings,
    refined: Option<u64>,
    occluders: &Occluders,
) -> Result<SceneSummary, BakeError> {
    // The grids' elements, which the transport is chosen for (a refined mesh has more).
    let grid_elements = mesher::element_count(&scene.polygons, settings.subdivision)?;
    // Only a scene the dense transport could take needs to know whether it has occluders
    // (the pair test stops at the first occludable pair); decided on the grids, as the
    // transport is, so that every solve of a refining bake plans alike.
    let occluded = grid_elements <= DENSE_AUTO_MAX as u64
        && settings.transport == TransportKind::Auto
        && occluders.any_can_occlude();
    Ok(SceneSummary {
        elements: refined.unwrap_or(grid_elements),
        grid_elements,
        lights: !scene.lights.is_empty(),
        rho_bound: scene_rho_bound(scene, settings.max_reflectance),
        bands: scene_bands(scene),
        occluded,
    })
}

/// Punctual lights and the sky: E per element, its irradiance E/π in b's unit (a diffuse
/// surface under illuminance E has exitance ρE, luminance ρE/π), and the source term e + ρE/π.
struct Light {
    lit: direct::DirectLight,
    /// H⁰ = E / π (lights and sky).
    external: Vec<[f64; BANDS]>,
    /// ρ H⁰ of the lights.
    direct: Vec<[f64; BANDS]>,
    /// ρ H⁰ of the sky.
    sky: Vec<[f64; BANDS]>,
    sky_stats: Option<SkyStats>,
    /// e + ρ H⁰.
    source: Vec<[f64; BANDS]>,
    /// ρ σ_E / π: the standard error of the sky's part of the source (empty without a sky).
    source_noise: Vec<[f64; BANDS]>,
}

impl Light {
    /// The lights' and the sky's first reflection on the elements of `mesh` (`rho`, `emission`:
    /// per element ρ and e); records the stages `direct_light` (with lights) and `sky_light`
    /// (with a sky).
    fn of(
        scene: &Scene,
        mesh: &ElementMesh,
        occluders: &Occluders,
        (rho, emission): (&[[f64; BANDS]], &[[f64; BANDS]]),
        settings: &Settings,
        progress: &dyn Progress,
        stages: &mut Stages,
    ) -> Light {
        progress.start("direct light", scene.lights.len() as u64);
        let lit = direct::illuminate(
            &scene.lights,
            mesh,
            occluders,
            &direct::Options {
                samples: settings.light_samples,
            },
        );
        progress.finish();
        if !scene.lights.is_empty() {
            stages.record("direct_light");
        }
        let sky_lit = settings.sky.as_ref().map(|sky| {
            progress.start("sky light", 0);
            let sky_lit = direct::sky::illuminate(sky, mesh, occluders, settings.sky_samples);
            progress.finish();
            stages.record("sky_light");
            sky_lit
        });
        let over_pi = |e: f64| e / std::f64::consts::PI;
        let reflected =
            |h: &[f64; BANDS], r: &[f64; BANDS]| [r[0] * h[0], r[1] * h[1], r[2] * h[2]];
        let lights_h: Vec<[f64; BANDS]> = lit.illuminance.iter().map(|e| e.map(over_pi)).collect();
        let sky_h: Vec<[f64; BANDS]> = match &sky_lit {
            Some(s) => s.illuminance.iter().map(|e| e.map(over_pi)).collect(),
            None => vec![[0.0; BANDS]; mesh.elements.len()],
        };
        let direct: Vec<[f64; BANDS]> = lights_h
            .iter()
            .zip(rho)
            .map(|(h, r)| reflected(h, r))
            .collect();
        let sky: Vec<[f64; BANDS]> = sky_h
            .iter()
            .zip(rho)
            .map(|(h, r)| reflected(h, r))
            .collect();
        let source_noise: Vec<[f64; BANDS]> = match &sky_lit {
            Some(s) => s
                .deviation
                .iter()
                .zip(rho)
                .map(|(d, r)| reflected(&d.map(over_pi), r))
                .collect(),
            None => Vec::new(),
        };
        let external: Vec<[f64; BANDS]> = lights_h
            .iter()
            .zip(&sky_h)
            .map(|(a, b)| [a[0] + b[0], a[1] + b[1], a[2] + b[2]])
            .collect();
        let source: Vec<[f64; BANDS]> = emission
            .iter()
            .zip(direct.iter().zip(&sky))
            .map(|(e, (d, s))| [e[0] + d[0] + s[0], e[1] + d[1] + s[1], e[2] + d[2] + s[2]])
            .collect();
        Light {
            lit,
            external,
            direct,
            sky,
            sky_stats: sky_lit.map(|s| s.stats),
            source,
            source_noise,
        }
    }
}

/// What the bake's accuracy rests on: the target, ρ_max, the form factors' stated accuracy,
/// the condition bound and the dense rows that were limited.
fn accuracy_of(plan: &Plan, rho_max: f64, done: &transports::Transported) -> Accuracy {
    let (settings, estimator) = (plan.settings(), plan.estimator());
    let row_sum_accuracy = estimator.row_sum_accuracy();
    let ff_tolerance = match estimator {
        Estimator::Auto { tolerance }
            if settings.derive_tolerance
                && plan.transport().kind != TransportKind::Hierarchical =>
        {
            Some(tolerance)
        }
        _ => None,
    };
    Accuracy {
        max_error: settings.max_error,
        rho_max,
        ff_tolerance,
        link_tolerance: done.link_tolerance.map(|(t, _)| t),
        amplification: done.link_tolerance.map(|(_, a)| a),
        row_sum_accuracy,
        condition_bound: Some(accuracy::condition_bound(rho_max, row_sum_accuracy))
            .filter(|c| c.is_finite()),
        error_bound: done.solution.condition.map(|c| {
            c.map(|c| c * rho_max * row_sum_accuracy)
                .filter(|b| b.is_finite())
        }),
        row_sums: done
            .row_sums
            .as_ref()
            .map(|l: &form_factor::RowSumLimit| accuracy::RowSums {
                largest_before: l.largest,
                largest_after: l.largest_after,
                scaled: l.scaled,
                seen_twice: l.beyond_margin.len(),
            }),
        // Summarised once the bake is final (after refinement): [`run`].
        error: None,
    }
}

/// The per-element error estimate of the solved bake.
fn estimate_error(p: &transports::Problem, done: &transports::Transported) -> Vec<error::Parts> {
    let solution = &done.solution;
    let sampled: Vec<bool> = p
        .mesh
        .elements
        .iter()
        .map(|e| done.sampled_polygons.get(e.polygon as usize) == Some(&true))
        .collect();
    error::estimate(&error::Inputs {
        mesh: p.mesh,
        b: &solution.b,
        rho: p.rho,
        source: p.source,
        row_sum_accuracy: p.plan.estimator().row_sum_accuracy(),
        condition: solution.condition.map(|c| c.unwrap_or(1.0)),
        rho_max: p.rho_max,
        residual: [0, 1, 2].map(|c| {
            if solution.residual_relative[c] {
                solution.residual[c]
            } else {
                0.0
            }
        }),
        sampled: &sampled,
        samples: done.samples,
        delivered: &done.delivered,
        link_error: done
            .link_error
            .as_ref()
            .map(|[local, carried, visibility]| error::LinkMisses {
                local,
                carried,
                visibility,
            }),
        source_noise: p.source_noise,
    })
}

/// A bake's hierarchical transport kept for `--save-links`, with the key that a later
/// `--load-links` must match.
pub struct SavedLinks {
    pub key: u64,
    pub transport: HierarchicalTransport,
}

impl SavedLinks {
    /// Writes the links file ([`HierarchicalTransport::save`]).
    pub fn write(&self, w: &mut dyn std::io::Write) -> std::io::Result<()> {
        self.transport.save(self.key, w)
    }
}

/// The version of [`links_key`]'s layout. 2: the options are hashed field by field
/// (version 1 hashed their `Debug` text, which moved whenever a type did); links saved under
/// version 1 are refused as made with other options, and must be saved again.
pub const LINKS_KEY_VERSION: u8 = 2;

/// What the links of a bake depend on: the polygons (vertices and normals, bit for bit), the
/// element mesh and the options that shape linking (subdivision, estimator, contour options,
/// link tolerance, shadow rays per link, linking passes), each as explicit bytes. Not ρ or e:
/// a re-bake with other emission or colours may reuse them (refinement followed the
/// radiosities of the bake that saved them). FNV-1a over the bytes, stable across runs and
/// platforms.
pub fn links_key(scene: &Scene, mesh: &ElementMesh, settings: &Settings) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            hash ^= u64::from(b);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
    };
    eat(b"bake links");
    eat(&[LINKS_KEY_VERSION]);
    eat(&(scene.polygons.len() as u64).to_le_bytes());
    for p in &scene.polygons {
        eat(&(p.vertices.len() as u64).to_le_bytes());
        for v in p.vertices.iter().chain([&p.normal]) {
            for c in v.to_array() {
                eat(&c.to_bits().to_le_bytes());
            }
        }
    }
    eat(&(mesh.elements.len() as u64).to_le_bytes());
    match settings.subdivision {
        mesher::Subdivision::Count(n) => {
            eat(&[0]);
            eat(&n.to_le_bytes());
        }
        mesher::Subdivision::MaxSize(l) => {
            eat(&[1]);
            eat(&l.to_bits().to_le_bytes());
        }
    }
    match settings.estimator {
        Estimator::Contour => eat(&[0]),
        Estimator::PointPolygon(rule) => eat(&[
            1,
            match rule {
                form_factor::TriangleRule::Centroid => 0,
                form_factor::TriangleRule::Three => 1,
                form_factor::TriangleRule::Seven => 2,
            },
        ]),
        Estimator::PointPoint => eat(&[2]),
        Estimator::Auto { tolerance } => {
            eat(&[3]);
            eat(&tolerance.to_bits().to_le_bytes());
        }
    }
    let c = settings.contour;
    eat(&c.segments.to_le_bytes());
    eat(&c.order.to_le_bytes());
    eat(&c.near_ratio.to_bits().to_le_bytes());
    eat(&[u8::from(c.auto_order)]);
    match settings.link_tolerance {
        Some(t) => eat(&t.to_bits().to_le_bytes()),
        None => {
            eat(b"E");
            eat(&settings.max_error.to_bits().to_le_bytes());
        }
    }
    eat(&settings.link_samples.to_le_bytes());
    eat(&LINK_PASSES.to_le_bytes());
    hash
}

fn load_links(
    path: &std::path::Path,
    scene: &Scene,
    mesh: &ElementMesh,
    key: u64,
) -> Result<HierarchicalTransport, BakeError> {
    let error = |source| BakeError::LinksFile {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(|e| error(transport::LinksFileError::Io(e)))?;
    let mut reader = std::io::BufReader::with_capacity(1 << 20, file);
    HierarchicalTransport::load(&scene.polygons, mesh, key, &mut reader).map_err(error)
}

/// The solver's refusal of a dense system, with its cause: a reflectance of 1 (no finite
/// answer whatever the accuracy; glTF's default material is ρ = 1), or a per-pair tolerance
/// given by the user that is too loose for this scene's conditioning.
fn explain_refusal(
    error: BakeError,
    settings: &Settings,
    estimator: Estimator,
    rho_max: f64,
) -> BakeError {
    let BakeError::Solve(error @ SolveError::Singular { .. }) = error else {
        return error;
    };
    let hint = if rho_max >= 1.0 {
        "a surface reflects everything (rho = 1) and no accuracy makes the answer finite:          lower its reflectance (glTF's default material, without baseColorFactor, has rho = 1)"
            .to_string()
    } else if !settings.derive_tolerance
        && estimator.row_sum_accuracy() > form_factor::ROW_SUM_ACCURACY
    {
        let tolerance = estimator.row_sum_accuracy();
        format!(
            "the largest reflectance is {rho_max}, so the form factors' stated accuracy              {tolerance:e} can change the answer entirely; give a smaller --ff-tolerance (or              none, and --max-error sets it: {:e} for {:e})",
            accuracy::pair_tolerance(settings.max_error, rho_max),
            settings.max_error
        )
    } else {
        return BakeError::Solve(error);
    };
    BakeError::Unsolvable { error, hint }
}

/// Dense rows of F that sum past 1 by more than this (or the estimator's stated accuracy,
/// when larger) are named in a warning: shadow-ray estimates of partly hidden pairs move row
/// sums by up to ~1% (two rooms at 121 rays per pair: 1.0085; the Cornell box 1.0003), while
/// coincident or overlapping surfaces seen twice add their whole share (1.9 in
/// `graz_overlap.obj`). Every row past 1 is scaled to 1 whether named or not.
pub const ROW_SUM_WARNING_MARGIN: f64 = 0.05;

/// The warning for rows of F that summed past 1 + the margin and were scaled to 1
/// ([`form_factor::DenseFormFactors::limit_row_sums`]): how many elements, the largest sum,
/// and the polygons with most of them (index, mesh, source face, material).
fn row_sum_warning(scene: &Scene, mesh: &ElementMesh, over: &[(usize, f64)]) -> Option<String> {
    if over.is_empty() {
        return None;
    }
    let largest = over.iter().map(|&(_, s)| s).fold(0.0f64, f64::max);
    let mut by_polygon = std::collections::BTreeMap::<u32, (usize, f64)>::new();
    for &(i, sum) in over {
        let entry = by_polygon.entry(mesh.elements[i].polygon).or_default();
        entry.0 += 1;
        entry.1 = entry.1.max(sum);
    }
    let mut ranked: Vec<(u32, (usize, f64))> = by_polygon.into_iter().collect();
    ranked.sort_by(|a, b| b.1 .1.total_cmp(&a.1 .1).then(a.0.cmp(&b.0)));
    const SHOWN: usize = 4;
    let named: Vec<String> = ranked
        .iter()
        .take(SHOWN)
        .map(|&(p, (_, sum))| format!("{} (row sum {sum:.3})", polygon_name(scene, p as usize)))
        .collect();
    let more = if ranked.len() > SHOWN {
        format!(" and {} more polygons", ranked.len() - SHOWN)
    } else {
        String::new()
    };
    Some(format!(
        "form factors of {} element{} summed past 1, up to {largest:.3}: coincident, \
         overlapping or interpenetrating surfaces are seen twice, which would create light; \
         those rows were scaled down to 1 (reciprocity kept) on {}{more}",
        over.len(),
        if over.len() == 1 { "" } else { "s" },
        named.join(", ")
    ))
}

/// How messages name a polygon: its index, the mesh and source face it came from, and its
/// material.
fn polygon_name(scene: &Scene, polygon: usize) -> String {
    let Some(p) = scene.polygons.get(polygon) else {
        return format!("polygon {polygon}");
    };
    let mesh = match scene.layout.meshes.get(p.origin.mesh) {
        Some(m) => match m.name.as_deref() {
            Some(name) => format!("mesh {name:?}"),
            None => format!("mesh {}", p.origin.mesh),
        },
        None => format!("mesh {}", p.origin.mesh),
    };
    let material = advice::material_name(
        scene
            .materials
            .get(p.material)
            .and_then(|m| m.name.as_deref()),
        p.material,
    );
    format!(
        "polygon {polygon} ({mesh}, face {}, {material})",
        p.origin.face
    )
}

/// GMRES or the bounce series through any operator (`Solve::Direct` needs the matrix).
fn solve_with<O: solver::Operator>(
    op: &O,
    solve: Solve,
    rho: &[[f64; BANDS]],
    emission: &[[f64; BANDS]],
    progress: &dyn Progress,
) -> Result<Solution, BakeError> {
    // The bar counts operator applications; how many GMRES needs is not known before it
    // converges (total 0: open-ended).
    let counted = Counted { op, progress };
    let result = match solve {
        Solve::Iterative(options) => {
            progress.start("solve", 0);
            solver::solve_iterative(&counted, rho, emission, &options)
        }
        Solve::Bounces(k) => {
            progress.start("solve", u64::from(k));
            solver::solve_bounces(&counted, rho, emission, k)
        }
        Solve::Direct => {
            return Err(BakeError::Options(
                "the direct solver needs the dense transport".into(),
            ))
        }
    };
    progress.finish();
    result.map_err(BakeError::Solve)
}

/// The transport of a scene with no light in it: `F b` for `b = 0` is 0 whatever `F` is.
struct NoTransport(usize);

impl solver::Operator for NoTransport {
    fn n(&self) -> usize {
        self.0
    }

    fn apply(&self, _: &[f64], y: &mut [f64]) {
        y.fill(0.0);
    }
}

impl Transport for NoTransport {}

/// An operator that tells `progress` of every application and is otherwise `op` itself.
struct Counted<'a, O> {
    op: &'a O,
    progress: &'a dyn Progress,
}

impl<O: solver::Operator> solver::Operator for Counted<'_, O> {
    fn n(&self) -> usize {
        self.op.n()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.op.apply(x, y);
        self.progress.advance(1);
    }

    fn apply_bands(&self, x: &[[f64; BANDS]], y: &mut [[f64; BANDS]]) {
        self.op.apply_bands(x, y);
        self.progress.advance(1);
    }

    fn accuracy(&self) -> f64 {
        self.op.accuracy()
    }

    fn rows_bounded(&self) -> bool {
        self.op.rows_bounded()
    }
}

/// Linking passes of the hierarchical transport (the first with B = e).
pub const LINK_PASSES: u32 = 4;

/// `H` per element and band.
type Irradiance = Vec<[f64; BANDS]>;

/// `H = F b + H⁰` if asked for, and the energy balance, through any transport; `external` is
/// the lights' irradiance `H⁰ = E / π`.
fn finish<T: Transport>(
    transport: &T,
    mesh: &ElementMesh,
    rho: &[[f64; BANDS]],
    emission: &[[f64; BANDS]],
    external: &[[f64; BANDS]],
    solution: &Solution,
    settings: &Settings,
) -> Result<(Option<Irradiance>, EnergyBalance), BakeError> {
    let irradiance = settings.irradiance.then(|| {
        let mut h = transport.irradiance(&solution.b);
        for (h, x) in h.iter_mut().zip(external) {
            for c in 0..BANDS {
                h[c] += x[c];
            }
        }
        h
    });
    let areas: Vec<f64> = mesh.elements.iter().map(|el| el.area).collect();
    let energy =
        solver::energy_balance_lit(transport, &areas, rho, emission, external, &solution.b)
            .map_err(BakeError::Internal)?;
    Ok((irradiance, energy))
}

/// Under `--transport auto`, bright scenes ([`BRIGHT_AMPLIFICATION`]) up to this many
/// elements whose hierarchy's link tolerance, so amplified, exceeds `--max-error` get the
/// dense transport anyway (an 8 000² matrix is 512 MB; the memory guard still applies).
pub const BRIGHT_DENSE_MAX: usize = 8_000;

/// The largest scene `--transport auto` costs the dense transport for ([`cost`]): above it the
/// hierarchy is always the cheaper by far (and the matrix alone passes 512 MB).
pub const DENSE_AUTO_MAX: usize = BRIGHT_DENSE_MAX;

/// A scene is bright when its a-priori condition bound `(1 + ρ_max)/(1 − ρ_max)` reaches this
/// (ρ_max ≥ 0.98): the hierarchy's link errors, measured at ρ ≤ 0.9 in docs/accuracy.md, are
/// then amplified enough to dominate (a closed ρ = 0.999 cube at `--quality high`, 2 166
/// elements, was 4% off e/(1 − ρ) with links, 1.4e-9 dense).
pub const BRIGHT_AMPLIFICATION: f64 = 100.0;

/// An upper bound on every element's reflectance before meshing: the largest ρ factor of the
/// materials the polygons use (textures and `COLOR_0` only multiply it by values ≤ 1), with
/// ρ ≥ 1 lowered to `max_reflectance` as [`limit_reflectance`] will.
fn scene_rho_bound(scene: &Scene, max_reflectance: f64) -> f64 {
    scene
        .polygons
        .iter()
        .filter_map(|p| scene.materials.get(p.material))
        .flat_map(|m| m.rho)
        .map(|r| {
            if r >= REFLECTS_ALL {
                max_reflectance
            } else {
                r
            }
        })
        .fold(0.0f64, f64::max)
}

/// A reflectance this close to 1 is 1: a white texture's exact mean over an element rounds to
/// 1 − 1.1e-16, and no authored value lies between this and 1 (an MTL or glTF colour is
/// written with at most ~9 significant digits).
pub const REFLECTS_ALL: f64 = 1.0 - 1e-12;

/// Lowers every element reflectance at or above 1 to `max_reflectance` (`--max-reflectance`):
/// ρ = 1 reflects all light, which no surface does, and leaves `(I − ρF) b = e` without a
/// finite answer in a closed scene (eq. 7's Neumann series needs ρ F to shrink). Values below
/// 1 stay as authored. Decided from the input alone, before any form factor or link; one
/// warning names the materials (glTF's default material, a white texture on a white base
/// colour). `None` when nothing was lowered.
fn limit_reflectance(
    scene: &Scene,
    mesh: &ElementMesh,
    rho: &mut [[f64; BANDS]],
    max_reflectance: f64,
) -> Option<String> {
    if max_reflectance >= 1.0 {
        return None;
    }
    let mut lowered = vec![0usize; scene.materials.len()];
    for (el, r) in mesh.elements.iter().zip(rho.iter_mut()) {
        if r.iter().any(|&v| v >= REFLECTS_ALL) {
            for v in r.iter_mut().filter(|v| **v >= REFLECTS_ALL) {
                *v = max_reflectance;
            }
            let material = scene.polygons[el.polygon as usize].material;
            if let Some(count) = lowered.get_mut(material) {
                *count += 1;
            }
        }
    }
    let named: Vec<String> = lowered
        .iter()
        .enumerate()
        .filter(|(_, &count)| count > 0)
        .map(|(k, &count)| {
            format!(
                "{}: {count} element{}",
                advice::material_name(scene.materials[k].name.as_deref(), k),
                if count == 1 { "" } else { "s" }
            )
        })
        .collect();
    if named.is_empty() {
        return None;
    }
    Some(format!(
        "reflectance rho = 1 (all light reflected: no real surface, and no finite answer in a \
         closed scene) lowered to --max-reflectance {max_reflectance} on {}; glTF's default \
         material and white textures on a white base colour have rho = 1",
        advice::list(&named)
    ))
}

/// Bytes every element costs whatever the transport: the element (80 B) and its grid
/// vertices, ρ, e, the lights' share, the source term, b and H (24 B each), the trees'
/// nodes, the error estimate (with the links' misses) and the exporter's vertex attributes.
/// Measured by `tools/memory-per-element`, which fails when this is too low: the whole
/// process's peak RSS on the cube, hierarchical, no refinement, vertex colours, from 98 304 to
/// 393 216 elements (`--subdiv 128` → `256`): 1 318 B per element (issue 31's links part
/// added ~60 B to the 1 260 measured before it); rounded up.
pub const BYTES_PER_ELEMENT: u64 = 1_400;

/// The memory a bake of `n` elements needs at least: [`BYTES_PER_ELEMENT`] each, plus for the
/// dense transport the n × n matrix F (8 B per entry) and, for the direct solver, one n × n
/// LU copy per distinct reflectance band (`bands`): `8 n² (1 + bands)` bytes, 16–32 B × n².
/// The hierarchical transport's links are guarded as they are made.
pub fn memory_estimate(n: u64, transport: TransportKind, solve: Solve, bands: usize) -> u128 {
    let n = u128::from(n);
    let per_element = n * u128::from(BYTES_PER_ELEMENT);
    match transport {
        TransportKind::Hierarchical => per_element,
        _ => {
            let copies = match solve {
                Solve::Direct => 1 + bands as u128,
                _ => 1,
            };
            per_element + n * n * 8 * copies
        }
    }
}

/// Refuses a bake whose [`memory_estimate`] exceeds the memory available now (`MemAvailable`),
/// saying both.
fn check_memory(
    n: u64,
    transport: TransportKind,
    solve: Solve,
    bands: usize,
) -> Result<(), BakeError> {
    let bytes = memory_estimate(n, transport, solve, bands);
    let Some(available) = available_memory() else {
        return Ok(());
    };
    if bytes <= u128::from(available) {
        return Ok(());
    }
    let what = match transport {
        TransportKind::Hierarchical => format!("{BYTES_PER_ELEMENT} B per element"),
        _ => match solve {
            Solve::Direct => format!(
                "the dense transport: F and {bands} LU cop{} of n×n f64",
                if bands == 1 { "y" } else { "ies" }
            ),
            _ => "the dense transport: the n×n f64 matrix F".into(),
        },
    };
    Err(BakeError::TooLarge(format!(
        "{n} elements need about {:.1} GiB ({what}), but only {:.1} GiB of memory is \
         available; use a larger --max-element-size or a smaller --subdiv{}",
        bytes as f64 / GIB,
        available as f64 / GIB,
        if transport == TransportKind::Hierarchical {
            ""
        } else {
            ", or --transport hierarchical"
        }
    )))
}

/// Distinct ρ bands of the materials the polygons use (3 when one is textured: its elements'
/// ρ is only known after meshing).
fn scene_bands(scene: &Scene) -> usize {
    let mut used = vec![false; scene.materials.len()];
    for p in &scene.polygons {
        if let Some(u) = used.get_mut(p.material) {
            *u = true;
        }
    }
    let materials: Vec<&scene::Material> = scene
        .materials
        .iter()
        .zip(&used)
        .filter_map(|(m, &u)| u.then_some(m))
        .collect();
    if materials.iter().any(|m| m.base_color_texture.is_some()) {
        return BANDS;
    }
    let rho: Vec<[f64; BANDS]> = materials.iter().map(|m| m.rho).collect();
    distinct_bands(&rho)
}

const GIB: f64 = (1u64 << 30) as f64;

/// Distinct ρ columns (a grey scene has one).
fn distinct_bands(rho: &[[f64; BANDS]]) -> usize {
    let same = |a: usize, b: usize| rho.iter().all(|r| r[a] == r[b]);
    1 + usize::from(!same(0, 1)) + usize::from(!same(0, 2) && !same(1, 2))
}

/// `MemAvailable` of `/proc/meminfo` in bytes (`None` where there is no such file).
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Per polygon whose material has alpha cut-outs (`alphaMode` `MASK`): whether it is there
/// at a point, `factor × alpha ≥ cutoff` with the base-colour texture's alpha (filtered and
/// wrapped by its sampler) at the point's texture coordinates.
fn cutouts(scene: &Scene) -> Vec<Option<visibility::Cutout>> {
    // One shared copy of each masked image.
    let mut shared: std::collections::HashMap<usize, std::sync::Arc<scene::Image>> =
        std::collections::HashMap::new();
    scene
        .polygons
        .iter()
        .enumerate()
        .map(|(k, polygon)| {
            let mask = (*scene.alpha_masks.get(polygon.material)?)?;
            let material = scene.materials.get(polygon.material)?;
            let Some(reference) = material.base_color_texture.clone() else {
                // No texture: there everywhere or nowhere.
                let there = mask.factor >= mask.cutoff;
                return Some(std::sync::Arc::new(move |_| there) as visibility::Cutout);
            };
            let texture = scene.textures.get(reference.texture)?.clone();
            let image = match shared.get(&texture.image) {
                Some(image) => image.clone(),
                None => {
                    let image = std::sync::Arc::new(scene.images.get(texture.image)?.clone());
                    shared.insert(texture.image, image.clone());
                    image
                }
            };
            let uv = scene.uvs.get(k)?.clone()?;
            let set = reference.tex_coord as usize;
            Some(std::sync::Arc::new(move |point: glam::DVec3| {
                uv.at(set, point).is_none_or(|t| {
                    let a = texture::sample_alpha(&texture, &image, reference.apply(t));
                    mask.factor * a >= mask.cutoff
                })
            }) as visibility::Cutout)
        })
        .collect()
}

/// Per element: ρ and e of its polygon's material (the one place they are gathered): the
/// factors, times the exact mean of `baseColorTexture` / `emissiveTexture` over the element's
/// surface where the material has one (`texture::element_mean`), ρ also times the exact mean
/// of the input's `COLOR_0` (`texture::element_colour_mean`).
pub fn element_values(scene: &Scene, mesh: &ElementMesh) -> (Vec<[f64; BANDS]>, Vec<[f64; BANDS]>) {
    use rayon::prelude::*;
    mesh.elements
        .par_iter()
        .map(|el| {
            let polygon = el.polygon as usize;
            let m = &scene.materials[scene.polygons[polygon].material];
            let uv = scene.uvs.get(polygon).and_then(Option::as_ref);
            let textured = |factor: [f64; BANDS], reference: &Option<scene::TextureRef>| {
                let (Some(reference), Some(uv)) = (reference, uv) else {
                    return factor;
                };
                let Some(texture) = scene.textures.get(reference.texture) else {
                    return factor;
                };
                let Some(image) = scene.images.get(texture.image) else {
                    return factor;
                };
                let corners: Vec<glam::DVec3> = el
                    .corner_indices()
                    .iter()
                    .map(|&k| mesh.vertices[k as usize])
                    .collect();
                let mean =
                    texture::element_mean(uv, reference, texture, image, &corners, el.normal);
                // Decoded texels are in [0, 1], so is their exact mean; the area-weighted sum
                // of per-piece means can round a white texture's just above 1 (ρ > 1 is
                // refused), hence the clamp.
                [0, 1, 2].map(|c| factor[c] * mean[c].clamp(0.0, 1.0))
            };
            let mut rho = textured(m.rho, &m.base_color_texture);
            // The input's COLOR_0 multiplies the base colour (glTF): its exact mean.
            if let Some(uv) = uv {
                let corners: Vec<glam::DVec3> = el
                    .corner_indices()
                    .iter()
                    .map(|&k| mesh.vertices[k as usize])
                    .collect();
                if let Some(c) = texture::element_colour_mean(uv, &corners, el.normal) {
                    // In [0, 1] like the colours (the importer refuses others): clamp the
                    // rounding of the area-weighted mean as for textures.
                    rho = [0, 1, 2].map(|k| rho[k] * c[k].clamp(0.0, 1.0));
                }
            }
            (rho, textured(m.emission, &m.emissive_texture))
        })
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Saved links are refused unless every option that shapes them is the same: the key
    /// changes with each one (and not with ρ, e or the solver).
    #[test]
    fn the_links_key_changes_with_every_option_that_shapes_links() {
        let scene = importer::load(&bake_testkit::fixture("cube.gltf")).expect("the cube");
        let key = |request: Request| {
            let settings = Settings::resolve(&request, &scene.polygons).expect("settings");
            let mesh = mesher::mesh(&scene.polygons, settings.subdivision).expect("mesh");
            links_key(&scene, &mesh, &settings)
        };
        let base = Request {
            subdivision: Some(mesher::Subdivision::Count(4)),
            ..Request::default()
        };
        let same = key(base.clone());
        assert_eq!(same, key(base.clone()), "the key is deterministic");
        assert_eq!(
            same,
            key(Request {
                solver: Some(SolverKind::Iterative),
                max_reflectance: Some(0.5),
                ..base.clone()
            }),
            "the solver and reflectances do not shape links"
        );
        assert_eq!(
            same,
            key(Request {
                sky: Some(Sky {
                    model: SkyModel::Overcast { zenith: 2.0 },
                    ground_reflectance: 0.3,
                }),
                sky_samples: Some(64),
                ..base.clone()
            }),
            "links are geometry only: the sky does not shape them"
        );
        let mut contour = base.contour;
        contour.segments += 1;
        let changed = [
            Request {
                subdivision: Some(mesher::Subdivision::Count(5)),
                ..base.clone()
            },
            Request {
                subdivision: Some(mesher::Subdivision::MaxSize(0.25)),
                ..base.clone()
            },
            Request {
                ff_estimator: Some(EstimatorKind::Contour),
                ..base.clone()
            },
            Request {
                ff_estimator: Some(EstimatorKind::PointPoint),
                ..base.clone()
            },
            Request {
                ff_tolerance: Some(2e-3),
                ..base.clone()
            },
            Request {
                contour,
                ..base.clone()
            },
            Request {
                link_tolerance: Some(0.0123),
                ..base.clone()
            },
            Request {
                visibility_samples: Some(49),
                ..base.clone()
            },
        ];
        let keys: Vec<u64> = changed.into_iter().map(key).collect();
        for (k, &changed) in keys.iter().enumerate() {
            assert_ne!(changed, same, "option change {k} kept the key");
            for &other in &keys[..k] {
                assert_ne!(changed, other, "option changes {k} and another share a key");
            }
        }
    }
}
