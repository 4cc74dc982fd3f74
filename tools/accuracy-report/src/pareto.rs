//! `--pareto`: the Pareto front of every knob on both transports (issue 31), on the paper's
//! cube, the Cornell box, the sun floor with its blocker and a 2 × 2-room office floor
//! (`tools/walkthrough`).
//!
//! Each knob is swept with the transport forced (`TransportKind::Dense` and `Hierarchical`
//! in the [`bake_core::Request`]): element size (uniform, `--refine off`), `--max-error` E
//! (refinement on, from the grid of diagonal / [`BASE`]), the link tolerance (hierarchical),
//! shadow rays per pair or link (`visibility_samples`), refinement on (at the preset's own
//! target; off is the uniform diagonal / [`BASE`] row); and the `--quality` presets as `bake
//! --quality Q` bakes them (transport `auto`: shown with the transport it picked).
//!
//! Every point is measured on the field a viewer shows, at a regular [`POINTS`] × [`POINTS`]
//! grid of points per polygon (bilinear parameters of a quad, sub-triangle centroids of a
//! triangle), area-weighted: the vertex-interpolated radiosity (`Field::smooth`), and the
//! lightmap a viewer samples (the bake's irradiance H → [`lightmap::build`] at its default
//! texel size, sampled bilinearly at each point's `TEXCOORD_1`, shown as ρH + e), both against
//! the reference at the same points, RMS over points and bands relative to the reference's
//! mean. References: the cube's exact solution on 48 × 48 elements per wall (closed-form form
//! factors; its vertex-interpolated field at the points), converged hierarchical bakes of the
//! Cornell box and the office (`presets::converged`), the sun floor's closed form (points within
//! 5 cm of the shadow's edge left out).

use crate::measure::{self, Field, Scene};
use crate::plot;
use crate::presets;
use crate::refinement;
use anyhow::{Context, Result};
use bake_core::presets::Quality;
use bake_core::TransportKind;
use glam::DVec3;
use importer::Polygon;
use mesher::Subdivision;
use std::collections::HashMap;
use std::fmt::Write;
use std::path::Path;

/// Bakes per point; the median time is kept.
pub const RUNS: usize = 3;

/// A point whose first bake takes longer than this (s) is not baked again: its one time is
/// kept (the sweep stays within about 20 minutes on 2 cores).
pub const ONE_RUN_ABOVE_S: f64 = 5.0;

/// A dense point predicted to take longer than this (s) is skipped: the dense transport's
/// time grows like the square of the elements (form factors and rays per element pair).
pub const DENSE_LIMIT_S: f64 = 60.0;

/// Sample points per side of every polygon.
pub const POINTS: usize = 32;

/// The knobs' base grid: diagonal / `BASE` (the `normal` preset's).
pub const BASE: f64 = 16.0;

/// One point of the sweep on one scene and transport.
#[derive(Clone, Debug)]
pub struct Point {
    pub scene: &'static str,
    /// The transport the table puts it under: the forced one, or the one `auto` picked.
    pub transport: TransportKind,
    pub knob: &'static str,
    pub label: String,
    /// A `--quality` preset baked with transport `auto`.
    pub preset: Option<Quality>,
    pub measured: Option<Measured>,
    /// Why the point was not baked.
    pub skipped: Option<String>,
    /// On the front of its scene and transport (filled in by [`mark_fronts`]).
    pub front: bool,
}

/// What one baked point cost and how far its displayed field is off.
#[derive(Clone, Copy, Debug)]
pub struct Measured {
    pub elements: usize,
    pub links: u64,
    pub rays: u64,
    /// Median wall time of the bakes (s).
    pub time_s: f64,
    pub runs: usize,
    /// RMS error of the vertex-interpolated field, relative to the reference's mean.
    pub displayed: f64,
    /// RMS error of the lightmap's bilinear samples (ρH + e), relative to the reference's mean.
    pub texels: f64,
}

