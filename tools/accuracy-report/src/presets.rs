//! The `--quality` presets against the uniform-mesh front (issue 31), on the three scenes of
//! the refinement sweep (`refinement.rs`: the paper's cube, the Cornell box, the sun floor)
//! and `small_room.obj` (from `../shared`, skipped when absent).
//!
//! - **Presets**: each baked exactly as `bake --quality Q IN OUT` bakes it: a default
//!   [`bake_core::Request`] with only `quality` set (transport `auto`, refinement and element
//!   budget as the plan decides).
//! - **Uniform front**: `bake --max-element-size D --refine off` (the normal preset's other
//!   knobs, `auto` transport) at several element sizes D.
//!
//! Times: the median of [`RUNS`] whole library bakes (mesh, transport, solve, refinement; no
//! import or export). Errors: cube, Cornell box and small room, area-weighted RMS of
//! the displayed (vertex-interpolated) field sampled at a finer reference's element centroids,
//! relative to the reference's mean b (`measure::displayed_errors`), against the exact 48 ×
//! 48-per-wall solution and converged Cornell and `small_room.obj` references (diagonal/40 and
//! /64, hierarchical at link tolerance 1e-3 with 121 rays); sun floor, the displayed field
//! against its closed form. The front's error at a preset's time
//! is read off the uniform points by log–log interpolation between the two around that time
//! (the fastest point's error before it, the slowest's after it): a preset passes when its error
//! is at most [`SLACK`] × that, and the presets are ordered when high < normal < draft.

use crate::measure::{self, Field, Scene};
use crate::refinement;
use anyhow::Result;
use bake_core::presets::Quality;
use mesher::Subdivision;
use std::fmt::Write;
use std::path::Path;
use std::time::Instant;

/// Whole bakes per setting; the median time is kept.
pub const RUNS: usize = 5;

/// How far above the uniform front a preset may lie (issue 31: 1.25×).
pub const SLACK: f64 = 1.25;

/// Errors below this are rounding: exact, and equal for the ordering.
const EXACT: f64 = 1e-12;

/// One setting's median bake.
#[derive(Clone, Debug)]
pub struct PresetRow {
    pub scene: &'static str,
    pub label: String,
    /// The preset, or `None` for a uniform-front point or the previous default.
    pub preset: Option<Quality>,
    /// Whether this is a uniform-front point.
    pub front: bool,
    pub elements: usize,
    pub transport: String,
    pub time_s: f64,
    pub error: f64,
}

/// `runs` (at least one) whole library bakes of `request` on `scene`: the last bake and every
/// run's wall time. A bake's own error (`BakeError`, e.g. the memory guard's refusal) is kept
/// as the `anyhow` error's source, for callers that skip what the guard refuses.
pub(crate) fn measure(
    scene: &Scene,
    request: &bake_core::Request,
    runs: usize,
) -> Result<(bake_core::Bake, Vec<f64>)> {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let settings = bake_core::Settings::resolve(request, &scene.polygons)?;
        let bake = bake_core::run(&scene.source, &settings, &bake_core::Silent)?;
        times.push(start.elapsed().as_secs_f64());
        last = Some(bake);
    }
    let bake = last.ok_or_else(|| anyhow::anyhow!("no run"))?;
    Ok((bake, times))
}

/// The median of `times` (the upper one of an even count; 0 when empty).
pub(crate) fn median(times: &[f64]) -> f64 {
    let mut t = times.to_vec();
    t.sort_by(f64::total_cmp);
    t.get(t.len() / 2).copied().unwrap_or(0.0)
}

fn uniform(d: f64, polygons: &[importer::Polygon]) -> bake_core::Request {
    bake_core::Request {
        subdivision: Some(Subdivision::MaxSize(mesher::max_element_size(polygons, d))),
        refine: Some(false),
        ..bake_core::Request::default()
    }
}

fn preset(q: Quality) -> bake_core::Request {
    bake_core::Request {
        quality: q,
        ..bake_core::Request::default()
    }
}

