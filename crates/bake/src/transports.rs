//! The transport of one bake, built ([`transport::build`]) and solved: none when nothing
//! emits or reflects a light (b = 0 exactly), the hierarchical transport (links, or links
//! loaded from a file), or the dense one (every element pair's form factor, rows limited to
//! 1). Each returns the same [`Transported`], so `run_mesh` never matches on the kind after
//! this; after the build, the solve asks the operator whether it has entries for LU.

use crate::{
    available_memory, explain_refusal, finish, links_key, load_links, row_sum_warning, solve_with,
    BakeError, Counts, Irradiance, NoTransport, Plan, Progress, SavedLinks, Settings, Solve,
    Stages, TransportKind,
};
use form_factor::RowSumLimit;
use mesher::ElementMesh;
use scene::Scene;
use solver::{EnergyBalance, Solution, BANDS};
use transport::{Built, LinkError, Stats, View};
use visibility::Occluders;

/// What every transport is given.
pub(crate) struct Problem<'a> {
    pub scene: &'a Scene,
    pub settings: &'a Settings,
    pub mesh: &'a ElementMesh,
    pub occluders: &'a Occluders,
    pub rho: &'a [[f64; BANDS]],
    pub emission: &'a [[f64; BANDS]],
    /// The lights' irradiance H⁰ = E / π per element.
    pub external: &'a [[f64; BANDS]],
    /// e + ρ H⁰ per element.
    pub source: &'a [[f64; BANDS]],
    /// The standard error of the sky's part of `source` per element (empty without a sky).
    pub source_noise: &'a [[f64; BANDS]],
    pub rho_max: f64,
    /// The transport, solve and estimator this solve runs with.
    pub plan: &'a Plan,
}

impl Problem<'_> {
    /// `H = F b + H⁰` if asked for, and the energy balance, through `transport`.
    fn finish<T: transport::Transport>(
        &self,
        transport: &T,
        solution: &Solution,
    ) -> Result<(Option<Irradiance>, EnergyBalance), BakeError> {
        finish(
            transport,
            self.mesh,
            self.rho,
            self.emission,
            self.external,
            solution,
            self.settings,
        )
    }
}

/// What a transport produced.
pub(crate) struct Transported {
    pub solution: Solution,
    pub irradiance: Option<Irradiance>,
    pub energy: EnergyBalance,
    pub counts: Counts,
    pub effects: visibility::Effects,
    /// Per polygon: whether shadow rays decided part of its light (for the error estimate).
    pub sampled_polygons: Vec<bool>,
    /// Shadow rays per such pair.
    pub samples: u32,
    /// The dense transport's row-sum limit (what geometry would have created).
    pub row_sums: Option<RowSumLimit>,
    pub saved_links: Option<SavedLinks>,
    /// Per element and band: the irradiance the links miss, by their models and their shadow
    /// rays, and the other elements' after one reflection (hierarchical transport only;
    /// [`crate::error::LinkMisses`]).
    pub link_error: Option<[Vec<[f64; BANDS]>; 3]>,
    /// Per element and band: what its pairs or links deliver, in quadrature
    /// ([`transport::View::delivered_quadrature`]; the form-factor part of the error estimate).
    pub delivered: Vec<[f64; BANDS]>,
    /// Hierarchical transport built here: the relative link tolerance its last pass ran with
    /// and the amplification `B̄ / Ē` that pass measured.
    pub link_tolerance: Option<(f64, f64)>,
}

/// Nothing emits and no surface reflects a light's direct light: b = 0 is the exact solution,
/// and no transport needs building (a large scene without emitters would otherwise build its
/// whole matrix or hierarchy to find zeros).
pub(crate) fn dark(p: &Problem) -> Result<Transported, BakeError> {
    let n = p.mesh.elements.len();
    let solution = Solution {
        b: vec![[0.0; BANDS]; n],
        residual: [0.0; BANDS],
        residual_relative: [false; BANDS],
        factorizations: 0,
        condition: [None; BANDS],
        iterations: [0; BANDS],
    };
    let (irradiance, energy) = p.finish(&NoTransport(n), &solution)?;
    Ok(Transported {
        solution,
        irradiance,
        energy,
        counts: Counts::default(),
        effects: visibility::Effects {
            occlusion: false,
            reason: "no light to transport: no shadow rays".into(),
        },
        sampled_polygons: vec![false; p.scene.polygons.len()],
        samples: 0,
        row_sums: None,
        saved_links: None,
        link_error: None,
        delivered: vec![[0.0; BANDS]; n],
        link_tolerance: None,
    })
}

/// The hierarchical transport: links built (or loaded from `--load-links`), solved by GMRES.
pub(crate) fn hierarchical(
    p: &Problem,
    progress: &dyn Progress,
    stages: &mut Stages,
) -> Result<Transported, BakeError> {
    let settings = p.settings;
    // Hashing every polygon only when links are saved or loaded.
    let key = if settings.save_links || settings.load_links.is_some() {
        links_key(p.scene, p.mesh, settings)
    } else {
        0
    };
    let built = match &settings.load_links {
        Some(path) => {
            progress.start("loading links", 0);
            let loaded = load_links(path, p.scene, p.mesh, key);
            progress.finish();
            stages.record("links");
            let polygons = p.scene.polygons.len();
            transport::hierarchical(loaded?, polygons, settings.link_samples, true)
        }
        None => {
            let max_links = available_memory().map_or(u64::MAX, |bytes| {
                bytes / transport::hierarchical::BYTES_PER_LINK
            });
            let options = transport::Options::Hierarchical(p.plan.hierarchical_options(max_links));
            build(p, &options, progress, stages)?
        }
    };
    solved(p, built, progress, stages, key)
}

