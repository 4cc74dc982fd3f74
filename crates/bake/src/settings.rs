//! What a bake was asked for ([`Request`]: the CLI's flags, `None` where the user gave none)
//! and what it runs with ([`Settings`]: the preset and defaults filled in, resolved once).

use crate::presets::Quality;
use crate::BakeError;
use form_factor::{ContourOptions, Estimator, TriangleRule};
use mesher::Subdivision;
use scene::Polygon;
use solver::IterativeOptions;

/// `--ff-estimator`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum EstimatorKind {
    Contour,
    PointPolygon,
    PointPoint,
    Auto,
}

/// `--solver`: how the dense transport's system is solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum SolverKind {
    /// LU factorisation (dense transport only).
    Direct,
    /// Restarted GMRES.
    Iterative,
}

/// `--transport`: how light transport between elements is represented (in the report, by
/// [`TransportKind::name`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum TransportKind {
    /// The cheaper of the two by [`crate::cost`] (dense where it is affordable: exact).
    #[cfg_attr(
        feature = "clap",
        value(help = "The cheaper of the two by a measured cost model (dense where affordable)")
    )]
    #[default]
    Auto,
    /// Every element pair's form factor in an n × n matrix.
    Dense,
    /// Hierarchical radiosity: links between the coarsest node pairs that meet the link
    /// tolerance.
    Hierarchical,
}

impl TransportKind {
    pub fn name(self) -> &'static str {
        match self {
            TransportKind::Auto => "auto",
            TransportKind::Dense => "dense",
            TransportKind::Hierarchical => "hierarchical",
        }
    }
}

/// How the radiosity system is solved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Solve {
    /// LU per distinct ρ band (dense only).
    Direct,
    /// GMRES to a relative residual.
    Iterative(IterativeOptions),
    /// Direct light plus exactly this many interreflections.
    Bounces(u32),
}

impl Solve {
    pub fn name(&self) -> &'static str {
        match self {
            Solve::Direct => "direct",
            Solve::Iterative(_) => "iterative",
            Solve::Bounces(_) => "bounces",
        }
    }
}

/// The options of one bake as the user gave them: `None` means "from the preset or default".
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    pub quality: Quality,
    pub subdivision: Option<Subdivision>,
    pub contour: ContourOptions,
    pub ff_estimator: Option<EstimatorKind>,
    pub ff_tolerance: Option<f64>,
    /// `--max-error`: target relative error of `b` (the preset's when `None`).
    pub max_error: Option<f64>,
    /// Points per triangle of `point-polygon` (1, 3 or 7).
    pub ff_points: u32,
    pub visibility_samples: Option<u32>,
    pub solver: Option<SolverKind>,
    pub bounces: Option<u32>,
    pub tolerance: Option<f64>,
    pub max_iterations: Option<u32>,
    pub transport: TransportKind,
    pub link_tolerance: Option<f64>,
    /// Shadow rays per element a polygon may shadow from a point or spot light.
    pub light_samples: Option<u32>,
    /// `--sky`, `--ground-reflectance`: a sky over the scene as a light source (none when
    /// `None`).
    pub sky: Option<direct::sky::Sky>,
    /// `--sky-samples`: rays per element some polygon may block from the sky (the preset's
    /// when `None`).
    pub sky_samples: Option<u32>,
    /// Compute the irradiance `H = F b` (lightmaps need it).
    pub irradiance: bool,
    /// Keep the hierarchical transport in the [`crate::Bake`] for saving (`--save-links`).
    pub save_links: bool,
    /// Read the hierarchical transport from this file instead of linking (`--load-links`).
    pub load_links: Option<std::path::PathBuf>,
    /// `--refine on|off`: split elements where the light changes and solve again (on when
    /// `None`).
    pub refine: Option<bool>,
    /// `--max-elements`: the element budget of refinement ([`Settings::element_budget`]'s
    /// default when `None`).
    pub max_elements: Option<u64>,
    /// `--max-reflectance`: reflectances at or above 1 are lowered to this
    /// ([`DEFAULT_MAX_REFLECTANCE`] when `None`).
    pub max_reflectance: Option<f64>,
    /// Most levels refinement splits below the grid (`None`: [`crate::refine::MAX_LEVELS`]);
    /// for measurements against a reference whose own elements are that fine.
    pub refine_levels: Option<u8>,
}

/// The reflectance a ρ ≥ 1 (glTF's default material, a white texture on a white factor) is
/// lowered to when `--max-reflectance` is not given: below what the draft preset's accuracy
/// can solve (its condition bound (1 + ρ)/(1 − ρ) is 99 here, against ∞ at ρ = 1), and a
/// bright white paint's albedo.
pub const DEFAULT_MAX_REFLECTANCE: f64 = 0.98;