/// The presets and the uniform front on each scene (`quick`: the cube only, fewer runs).
pub fn sweep(root: &Path, out: &Path, quick: bool) -> Result<Vec<PresetRow>> {
    let runs = if quick { 1 } else { RUNS };
    let mut rows = Vec::new();
    let mut scene_rows =
        |scene: &Scene, diagonals: &[f64], error: &dyn Fn(&bake_core::Bake) -> f64| -> Result<()> {
            let mut requests: Vec<(String, Option<Quality>, bake_core::Request)> = diagonals
                .iter()
                .map(|&d| {
                    (
                        format!("uniform diag/{d}"),
                        None,
                        uniform(d, &scene.polygons),
                    )
                })
                .collect();
            for q in Quality::ALL {
                requests.push((format!("--quality {}", q.name()), Some(q), preset(q)));
            }
            let fronts = diagonals.len();
            requests.push((
                "previous default".into(),
                None,
                previous_default(&scene.polygons),
            ));
            for (k, (label, q, request)) in requests.into_iter().enumerate() {
                let (bake, times) = measure(scene, &request, runs)?;
                let (time_s, e) = (median(&times), error(&bake));
                let transport = format!("{:?}", bake.plan.transport().kind).to_lowercase();
                eprintln!(
                    "presets {}: {label}: {} elements ({transport}), {time_s:.3} s, rms {e:.3e}",
                    scene.name,
                    bake.mesh.elements.len()
                );
                rows.push(PresetRow {
                    scene: scene.name,
                    label,
                    preset: q,
                    front: k < fronts,
                    elements: bake.mesh.elements.len(),
                    transport,
                    time_s,
                    error: e,
                });
            }
            Ok(())
        };

    let cube = Scene::load("cube", &root.join("fixtures/cube.gltf"))?;
    let reference_mesh = mesher::mesh(&cube.polygons, Subdivision::Count(48))?;
    let reference_b = measure::closed_form_solution(&cube, &reference_mesh)?;
    let reference = Field::new(&reference_mesh, &reference_b);

    let diagonals: &[f64] = if quick {
        &[8.0, 16.0]
    } else {
        &[6.0, 8.0, 12.0, 16.0, 24.0, 32.0, 48.0, 64.0]
    };
    scene_rows(&cube, diagonals, &displayed_rms(&reference, &cube))?;
    if quick {
        return Ok(rows);
    }

    let cornell = Scene::load("cornell", &root.join("fixtures/cornell.gltf"))?;
    let reference_bake = converged(&cornell, 40.0)?;
    let reference = Field::new(&reference_bake.mesh, &reference_bake.solution.b);
    scene_rows(
        &cornell,
        &[6.0, 8.0, 12.0, 16.0, 24.0, 32.0],
        &displayed_rms(&reference, &cornell),
    )?;

    // small_room.obj (issue 31's repro of a small scene with occluders), when ../shared has it.
    let path = root.join("../shared/corpus/repro/small_room.obj");
    if path.exists() {
        let room = Scene::load("small_room", &path)?;
        let reference_bake = converged(&room, 64.0)?;
        let reference = Field::new(&reference_bake.mesh, &reference_bake.solution.b);
        scene_rows(
            &room,
            &[8.0, 12.0, 16.0, 24.0, 32.0],
            &displayed_rms(&reference, &room),
        )?;
    } else {
        eprintln!("presets small_room: skipped ({} not found)", path.display());
    }

    let path = refinement::write_floor(out)?;
    let floor = Scene::load("sun floor", &path)?;
    let floor_error = |b: &bake_core::Bake| refinement::displayed_errors(&b.mesh, &b.solution.b).0;
    scene_rows(&floor, &[16.0, 32.0, 48.0, 64.0, 96.0], &floor_error)?;
    Ok(rows)
}

/// The default bake before issue 31's plan (commit c40dda1): `--max-error` 1e-3 with
/// refinement on the estimate up to 2 000 elements (dense) or 4 000 (a small scene with
/// occluders, hierarchical at link tolerance 0.01), from the grid of diagonal / 16.
fn previous_default(polygons: &[importer::Polygon]) -> bake_core::Request {
    bake_core::Request {
        subdivision: Some(Subdivision::MaxSize(mesher::max_element_size(
            polygons, 16.0,
        ))),
        max_error: Some(1e-3),
        link_tolerance: Some(0.01),
        refine: Some(true),
        ..bake_core::Request::default()
    }
}

