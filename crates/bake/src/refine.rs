//! Refinement where the light changes: the paper's "smarter subdivision algorithm to obtain
//! finer meshes in regions of high intensity gradients" (Goral et al. 1984, §6).
//!
//! After a solve, an element is marked when
//! - a light's shadow edge crosses it ([`Bake::partly_lit`]: a sun's exact lit share, or a
//!   point or spot light's shadow rays, strictly between 0 and 1) and the jump in `b` to its
//!   neighbours exceeds the target, or
//! - its discretisation estimate ([`crate::error`]: `b` against the plane through its
//!   neighbours) exceeds the target, with neighbours taken on its own side of every shadow
//!   edge only (a step is not a gradient a finer mesh would follow),
//!
//! where the target is `--max-error` (the preset's refinement target when it is not given:
//! [`crate::presets::Preset::refine_target`]) times the area-weighted mean of `b`'s brightest
//! band. The second kind only with [`crate::presets::Preset::refine_smooth`] (not `draft`'s,
//! unless a target was asked for).
//! Marked elements are split (quads 2 × 2, triangles into 4, [`mesher::ElementMesh::refine`]),
//! worst first within the element budget (`--max-elements`), at most [`MAX_LEVELS`] times
//! below the grid, and the scene is solved again on the new mesh (either transport: the
//! hierarchical one's trees continue below the grid elements into their quarters; it refines
//! only when asked, `--refine on` or `--max-elements`, and at most [`MAX_HIERARCHICAL_PASSES`]
//! solves, since each links the whole scene again — except a small scene `auto` gave it,
//! which refines by default and as far as on the dense transport). This
//! repeats until nothing is marked, the budget is reached (a warning names where, when the user
//! asked for a target: [`crate::Settings::warn_refinement`]), or
//! [`MAX_PASSES`] solves ran. Where the light is smooth nothing is marked. A small scene
//! whose light is smooth everywhere (nothing occludes, no punctual light) is not refined at
//! all: it starts at the budget's uniform grid instead (`crate::plan::finer_start`). Finally each vertex
//! gets one copy per side of every shadow edge ([`mesher::ElementMesh::split_at_discontinuities`]),
//! so smoothing never blends lit and shadowed elements.

use crate::{error, run_mesh, Bake, BakeError, Progress, Settings, TransportKind};
use scene::Scene;
use std::time::Instant;
use visibility::Occluders;

/// Elements are split at most this many times below the mesher's grid (to 1/32 of its size).
pub const MAX_LEVELS: u8 = 5;

/// The most solves a refining bake runs (the first on the grid included).
pub const MAX_PASSES: u32 = 8;

/// The most solves of a refining bake on the hierarchical transport, each of which links the
/// whole scene again (the grid's included), unless the scene is small
/// ([`crate::Plan::small`]: then [`MAX_PASSES`]).
pub const MAX_HIERARCHICAL_PASSES: u32 = 3;

/// What refinement did: the report's `refinement` object.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Refinement {
    /// Whether refinement was on and could run (dense transport).
    pub enabled: bool,
    /// Solves after the first, on refined meshes.
    pub passes: u32,
    pub elements_before: usize,
    pub elements_after: usize,
    /// The element budget ([`crate::Settings::element_budget`]; absent in older reports).
    #[serde(default)]
    pub budget: u64,
    /// Elements split, over all passes.
    pub split: usize,
    /// Elements still above the target at the end (at the finest level, or past the budget);
    /// shadow-edge elements at the finest level are not counted (a step stays a step).
    pub above_target: usize,
    /// Vertices given a copy per side of a shadow edge, and the edges between them.
    pub discontinuity_vertices: usize,
    pub discontinuity_edges: usize,
    /// Why it stopped.
    pub stopped: String,
}

/// The elements refinement wants split this pass.
struct Marks {
    /// Per element: its error over the target (> 1: wants splitting).
    priority: Vec<f64>,
    /// Elements above the target that may still be split.
    wanted: Vec<usize>,
    /// Elements above the target at the finest level (shadow-edge elements excluded).
    at_finest: usize,
    /// Elements above the target off shadow edges, left as they are without
    /// [`Settings::refine_smooth`].
    smooth: usize,
}

/// The target of one bake: `--max-error` (or the preset's refinement target) × the
/// area-weighted mean of the brightest band of b.
fn target(bake: &Bake, settings: &Settings) -> f64 {
    let (mut sum, mut area) = (0.0, 0.0);
    for (e, b) in bake.mesh.elements.iter().zip(&bake.solution.b) {
        sum += e.area * b[0].max(b[1]).max(b[2]);
        area += e.area;
    }
    if area > 0.0 {
        settings.refine_target * sum / area
    } else {
        0.0
    }
}