impl Default for Request {
    /// `bake IN OUT` with no options.
    fn default() -> Self {
        Request {
            quality: Quality::Normal,
            subdivision: None,
            contour: ContourOptions::default(),
            ff_estimator: None,
            ff_tolerance: None,
            max_error: None,
            ff_points: 3,
            visibility_samples: None,
            solver: None,
            bounces: None,
            tolerance: None,
            max_iterations: None,
            transport: TransportKind::Auto,
            link_tolerance: None,
            light_samples: None,
            sky: None,
            sky_samples: None,
            irradiance: false,
            save_links: false,
            load_links: None,
            refine: None,
            max_elements: None,
            max_reflectance: None,
            refine_levels: None,
        }
    }
}

/// GMRES tolerance of the hierarchical transport when `--tolerance` is not given, as a share of
/// `--max-error`: its links are accurate to about `E` (ε derived from it,
/// [`transport::LinkTolerance::FromMaxError`]), so a residual a hundred times smaller costs the
/// result nothing it could resolve.
pub const HIERARCHICAL_SOLVE_SHARE: f64 = 1e-2;

/// The loosest hierarchical solve: the residual bounds the energy balance's imbalance
/// (absorbed + escaped against emitted), which is held to 1e-6 of the emitted power whatever
/// the target.
pub const HIERARCHICAL_SOLVE_LOOSEST: f64 = 1e-6;

/// The hierarchical solve's tolerance for target `max_error`: [`HIERARCHICAL_SOLVE_SHARE`] of
/// it, no looser than [`HIERARCHICAL_SOLVE_LOOSEST`] and no tighter than 1e-12.
pub fn hierarchical_solve_tolerance(max_error: f64) -> f64 {
    (max_error * HIERARCHICAL_SOLVE_SHARE).clamp(1e-12, HIERARCHICAL_SOLVE_LOOSEST)
}

/// Everything one bake runs with, resolved from a [`Request`] and its preset.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub(crate) quality: Quality,
    pub(crate) subdivision: Subdivision,
    /// Whether `--subdiv` or `--max-element-size` was given (else the preset's element size,
    /// which a scene of smooth light may start finer than: [`crate::plan::finer_start`]).
    pub(crate) subdivision_requested: bool,
    /// The grid's elements this bake started finer than, and the budget it started at, when
    /// it did ([`crate::plan::finer_start`]); `None` otherwise.
    pub(crate) started_finer: Option<(u64, u64)>,
    pub(crate) contour: ContourOptions,
    /// The estimator as given or preset; under the dense transport, when
    /// [`Settings::derive_tolerance`], `auto`'s tolerance comes from `max_error` instead
    /// ([`Settings::dense_estimator`]).
    pub(crate) estimator: Estimator,
    /// Target relative error of `b` (`--max-error` or the preset's).
    pub(crate) max_error: f64,
    /// Refinement's target on the discretisation estimate, relative to the mean radiosity:
    /// `--max-error` when given, else the preset's [`crate::presets::Preset::refine_target`].
    pub(crate) refine_target: f64,
    /// Whether the dense transport derives `auto`'s per-pair tolerance from `max_error` and
    /// the scene's largest reflectance: no `--ff-tolerance` and no estimator other than `auto`.
    pub(crate) derive_tolerance: bool,
    /// Shadow rays per occludable element pair (dense transport).
    pub(crate) visibility_samples: u32,
    /// The transport asked for (`Auto` is decided per scene by [`crate::run`]).
    pub(crate) transport: TransportKind,
    /// Solve for the dense transport.
    pub(crate) dense_solve: Solve,
    /// Solve for the hierarchical transport (never `Direct`).
    pub(crate) hierarchical_solve: Solve,
    /// Whether `--solver direct` was given (then `auto` keeps the dense transport).
    pub(crate) direct_requested: bool,
    /// `--link-tolerance`: the largest estimated error of a link's contribution to its
    /// receiver's radiosity, relative to the scene's mean radiosity; `None` derives it from
    /// `max_error` ([`transport::LinkTolerance::FromMaxError`]).
    pub(crate) link_tolerance: Option<f64>,
    /// Shadow rays per occludable link.
    pub(crate) link_samples: u32,
    /// Shadow rays per element a polygon may shadow from a point or spot light.
    pub(crate) light_samples: u32,
    /// The sky lighting the scene, if any.
    pub(crate) sky: Option<direct::sky::Sky>,
    /// Rays per element some polygon may block from the sky.
    pub(crate) sky_samples: u32,
    pub(crate) irradiance: bool,
    /// `--save-links` / `--load-links` (either makes the transport hierarchical).
    pub(crate) save_links: bool,
    pub(crate) load_links: Option<std::path::PathBuf>,
    /// Refine where the light changes ([`crate::refine`]).
    pub(crate) refine: bool,
    /// Whether `--refine on` was given (then a bake that cannot refine says why).
    pub(crate) refine_requested: bool,
    /// Whether the user asked for a target (`--max-error`, `--max-elements` or `--refine on`):
    /// then refinement that stops short of it warns. Otherwise (the preset's defaults) the
    /// report's `refinement` says where it stopped and the bake stays quiet.
    pub(crate) warn_refinement: bool,
    /// `--max-elements`: refinement stops before the mesh passes this many elements (`None`:
    /// [`Settings::element_budget`]'s default).
    pub(crate) max_elements: Option<u64>,
    /// Elements are split at most this many times below the grid
    /// ([`crate::refine::MAX_LEVELS`]; `tools/accuracy-report` lowers it so that its
    /// reference mesh resolves every refined element).
    pub(crate) refine_levels: u8,
    /// Element reflectances at or above 1 are lowered to this (`--max-reflectance`, in
    /// (0, 1]; 1 keeps them, and the solver then refuses a closed scene with an emitter).
    pub(crate) max_reflectance: f64,
}

