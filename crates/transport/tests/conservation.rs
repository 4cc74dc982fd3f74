//! Energy conservation and leaks of the hierarchical transport (issue 31), against the dense
//! transport of the same mesh as an independent reference (every element pair integrated,
//! Goral et al. 1984 eq. 13, rows past 1 scaled to 1):
//!
//! - row sums `H = F·1` (the share of an element's light that lands somewhere): the
//!   hierarchy's may not exceed 1 beyond a tolerance, nor fall short of the dense ones
//!   (light lost on links, blocked pairs and dropped clusters shows up here, as escaped);
//! - the escaped share of the emitted power, `Σ A b (1 − F·1) / Σ A e`, close to the dense one;
//! - no element the dense solve finds fully hidden (b = 0) lit by push–pull;
//! - both transports' escape against an estimate that shares nothing with them but the
//!   geometry: particles traced from the emitters (`photon_escape`), reflected by each
//!   polygon's ρ until they leave through an opening or reach a polygon's back.
//!
//! `measure` (ignored; `cargo test --release -p bake-transport --test conservation -- --ignored
//! --nocapture`) prints the numbers of docs/accuracy.md on the Cornell box at the size
//! and on a 2 × 2 office floor written by `tools/walkthrough` (path in `BAKE_OFFICE`).

use bake_transport::{build, DenseOptions, HierarchicalOptions, Options, Problem, Progress};
use form_factor::{ContourOptions, Estimator};
use glam::DVec3;
use mesher::Subdivision;
use rayon::prelude::*;
use solver::{IterativeOptions, Operator, BANDS};
use std::path::Path;
use visibility::{cosine_direction, point_on_element, Occluders, SplitMix64};

