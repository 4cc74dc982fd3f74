//! The transport of one bake, built and solved: none when nothing emits or reflects a light
//! (b = 0 exactly), the hierarchical transport (links, or links loaded from a file), or the
//! dense one (every element pair's form factor, rows limited to 1). Each returns the same
//! [`Transported`], so `run_mesh` never matches on the kind after this.

use crate::{
    available_memory, explain_refusal, finish, links_key, load_links, row_sum_warning, solve_with,
    BakeError, Counts, Irradiance, NoTransport, Progress, SavedLinks, Settings, Solve, Stages,
    TransportKind, LINK_PASSES, ROW_SUM_WARNING_MARGIN,
};
use form_factor::{Estimator, FormFactors, Occluders, Occlusion, RowSumLimit};
use mesher::ElementMesh;
use scene::Scene;
use solver::{EnergyBalance, Solution, BANDS};
use transport::{HierarchicalOptions, HierarchicalTransport, LinkError, LinkProgress};

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
    pub rho_max: f64,
    pub solve: Solve,
    /// The dense transport's estimator (`auto`'s tolerance from the target and ρ_max).
    pub estimator: Estimator,
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
    let (h, loaded) = match &settings.load_links {
        Some(path) => {
            progress.start("loading links", 0);
            let loaded = load_links(path, p.scene, p.mesh, key);
            progress.finish();
            (loaded?, true)
        }
        None => (build_links(p, progress)?, false),
    };
    stages.record("links");
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
        blocked_links: s.blocked_links,
        polygon_pairs: s.polygon_pairs,
        clusters_dropped: s.clusters_dropped,
    };
    let effects = visibility::Effects {
        occlusion: s.pairs_occludable > 0,
        reason: if loaded {
            "links loaded: their visible fractions are those computed when they were saved"
                .to_string()
        } else if s.pairs_occludable > 0 {
            format!(
                "{} of the {} node pairs tested may be partly hidden by another polygon: \
                 shadow rays were cast for them",
                s.pairs_occludable, s.pairs_tested
            )
        } else {
            format!(
                "no polygon can come between any of the {} node pairs tested: no rays are cast",
                s.pairs_tested
            )
        },
    };
    let solution = solve_with(&h, p.solve, p.rho, p.source, progress)
        .map_err(|e| explain_refusal(e, settings, settings.estimator, p.rho_max))?;
    // The hierarchy keeps no per-polygon record: every element is charged.
    let occluded = s.pairs_occludable > 0;
    stages.record("solve");
    let (irradiance, energy) = p.finish(&h, &solution)?;
    Ok(Transported {
        solution,
        irradiance,
        energy,
        counts,
        effects,
        sampled_polygons: vec![occluded; p.scene.polygons.len()],
        samples: if occluded { settings.link_samples } else { 0 },
        row_sums: None,
        saved_links: settings
            .save_links
            .then_some(SavedLinks { key, transport: h }),
    })
}

/// Links between the coarsest node pairs that meet the link tolerance.
fn build_links(p: &Problem, progress: &dyn Progress) -> Result<HierarchicalTransport, BakeError> {
    let settings = p.settings;
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
    progress.start("links", p.scene.polygons.len() as u64);
    let built = HierarchicalTransport::build(
        &p.scene.polygons,
        p.mesh,
        p.occluders,
        p.rho,
        p.source,
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
    built.map_err(|e| match e {
        LinkError::Solve(e) => {
            explain_refusal(BakeError::Solve(e), settings, settings.estimator, p.rho_max)
        }
        e => BakeError::TooLarge(e.to_string()),
    })
}

/// Dense: every element pair, exact (or within the estimator's tolerance); rows past 1 are
/// scaled to 1 (geometry never creates light), with a warning into `warnings`.
pub(crate) fn dense(
    p: &Problem,
    progress: &dyn Progress,
    stages: &mut Stages,
    warnings: &mut Vec<String>,
) -> Result<Transported, BakeError> {
    let settings = p.settings;
    let n = p.mesh.elements.len();
    crate::check_memory(
        n as u64,
        TransportKind::Dense,
        p.solve,
        crate::distinct_bands(p.rho),
    )?;
    // The occlusion pre-pass (polygon pairs × candidate occluders) can take seconds.
    progress.start("occlusion", p.occluders.len() as u64);
    let occludable = p
        .occluders
        .occludable_pairs_with_progress(&|k| progress.advance(k));
    progress.finish();
    let effects = occludable.effects();
    let mut sampled_polygons = vec![false; p.scene.polygons.len()];
    for &(a, b) in occludable.pairs() {
        for k in [a, b] {
            if let Some(s) = sampled_polygons.get_mut(k as usize) {
                *s = true;
            }
        }
    }
    stages.record("occludable_pairs");
    let mut form_factors = FormFactors::new(p.mesh, settings.contour).with_estimator(p.estimator);
    if effects.occlusion {
        form_factors = form_factors.with_occlusion(Occlusion {
            occluders: p.occluders,
            pairs: &occludable,
            samples: settings.visibility_samples,
        });
    }
    progress.start("form factors", n as u64);
    let mut matrix = form_factors.dense_with_progress(&|rows| progress.advance(rows));
    progress.finish();
    // Geometry never creates light: rows past 1 (coincident or interpenetrating surfaces) are
    // scaled to 1, reciprocity kept.
    let limited = matrix.limit_row_sums(p.estimator.row_sum_accuracy().max(ROW_SUM_WARNING_MARGIN));
    warnings.extend(row_sum_warning(p.scene, p.mesh, &limited.beyond_margin));
    stages.record("form_factors");
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
        .with_accuracy(p.estimator.row_sum_accuracy());
    let solution = match p.solve {
        Solve::Direct => solver::solve_direct(&f, p.rho, p.source).map_err(BakeError::Solve),
        _ => solve_with(&f, p.solve, p.rho, p.source, progress),
    }
    .map_err(|e| explain_refusal(e, settings, p.estimator, p.rho_max))?;
    stages.record("solve");
    let (irradiance, energy) = p.finish(&f, &solution)?;
    Ok(Transported {
        solution,
        irradiance,
        energy,
        counts,
        effects,
        sampled_polygons,
        samples: settings.visibility_samples,
        row_sums: Some(limited),
        saved_links: None,
    })
}