impl Settings {
    /// Refinement's element budget for a bake of `grid` elements: `--max-elements`, or by
    /// default [`crate::DEFAULT_MAX_ELEMENTS`] (the dense crossover, so that a dense bake stays
    /// dense), and on the hierarchical transport (`hierarchical`) the grid plus a quarter
    /// ([`crate::DEFAULT_GROWTH_DIVISOR`]) where that is more.
    pub fn element_budget(&self, grid: usize, hierarchical: bool) -> u64 {
        self.max_elements.unwrap_or_else(|| {
            let grid = grid as u64;
            if hierarchical {
                crate::DEFAULT_MAX_ELEMENTS
                    .max(grid.saturating_add(grid / crate::DEFAULT_GROWTH_DIVISOR))
            } else {
                crate::DEFAULT_MAX_ELEMENTS
            }
        })
    }

    /// Fills in the preset of `request.quality` and the defaults; checks the combinations.
    pub fn resolve(request: &Request, polygons: &[Polygon]) -> Result<Settings, BakeError> {
        let preset = request.quality.preset();
        let subdivision = request
            .subdivision
            .unwrap_or_else(|| Subdivision::MaxSize(preset.max_element_size(polygons)));
        let estimator = estimator(request, preset.estimator);
        check(request)?;
        let default = IterativeOptions::default();
        let iterative = |tolerance: f64| IterativeOptions {
            tolerance: request.tolerance.unwrap_or(tolerance),
            max_iterations: request.max_iterations.unwrap_or(default.max_iterations),
            ..default
        };
        let max_error = request.max_error.unwrap_or(preset.max_error);
        let hierarchical_tolerance = hierarchical_solve_tolerance(max_error);
        let (dense_solve, hierarchical_solve) = match (request.bounces, request.solver) {
            (Some(k), _) => (Solve::Bounces(k), Solve::Bounces(k)),
            (None, Some(SolverKind::Iterative)) => (
                Solve::Iterative(iterative(default.tolerance)),
                Solve::Iterative(iterative(hierarchical_tolerance)),
            ),
            (None, _) => (
                Solve::Direct,
                Solve::Iterative(iterative(hierarchical_tolerance)),
            ),
        };
        Ok(Settings {
            quality: request.quality,
            subdivision,
            subdivision_requested: request.subdivision.is_some(),
            started_finer: None,
            contour: request.contour,
            estimator,
            max_error,
            refine_target: request.max_error.unwrap_or(preset.refine_target),
            derive_tolerance: request.ff_tolerance.is_none()
                && matches!(request.ff_estimator, None | Some(EstimatorKind::Auto)),
            visibility_samples: request
                .visibility_samples
                .unwrap_or(preset.visibility_samples),
            transport: request.transport,
            dense_solve,
            hierarchical_solve,
            direct_requested: request.solver == Some(SolverKind::Direct),
            link_tolerance: request.link_tolerance,
            link_samples: request.visibility_samples.unwrap_or(preset.link_samples),
            light_samples: request.light_samples.unwrap_or(preset.light_samples),
            sky: request.sky.clone(),
            sky_samples: request.sky_samples.unwrap_or(preset.sky_samples),
            irradiance: request.irradiance,
            save_links: request.save_links,
            load_links: request.load_links.clone(),
            // Links saved or loaded are the grid's: refinement would change the mesh.
            refine: request.refine.unwrap_or(true)
                && !request.save_links
                && request.load_links.is_none(),
            refine_requested: request.refine == Some(true),
            warn_refinement: request.refine == Some(true)
                || request.max_error.is_some()
                || request.max_elements.is_some(),
            max_elements: request.max_elements,
            refine_levels: request.refine_levels.unwrap_or(crate::refine::MAX_LEVELS),
            max_reflectance: request.max_reflectance.unwrap_or(DEFAULT_MAX_REFLECTANCE),
        })
    }