/// Sets `front` on the measured points of each scene and transport that no other point of
/// the same scene and transport dominates in (time, displayed error) ([`plot::pareto_front`]).
pub fn mark_fronts(points: &mut [Point]) {
    let mut groups: Vec<(&'static str, TransportKind)> = Vec::new();
    for p in points.iter() {
        if !groups.contains(&(p.scene, p.transport)) {
            groups.push((p.scene, p.transport));
        }
    }
    for (scene, transport) in groups {
        let members: Vec<usize> = (0..points.len())
            .filter(|&k| {
                points[k].scene == scene
                    && points[k].transport == transport
                    && points[k].measured.is_some()
            })
            .collect();
        let pairs: Vec<plot::Point> = members
            .iter()
            .filter_map(|&k| {
                points[k].measured.map(|m| plot::Point {
                    label: points[k].label.clone(),
                    group: points[k].knob.into(),
                    time_s: m.time_s,
                    error: m.displayed,
                })
            })
            .collect();
        for i in plot::pareto_front(&pairs) {
            points[members[i]].front = true;
        }
    }
}

/// One sample point of the displayed field.
struct Sample {
    polygon: usize,
    point: DVec3,
    weight: f64,
    reference: [f64; 3],
}

/// The sample points of a scene with the reference's values at them.
pub struct Probe {
    samples: Vec<Sample>,
    /// Per band: the reference's area-weighted mean over the samples.
    mean: [f64; 3],
}

/// A field on the scene's surfaces: its value at a point of a polygon (`None`: not compared).
type Lookup<'a> = dyn Fn(usize, DVec3) -> Option<[f64; 3]> + 'a;

impl Probe {
    /// `points` × `points` samples per polygon that shows light (not emitting, ρ > 0), each
    /// with its share of the polygon's area and the reference's value there.
    pub fn new(scene: &Scene, points: usize, reference: &Lookup) -> Probe {
        let mut samples = Vec::new();
        for (p, polygon) in scene.polygons.iter().enumerate() {
            let emits = scene
                .emission
                .get(p)
                .is_some_and(|e| e.iter().any(|&v| v > 0.0));
            let black = scene.rho.get(p).is_none_or(|r| r.iter().all(|&v| v <= 0.0));
            if emits || black {
                continue;
            }
            for (point, weight) in polygon_points(polygon, points) {
                if let Some(value) = reference(p, point) {
                    samples.push(Sample {
                        polygon: p,
                        point,
                        weight,
                        reference: value,
                    });
                }
            }
        }
        let total: f64 = samples.iter().map(|s| s.weight).sum();
        let mut mean = [0.0; 3];
        for s in &samples {
            for (m, v) in mean.iter_mut().zip(s.reference) {
                *m += s.weight * v / total.max(f64::MIN_POSITIVE);
            }
        }
        Probe { samples, mean }
    }

    /// RMS over samples (area-weighted) and bands of `(shown − reference) / mean`; a point
    /// `shown` has no value at counts as an error of the whole reference value there.
    pub fn rms(&self, shown: &Lookup) -> f64 {
        let (mut squares, mut weight) = (0.0, 0.0);
        for s in &self.samples {
            let v = shown(s.polygon, s.point).unwrap_or([0.0; 3]);
            for ((shown, reference), mean) in v.iter().zip(s.reference).zip(self.mean) {
                if mean > 0.0 {
                    let e = (shown - reference) / mean;
                    squares += s.weight * e * e;
                    weight += s.weight;
                }
            }
        }
        if weight > 0.0 {
            (squares / weight).sqrt()
        } else {
            0.0
        }
    }

    pub fn len(&self) -> usize {
        self.samples.len()
    }
}

/// A regular grid of `n` × `n` points on `polygon` with their area shares: a quad's bilinear
/// parameters at cell centres, a triangle's (or a fan triangle's) sub-triangle centroids.
fn polygon_points(polygon: &Polygon, n: usize) -> Vec<(DVec3, f64)> {
    let c = &polygon.vertices;
    let area = |a: DVec3, b: DVec3, d: DVec3| (b - a).cross(d - a).length() / 2.0;
    let mut out = Vec::with_capacity(n * n);
    if c.len() == 4 {
        let total = area(c[0], c[1], c[2]) + area(c[0], c[2], c[3]);
        let w = total / (n * n) as f64;
        for j in 0..n {
            for i in 0..n {
                let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                let p = c[0] * ((1.0 - u) * (1.0 - v))
                    + c[1] * (u * (1.0 - v))
                    + c[2] * (u * v)
                    + c[3] * ((1.0 - u) * v);
                out.push((p, w));
            }
        }
        return out;
    }
    for k in 1..c.len().saturating_sub(1) {
        let (a, b, d) = (c[0], c[k], c[k + 1]);
        let w = area(a, b, d) / (n * n) as f64;
        let at = |x: f64, y: f64| a + (b - a) * (x / n as f64) + (d - a) * (y / n as f64);
        for i in 0..n {
            for j in 0..n - i {
                out.push((at(i as f64 + 1.0 / 3.0, j as f64 + 1.0 / 3.0), w));
                if i + j + 1 < n {
                    out.push((at(i as f64 + 2.0 / 3.0, j as f64 + 2.0 / 3.0), w));
                }
            }
        }
    }
    out
}

/// The displayed (vertex-interpolated) value of `field` at a point.
fn displayed<'a>(field: &'a Field<'a>) -> impl Fn(usize, DVec3) -> Option<[f64; 3]> + 'a {
    move |p, x| field.smooth(p, x).or_else(|| field.flat(p, x))
}

/// What a viewer shows from `map` at point `x` of polygon `p` (`Lightmap::viewed_at`: the atlas
/// sampled bilinearly at the point's `TEXCOORD_1`), as ρH + e with the polygon's ρ and e.
fn lightmap_value(
    map: &lightmap::Lightmap,
    polygons: &[Polygon],
    rho_e: &[([f64; 3], [f64; 3])],
    p: usize,
    x: DVec3,
) -> Option<[f64; 3]> {
    let h = map.viewed_at(polygons, p, x)?;
    let (rho, e) = rho_e.get(p)?;
    Some(std::array::from_fn(|k| rho[k] * h[k] + e[k]))
}

/// The errors of one bake on `probe`: displayed field and lightmap texels.
fn errors(scene: &Scene, probe: &Probe, bake: &bake_core::Bake) -> Result<(f64, f64)> {
    let field = Field::new(&bake.mesh, &bake.solution.b);
    let shown = probe.rms(&displayed(&field));
    let h = bake
        .irradiance
        .as_ref()
        .context("the bake kept no irradiance H")?;
    let options = lightmap::Options {
        texel_size: lightmap::default_texel_size(&scene.polygons),
        max_size: lightmap::DEFAULT_MAX_SIZE,
        shading: lightmap::Shading::Smooth,
        max_atlases: lightmap::DEFAULT_MAX_ATLASES,
    };
    let map = lightmap::build(&scene.polygons, &bake.mesh, h, &options)?;
    // ρ and e as the bake used them (ρ ≥ 1 lowered), from each polygon's first element.
    let rho_e: Vec<([f64; 3], [f64; 3])> = bake
        .mesh
        .patches
        .iter()
        .map(|patch| {
            let k = patch.elements.start as usize;
            (
                bake.rho.get(k).copied().unwrap_or([0.0; 3]),
                bake.emission.get(k).copied().unwrap_or([0.0; 3]),
            )
        })
        .collect();
    let texels = probe.rms(&|p, x| lightmap_value(&map, &scene.polygons, &rho_e, p, x));
    Ok((shown, texels))
}

/// One setting of a knob: its label and request (transport set by the sweep).
struct Setting {
    knob: &'static str,
    label: String,
    request: bake_core::Request,
}

fn grid(scene: &Scene, per_diagonal: f64) -> Subdivision {
    Subdivision::MaxSize(mesher::max_element_size(&scene.polygons, per_diagonal))
}

/// Which knob values a scene is swept at.
struct Plan {
    diagonals: Vec<f64>,
    max_errors: Vec<f64>,
    link_tolerances: Vec<f64>,
    rays: Vec<u32>,
    presets: bool,
}

impl Plan {
    fn quick() -> Plan {
        Plan {
            diagonals: vec![4.0, 8.0],
            max_errors: Vec::new(),
            link_tolerances: Vec::new(),
            rays: Vec::new(),
            presets: false,
        }
    }

    fn full(diagonals: &[f64]) -> Plan {
        Plan {
            diagonals: diagonals.to_vec(),
            max_errors: vec![3e-2, 1e-2, 3e-3],
            link_tolerances: vec![3e-2, 1e-2, 3e-3],
            rays: vec![9, 49, 121],
            presets: true,
        }
    }

    /// The uniform grid of diagonal / `d` on `transport`, refinement off, H kept.
    fn uniform(scene: &Scene, transport: TransportKind, d: f64) -> bake_core::Request {
        bake_core::Request {
            subdivision: Some(grid(scene, d)),
            refine: Some(false),
            irradiance: true,
            transport,
            ..bake_core::Request::default()
        }
    }

    /// The knobs' base point: the uniform grid of diagonal / [`BASE`].
    fn base(&self, scene: &Scene, transport: TransportKind) -> bake_core::Request {
        Self::uniform(scene, transport, BASE)
    }

    /// The settings on `transport` (not `auto`): element size, refinement, E, link
    /// tolerance, rays.
    fn settings(&self, scene: &Scene, transport: TransportKind) -> Vec<Setting> {
        let base = bake_core::Request {
            irradiance: true,
            transport,
            ..bake_core::Request::default()
        };
        let uniform = |d: f64| Self::uniform(scene, transport, d);
        let mut out: Vec<Setting> = self
            .diagonals
            .iter()
            .map(|&d| Setting {
                knob: "element size",
                label: format!("diag/{d}"),
                request: uniform(d),
            })
            .collect();
        if self.presets {
            out.push(Setting {
                knob: "refinement",
                label: format!("on, from diag/{BASE}"),
                request: bake_core::Request {
                    subdivision: Some(grid(scene, BASE)),
                    refine: Some(true),
                    ..base.clone()
                },
            });
        }
        for &e in &self.max_errors {
            out.push(Setting {
                knob: "max error",
                label: format!("E={e}, refined from diag/{BASE}"),
                request: bake_core::Request {
                    subdivision: Some(grid(scene, BASE)),
                    refine: Some(true),
                    max_error: Some(e),
                    ..base.clone()
                },
            });
        }
        if transport == TransportKind::Hierarchical {
            for &t in &self.link_tolerances {
                out.push(Setting {
                    knob: "link tolerance",
                    label: format!("{t}, diag/{BASE}"),
                    request: bake_core::Request {
                        link_tolerance: Some(t),
                        ..uniform(BASE)
                    },
                });
            }
        }
        for &n in &self.rays {
            out.push(Setting {
                knob: "shadow rays",
                label: format!("{n} per {}, diag/{BASE}", ray_unit(transport)),
                request: bake_core::Request {
                    visibility_samples: Some(n),
                    ..uniform(BASE)
                },
            });
        }
        out
    }
}

fn ray_unit(transport: TransportKind) -> &'static str {
    match transport {
        TransportKind::Hierarchical => "link",
        _ => "pair",
    }
}