/// Dense: every element pair, exact (or within the estimator's tolerance); rows past 1 are
/// scaled to 1 (geometry never creates light), with a warning into `warnings`.
pub(crate) fn dense(
    p: &Problem,
    progress: &dyn Progress,
    stages: &mut Stages,
    warnings: &mut Vec<String>,
) -> Result<Transported, BakeError> {
    crate::check_memory(
        p.mesh.elements.len() as u64,
        TransportKind::Dense,
        p.plan.solve(),
        crate::distinct_bands(p.rho),
    )?;
    let options = transport::Options::Dense(p.plan.dense_options());
    let built = build(p, &options, progress, stages)?;
    if let Some(limited) = built.row_sums() {
        warnings.extend(row_sum_warning(p.scene, p.mesh, &limited.beyond_margin));
    }
    solved(p, built, progress, stages, 0)
}

/// Solves on a built transport (its operator checked once, for the solve and for H and the
/// energy balance) and keeps its links, under `key`, when `--save-links` asked for them.
fn solved(
    p: &Problem,
    built: Built,
    progress: &dyn Progress,
    stages: &mut Stages,
    key: u64,
) -> Result<Transported, BakeError> {
    let (solution, irradiance, energy, link_error, delivered) = {
        let view = built.operator.view().map_err(BakeError::Internal)?;
        let solution = solve(p, view, progress)?;
        stages.record("solve");
        let (irradiance, energy) = p.finish(&view, &solution)?;
        let misses = view.link_error(&solution.b);
        // The links' deliveries come with their misses; a dense matrix's rows are summed here.
        let delivered = match &misses {
            Some(m) => m.delivered.clone(),
            None => view.delivered_quadrature(&solution.b),
        };
        let link_error = misses.map(|misses| {
            // F (ρ δH): the other elements' misses of both kinds (in quadrature: independent)
            // after one reflection.
            let reflected: Vec<[f64; BANDS]> = misses
                .models
                .iter()
                .zip(&misses.visibility)
                .zip(p.rho)
                .map(|((m, v), r)| [0, 1, 2].map(|c| r[c] * m[c].hypot(v[c])))
                .collect();
            let mut carried = vec![[0.0; BANDS]; reflected.len()];
            solver::Operator::apply_bands(&view, &reflected, &mut carried);
            [misses.models, carried, misses.visibility]
        });
        (solution, irradiance, energy, link_error, delivered)
    };
    let row_sums = built.row_sums().cloned();
    let counts = counts(&built.stats);
    let link_tolerance = match &built.stats {
        Stats::Hierarchical(s) if s.relative_tolerance > 0.0 => {
            Some((s.relative_tolerance, s.amplification))
        }
        _ => None,
    };
    let saved_links = match built.operator.into_links() {
        Some(transport) if p.settings.save_links => Some(SavedLinks { key, transport }),
        _ => None,
    };
    Ok(Transported {
        solution,
        irradiance,
        energy,
        counts,
        effects: built.effects,
        sampled_polygons: built.sampled_polygons,
        samples: built.samples,
        row_sums,
        saved_links,
        link_error,
        delivered,
        link_tolerance,
    })
}

/// [`transport::build`] for this problem, its stages timed into `stages`.
fn build(
    p: &Problem,
    options: &transport::Options,
    progress: &dyn Progress,
    stages: &mut Stages,
) -> Result<Built, BakeError> {
    let problem = transport::Problem {
        polygons: &p.scene.polygons,
        mesh: p.mesh,
        occluders: p.occluders,
        rho: p.rho,
        source: p.source,
    };
    transport::build(&problem, options, progress, &mut |stage| {
        stages.record(stage)
    })
    .map_err(|e| match e {
        LinkError::Solve(e) => explain_refusal(
            BakeError::Solve(e),
            p.settings,
            p.settings.estimator,
            p.rho_max,
        ),
        // The link limit comes from the memory available (`BYTES_PER_LINK` each).
        e @ LinkError::TooManyLinks { .. } => BakeError::TooLarge(e.to_string()),
        e => BakeError::Transport(e),
    })
}

/// Solves the system on a built operator: LU where the operator has entries and the plan
/// asks for it, else through products ([`solve_with`]).
fn solve(p: &Problem, view: View, progress: &dyn Progress) -> Result<Solution, BakeError> {
    let solve = p.plan.solve();
    match (solve, view.dense()) {
        (Solve::Direct, Some(f)) => {
            solver::solve_direct(&f, p.rho, p.source).map_err(BakeError::Solve)
        }
        _ => solve_with(&view, solve, p.rho, p.source, progress),
    }
    .map_err(|e| explain_refusal(e, p.settings, p.plan.estimator(), p.rho_max))
}

/// The report's counts of what building the transport did.
fn counts(stats: &Stats) -> Counts {
    match stats {
        Stats::Dense { form_factors, .. } => Counts {
            pairs_evaluated: form_factors.pairs_integrated,
            pairs_tested: form_factors.visibility.pairs_tested,
            pairs_occludable: form_factors.visibility.pairs_occludable,
            rays_cast: form_factors.visibility.rays_cast,
            kernel_evaluations: form_factors.evaluations,
            pairs_contour: form_factors.pairs_by_method.contour,
            pairs_point_polygon: form_factors.pairs_by_method.point_polygon,
            pairs_point_point: form_factors.pairs_by_method.point_point,
            ..Counts::default()
        },
        Stats::Hierarchical(s) => Counts {
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
            refinement_passes: s.passes,
            blocked_links: s.blocked_links,
            polygon_pairs: s.polygon_pairs,
            cluster_pairs_dropped: s.clusters_dropped,
            masked_nodes: s.masked_nodes,
            mask_rays: s.mask_rays,
            ..Counts::default()
        },
    }
}