fn marks(bake: &Bake, settings: &Settings) -> Marks {
    use rayon::prelude::*;
    let mesh = &bake.mesh;
    let b = &bake.solution.b;
    let n = mesh.elements.len();
    let target = target(bake, settings);
    let class = &bake.shadow_class;
    let same_side = error::neighbours_where(mesh, |i, j| class.get(i) == class.get(j));
    let all = error::neighbours(mesh);
    let brightest = |v: [f64; 3]| v[0].max(v[1]).max(v[2]);
    let priority: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| {
            if target.is_nan() || target <= 0.0 {
                return 0.0;
            }
            let err = if bake.partly_lit.get(i) == Some(&true) {
                // The step it straddles.
                all[i]
                    .iter()
                    .map(|&j| brightest([0, 1, 2].map(|c| (b[j as usize][c] - b[i][c]).abs())))
                    .fold(0.0, f64::max)
            } else {
                brightest(error::discretisation(mesh, b, i, &same_side[i]))
            };
            err / target
        })
        .collect();
    let mut wanted = Vec::new();
    let mut at_finest = 0;
    let mut smooth = 0;
    let refine_smooth = settings.refine_smooth();
    for (i, &p) in priority.iter().enumerate() {
        if p.is_nan() || p <= 1.0 {
            continue;
        }
        if !refine_smooth && bake.partly_lit.get(i) != Some(&true) {
            smooth += 1;
            continue;
        }
        if mesh.level(i) < settings.refine_levels {
            wanted.push(i);
        } else if bake.partly_lit.get(i) != Some(&true) {
            at_finest += 1;
        }
    }
    // Worst first; ties in element order (deterministic).
    wanted.sort_by(|&a, &b| priority[b].total_cmp(&priority[a]).then(a.cmp(&b)));
    Marks {
        priority,
        wanted,
        at_finest,
        smooth,
    }
}

/// Where the elements still above the target are: the polygon with most of them and its
/// material, for a warning.
fn where_above(scene: &Scene, bake: &Bake, elements: &[usize]) -> String {
    let mut count = std::collections::BTreeMap::<u32, usize>::new();
    for &i in elements {
        *count.entry(bake.mesh.elements[i].polygon).or_default() += 1;
    }
    let Some((&polygon, &k)) = count.iter().max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(a.0))) else {
        return String::new();
    };
    let material = scene
        .polygons
        .get(polygon as usize)
        .and_then(|p| scene.materials.get(p.material).map(|m| (p.material, m)));
    let name = match material {
        Some((_, m)) if m.name.is_some() => {
            format!("material '{}'", m.name.as_deref().unwrap_or(""))
        }
        Some((k, _)) => format!("material {k}"),
        None => "no material".into(),
    };
    format!(
        "{} of them on polygon {polygon} ({name}){}",
        k,
        if count.len() > 1 {
            format!(", the rest on {} other polygons", count.len() - 1)
        } else {
            String::new()
        }
    )
}

/// Why `bake` is not refined at all, if it is not: refinement off, links saved or loaded, or
/// a hierarchical bake that did not ask for it.
fn not_refined(settings: &Settings, bake: &Bake) -> Option<String> {
    if let Some((grid, budget)) = settings.started_finer {
        return Some(format!(
            "started finer instead: nothing occludes and no light casts a shadow, so the light \
             is smooth, and a uniform grid at the element budget ({budget}) is more accurate \
             for its time than refining the preset's grid of {grid} elements"
        ));
    }
    if !settings.refine {
        return Some("--refine off".into());
    }
    if settings.save_links || settings.load_links.is_some() {
        // Saved links are keyed by the grids (and loaded ones were made over them).
        return Some("not refined: --save-links and --load-links keep the grids".into());
    }
    if !bake.plan.refines_by_default()
        && !settings.refine_requested
        && settings.max_elements.is_none()
    {
        // Each solve of a refining hierarchical bake links the whole scene again: a
        // walkthrough's default bake stays one solve, and `--refine on` asks for more.
        return Some(
            "not refined by default on the hierarchical transport (each refinement solve links \
             the scene again): --refine on or --max-elements asks for it"
                .into(),
        );
    }
    None
}

/// What one refinement pass decides.
enum Step {
    /// Split the first this many of the wanted elements.
    Split(usize),
    /// Stop: how many elements are still above the target, why (for the report), and the
    /// warning that says where (when `--max-error` or `--max-elements` was asked for).
    Stop {
        above: usize,
        stopped: String,
        warning: Option<String>,
    },
}