/// Per scene: the largest dense time per element² measured so far, to skip points predicted
/// past [`DENSE_LIMIT_S`].
struct DenseCost {
    seconds_per_pair: f64,
}

impl DenseCost {
    /// Elements a dense point may end with: its grid, or refinement's budget.
    fn elements(scene: &Scene, request: &bake_core::Request) -> Option<u64> {
        let grid = mesher::element_count(&scene.polygons, request.subdivision?).ok()?;
        Some(if request.refine == Some(true) {
            grid.max(
                request
                    .max_elements
                    .unwrap_or(bake_core::DEFAULT_MAX_ELEMENTS),
            )
        } else {
            grid
        })
    }

    /// Why `request` is skipped, when its predicted time is past the limit.
    fn skip(&self, scene: &Scene, request: &bake_core::Request) -> Option<String> {
        let n = Self::elements(scene, request)? as f64;
        // A refined bake solves more than once: counted as two solves of its budget.
        let solves = if request.refine == Some(true) {
            2.0
        } else {
            1.0
        };
        let predicted = self.seconds_per_pair * n * n * solves;
        (predicted > DENSE_LIMIT_S).then(|| {
            format!("skipped: {n} elements, predicted {predicted:.0} s dense (> {DENSE_LIMIT_S} s)")
        })
    }