struct Quiet;
impl Progress for Quiet {
    fn start(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
}

/// What one transport gives on one mesh.
struct Run {
    rows: Vec<f64>,
    b: Vec<[f64; BANDS]>,
    escaped: f64,
    links: u64,
    blocked: u64,
    dropped: u64,
}

struct Scene {
    polygons: Vec<scene::Polygon>,
    mesh: mesher::ElementMesh,
    occluders: Occluders,
    rho: Vec<[f64; BANDS]>,
    e: Vec<[f64; BANDS]>,
}

fn scene(path: &Path, size: f64) -> Scene {
    let s = importer::load(path).expect("load");
    let mesh = mesher::mesh(&s.polygons, Subdivision::MaxSize(size)).expect("mesh");
    let occluders = Occluders::new(&s.polygons).expect("occluders");
    let (rho, e) = mesh
        .elements
        .iter()
        .map(|el| {
            let m = &s.materials[s.polygons[el.polygon as usize].material];
            (m.rho.map(|r| r.min(0.98)), m.emission)
        })
        .unzip();
    Scene {
        polygons: s.polygons,
        mesh,
        occluders,
        rho,
        e,
    }
}

fn run(s: &Scene, options: &Options) -> Run {
    let problem = Problem {
        polygons: &s.polygons,
        mesh: &s.mesh,
        occluders: &s.occluders,
        rho: &s.rho,
        source: &s.e,
    };
    let start = std::time::Instant::now();
    let built = build(&problem, options, &Quiet, &mut |_| {}).expect("build");
    let (links, blocked, dropped) = match &built.stats {
        bake_transport::Stats::Hierarchical(h) => {
            println!(
                "hierarchy: {} links, relative tolerance {:.2e}, amplification {:.2}, built in {:.2} s",
                h.links,
                h.relative_tolerance,
                h.amplification,
                start.elapsed().as_secs_f64()
            );
            (h.links, h.blocked_links, h.clusters_dropped)
        }
        _ => (0, 0, 0),
    };
    let op = built.operator.view().expect("view");
    let n = op.n();
    let mut rows = vec![0.0; n];
    op.apply(&vec![1.0; n], &mut rows);
    let solution = solver::solve_iterative(
        &op,
        &s.rho,
        &s.e,
        &IterativeOptions {
            tolerance: 1e-10,
            condition: false,
            ..IterativeOptions::default()
        },
    )
    .expect("solve");
    let area: Vec<f64> = s.mesh.elements.iter().map(|el| el.area).collect();
    let balance = solver::energy_balance(&op, &area, &s.rho, &s.e, &solution.b).expect("energy");
    let escaped = balance.escaped.iter().sum::<f64>() / balance.emitted.iter().sum::<f64>();
    Run {
        rows,
        b: solution.b,
        escaped,
        links,
        blocked,
        dropped,
    }
}

fn dense() -> Options {
    Options::Dense(DenseOptions {
        estimator: Estimator::Auto { tolerance: 1e-3 },
        contour: ContourOptions::default(),
        samples: 121,
        row_sum_margin: 0.05,
    })
}

/// The hierarchical transport at its defaults (link tolerance 1 % of the mean radiosity, the
/// `normal` preset's), or at `BAKE_LINK_TOLERANCE` (or derived from `BAKE_MAX_ERROR`) and without shadow masks when
/// `BAKE_SHADOW_MASKS=0`, for [`measure`].
fn hierarchical() -> Options {
    let mut o = HierarchicalOptions::default();
    if let Some(t) = std::env::var("BAKE_LINK_TOLERANCE")
        .ok()
        .and_then(|t| t.parse().ok())
    {
        o.link_tolerance = bake_transport::LinkTolerance::OfMeanRadiosity(t);
    }
    if let Some(e) = std::env::var("BAKE_MAX_ERROR")
        .ok()
        .and_then(|t| t.parse().ok())
    {
        o.link_tolerance = bake_transport::LinkTolerance::FromMaxError(e);
    }
    if std::env::var("BAKE_SHADOW_MASKS").is_ok_and(|v| v == "0") {
        o.shadow_masks = false;
    }
    Options::Hierarchical(o)
}

/// The numbers compared: per-row and area-weighted row-sum differences, RMS and worst element
/// (relative to the dense mean b), hidden elements lit, escaped shares.
#[derive(Debug)]
#[allow(dead_code)] // Some fields are read only through Debug, in the printed measurements.
struct Comparison {
    elements: usize,
    max_row: f64,
    rows_above_1: usize,
    /// Σ A (H_h − H_d) / Σ A, and the same of |H_h − H_d|.
    row_bias: f64,
    row_abs: f64,
    /// Σ A b_d (H_h − H_d) / Σ A e: the escape the row differences account for.
    row_escape: f64,
    rms: f64,
    worst: f64,
    /// Elements with dense b = 0 whose hierarchical b exceeds 1e-3 × mean b.
    hidden_lit: usize,
    hidden: usize,
    escaped_dense: f64,
    escaped_hierarchical: f64,
    links: u64,
    blocked: u64,
    dropped: u64,
}

fn compare(s: &Scene, d: &Run, h: &Run) -> Comparison {
    let els = &s.mesh.elements;
    let area: f64 = els.iter().map(|e| e.area).sum();
    let power: f64 = els
        .iter()
        .zip(&s.e)
        .map(|(el, e)| el.area * e.iter().sum::<f64>())
        .sum();
    let mean = |b: &[[f64; BANDS]]| {
        els.iter()
            .zip(b)
            .map(|(el, b)| el.area * b.iter().sum::<f64>() / 3.0)
            .sum::<f64>()
            / area
    };
    let mean_b = mean(&d.b);
    let (mut num, mut den, mut worst) = (0.0, 0.0, 0.0f64);
    let (mut hidden, mut hidden_lit) = (0, 0);
    let (mut bias, mut abs, mut escape) = (0.0, 0.0, 0.0);
    for (k, el) in els.iter().enumerate() {
        let a = el.area;
        for c in 0..BANDS {
            num += a * (h.b[k][c] - d.b[k][c]).powi(2);
            den += a * d.b[k][c].powi(2);
            worst = worst.max((h.b[k][c] - d.b[k][c]).abs() / mean_b);
        }
        if s.e[k].iter().all(|v| *v == 0.0) && d.b[k].iter().all(|v| *v == 0.0) {
            hidden += 1;
            if h.b[k].iter().any(|v| *v > 1e-3 * mean_b) {
                hidden_lit += 1;
            }
        }
        let dr = h.rows[k] - d.rows[k];
        bias += a * dr;
        abs += a * dr.abs();
        escape += a * d.b[k].iter().sum::<f64>() * dr;
    }
    Comparison {
        elements: els.len(),
        max_row: h.rows.iter().cloned().fold(0.0, f64::max),
        rows_above_1: h.rows.iter().filter(|r| **r > 1.0 + 1e-3).count(),
        row_bias: bias / area,
        row_abs: abs / area,
        row_escape: escape / power,
        rms: (num / den).sqrt(),
        worst,
        hidden_lit,
        hidden,
        escaped_dense: d.escaped,
        escaped_hierarchical: h.escaped,
        links: h.links,
        blocked: h.blocked,
        dropped: h.dropped,
    }
}

/// The escaped share of the emitted power (all bands together) by tracing `photons`
/// particles from the emitters: each starts at a point of an emitting element drawn by its
/// power, leaves in a cosine-distributed direction, and at every front-side hit continues
/// with its band weights times the polygon's ρ (Russian roulette on the largest, so paths
/// end without bias); it escapes where a ray meets nothing or a polygon's back (one-sided
/// surfaces: the light there leaves the solution). Independent of the form factors, the
/// links and the solver: only the polygons, their ρ and the elements' emission. Seeded per
/// chunk of particles, so the result does not depend on threads.
fn photon_escape(s: &Scene, photons: u64) -> f64 {
    let els = &s.mesh.elements;
    // Per polygon, its ρ (uniform over its elements: materials are per polygon here).
    let mut rho = vec![[0.0; BANDS]; s.polygons.len()];
    for (el, r) in els.iter().zip(&s.rho) {
        rho[el.polygon as usize] = *r;
    }
    let power: Vec<f64> = els
        .iter()
        .zip(&s.e)
        .map(|(el, e)| el.area * e.iter().sum::<f64>())
        .collect();
    let total: f64 = power.iter().sum();
    let mut cumulative = Vec::with_capacity(power.len());
    let mut sum = 0.0;
    for p in &power {
        sum += p;
        cumulative.push(sum);
    }
    let (lo, hi) = s
        .mesh
        .vertices
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    let reach = 4.0 * (hi - lo).length();
    let lift = s.occluders.ray_offset();
    let chunks = 64u64;
    let escaped: f64 = (0..chunks)
        .into_par_iter()
        .map(|chunk| {
            let mut rng = SplitMix64::new(0x9407_0000 + chunk);
            let mut escaped = 0.0;
            for _ in 0..photons / chunks {
                let t = rng.next_f64() * total;
                let k = cumulative.partition_point(|&c| c <= t).min(els.len() - 1);
                let el = &els[k];
                let e = s.e[k];
                let e_sum: f64 = e.iter().sum();
                // Weights per band, summing to 1 (a share of the emitted power).
                let mut w = e.map(|v| v / e_sum);
                let mut at = point_on_element(&s.mesh, k, &mut rng);
                let (mut normal, mut polygon) = (el.normal, el.polygon as usize);
                loop {
                    let dir = cosine_direction(normal, &mut rng);
                    let from = at + normal * lift;
                    match s.occluders.first_hit(from, from + dir * reach, polygon) {
                        Some(hit) if hit.front => {
                            let r = rho[hit.polygon];
                            let keep = r[0].max(r[1]).max(r[2]);
                            if keep <= 0.0 || rng.next_f64() >= keep {
                                break;
                            }
                            for (wc, rc) in w.iter_mut().zip(r) {
                                *wc *= rc / keep;
                            }
                            at = from + dir * reach * hit.t;
                            polygon = hit.polygon;
                            normal = s.polygons[polygon].normal;
                        }
                        _ => {
                            escaped += w.iter().sum::<f64>();
                            break;
                        }
                    }
                }
            }
            escaped
        })
        .collect::<Vec<f64>>()
        .iter()
        .sum();
    escaped / (photons / chunks * chunks) as f64
}

/// Particles per escape estimate: the escaped share's standard error is below
/// √(share / photons) ≈ 3e-4 at 2e5 for shares up to 2 % (0.1 % at the Cornell box's 31 %).
const PHOTONS: u64 = 200_000;

fn measure_one(path: &Path, size: f64) -> Comparison {
    let s = scene(path, size);
    let d = run(&s, &dense());
    let h = run(&s, &hierarchical());
    println!(
        "{}: escaped by particle tracing {}",
        path.display(),
        photon_escape(&s, PHOTONS)
    );
    compare(&s, &d, &h)
}

/// The report's escape (the solver's `Σ A b (1 − F·1)`) on the hierarchical transport agrees
/// with particles traced from the emitters (issue 31: within 2 % of the emitted power) on the
/// open Cornell box (its front is open: about a third leaves) and the closed two rooms.
#[test]
fn fixtures_escape_matches_particle_tracing() {
    for (name, size) in [("cornell.gltf", 40.0), ("two-rooms.gltf", 0.25)] {
        check_escape_against_particles(name, &scene(&fixture(name), size));
    }
}

/// The hierarchy's escape on `s` within 2 % of the emitted power of the particles'.
fn check_escape_against_particles(name: &str, s: &Scene) {
    let h = run(s, &hierarchical());
    let photons = photon_escape(s, PHOTONS);
    let line = format!(
        "{name}: {} elements, escaped {} (hierarchical), {photons} (particles)",
        s.mesh.elements.len(),
        h.escaped
    );
    println!("{line}");
    assert!((h.escaped - photons).abs() <= 0.02, "{line}");
}

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(name)
}