/// Whether to split and how many, within the element `budget` and `max_passes` solves.
fn step(
    scene: &Scene,
    settings: &Settings,
    bake: &Bake,
    m: &Marks,
    (budget, passes, max_passes): (u64, u32, u32),
) -> Step {
    let n = bake.mesh.elements.len();
    let warn = settings.warn_refinement;
    if m.wanted.is_empty() {
        if m.at_finest == 0 && m.smooth == 0 {
            return Step::Stop {
                above: 0,
                stopped: "the estimate meets the target".to_string(),
                warning: None,
            };
        }
        if m.at_finest == 0 {
            return Step::Stop {
                above: m.smooth,
                stopped: "shadow edges resolved; the preset refines nothing else (--refine on \
                          refines for the estimate too)"
                    .to_string(),
                warning: None,
            };
        }
        let at: Vec<usize> = (0..n)
            .filter(|&i| {
                m.priority[i] > 1.0
                    && bake.mesh.level(i) >= settings.refine_levels
                    && bake.partly_lit.get(i) != Some(&true)
            })
            .collect();
        return Step::Stop {
            above: m.at_finest + m.smooth,
            stopped: "finest level reached".to_string(),
            warning: warn.then(|| {
                format!(
                    "refinement reached its finest elements (1/{} of the grid's) with {} elements \
                 still above --max-error {:e}: {}",
                    1u64 << settings.refine_levels.min(63),
                    m.at_finest,
                    settings.refine_target,
                    where_above(scene, bake, &at)
                )
            }),
        };
    }
    let room = (budget.saturating_sub(n as u64) / 3) as usize;
    if room == 0 || passes + 1 >= max_passes {
        let why = if room == 0 {
            format!("the element budget --max-elements {budget}")
        } else {
            format!("{max_passes} solves")
        };
        return Step::Stop {
            above: m.wanted.len() + m.at_finest + m.smooth,
            warning: warn.then(|| {
                format!(
                    "refinement stopped at {why} ({n} elements) with {} elements still above \
                 --max-error {:e}: {}",
                    m.wanted.len(),
                    settings.refine_target,
                    where_above(scene, bake, &m.wanted)
                )
            }),
            stopped: format!("stopped at {why}"),
        };
    }
    // Where the budget cuts, elements tied with the first one left out (within 1e-9: mirror
    // images of a symmetric scene) are left out too, so that refinement keeps symmetries.
    let mut chosen = m.wanted.len().min(room);
    if chosen < m.wanted.len() {
        let cut = m.priority[m.wanted[chosen]] * (1.0 + 1e-9);
        chosen = m.wanted[..chosen]
            .iter()
            .take_while(|&&i| m.priority[i] > cut)
            .count();
    }
    if chosen > 0 {
        return Step::Split(chosen);
    }
    Step::Stop {
        above: m.wanted.len() + m.at_finest + m.smooth,
        warning: warn.then(|| {
            format!(
                "refinement stopped at the element budget --max-elements {} ({n} elements): \
             splitting any of the {} elements above --max-error {:e} (tied, e.g. mirror \
             images) would pass it: {}",
                budget,
                m.wanted.len(),
                settings.refine_target,
                where_above(scene, bake, &m.wanted)
            )
        }),
        stopped: format!("stopped at the element budget --max-elements {budget}"),
    }
}

/// Adds `more` stage times to `timings` (summing a stage that is there already).
fn add_timings(timings: &mut Vec<(&'static str, f64)>, more: &[(&'static str, f64)]) {
    for &(name, t) in more {
        match timings.iter_mut().find(|(n, _)| *n == name) {
            Some(slot) => slot.1 += t,
            None => timings.push((name, t)),
        }
    }
}