    fn record(&mut self, elements: usize, time_s: f64) {
        let n = elements.max(1) as f64;
        self.seconds_per_pair = self.seconds_per_pair.max(time_s / (n * n));
    }
}

/// Bakes `request` (median of up to `runs`), or says why not (the memory guard's refusal).
fn bake_point(
    scene: &Scene,
    probe: &Probe,
    request: &bake_core::Request,
    runs: usize,
) -> Result<std::result::Result<(bake_core::Bake, Measured), String>> {
    let (mut bake, mut times) = match presets::measure(scene, request, 1) {
        Ok(r) => r,
        Err(e) => {
            if let Some(b) = e.downcast_ref::<bake_core::BakeError>() {
                if b.is_too_large() {
                    return Ok(Err(format!("skipped: the memory guard refuses it ({b})")));
                }
            }
            return Err(e);
        }
    };
    if runs > 1 && times[0] < ONE_RUN_ABOVE_S {
        let (again, more) = presets::measure(scene, request, runs - 1)?;
        bake = again;
        times.extend(more);
    }
    let (displayed, texels) = errors(scene, probe, &bake)?;
    let measured = Measured {
        elements: bake.mesh.elements.len(),
        links: bake.counts.links,
        rays: bake.counts.rays_cast,
        time_s: presets::median(&times),
        runs: times.len(),
        displayed,
        texels,
    };
    Ok(Ok((bake, measured)))
}