    /// The sky lighting the scene (`--sky`), if any.
    pub fn sky(&self) -> Option<direct::sky::Sky> {
        self.sky.clone()
    }

    /// The hierarchical transport's link tolerance: `--link-tolerance`, else derived from
    /// `max_error`.
    pub fn link_tolerance(&self) -> transport::LinkTolerance {
        match self.link_tolerance {
            Some(t) => transport::LinkTolerance::OfMeanRadiosity(t),
            None => transport::LinkTolerance::FromMaxError(self.max_error),
        }
    }

    /// Whether refinement splits for the discretisation estimate, or only at lights' shadow
    /// edges: the preset's [`crate::presets::Preset::refine_smooth`], or always when a target
    /// was asked for ([`Settings::warn_refinement`]: `--refine on`, `--max-error`,
    /// `--max-elements`).
    pub(crate) fn refine_smooth(&self) -> bool {
        self.quality.preset().refine_smooth || self.warn_refinement
    }

    /// The solve the given transport runs with.
    pub fn solve(&self, transport: TransportKind) -> Solve {
        match transport {
            TransportKind::Hierarchical => self.hierarchical_solve,
            _ => self.dense_solve,
        }
    }

    /// The dense transport's estimator for a scene whose largest reflectance is `rho_max`:
    /// `auto` with [`crate::accuracy::pair_tolerance`] of `max_error` when
    /// [`Settings::derive_tolerance`], else [`Settings::estimator`]. Below
    /// [`form_factor::MIN_TOLERANCE`] `auto` gives every pair the contour integral.
    pub fn dense_estimator(&self, rho_max: f64) -> Estimator {
        match self.estimator {
            Estimator::Auto { .. } if self.derive_tolerance => Estimator::Auto {
                tolerance: crate::accuracy::pair_tolerance(self.max_error, rho_max),
            },
            e => e,
        }
    }

    /// The resolved options for the report's `options` object, given the transport the bake
    /// used and the estimator it used (the CLI adds its output options to it).
    pub fn to_json(&self, used: TransportKind, estimator: Estimator) -> serde_json::Value {
        let (estimator, ff_tolerance, ff_points) = match estimator {
            Estimator::Contour => ("contour", None, None),
            Estimator::PointPolygon(rule) => ("point-polygon", None, Some(rule.points())),
            Estimator::PointPoint => ("point-point", None, None),
            Estimator::Auto { tolerance } => ("auto", Some(tolerance), None),
        };
        let subdivision = match self.subdivision {
            Subdivision::Count(n) => serde_json::json!({ "subdiv": n }),
            Subdivision::MaxSize(l) => serde_json::json!({ "max_element_size": l }),
        };
        let solve = self.solve(used);
        let (tolerance, max_iterations, bounces) = match solve {
            Solve::Iterative(o) => (Some(o.tolerance), Some(o.max_iterations), None),
            Solve::Bounces(k) => (None, None, Some(k)),
            Solve::Direct => (None, None, None),
        };
        let hierarchical = used == TransportKind::Hierarchical;
        serde_json::json!({
            "quality": self.quality.name(),
            "max_error": self.max_error,
            "refine_target": self.refine_target,
            "refine_smooth": self.refine_smooth(),
            "ff_tolerance_from_max_error": used != TransportKind::Hierarchical
                && self.derive_tolerance,
            "subdivision": subdivision,
            "transport": used.name(),
            "transport_requested": self.transport.name(),
            "solver": solve.name(),
            "tolerance": tolerance,
            "max_iterations": max_iterations,
            "bounces": bounces,
            "ff_segments": self.contour.segments,
            "ff_order": self.contour.order,
            "ff_auto_order": self.contour.auto_order,
            "ff_near_ratio": self.contour.near_ratio,
            "ff_estimator": estimator,
            "ff_tolerance": ff_tolerance,
            "ff_points": ff_points,
            "visibility_samples": self.visibility_samples,
            "link_tolerance": hierarchical.then_some(self.link_tolerance).flatten(),
            "link_tolerance_from_max_error": hierarchical && self.link_tolerance.is_none(),
            "link_samples": hierarchical.then_some(self.link_samples),
            "light_samples": self.light_samples,
            "sky": self.sky,
            "sky_samples": self.sky.is_some().then_some(self.sky_samples),
            "load_links": self.load_links.as_ref().map(|p| p.to_string_lossy().into_owned()),
            "refine": self.refine,
            "started_finer_than_elements": self.started_finer.map(|(grid, _)| grid),
            "max_elements": self.max_elements,
            "max_reflectance": self.max_reflectance,
        })
    }
}

