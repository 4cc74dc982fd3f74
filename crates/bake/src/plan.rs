//! One solve's plan: which transport and why, the solver, the form-factor estimator and the
//! chosen transport's build options (tolerances, samples, the link budget), decided from the
//! resolved [`Settings`] and a [`SceneSummary`] before anything is built. The plan is what a
//! bake reports as its `options` ([`Plan::options_json`]), and what the transport stage reads:
//! `run_mesh` asks it, instead of matching the settings against the transport kind.
//!
//! A refining bake makes one plan per solve (the element count changes).

use crate::cost::{self, Costs};
use crate::{
    accuracy, check_memory, BakeError, Settings, Solve, TransportChoice, TransportKind,
    BRIGHT_AMPLIFICATION, BRIGHT_DENSE_MAX, DENSE_AUTO_MAX, DENSE_CROSSOVER, LINK_PASSES,
    OCCLUDED_MAX_ELEMENTS, ROW_SUM_WARNING_MARGIN, SMALL_SCENE_ELEMENTS,
};
use form_factor::Estimator;
use transport::{DenseOptions, HierarchicalOptions};

/// What a plan needs to know of the scene before meshing: sizes and the reflectance bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneSummary {
    /// Elements the mesh will have.
    pub elements: u64,
    /// Elements of the mesher's grids (before any refinement): the transport is chosen for
    /// them, so that every solve of a refining bake gets the same one.
    pub grid_elements: u64,
    /// Whether the scene has punctual lights (whose shadow edges refinement follows even
    /// where it does not refine smooth light).
    pub lights: bool,
    /// The largest reflectance any surface can have (textures included), after
    /// `--max-reflectance`.
    pub rho_bound: f64,
    /// Distinct reflectance bands (1 for a grey scene): LU copies a direct solve needs.
    pub bands: usize,
    /// Whether some polygon can come between two others (asked only of scenes the dense
    /// transport could take under `auto`, at most [`DENSE_AUTO_MAX`] elements; false
    /// otherwise).
    pub occluded: bool,
}

/// One solve's plan (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    settings: Settings,
    transport: TransportChoice,
    solve: Solve,
    estimator: Estimator,
    /// The hierarchy chosen for a small scene with occlusion (then a dense bake is the
    /// fallback when it has no solution).
    small_occluded: bool,
    /// The hierarchy `auto` chose for a scene of at most [`SMALL_SCENE_ELEMENTS`]: refined by
    /// default, up to twice its grid's elements and at least [`OCCLUDED_MAX_ELEMENTS`].
    small: bool,
}

impl Plan {
    /// The plan for `scene` under `settings`: the transport and why, the solve, and a memory
    /// check of both. A warning goes to `warnings` when the hierarchy's link tolerance cannot
    /// promise `--max-error` on so bright a scene.
    pub(crate) fn new(
        settings: &Settings,
        scene: &SceneSummary,
        warnings: &mut Vec<String>,
    ) -> Result<Plan, BakeError> {
        let rho_bound = scene.rho_bound;
        let n = usize::try_from(scene.elements).unwrap_or(usize::MAX);
        let transport = choose_transport(settings, scene);
        let small_occluded = transport.kind == TransportKind::Hierarchical
            && settings.transport == TransportKind::Auto
            && scene.occluded
            && n <= DENSE_CROSSOVER;
        let small = transport.kind == TransportKind::Hierarchical
            && settings.transport == TransportKind::Auto
            && n <= SMALL_SCENE_ELEMENTS;
        let risk = LinkRisk::of(settings, rho_bound);
        if transport.kind == TransportKind::Hierarchical && risk.bright {
            warnings.push(format!(
                "reflectances up to {rho_bound} amplify errors up to {:.0}x: the hierarchical \
                 transport's link tolerance ({}) may leave b far from --max-error {:e} (a \
                 smaller --max-error, or --transport dense where memory allows, tightens it)",
                risk.amplification,
                risk.describe(),
                settings.max_error
            ));
        }
        let solve = settings.solve(transport.kind);
        check_memory(scene.elements, transport.kind, solve, scene.bands)?;
        Ok(Plan {
            settings: settings.clone(),
            transport,
            solve,
            estimator: settings.estimator,
            small_occluded,
            small,
        })
    }

    /// The form-factor estimator once the elements' largest reflectance is known: the dense
    /// transport's `auto` tolerance from the target and `rho_max`; the hierarchy's as set.
    pub(crate) fn with_rho_max(self, rho_max: f64) -> Plan {
        let estimator = match self.transport.kind {
            TransportKind::Hierarchical => self.settings.estimator,
            _ => self.settings.dense_estimator(rho_max),
        };
        Plan { estimator, ..self }
    }