/// Every knob of `plan` on both transports, and the presets, on one scene.
fn sweep_scene(
    scene: &Scene,
    probe: &Probe,
    plan: &Plan,
    runs: usize,
    points: &mut Vec<Point>,
) -> Result<()> {
    eprintln!("pareto {}: {} sample points", scene.name, probe.len());
    for transport in [TransportKind::Dense, TransportKind::Hierarchical] {
        let mut cost = DenseCost {
            seconds_per_pair: 0.0,
        };
        // The same request twice (refinement off = the uniform base grid) is baked once.
        let mut seen: HashMap<String, Measured> = HashMap::new();
        let base_key = format!("{:?}", plan.base(scene, transport));
        for s in plan.settings(scene, transport) {
            let key = format!("{:?}", s.request);
            // Shadow rays change nothing where the base grid casts none (the convex cube).
            if s.knob == "shadow rays" && seen.get(&base_key).is_some_and(|m| m.rays == 0) {
                continue;
            }
            let mut point = Point {
                scene: scene.name,
                transport,
                knob: s.knob,
                label: s.label,
                preset: None,
                measured: seen.get(&key).copied(),
                skipped: None,
                front: false,
            };
            if point.measured.is_none() {
                let skip = (transport == TransportKind::Dense)
                    .then(|| cost.skip(scene, &s.request))
                    .flatten();
                match skip {
                    Some(why) => point.skipped = Some(why),
                    None => match bake_point(scene, probe, &s.request, runs)? {
                        Ok((_, m)) => {
                            if transport == TransportKind::Dense {
                                cost.record(m.elements, m.time_s);
                            }
                            seen.insert(key, m);
                            point.measured = Some(m);
                        }
                        Err(why) => point.skipped = Some(why),
                    },
                }
            }
            log(&point);
            points.push(point);
        }
    }
    if plan.presets {
        for q in Quality::ALL {
            let request = bake_core::Request {
                quality: q,
                irradiance: true,
                ..bake_core::Request::default()
            };
            let (bake, m) = match bake_point(scene, probe, &request, runs)? {
                Ok(r) => r,
                Err(why) => anyhow::bail!("{} --quality {}: {why}", scene.name, q.name()),
            };
            let point = Point {
                scene: scene.name,
                transport: bake.plan.transport().kind,
                knob: "preset",
                label: format!("--quality {}", q.name()),
                preset: Some(q),
                measured: Some(m),
                skipped: None,
                front: false,
            };
            log(&point);
            points.push(point);
        }
    }
    Ok(())
}

fn log(p: &Point) {
    match (&p.measured, &p.skipped) {
        (Some(m), _) => eprintln!(
            "pareto {} {}: {} {}: {} elements, {} links, {} rays, {:.3} s, displayed {:.6e}, \
             texels {:.6e}",
            p.scene,
            p.transport.name(),
            p.knob,
            p.label,
            m.elements,
            m.links,
            m.rays,
            m.time_s,
            m.displayed,
            m.texels
        ),
        (None, Some(why)) => eprintln!(
            "pareto {} {}: {} {}: {why}",
            p.scene,
            p.transport.name(),
            p.knob,
            p.label
        ),
        (None, None) => {}
    }
}

/// Office rooms (2 × 2), room size and height (m) of the sweep's office floor.
pub const OFFICE: (usize, usize, f64, f64) = (2, 2, 4.0, 3.0);

/// The sweep (`quick`: the cube only, two element sizes per transport against a 16 × 16
/// reference, one run).
pub fn sweep(root: &Path, out: &Path, quick: bool) -> Result<Vec<Point>> {
    let runs = if quick { 1 } else { RUNS };
    let mut points = Vec::new();

    let cube = Scene::load("cube", &root.join("fixtures/cube.gltf"))?;
    let n = if quick { 16 } else { 48 };
    let reference_mesh = mesher::mesh(&cube.polygons, Subdivision::Count(n))?;
    let reference_b = measure::closed_form_solution(&cube, &reference_mesh)?;
    let reference = Field::new(&reference_mesh, &reference_b);
    let probe = Probe::new(&cube, POINTS, &displayed(&reference));
    let plan = if quick {
        Plan::quick()
    } else {
        Plan::full(&[8.0, 16.0, 24.0, 32.0, 48.0])
    };
    sweep_scene(&cube, &probe, &plan, runs, &mut points)?;
    if quick {
        mark_fronts(&mut points);
        return Ok(points);
    }

    let cornell = Scene::load("cornell", &root.join("fixtures/cornell.gltf"))?;
    let reference_bake = presets::converged(&cornell, 40.0)?;
    let reference = Field::new(&reference_bake.mesh, &reference_bake.solution.b);
    let probe = Probe::new(&cornell, POINTS, &displayed(&reference));
    let plan = Plan::full(&[8.0, 12.0, 16.0, 24.0, 32.0]);
    sweep_scene(&cornell, &probe, &plan, runs, &mut points)?;

    let path = refinement::write_floor(out)?;
    let floor = Scene::load("sun floor", &path)?;
    let exact = |_: usize, x: DVec3| -> Option<[f64; 3]> {
        // The floor (y = 0) has the closed form; the black blocker is left out by the probe.
        if x.y.abs() > 1e-9 {
            return Some([0.0; 3]);
        }
        refinement::floor_exact(x.x, x.z).map(|v| [v; 3])
    };
    let probe = Probe::new(&floor, POINTS, &exact);
    let plan = Plan::full(&[16.0, 32.0, 48.0, 64.0, 96.0]);
    sweep_scene(&floor, &probe, &plan, runs, &mut points)?;

    let (x, z, size, height) = OFFICE;
    let rooms = bake_walkthrough::office::Rooms { x, z };
    let office_floor = bake_walkthrough::office::office(rooms, size, height)
        .map_err(|e| anyhow::anyhow!("office floor: {e}"))?;
    let path = out.join("office-2x2.gltf");
    bake_walkthrough::gltf::write(&office_floor, &path)?;
    let office = Scene::load("office 2 × 2", &path)?;
    let reference_bake = presets::converged(&office, 48.0)?;
    let reference = Field::new(&reference_bake.mesh, &reference_bake.solution.b);
    let probe = Probe::new(&office, POINTS, &displayed(&reference));
    let plan = Plan::full(&[8.0, 12.0, 16.0, 24.0]);
    sweep_scene(&office, &probe, &plan, runs, &mut points)?;

    mark_fronts(&mut points);
    Ok(points)
}