/// The form-factor estimator: explicit options over the preset's.
fn estimator(request: &Request, preset: Estimator) -> Estimator {
    let preset_tolerance = match preset {
        Estimator::Auto { tolerance } => tolerance,
        _ => form_factor::MIN_TOLERANCE,
    };
    match (request.ff_estimator, request.ff_tolerance) {
        (None, None) => preset,
        (None | Some(EstimatorKind::Auto), Some(tolerance)) => Estimator::Auto { tolerance },
        (Some(EstimatorKind::Auto), None) => Estimator::Auto {
            tolerance: preset_tolerance,
        },
        (Some(EstimatorKind::Contour), _) => Estimator::Contour,
        (Some(EstimatorKind::PointPoint), _) => Estimator::PointPoint,
        (Some(EstimatorKind::PointPolygon), _) => Estimator::PointPolygon(
            TriangleRule::from_points(request.ff_points).unwrap_or(TriangleRule::Three),
        ),
    }
}

/// The combinations and values of a request no parser checks.
fn check(request: &Request) -> Result<(), BakeError> {
    if request.transport == TransportKind::Hierarchical
        && request.solver == Some(SolverKind::Direct)
    {
        return Err(BakeError::Options(
            "--solver direct needs the dense transport (the hierarchical transport is \
             solved by GMRES); use --transport dense or --solver iterative"
                .into(),
        ));
    }
    if let Some(k) = request.bounces.filter(|&k| k > crate::MAX_BOUNCES) {
        return Err(BakeError::Options(format!(
            "--bounces must be at most {}, got {k}",
            crate::MAX_BOUNCES
        )));
    }
    if let Some(e) = request.max_error {
        if !(e.is_finite() && e > 0.0 && e < 1.0) {
            return Err(BakeError::Options(format!(
                "--max-error must be a relative error in (0, 1), got {e}"
            )));
        }
    }
    if let Some(k) = request.light_samples {
        if !(1..=1024).contains(&k) {
            return Err(BakeError::Options(format!(
                "--light-samples must be between 1 and 1024, got {k}"
            )));
        }
    }
    if let Some(k) = request.sky_samples {
        let most = direct::sky::MAX_SKY_SAMPLES;
        if !(1..=most).contains(&k) {
            return Err(BakeError::Options(format!(
                "--sky-samples must be between 1 and {most}, got {k}"
            )));
        }
    }
    if let Some(sky) = &request.sky {
        sky.check()
            .map_err(|e| BakeError::Options(format!("--sky: {e}")))?;
    }
    if (request.save_links || request.load_links.is_some())
        && (request.transport == TransportKind::Dense || request.solver == Some(SolverKind::Direct))
    {
        return Err(BakeError::Options(
            "--save-links and --load-links need the hierarchical transport (the dense one \
             has no links); leave out --transport dense and --solver direct"
                .into(),
        ));
    }
    if let Some(t) = request.link_tolerance {
        if !(t.is_finite() && t > 0.0) {
            return Err(BakeError::Options(format!(
                "--link-tolerance must be a positive number, got {t}"
            )));
        }
    }
    if request.refine == Some(true) && (request.save_links || request.load_links.is_some()) {
        return Err(BakeError::Options(
            "--refine on cannot be combined with --save-links or --load-links: links are \
             built over the element grids, which refinement changes"
                .into(),
        ));
    }
    if let Some(r) = request.max_reflectance {
        if !(r.is_finite() && r > 0.0 && r <= 1.0) {
            return Err(BakeError::Options(format!(
                "--max-reflectance must be a reflectance in (0, 1], got {r}"
            )));
        }
    }
    if request.max_elements == Some(0) {
        return Err(BakeError::Options(
            "--max-elements must be at least 1".into(),
        ));
    }
    Ok(())
}
