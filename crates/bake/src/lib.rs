//! One bake: an imported scene in, the solved radiosity of its element mesh out.
//!
//! This crate owns the wiring of the pipeline (mesher → visibility → form factors / transport
//! → solver) so that the `bake` CLI, `tools/accuracy-report`, the benchmarks and the tests run
//! exactly the same bake: [`Settings::resolve`] turns a [`Request`] (the user's options) and
//! its quality preset into settings once, and [`run`] performs the stages, gathers ρ and e per
//! element, adds the punctual lights' first reflection `ρ E / π` to e (the paper's §2 E(j)),
//! chooses the transport, solves, and times every stage.
//!
//! It is not the importer or the exporter (the caller reads the scene and writes the outputs)
//! and knows no file formats or command-line syntax. It is the only crate that knows the
//! presets ([`presets`]).

pub mod presets;
mod settings;

pub use settings::{
    EstimatorKind, Request, Settings, Solve, SolverKind, TransportKind,
    HIERARCHICAL_SOLVE_TOLERANCE,
};

use form_factor::{FormFactors, Occluders, Occlusion};
use importer::Scene;
use mesher::ElementMesh;
use solver::{EnergyBalance, Solution, SolveError, BANDS};
use std::time::Instant;
use transport::{HierarchicalOptions, HierarchicalTransport, LinkError, LinkProgress, Transport};