    /// The transport `auto` chose first could not be solved and this plan's replaced it
    /// (`why`, in the reason).
    pub(crate) fn fell_back(&mut self, why: &str) {
        self.transport.reason = format!("{}; {why}", self.transport.reason);
    }

    /// Nothing emits or reflects a light: no transport is built (said in the reason).
    pub(crate) fn not_built(&mut self) {
        self.transport.reason = format!(
            "{}; not built: nothing emits or reflects direct light, so b = 0 exactly",
            self.transport.reason
        );
    }

    /// Whether refinement runs without being asked for: always on the dense transport, and on
    /// the hierarchy that `auto` chose for a scene of at most [`SMALL_SCENE_ELEMENTS`] (else
    /// each refining solve of a large scene would link it again).
    pub fn refines_by_default(&self) -> bool {
        self.transport.kind != TransportKind::Hierarchical || self.small
    }

    /// Whether this is the hierarchy `auto` chose for a scene of at most
    /// [`SMALL_SCENE_ELEMENTS`] (refined by default, as far as the dense transport refines).
    pub fn small(&self) -> bool {
        self.small
    }

    /// Whether this is the hierarchy `auto` chose for a small scene with occluders.
    pub(crate) fn small_occluded(&self) -> bool {
        self.small_occluded
    }

    /// Refinement's element budget from a bake of `grid` elements: `--max-elements`, else
    /// twice the grid and at least [`OCCLUDED_MAX_ELEMENTS`] for a small scene on the hierarchy
    /// (`auto`), else [`Settings::element_budget`]'s default.
    pub fn element_budget(&self, grid: usize) -> u64 {
        budget(
            &self.settings,
            grid as u64,
            self.transport.kind == TransportKind::Hierarchical,
            self.small,
        )
    }

    /// The transport and why.
    pub fn transport(&self) -> &TransportChoice {
        &self.transport
    }

    /// The solve.
    pub fn solve(&self) -> Solve {
        self.solve
    }

    /// The form-factor estimator (under the dense transport with `auto`, its tolerance is the
    /// one the target chose).
    pub fn estimator(&self) -> Estimator {
        self.estimator
    }

    /// The settings the plan was made from.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The dense transport's build options.
    pub(crate) fn dense_options(&self) -> DenseOptions {
        DenseOptions {
            estimator: self.estimator,
            contour: self.settings.contour,
            samples: self.settings.visibility_samples,
            row_sum_margin: self
                .estimator
                .row_sum_accuracy()
                .max(ROW_SUM_WARNING_MARGIN),
        }
    }

    /// The hierarchical transport's build options, keeping at most `max_links` links.
    pub(crate) fn hierarchical_options(&self, max_links: u64) -> HierarchicalOptions {
        HierarchicalOptions {
            link_tolerance: self.settings.link_tolerance(),
            samples: self.settings.link_samples,
            estimator: self.settings.estimator,
            contour: self.settings.contour,
            passes: LINK_PASSES,
            max_links,
            shadow_masks: true,
        }
    }

    /// The report's `options`: the settings as resolved, with the transport and estimator
    /// this plan chose.
    pub fn options_json(&self) -> serde_json::Value {
        self.settings.to_json(self.transport.kind, self.estimator)
    }
}

/// What the hierarchy's links could cost b, a priori: their tolerance amplified by the
/// condition bound, against the target.
struct LinkRisk {
    /// [`accuracy::condition_bound`] of the reflectance bound.
    amplification: f64,
    /// The error of b one link's tolerance could become.
    amplified: f64,
    /// Whether that passes `--max-error` on a scene bright enough to matter
    /// ([`BRIGHT_AMPLIFICATION`]).
    bright: bool,
    /// `--link-tolerance`, when given.
    explicit: Option<f64>,
}

impl LinkRisk {
    fn of(settings: &Settings, rho_bound: f64) -> LinkRisk {
        let amplification = accuracy::condition_bound(rho_bound, 0.0);
        let amplified = match settings.link_tolerance {
            Some(t) => amplification * rho_bound * t,
            // ε = E B̄ / a with the measured amplification a ≈ 1 / (1 − ρ) of a grey scene,
            // at most MAX_AMPLIFICATION (transport::LinkTolerance::FromMaxError).
            // (ρ = 1 gives ∞, clamped to the cap.)
            None => {
                let measured = (1.0 / (1.0 - rho_bound)).clamp(1.0, transport::MAX_AMPLIFICATION);
                amplification * rho_bound * settings.max_error / measured
            }
        };
        LinkRisk {
            amplification,
            amplified,
            bright: amplification >= BRIGHT_AMPLIFICATION && amplified > settings.max_error,
            explicit: settings.link_tolerance,
        }
    }