/// Refines `first` (a bake on the grids) as the module docs say; returns it unchanged when
/// refinement is off, links are saved or loaded, or a hierarchical bake did not ask for it.
pub fn refine(
    scene: &Scene,
    settings: &Settings,
    progress: &dyn Progress,
    first: Bake,
    occluders: &Occluders,
) -> Result<Bake, BakeError> {
    let mut bake = first;
    let before = bake.mesh.elements.len();
    bake.refinement.elements_before = before;
    bake.refinement.elements_after = before;
    if let Some(why) = not_refined(settings, &bake) {
        bake.refinement.stopped = why;
        if let Some((_, budget)) = settings.started_finer {
            bake.refinement.budget = budget;
        }
        return Ok(bake);
    }
    let hierarchical = bake.plan.transport().kind == TransportKind::Hierarchical;
    // Every solve of a hierarchical bake links the whole scene again: fewer of them, except
    // on a small scene (`auto`'s, at most SMALL_SCENE_ELEMENTS on its grids), which links in
    // a fraction of a second and refines like the dense transport.
    let max_passes = if hierarchical && !bake.plan.small() {
        MAX_HIERARCHICAL_PASSES
    } else {
        MAX_PASSES
    };
    let budget = bake.plan.element_budget(before);
    let mut timings: Vec<(&'static str, f64)> = bake.timings.clone();
    let mut passes = 0;
    let mut split = 0;
    let (above, stopped) = loop {
        let lap = Instant::now();
        let m = marks(&bake, settings);
        let chosen = match step(scene, settings, &bake, &m, (budget, passes, max_passes)) {
            Step::Split(chosen) => chosen,
            Step::Stop {
                above,
                stopped,
                warning,
            } => {
                bake.warnings.extend(warning);
                break (above, stopped);
            }
        };
        let mut marked = vec![false; bake.mesh.elements.len()];
        for &i in m.wanted.iter().take(chosen) {
            marked[i] = true;
        }
        let refined = bake.mesh.refine(&marked)?.mesh;
        let spent = lap.elapsed().as_secs_f64();
        let mut next = run_mesh(scene, settings, progress, Some(refined), occluders)?;
        add_timings(&mut timings, &[("refine", spent)]);
        add_timings(&mut timings, &next.timings);
        for w in std::mem::take(&mut bake.warnings) {
            if !next.warnings.contains(&w) {
                next.warnings.insert(0, w);
            }
        }
        bake = next;
        passes += 1;
        split += chosen;
    };
    let lap = Instant::now();
    let mesh = bake.mesh.split_at_discontinuities(&bake.shadow_class);
    let discontinuity_vertices = mesh.vertices.len() - bake.mesh.vertices.len();
    let discontinuity_edges = mesh.discontinuities.len();
    bake.mesh = mesh;
    add_timings(
        &mut timings,
        &[("discontinuities", lap.elapsed().as_secs_f64())],
    );
    bake.timings = timings;
    bake.refinement = Refinement {
        enabled: true,
        passes,
        elements_before: before,
        elements_after: bake.mesh.elements.len(),
        budget,
        split,
        above_target: above,
        discontinuity_vertices,
        discontinuity_edges,
        stopped,
    };
    Ok(bake)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Request;

    /// Splitting every element of the cube's 4 × 4 grids once gives the 8 × 8 grids' elements
    /// (midpoints are grid points): the bake on the refined mesh must agree with the bake on
    /// the 8 × 8 grid element by element (the transport takes any mesh; only the rounding of
    /// the vertex positions differs).
    #[test]
    fn a_mesh_refined_everywhere_bakes_like_the_finer_grid() {
        let scene = importer::load(&bake_testkit::fixture("cube.gltf")).expect("the cube");
        let settings = |n| {
            let request = Request {
                subdivision: Some(mesher::Subdivision::Count(n)),
                refine: Some(false),
                ..Request::default()
            };
            Settings::resolve(&request, &scene.polygons).expect("settings")
        };
        let coarse = mesher::mesh(&scene.polygons, mesher::Subdivision::Count(4)).expect("mesh");
        let refined = coarse
            .refine(&vec![true; coarse.elements.len()])
            .expect("refine")
            .mesh;
        let occluders = visibility::Occluders::new(&scene.polygons).expect("occluders");
        let on_refined = run_mesh(
            &scene,
            &settings(8),
            &crate::Silent,
            Some(refined),
            &occluders,
        )
        .expect("bake");
        let fine = run_mesh(&scene, &settings(8), &crate::Silent, None, &occluders).expect("bake");
        assert_eq!(on_refined.mesh.elements.len(), fine.mesh.elements.len());
        let key = |c: glam::DVec3| (c * 1e6).round().to_array().map(|x| x as i64);
        let at: std::collections::HashMap<_, _> = fine
            .mesh
            .elements
            .iter()
            .zip(&fine.solution.b)
            .map(|(e, b)| (key(e.centroid), *b))
            .collect();
        for (e, b) in on_refined.mesh.elements.iter().zip(&on_refined.solution.b) {
            let want = at.get(&key(e.centroid)).expect("the same element");
            for c in 0..3 {
                assert!(
                    (b[c] - want[c]).abs() <= 1e-9 * want[c].abs().max(1e-3),
                    "{b:?} {want:?}"
                );
            }
        }
    }
}