/// Why a bake failed. [`BakeError::is_input`] tells bad input (exit 1) from internal errors.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    #[error("{0}")]
    Options(String),
    #[error("cannot subdivide: {0}")]
    Mesh(#[from] mesher::MeshError),
    #[error("cannot build the occlusion structure: {0}")]
    Visibility(#[from] visibility::VisibilityError),
    #[error("{0}")]
    TooLarge(String),
    #[error("no solution: {0}")]
    Solve(SolveError),
    #[error("internal error: {0}")]
    Internal(SolveError),
}

impl BakeError {
    /// Whether the input (scene or options) is at fault rather than the baker.
    pub fn is_input(&self) -> bool {
        !matches!(self, BakeError::Internal(_))
    }
}

/// Progress of the long stages, for a progress bar; called from any thread.
pub trait Progress: Sync {
    /// A stage of `total` steps (rows, polygons, iterations) begins; 0 when the number of
    /// steps is not known in advance.
    fn start(&self, stage: &str, total: u64);
    /// `steps` more steps are done.
    fn advance(&self, steps: u64);
    /// The stage is over.
    fn finish(&self);
}

/// Reports nothing.
pub struct Silent;

impl Progress for Silent {
    fn start(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
}

/// What the bake did, for the report and the summary line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Element pairs (dense) or node pairs (hierarchical) whose form factor was computed.
    pub pairs_evaluated: u64,
    /// Pairs facing each other whose visibility was decided.
    pub pairs_tested: u64,
    /// Of those, pairs some polygon may come between (rays were cast).
    pub pairs_occludable: u64,
    pub rays_cast: u64,
    pub kernel_evaluations: u64,
    pub pairs_contour: u64,
    pub pairs_point_polygon: u64,
    pub pairs_point_point: u64,
    /// Hierarchical transport: links kept, nodes of the hierarchy, refinement passes.
    pub links: u64,
    pub nodes: u64,
    pub passes: u32,
}

/// The transport a bake used and why.
#[derive(Clone, Debug, PartialEq)]
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
    pub solution: Solution,
    /// The solve that ran.
    pub solve: Solve,
    /// `H = F b + E / π` per element (interreflected plus direct light), when
    /// [`Request::irradiance`] asked for it.
    pub irradiance: Option<Vec<[f64; BANDS]>>,
    /// Delivered + emitted = absorbed + escaped, per band.
    pub energy: EnergyBalance,
    pub counts: Counts,
    pub effects: visibility::Effects,
    pub transport: TransportChoice,
    /// Seconds per stage, in pipeline order (`mesh`, `visibility_setup`, `form_factors`,
    /// `solve`, ...).
    pub timings: Vec<(&'static str, f64)>,
    pub warnings: Vec<String>,
}

impl Bake {
    /// The report's `options`: the settings as resolved, with the transport used.
    pub fn options_json(&self, settings: &Settings) -> serde_json::Value {
        settings.to_json(self.transport.kind)
    }
}

/// The most interreflections `--bounces` may ask for: each is one product with the
/// transport (a series that has not converged after 10 000 bounces is better solved
/// exactly).
pub const MAX_BOUNCES: u32 = 10_000;

/// Scenes up to this many elements get the dense transport under `--transport auto`.
pub const DENSE_CROSSOVER: usize = 2_000;

/// Bakes `scene` with `settings`: mesh, visibility, transport, solve (and `H = F b` if asked).
pub fn run(scene: &Scene, settings: &Settings, progress: &dyn Progress) -> Result<Bake, BakeError> {
    let mut timings = Vec::new();
    let mut lap = Instant::now();
    let mut stage = |name: &'static str, lap: &mut Instant| {
        timings.push((name, lap.elapsed().as_secs_f64()));
        *lap = Instant::now();
    };
    let mut warnings = Vec::new();

    // The cost first, from the element count alone: a request too large for this machine is
    // refused before anything is allocated.
    let planned = mesher::element_count(&scene.polygons, settings.subdivision)?;
    let mut transport = choose_transport(settings, usize::try_from(planned).unwrap_or(usize::MAX));
    let solve = settings.solve(transport.kind);
    check_memory(planned, transport.kind, solve, scene_bands(scene))?;
    let mesh = mesher::mesh(&scene.polygons, settings.subdivision)?;
    let n = mesh.elements.len();
    let (rho, emission) = element_values(scene, &mesh);
    if scene.lights.is_empty() && emission.iter().all(|x| x.iter().all(|&v| v == 0.0)) {
        warnings.push("the scene has no emitters and no lights: every radiosity is 0".to_string());
    }
    stage("mesh", &mut lap);

    let cutouts = cutouts(scene);
    let occluders = Occluders::new(&scene.polygons)?.with_cutouts(cutouts);
    stage("visibility_setup", &mut lap);

    // Punctual lights: E per element, its irradiance E/π in b's unit (a diffuse surface under
    // illuminance E has exitance ρE, luminance ρE/π), and the source term e + ρE/π.
    progress.start("direct light", scene.lights.len() as u64);
    let lit = direct::illuminate(
        &scene.lights,
        &mesh,
        &occluders,
        &direct::Options {
            samples: settings.light_samples,
        },
    );
    progress.finish();
    let external: Vec<[f64; BANDS]> = lit
        .illuminance
        .iter()
        .map(|e| e.map(|v| v / std::f64::consts::PI))
        .collect();
    let direct: Vec<[f64; BANDS]> = external
        .iter()
        .zip(&rho)
        .map(|(h, r)| [r[0] * h[0], r[1] * h[1], r[2] * h[2]])
        .collect();
    let source: Vec<[f64; BANDS]> = emission
        .iter()
        .zip(&direct)
        .map(|(e, d)| [e[0] + d[0], e[1] + d[1], e[2] + d[2]])
        .collect();
    if !scene.lights.is_empty() {
        stage("direct_light", &mut lap);
    }
    // Nothing emits and no surface reflects a light's direct light: b = 0 is the exact
    // solution, and no transport needs building (a large scene without emitters would
    // otherwise build its whole matrix or hierarchy to find zeros).
    let dark = source.iter().all(|s| s.iter().all(|&v| v == 0.0));
    let (solution, irradiance, energy, counts, effects) = if dark {
        transport.reason = format!(
            "{}; not built: nothing emits or reflects direct light, so b = 0 exactly",
            transport.reason
        );
        let solution = Solution {
            b: vec![[0.0; BANDS]; n],
            residual: [0.0; BANDS],
            residual_relative: [false; BANDS],
            factorizations: 0,
            condition: [None; BANDS],
            iterations: [0; BANDS],
        };
        let (irradiance, energy) = finish(
            &NoTransport(n),
            &mesh,
            &rho,
            &emission,
            &external,
            &solution,
            settings,
        )?;
        let effects = visibility::Effects {
            occlusion: false,
            reason: "no light to transport: no shadow rays".into(),
        };
        (solution, irradiance, energy, Counts::default(), effects)
    } else {
        match transport.kind {
            TransportKind::Hierarchical => {
                let max_links = available_memory().map_or(u64::MAX, |bytes| {
                    bytes / transport::hierarchical::BYTES_PER_LINK
                });
                let options = HierarchicalOptions {
                    link_tolerance: settings.link_tolerance,
                    samples: settings.link_samples,
                    estimator: settings.estimator,
                    contour: settings.contour,
                    passes: LINK_PASSES,
                    max_links,
                };
                progress.start("links", scene.polygons.len() as u64);
                let built = HierarchicalTransport::build(
                    &scene.polygons,
                    &mesh,
                    &occluders,
                    &rho,
                    &source,
                    &options,
                    &|step| match step {
                        LinkProgress::Polygons(k) | LinkProgress::Links(k) => progress.advance(k),
                        LinkProgress::Pass { pass, links } => {
                            progress.finish();
                            progress.start(&format!("links pass {pass}"), links);
                        }
                    },
                );
                progress.finish();
                let h = built.map_err(|e| match e {
                    LinkError::Solve(e) => BakeError::Solve(e),
                    e => BakeError::TooLarge(e.to_string()),
                })?;
                stage("links", &mut lap);
                let s = h.stats();
                let counts = Counts {
                    // Integrated node pairs (the kept links); screened pairs are in the stats.
                    pairs_evaluated: s.by_method.iter().sum(),
                    pairs_tested: s.pairs_tested,
                    pairs_occludable: s.pairs_occludable,
                    rays_cast: s.rays_cast,
                    kernel_evaluations: s.kernel_evaluations,
                    pairs_contour: s.by_method[0],
                    pairs_point_polygon: s.by_method[1],
                    pairs_point_point: s.by_method[2],
                    links: s.links,
                    nodes: s.nodes,
                    passes: s.passes,
                };
                let effects = visibility::Effects {
                    occlusion: s.pairs_occludable > 0,
                    reason: if s.pairs_occludable > 0 {
                        format!(
                            "{} of the {} node pairs tested may be partly hidden by another \
                         polygon: shadow rays were cast for them",
                            s.pairs_occludable, s.pairs_tested
                        )
                    } else {
                        format!(
                            "no polygon can come between any of the {} node pairs tested: no rays \
                         are cast",
                            s.pairs_tested
                        )
                    },
                };
                let solution = solve_with(&h, solve, &rho, &source, progress)?;
                stage("solve", &mut lap);
                let (irradiance, energy) =
                    finish(&h, &mesh, &rho, &emission, &external, &solution, settings)?;
                (solution, irradiance, energy, counts, effects)
            }
            _ => {
                // Dense: every element pair, exact (or within the estimator's tolerance).
                check_memory(n as u64, TransportKind::Dense, solve, distinct_bands(&rho))?;
                // The occlusion pre-pass (polygon pairs × candidate occluders) can take seconds.
                progress.start("occlusion", occluders.len() as u64);
                let occludable = occluders.occludable_pairs_with_progress(&|k| progress.advance(k));
                progress.finish();
                let effects = occludable.effects();
                stage("occludable_pairs", &mut lap);
                let mut form_factors =
                    FormFactors::new(&mesh, settings.contour).with_estimator(settings.estimator);
                if effects.occlusion {
                    form_factors = form_factors.with_occlusion(Occlusion {
                        occluders: &occluders,
                        pairs: &occludable,
                        samples: settings.visibility_samples,
                    });
                }
                progress.start("form factors", n as u64);
                let matrix = form_factors.dense_with_progress(&|rows| progress.advance(rows));
                progress.finish();
                stage("form_factors", &mut lap);
                let stats = matrix.stats;
                let counts = Counts {
                    pairs_evaluated: stats.pairs_integrated,
                    pairs_tested: stats.visibility.pairs_tested,
                    pairs_occludable: stats.visibility.pairs_occludable,
                    rays_cast: stats.visibility.rays_cast,
                    kernel_evaluations: stats.evaluations,
                    pairs_contour: stats.pairs_by_method.contour,
                    pairs_point_polygon: stats.pairs_by_method.point_polygon,
                    pairs_point_point: stats.pairs_by_method.point_point,
                    ..Counts::default()
                };
                let f = solver::DenseMatrix::new(n, &matrix.data)
                    .map_err(BakeError::Internal)?
                    .with_accuracy(settings.estimator.row_sum_accuracy());
                let solution = match solve {
                    Solve::Direct => {
                        solver::solve_direct(&f, &rho, &source).map_err(BakeError::Solve)?
                    }
                    _ => solve_with(&f, solve, &rho, &source, progress)?,
                };
                stage("solve", &mut lap);
                let (irradiance, energy) =
                    finish(&f, &mesh, &rho, &emission, &external, &solution, settings)?;
                (solution, irradiance, energy, counts, effects)
            }
        }
    };
    stage("energy", &mut lap);

    Ok(Bake {
        mesh,
        rho,
        emission,
        direct,
        light_stats: lit.stats,
        solution,
        solve,
        irradiance,
        energy,
        counts,
        effects,
        transport,
        timings,
        warnings,
    })
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

/// Which transport `settings` asks for on a scene of `n` elements, and why.
fn choose_transport(settings: &Settings, n: usize) -> TransportChoice {
    match settings.transport {
        TransportKind::Dense => TransportChoice {
            kind: TransportKind::Dense,
            reason: "--transport dense".into(),
        },
        TransportKind::Hierarchical => TransportChoice {
            kind: TransportKind::Hierarchical,
            reason: "--transport hierarchical".into(),
        },
        TransportKind::Auto if settings.direct_requested => TransportChoice {
            kind: TransportKind::Dense,
            reason: "--solver direct needs the dense transport".into(),
        },
        TransportKind::Auto if n <= DENSE_CROSSOVER => TransportChoice {
            kind: TransportKind::Dense,
            reason: format!(
                "{n} elements, at most the crossover of {DENSE_CROSSOVER}: the dense transport \
                 is exact and about as fast"
            ),
        },
        TransportKind::Auto => TransportChoice {
            kind: TransportKind::Hierarchical,
            reason: format!(
                "{n} elements, more than the crossover of {DENSE_CROSSOVER}: the hierarchical \
                 transport's links grow about linearly with the elements, the dense one's pairs \
                 quadratically"
            ),
        },
    }
}

/// Bytes every element costs whatever the transport: the element (80 B) and its grid
/// vertices, ρ, e, the lights' share, the source term, b and H (24 B each), and the
/// exporter's vertex attributes. A lower bound, rounded up.
pub const BYTES_PER_ELEMENT: u64 = 512;

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
    let materials: Vec<&importer::Material> = scene
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
    let mut shared: std::collections::HashMap<usize, std::sync::Arc<importer::Image>> =
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
            let textured = |factor: [f64; BANDS], reference: &Option<importer::TextureRef>| {
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
                [0, 1, 2].map(|c| factor[c] * mean[c])
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
                    rho = [0, 1, 2].map(|k| rho[k] * c[k]);
                }
            }
            (rho, textured(m.emission, &m.emissive_texture))
        })
        .unzip()
}