    fn describe(&self) -> String {
        match self.explicit {
            Some(t) => format!("--link-tolerance {t}"),
            None => format!(
                "from --max-error, with amplification at most {}",
                transport::MAX_AMPLIFICATION
            ),
        }
    }
}

/// What each transport would cost `scene` under `settings` ([`crate::cost`]): the dense one
/// refined to its element budget, the hierarchy refined to its own where `auto` would refine
/// it (a scene of at most [`SMALL_SCENE_ELEMENTS`]), each from the grids' elements, when
/// refinement is on and has something to follow (smooth light, or lights' shadow edges).
pub fn costs(settings: &Settings, scene: &SceneSummary) -> Costs {
    let grid = scene.grid_elements;
    let grows = settings.refine
        && !settings.save_links
        && settings.load_links.is_none()
        && (settings.refine_smooth() || scene.lights);
    let dense_budget = budget(settings, grid, false, false);
    let dense_refines = grows && dense_budget > grid;
    let small = grid <= SMALL_SCENE_ELEMENTS as u64;
    let hierarchical_budget = budget(settings, grid, true, small);
    let hierarchical_refines = grows
        && (small || settings.refine_requested || settings.max_elements.is_some())
        && hierarchical_budget > grid;
    Costs::estimate(&cost::Inputs {
        dense_elements: if dense_refines { dense_budget } else { grid },
        dense_refines,
        hierarchical_elements: if hierarchical_refines {
            hierarchical_budget
        } else {
            grid
        },
        hierarchical_refines,
        occluded: scene.occluded,
        samples: settings.visibility_samples,
        max_error: links_error(settings, scene.rho_bound),
    })
}

/// Refinement's element budget from `grid` elements: `--max-elements`, else twice the grid and
/// at least [`OCCLUDED_MAX_ELEMENTS`] for a `small` scene on the hierarchy (`auto`), else
/// [`Settings::element_budget`]'s default.
fn budget(settings: &Settings, grid: u64, hierarchical: bool, small: bool) -> u64 {
    match settings.max_elements {
        None if hierarchical && small => OCCLUDED_MAX_ELEMENTS.max(2 * grid),
        _ => settings.element_budget(grid as usize, hierarchical),
    }
}

/// The `--max-error` the hierarchy's links are built for: an explicit `--link-tolerance` t is
/// the E whose derived tolerance it equals, `ε / B̄ = E / a` with the amplification a of a grey
/// scene of the reflectance bound, `1 / (1 − ρ)` (at most [`transport::MAX_AMPLIFICATION`]).
fn links_error(settings: &Settings, rho_bound: f64) -> f64 {
    match settings.link_tolerance {
        Some(t) => t * (1.0 / (1.0 - rho_bound)).clamp(1.0, transport::MAX_AMPLIFICATION),
        None => settings.max_error,
    }
}