pub const BEGIN: &str = "<!-- pareto: written by accuracy-report --pareto -->";
pub const END: &str = "<!-- /pareto -->";

fn count(n: u64) -> String {
    match n {
        0 => "—".into(),
        n if n >= 1_000_000 => format!("{:.2} M", n as f64 / 1e6),
        n if n >= 10_000 => format!("{:.1} k", n as f64 / 1e3),
        n => n.to_string(),
    }
}

/// The markdown section for `docs/accuracy.md` (`quick`: marked as a quick run).
pub fn markdown(points: &[Point], quick: bool) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{BEGIN}\n## The Pareto front of every knob on both transports (issue 31)\n"
    );
    if quick {
        let _ = writeln!(
            s,
            "**Quick run** (`--pareto --quick`: the cube only, two element sizes per transport, \
             against a 16 × 16-per-wall reference, one run each): not the measurement. \
             Regenerate the full section with `cargo run --release -p bake-accuracy-report -- \
             --pareto`.\n"
        );
    }
    let _ = writeln!(
        s,
        "Each knob swept with the transport forced (`--transport dense` and `hierarchical`): \
         element size (uniform, `--max-element-size diag/N --refine off`), refinement on \
         (`--refine on` from diag/{BASE} at the preset's own target; off is the diag/{BASE} \
         row), `--max-error` E (refined from diag/{BASE}), the link tolerance (hierarchical, \
         diag/{BASE}, refinement off), shadow rays per element pair (dense) or per link \
         (hierarchical; `visibility_samples`, diag/{BASE}, off; only on scenes that cast rays); \
         every other knob the `normal` preset's. The presets (★) are baked as `bake --quality \
         Q` bakes them, transport `auto`, and listed under the transport it picked. Dense \
         points predicted past {DENSE_LIMIT_S} s (time ∝ elements², from the dense points \
         measured before) or refused by the memory guard are skipped and say so.\n\n\
         *Time*: the median wall time of {RUNS} library bakes (mesh, visibility, transport, \
         solve, refinement, H; no import, export or lightmap; one bake where the first took \
         over {ONE_RUN_ABOVE_S} s, marked ¹), 2 cores shared with other work. *Links*, \
         *rays*: the bake's counts, of its last solve where refinement solved more than once \
         (links; shadow rays cast, masks included). *Displayed* and \
         *lightmap*: RMS error over a regular {POINTS} × {POINTS} grid of points on every \
         polygon that shows light (bilinear parameters of a quad; sub-triangle centroids of \
         a triangle), area-weighted, over the three bands, relative to the reference's mean \
         over the same points: *displayed* is the vertex-interpolated radiosity (the vertex \
         bake), *lightmap* the lightmap built from the bake's irradiance H at the default \
         texel size (diagonal / 256), sampled bilinearly at the point's `TEXCOORD_1` (the \
         glTF triangle's interpolation) and shown as ρH + e. References: the cube's exact \
         solution on 48 × 48 elements per wall (closed-form form factors, its \
         vertex-interpolated field at the points); the Cornell box and the office floor \
         (`walkthrough office --rooms 2x2`, written to the out folder) converged \
         hierarchical bakes at diag/40 and diag/48 (link tolerance 1e-3, 121 rays, not \
         refined; their vertex-interpolated field); the sun floor its closed form (points \
         within 5 cm of the shadow's edge left out; the black blocker shows no light). \
         *Front* ✓: no other point of the same scene and transport is at most as slow and at \
         most as wrong on the displayed field, and better in one. Regenerate with `cargo run \
         --release -p bake-accuracy-report -- --pareto` (this section only).\n"
    );
    let mut groups: Vec<(&'static str, TransportKind)> = Vec::new();
    for p in points {
        if !groups.contains(&(p.scene, p.transport)) {
            groups.push((p.scene, p.transport));
        }
    }
    for (scene, transport) in groups {
        let _ = writeln!(s, "### {scene}, {}\n", transport.name());
        let _ = writeln!(
            s,
            "| knob | setting | elements | links | rays | time (s) | displayed RMS | lightmap RMS | front |\n\
             | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | :---: |"
        );
        let rows: Vec<&Point> = points
            .iter()
            .filter(|p| p.scene == scene && p.transport == transport)
            .collect();
        for p in &rows {
            let label = match p.preset {
                Some(_) => format!("★ {} (auto → {})", p.label, transport.name()),
                None => p.label.clone(),
            };
            match (&p.measured, &p.skipped) {
                (Some(m), _) => {
                    let _ = writeln!(
                        s,
                        "| {} | {label} | {} | {} | {} | {:.3}{} | {:.2e} | {:.2e} | {} |",
                        p.knob,
                        m.elements,
                        count(m.links),
                        count(m.rays),
                        m.time_s,
                        if m.runs < RUNS { "¹" } else { "" },
                        m.displayed,
                        m.texels,
                        if p.front { "✓" } else { "" }
                    );
                }
                (None, why) => {
                    let _ = writeln!(
                        s,
                        "| {} | {label} | | | | | {} | | |",
                        p.knob,
                        why.as_deref().unwrap_or("skipped")
                    );
                }
            }
        }
        let mut front: Vec<(&&Point, Measured)> = rows
            .iter()
            .filter(|p| p.front)
            .filter_map(|p| p.measured.map(|m| (p, m)))
            .collect();
        front.sort_by(|a, b| a.1.time_s.total_cmp(&b.1.time_s));
        let front: Vec<String> = front
            .into_iter()
            .map(|(p, m)| {
                format!(
                    "{} {} ({:.3} s, {:.2e})",
                    p.knob, p.label, m.time_s, m.displayed
                )
            })
            .collect();
        let _ = writeln!(s, "\nFront, fastest first: {}.", front.join("; "));
        let presets: Vec<String> = rows
            .iter()
            .filter(|p| p.preset.is_some())
            .map(|p| {
                format!(
                    "{} {}",
                    p.label,
                    if p.front {
                        "on the front".to_string()
                    } else {
                        dominated_by(p, &rows)
                    }
                )
            })
            .collect();
        if !presets.is_empty() {
            let _ = writeln!(s, "Presets: {}.", presets.join("; "));
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "{END}");
    s
}

/// "behind X" for a point off the front: the fastest front point at least as accurate.
fn dominated_by(p: &Point, rows: &[&Point]) -> String {
    let Some(m) = p.measured else {
        return "not baked".into();
    };
    rows.iter()
        .filter(|q| q.front)
        .filter_map(|q| q.measured.map(|n| (q, n)))
        .filter(|(_, n)| n.time_s <= m.time_s && n.displayed <= m.displayed)
        .min_by(|a, b| a.1.time_s.total_cmp(&b.1.time_s))
        .map_or_else(
            || "off the front".into(),
            |(q, n)| {
                format!(
                    "off the front ({} {} is {:.1}× faster at {:.2e})",
                    q.knob,
                    q.label,
                    m.time_s / n.time_s.max(1e-9),
                    n.displayed
                )
            },
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(scene: &'static str, transport: TransportKind, time_s: f64, displayed: f64) -> Point {
        Point {
            scene,
            transport,
            knob: "element size",
            label: format!("{time_s} s"),
            preset: None,
            measured: Some(Measured {
                elements: 1,
                links: 0,
                rays: 0,
                time_s,
                runs: 1,
                displayed,
                texels: displayed,
            }),
            skipped: None,
            front: false,
        }
    }

    /// Each scene and transport has its own front: the points no other point of the same
    /// scene and transport is at least as good as in time and displayed error (and better in
    /// one); skipped points are on none.
    #[test]
    fn fronts_are_the_non_dominated_sets_per_scene_and_transport() {
        use TransportKind::{Dense, Hierarchical};
        let mut points = vec![
            point("a", Dense, 1.0, 0.10),        // 0: front (fastest)
            point("a", Dense, 2.0, 0.05),        // 1: front
            point("a", Dense, 2.5, 0.07),        // 2: dominated by 1
            point("a", Dense, 3.0, 0.05),        // 3: dominated by 1 (slower, same error)
            point("a", Dense, 4.0, 0.01),        // 4: front (most accurate)
            point("a", Dense, 1.0, 0.20),        // 5: dominated by 0 (as fast, worse)
            point("a", Hierarchical, 5.0, 0.20), // 6: alone on its transport: front
            point("b", Dense, 3.0, 0.06),        // 7: another scene: front
        ];
        let mut skipped = point("a", Dense, 0.1, 0.0);
        skipped.measured = None;
        skipped.skipped = Some("skipped".into());
        points.push(skipped);
        mark_fronts(&mut points);
        let front: Vec<usize> = (0..points.len()).filter(|&k| points[k].front).collect();
        assert_eq!(front, vec![0, 1, 4, 6, 7]);
    }

    /// The sample grid covers each polygon's area once: the weights sum to its area, and a
    /// triangle gets n² points.
    #[test]
    fn sample_points_cover_the_polygon() {
        let quad = Polygon {
            vertices: vec![
                DVec3::ZERO,
                DVec3::new(2.0, 0.0, 0.0),
                DVec3::new(2.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            ..test_polygon()
        };
        let points = polygon_points(&quad, 32);
        assert_eq!(points.len(), 32 * 32);
        let area: f64 = points.iter().map(|p| p.1).sum();
        assert!((area - 2.0).abs() < 1e-12, "{area}");
        let triangle = Polygon {
            vertices: quad.vertices[..3].to_vec(),
            ..test_polygon()
        };
        let points = polygon_points(&triangle, 32);
        assert_eq!(points.len(), 32 * 32);
        let area: f64 = points.iter().map(|p| p.1).sum();
        assert!((area - 1.0).abs() < 1e-12, "{area}");
        for (p, _) in &points {
            let l = barycentric(
                triangle.vertices[0],
                triangle.vertices[1],
                triangle.vertices[2],
                *p,
            );
            assert!(l.iter().all(|&w| w > 0.0), "{p} {l:?}");
        }
    }

    /// Barycentric weights of `p` in the triangle (a, b, d), in the triangle's plane.
    fn barycentric(a: DVec3, b: DVec3, d: DVec3, p: DVec3) -> [f64; 3] {
        let (e1, e2, q) = (b - a, d - a, p - a);
        let n = e1.cross(e2);
        let nn = n.length_squared();
        if nn <= 0.0 {
            return [1.0, 0.0, 0.0];
        }
        let l1 = q.cross(e2).dot(n) / nn;
        let l2 = e1.cross(q).dot(n) / nn;
        [1.0 - l1 - l2, l1, l2]
    }

    fn test_polygon() -> Polygon {
        let cube =
            Scene::load("cube", &crate::workspace_root().join("fixtures/cube.gltf")).unwrap();
        cube.polygons[0].clone()
    }

    /// `--pareto --quick`: rows on both transports with finite errors on the displayed field
    /// and the lightmap, which fall from the coarser to the finer mesh.
    #[test]
    fn quick_sweep_errors_fall_with_refinement() {
        let dir = tempfile::tempdir().unwrap();
        let points = sweep(&crate::workspace_root(), dir.path(), true).unwrap();
        for transport in [TransportKind::Dense, TransportKind::Hierarchical] {
            let rows: Vec<Measured> = points
                .iter()
                .filter(|p| p.transport == transport)
                .map(|p| p.measured.expect("baked"))
                .collect();
            assert_eq!(rows.len(), 2, "{transport:?}");
            for m in &rows {
                assert!(m.displayed.is_finite() && m.displayed > 0.0, "{m:?}");
                assert!(m.texels.is_finite() && m.texels > 0.0, "{m:?}");
            }
            assert!(rows[1].elements > rows[0].elements, "{rows:?}");
            assert!(rows[1].displayed < rows[0].displayed, "{rows:?}");
            assert!(rows[1].texels < rows[0].texels, "{rows:?}");
            // The lightmap shows the same field as the vertices, through texels.
            for m in &rows {
                assert!(m.texels < 2.0 * m.displayed + 2e-2, "{m:?}");
            }
        }
        assert!(points.iter().any(|p| p.front));
        let doc = markdown(&points, true);
        assert!(doc.contains("Quick run") && doc.contains(BEGIN) && doc.contains(END));
    }
}