/// A 2 × 2-room office floor (4 m rooms, doors, desks open below, one-sided ceiling lamps)
/// written by `tools/walkthrough` into a fresh temporary folder, meshed at `size` metres.
fn office(size: f64) -> Scene {
    office_of(2, size)
}

/// An `n` × `n`-room office floor as [`office`].
fn office_of(n: usize, size: f64) -> Scene {
    use bake_walkthrough::{gltf, office};
    let dir = std::env::temp_dir().join(format!(
        "bake-conservation-{}-{n}-{size}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).expect("temporary folder");
    let path = dir.join("office.gltf");
    let floor = office::office(office::Rooms { x: n, z: n }, 4.0, 3.0).expect("office floor");
    gltf::write(&floor, &path).expect("write the floor");
    let s = scene(&path, size);
    let _ = std::fs::remove_dir_all(&dir);
    s
}

/// Light is neither lost nor made on the hierarchy: on a closed office floor (where the dense
/// transport's escape is only the light that reaches the back of the one-sided desks and
/// lamps) the hierarchical escaped share of the emitted power is within 0.3 % of the dense one
/// (issue 31's target; 1.45 % before shadow masks, when coarse links lit the floor under the
/// desks, whose reflection then left through the desks' backs; 1.85 % before blocked links
/// were bounded by FAINT × ε), and its area-weighted mean row sum within 0.5 % of the dense
/// one's, while no row gathers more than 1.2 (single rows carry the links' receiver error).
#[test]
fn office_floor_escape_matches_dense() {
    let s = office(0.5);
    let d = run(&s, &dense());
    let h = run(&s, &hierarchical());
    let c = compare(&s, &d, &h);
    println!("{c:#?}");
    let photons = photon_escape(&s, PHOTONS);
    println!("escaped by particle tracing: {photons}");
    for (transport, escaped) in [("dense", d.escaped), ("hierarchical", h.escaped)] {
        assert!(
            (escaped - photons).abs() <= 0.02,
            "{transport}: escaped {escaped}, particles {photons}"
        );
    }
    assert!(
        (c.escaped_hierarchical - c.escaped_dense).abs() <= 0.003,
        "escaped {} (hierarchical) vs {} (dense)",
        c.escaped_hierarchical,
        c.escaped_dense
    );
    assert!(
        c.row_bias.abs() <= 5e-3,
        "mean row sum off by {}",
        c.row_bias
    );
    assert!(c.max_row <= 1.2, "a row gathers {}", c.max_row);
}

/// No leak: an element the dense solve finds fully hidden (b = 0: under a desk's leg, against
/// a wall) receives nothing beyond 1e-3 × the mean b (before shadow masks, 6 of its 6 did:
/// push–pull handed a coarse link's light to hidden children evenly).
#[test]
fn office_floor_hidden_elements_stay_dark() {
    let s = office(0.5);
    let c = compare(&s, &run(&s, &dense()), &run(&s, &hierarchical()));
    assert_eq!(
        c.hidden_lit, 0,
        "{} of {} hidden elements lit",
        c.hidden_lit, c.hidden
    );
}

/// The larger office floors (4 × 4 and 8 × 8 rooms at 0.25 m, 22 288 and 88 544 elements):
/// the hierarchy's escape against the particles, within 2 % of the emitted power.
#[test]
#[ignore = "88 544 elements: run in a release build"]
fn office_floors_escape_matches_particle_tracing() {
    for n in [4, 8] {
        check_escape_against_particles(&format!("office {n} x {n}"), &office_of(n, 0.25));
    }
}

#[test]
#[ignore = "dense references of ~1 500 and ~4 200 elements: run in a release build"]
fn measure() {
    if let Ok(office) = std::env::var("BAKE_OFFICE") {
        println!(
            "office 2x2 at 0.5: {:#?}",
            measure_one(Path::new(&office), 0.5)
        );
    }
    println!(
        "cube at diagonal/32: {:#?}",
        measure_one(&fixture("cube.gltf"), 3f64.sqrt() / 32.0)
    );
    println!(
        "cornell at 27: {:#?}",
        measure_one(&fixture("cornell.gltf"), 27.0)
    );
    println!(
        "two rooms at 0.2: {:#?}",
        measure_one(&fixture("two-rooms.gltf"), 0.2)
    );
}
