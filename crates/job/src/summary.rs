//! The one-line summary of a finished bake (what the binary prints last).

use crate::{Exposure, Job};
use std::time::Instant;

/// `IN → OUT: polygons, elements, transport, pairs, residuals, …, seconds`.
pub(crate) fn line(
    job: &Job,
    scene: &importer::Scene,
    bake: &bake_core::Bake,
    lightmap: Option<&lightmap::Lightmap>,
    exposure: f64,
    started: Instant,
) -> String {
    let solution = &bake.solution;
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
    if matches!(bake.plan.solve(), bake_core::Solve::Iterative(_)) {
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
    if let Some(sky) = &bake.sky_stats {
        hardness += &format!(", sky ({} sky rays)", sky.rays_cast);
    }
    match job.exposure {
        Exposure::Auto => hardness += &format!(", exposure auto = {exposure:.4e}"),
        Exposure::Value(x) if x != 1.0 => hardness += &format!(", exposure {x}"),
        Exposure::Value(_) => {}
        Exposure::Ev100(n) => hardness += &format!(", exposure ev100:{n} = {exposure:.4e}"),
    }
    if let Some(built) = lightmap {
        hardness += &lightmap_part(built);
    }
    // A missing OBJ material library bakes its materials as the default grey with no
    // emission (often a black bake): said here too, where a build log's last line shows it.
    match scene.stats.material_libraries_missing {
        0 => {}
        1 => hardness += ", 1 material library missing (default grey used)",
        n => hardness += &format!(", {n} material libraries missing (default grey used)"),
    }
    format!(
        "{} → {}: {} polygons, {} elements, {} transport, {} pairs integrated, residual {:.1e}/{:.1e}/{:.1e}{hardness}, {:.2} s",
        job.input.display(),
        job.output.display(),
        scene.polygons.len(),
        bake.mesh.elements.len(),
        bake.plan.transport().kind.name(),
        bake.counts.pairs_evaluated,
        r[0],
        r[1],
        r[2],
        started.elapsed().as_secs_f64()
    )
}

/// `, lightmap W×H (texel t, o% occupied, layout)`.
fn lightmap_part(built: &lightmap::Lightmap) -> String {
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
    format!(
        ", lightmap {atlases}{} (texel {:.6}, {:.1}% occupied, {layout})",
        sizes.join(" + "),
        built.texel_size,
        100.0 * built.stats.occupancy
    )
}