/// A converged reference bake of a scene with occluders: elements of diagonal /
/// `per_diagonal`, not refined, hierarchical at link tolerance 1e-3 with 121 rays per link.
pub(crate) fn converged(scene: &Scene, per_diagonal: f64) -> Result<bake_core::Bake> {
    eprintln!("presets {}: reference ...", scene.name);
    let request = bake_core::Request {
        subdivision: Some(Subdivision::MaxSize(mesher::max_element_size(
            &scene.polygons,
            per_diagonal,
        ))),
        refine: Some(false),
        transport: bake_core::TransportKind::Hierarchical,
        link_tolerance: Some(1e-3),
        visibility_samples: Some(121),
        ..bake_core::Request::default()
    };
    let settings = bake_core::Settings::resolve(&request, &scene.polygons)?;
    Ok(bake_core::run(
        &scene.source,
        &settings,
        &bake_core::Silent,
    )?)
}

/// A bake's RMS error on the displayed field against `reference` ([`measure::displayed_errors`]).
fn displayed_rms<'a>(
    reference: &'a Field<'a>,
    scene: &'a Scene,
) -> impl Fn(&bake_core::Bake) -> f64 + 'a {
    move |b| measure::displayed_errors(&Field::new(&b.mesh, &b.solution.b), reference, scene).rms
}

/// The uniform front's error at `time`: log–log interpolation between the uniform points
/// around it (sorted by time, each the best error so far); before the fastest point, the first
/// segment's log–log line continued (a preset faster than every uniform bake is held to the
/// front's own trend, not to a slower bake's error), its slope no steeper than −1 (error
/// inversely proportional to time, already steeper than a uniform mesh can go: error ∝ h,
/// time ∝ h⁻² or more; two fast points a timing jitter apart would otherwise extrapolate any
/// error); flat after the slowest (a preset slower than every uniform bake is held to the best
/// of them).
pub fn front_error(points: &[(f64, f64)], time: f64) -> Option<f64> {
    let mut front: Vec<(f64, f64)> = points.to_vec();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Keep the points that improve on every faster one: the front.
    let mut kept: Vec<(f64, f64)> = Vec::new();
    for p in front {
        if kept.last().is_none_or(|l| p.1 < l.1) {
            kept.push(p);
        }
    }
    let first = *kept.first()?;
    let last = *kept.last()?;
    if time <= first.0 {
        return Some(match kept.get(1) {
            Some(&second) => {
                let slope =
                    ((second.1.ln() - first.1.ln()) / (second.0.ln() - first.0.ln())).max(-1.0);
                (first.1.ln() + slope * (time.ln() - first.0.ln())).exp()
            }
            None => first.1,
        });
    }
    if time >= last.0 {
        return Some(last.1);
    }
    let k = kept.windows(2).find(|w| w[0].0 <= time && time <= w[1].0)?;
    let (a, b) = (k[0], k[1]);
    let t = (time.ln() - a.0.ln()) / (b.0.ln() - a.0.ln());
    Some((a.1.ln() + t * (b.1.ln() - a.1.ln())).exp())
}

/// Per scene and preset: (scene, preset, its error, the uniform front's error at its time;
/// `None` when the scene has no uniform point).
pub fn verdicts(rows: &[PresetRow]) -> Vec<(&'static str, Quality, f64, Option<f64>)> {
    let mut out = Vec::new();
    let mut scenes: Vec<&'static str> = rows.iter().map(|r| r.scene).collect();
    scenes.dedup();
    for scene in scenes {
        let points: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.scene == scene && r.front)
            .map(|r| (r.time_s, r.error))
            .collect();
        for r in rows.iter().filter(|r| r.scene == scene) {
            if let Some(q) = r.preset {
                out.push((scene, q, r.error, front_error(&points, r.time_s)));
            }
        }
    }
    out
}