/// Which transport `settings` asks for on `scene`, and why.
fn choose_transport(settings: &Settings, scene: &SceneSummary) -> TransportChoice {
    let n = usize::try_from(scene.elements).unwrap_or(usize::MAX);
    let rho_bound = scene.rho_bound;
    let risk = LinkRisk::of(settings, rho_bound);
    let (amplification, amplified, bright) = (risk.amplification, risk.amplified, risk.bright);
    if let Some(path) = &settings.load_links {
        return TransportChoice {
            kind: TransportKind::Hierarchical,
            reason: format!("links loaded from {}", path.display()),
        };
    }
    match settings.transport {
        TransportKind::Dense => TransportChoice {
            kind: TransportKind::Dense,
            reason: "--transport dense".into(),
        },
        TransportKind::Hierarchical => TransportChoice {
            kind: TransportKind::Hierarchical,
            reason: "--transport hierarchical".into(),
        },
        TransportKind::Auto if settings.save_links => TransportChoice {
            kind: TransportKind::Hierarchical,
            reason: "--save-links: the links are the hierarchical transport's".into(),
        },
        TransportKind::Auto if settings.direct_requested => TransportChoice {
            kind: TransportKind::Dense,
            reason: "--solver direct needs the dense transport".into(),
        },
        TransportKind::Auto if n <= BRIGHT_DENSE_MAX && bright => TransportChoice {
            kind: TransportKind::Dense,
            reason: format!(
                "reflectances up to {rho_bound} amplify errors up to {:.0}×: the hierarchy's \
                 link tolerance ({}) could cost b {amplified:.1e}, more than --max-error {:e}; \
                 the dense transport meets it (up to {BRIGHT_DENSE_MAX} elements)",
                amplification,
                risk.describe(),
                settings.max_error
            ),
        },
        TransportKind::Auto if n > DENSE_AUTO_MAX => TransportChoice {
            kind: TransportKind::Hierarchical,
            reason: format!(
                "{n} elements, more than the dense transport takes under auto \
                 ({DENSE_AUTO_MAX}): the hierarchical transport's links grow about linearly \
                 with the elements, the dense one's pairs quadratically"
            ),
        },
        TransportKind::Auto => {
            let costs = costs(settings, scene);
            let kind = costs.cheaper();
            let why = match kind {
                TransportKind::Dense if costs.dense.seconds > costs.hierarchical.seconds => {
                    format!(
                        "both cheap (under {} s): the dense transport is exact",
                        cost::DENSE_AFFORDABLE_S
                    )
                }
                TransportKind::Dense => "the dense transport is cheaper, and exact".into(),
                _ if scene.occluded => "the hierarchy is cheaper: the dense transport would \
                     cast shadow rays for every element pair some polygon can come between, \
                     the hierarchy only per link"
                    .into(),
                _ => "the hierarchy is cheaper: its links grow about linearly with the \
                     elements, the dense transport's pairs quadratically"
                    .into(),
            };
            TransportChoice {
                kind,
                reason: format!(
                    "{} elements on the grids, {}: {why}",
                    scene.grid_elements,
                    costs.describe()
                ),
            }
        }
    }
}

/// Where no polygon can come between two others and no punctual light casts a shadow, the light
/// is smooth everywhere: refinement has only gentle gradients to follow, and a uniform grid of
/// as many elements as it would reach is more accurate for its time. Measured on the paper's
/// cube at `--quality normal` (issue 31, docs/accuracy.md): refined from 600 to 3 999 elements,
/// 1.92e-2 RMS on the displayed field in 0.17 s; uniform at 4 056 elements, 1.72e-2 in 0.10 s;
/// refined from a finer grid (2 166 → 4 332), 1.77e-2 in 0.22 s.
///
/// So a bake that would refine smooth light from the preset's grid on the hierarchy `auto`
/// gives a small scene ([`Plan::small`]), with nothing to occlude and no lights, starts at the
/// element budget instead and is not refined: this returns those settings (the element size
/// whose grids stay within the budget, refinement off, and [`Settings::started_finer`] saying
/// so), or `None` where the rule does not apply. An element size, `--refine on`, a target or a
/// budget the user gave keeps the preset's way (refinement from the grid).
pub(crate) fn finer_start(
    settings: &Settings,
    scene: &SceneSummary,
    polygons: &[scene::Polygon],
) -> Result<Option<Settings>, BakeError> {
    // `settings.refine` is off when links are saved or loaded; `plan.small()` below holds
    // only under `--transport auto`, where `scene.occluded` is asked.
    let applies = settings.refine
        && settings.refine_smooth()
        && !settings.warn_refinement
        && !settings.subdivision_requested
        && !scene.lights
        && !scene.occluded;
    let mesher::Subdivision::MaxSize(size) = settings.subdivision else {
        return Ok(None);
    };
    if !applies {
        return Ok(None);
    }
    let plan = Plan::new(settings, scene, &mut Vec::new())?;
    if !plan.small() {
        return Ok(None);
    }
    let grid = scene.grid_elements;
    let budget = plan.element_budget(grid as usize);
    if budget <= grid {
        return Ok(None);
    }
    // The smallest element size whose grids stay within the budget (the count falls as the
    // size grows): bisection, in log size, between a size whose grids pass the budget and
    // the preset's, whose grids do not.
    let count = |l: f64| mesher::element_count(polygons, mesher::Subdivision::MaxSize(l));
    let mut within = size;
    let mut over = size * (grid as f64 / budget as f64).sqrt() / 2.0;
    if count(over)? <= budget {
        return Ok(None);
    }
    for _ in 0..40 {
        let mid = (within * over).sqrt();
        if count(mid)? <= budget {
            within = mid;
        } else {
            over = mid;
        }
    }
    Ok(Some(Settings {
        subdivision: mesher::Subdivision::MaxSize(within),
        refine: false,
        started_finer: Some((grid, budget)),
        ..settings.clone()
    }))
}