/// The markdown section for `docs/accuracy.md`.
pub fn markdown(rows: &[PresetRow]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{BEGIN}\n## The presets against the uniform-mesh front (issue 31)\n\n\
         Each `--quality` preset baked as `bake --quality Q` bakes it (everything else default), \
         against uniform meshes (`--max-element-size D --refine off`, the default preset's \
         other knobs), and the default bake before issue 31's plan (*previous default*: \
         `--max-error 1e-3 --link-tolerance 0.01 --refine on` from diagonal/16). Median of \
         {RUNS} library bakes (mesh, transport, solve, refinement; no import/export), 2 cores. \
         *RMS error*: the field a viewer shows (vertex-interpolated) at the centroid of every \
         element of a finer reference, against the reference's value, over the reference's \
         mean b (area-weighted over non-emitting elements; `measure::displayed_errors`): the \
         cube against its exact 48 × 48-per-wall solution, the Cornell box and \
         `small_room.obj` against converged bakes (diagonal/40 and /64, hierarchical, link \
         tolerance 1e-3, 121 rays, not refined); the sun floor against its closed form. \
         *Front*: the uniform points' error at the preset's time, interpolated log–log (along \
         the first segment, no steeper than error ∝ 1/time, before the fastest point, flat \
         after the slowest). Regenerate with \
         `cargo run --release -p bake-accuracy-report -- --presets` (this section only).\n"
    );
    let mut scenes: Vec<&'static str> = rows.iter().map(|r| r.scene).collect();
    scenes.dedup();
    let verdicts = verdicts(rows);
    for scene in scenes {
        let _ = writeln!(s, "### {scene}\n");
        let _ = writeln!(
            s,
            "| setting | elements | transport | time (s) | RMS error | front at that time | error / front |\n\
             | --- | ---: | --- | ---: | ---: | ---: | ---: |"
        );
        for r in rows.iter().filter(|r| r.scene == scene) {
            let front = verdicts
                .iter()
                .find(|v| v.0 == scene && Some(v.1) == r.preset)
                .and_then(|v| v.3);
            let (f, ratio) = match front {
                Some(f) => (format!("{f:.2e}"), format!("{:.2}", r.error / f)),
                None => (String::new(), String::new()),
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.3} | {:.2e} | {f} | {ratio} |",
                r.label, r.elements, r.transport, r.time_s, r.error
            );
        }
        let errors: Vec<f64> = Quality::ALL
            .iter()
            .filter_map(|q| {
                rows.iter()
                    .find(|r| r.scene == scene && r.preset == Some(*q))
                    .map(|r| r.error)
            })
            .collect();
        // Errors at rounding (the sun floor's refined presets are exact) are ties, not disorder.
        let ordered = errors
            .windows(2)
            .all(|w| w[1] < w[0] || w[0].max(w[1]) < EXACT);
        let within = verdicts
            .iter()
            .filter(|v| v.0 == scene)
            .all(|v| v.3.is_some_and(|f| v.2 <= SLACK * f));
        let _ = writeln!(
            s,
            "\nOrdered (high < normal < draft, or exact to rounding): {}. Every preset within \
             {SLACK}× of the front: {}.\n",
            if ordered { "yes" } else { "**no**" },
            if within { "yes" } else { "**no**" }
        );
    }
    let _ = writeln!(s, "{END}");
    s
}

pub const BEGIN: &str = "<!-- presets: written by accuracy-report --presets -->";
pub const END: &str = "<!-- /presets -->";

#[cfg(test)]
mod tests {
    use super::*;

    /// The front is read between its points on log–log axes, continued before the fastest
    /// along its first segment, flat after the slowest, and points that do not improve on a
    /// faster one are not on it.
    #[test]
    fn the_front_interpolates_log_log() {
        let points = [(0.1, 1e-2), (1.0, 1e-3), (0.5, 5e-2), (10.0, 1e-4)];
        let before = front_error(&points, 0.01).unwrap();
        assert!((before / 1e-1 - 1.0).abs() < 1e-12, "{before}");
        assert_eq!(front_error(&[(0.1, 1e-2)], 0.01), Some(1e-2));
        assert_eq!(front_error(&points, 100.0), Some(1e-4));
        let mid = front_error(&points, 0.1f64.sqrt()).unwrap();
        assert!(
            (mid - 1e-2f64.sqrt() * 1e-3f64.sqrt()).abs() < 1e-12,
            "{mid}"
        );
        assert_eq!(front_error(&[], 1.0), None);
        // Two fast points a jitter apart: the slope is held at −1.
        let jitter = [(0.128, 0.300), (0.135, 0.217)];
        let held = front_error(&jitter, 0.064).unwrap();
        assert!((held / 0.600 - 1.0).abs() < 1e-12, "{held}");
    }
}
