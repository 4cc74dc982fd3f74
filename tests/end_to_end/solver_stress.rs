//! Stress tests of the solvers through the real `bake` binary: the furnace identity
//! b = e/(1 − ρ) up to ρ = 0.9999 with `--solver direct` and `--solver iterative`, a closed
//! ρ = 1 box with an emitter (no finite solution), a scene without emitters, honest
//! non-convergence, and conservation of energy (emitted = absorbed + escaped) on closed and
//! open scenes. Every run writes into a temporary directory and is checked through its report.

use bake_job::report::{read_failed_report, read_report, Report, SolverMethod};
use bake_testkit::{file_names, fixture};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `bake input dir/out.glb --report dir/report.json --ff-estimator contour args...`
/// (exact form factors: these tests hold the solver to ~1e-12).
fn run(input: &Path, dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_bake"))
        .arg(input)
        .arg(dir.join("out.glb"))
        .arg("--report")
        .arg(dir.join("report.json"))
        .args(["--ff-estimator", "contour"])
        // The uniform mesh: these tests hold the solver to ~1e-12 on the mesh they ask for.
        .args(["--refine", "off"])
        .args(args)
        .output()
        .expect("run bake")
}

/// [`run`], asserting success; returns the report.
fn bake(input: &Path, args: &[&str]) -> Report {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = run(input, dir.path(), args);
    assert!(
        out.status.success(),
        "bake {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    read_report(&dir.path().join("report.json")).expect("report")
}

/// The stderr lines that are not warnings.
fn error_lines(out: &Output) -> Vec<String> {
    String::from_utf8_lossy(&out.stderr)
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("bake: warning:"))
        .map(String::from)
        .collect()
}

/// A material: name, Kd, Ke.
type Material = (&'static str, [f64; 3], [f64; 3]);

/// One box wall: corner, edge a, edge b (a × b points inward), cuts along a (fractions).
type Strips = ([f64; 3], [f64; 3], [f64; 3], &'static [f64]);

/// The walls of the box [0,X]×[0,Y]×[0,Z] facing inward, each cut into unequal strips:
/// floor (y = 0), ceiling (y = Y), x = 0, x = X, z = 0, z = Z.
fn walls(size: [f64; 3]) -> [Strips; 6] {
    let [x, y, z] = size;
    [
        ([0., 0., 0.], [0., 0., z], [x, 0., 0.], &[0.0, 0.3, 1.0]),
        ([0., y, 0.], [x, 0., 0.], [0., 0., z], &[0.0, 1.0]),
        (
            [0., 0., 0.],
            [0., y, 0.],
            [0., 0., z],
            &[0.0, 0.2, 0.7, 1.0],
        ),
        ([x, 0., 0.], [0., 0., z], [0., y, 0.], &[0.0, 0.55, 1.0]),
        ([0., 0., 0.], [x, 0., 0.], [0., y, 0.], &[0.0, 1.0]),
        ([0., 0., z], [0., y, 0.], [x, 0., 0.], &[0.0, 0.4, 1.0]),
    ]
}

/// Writes `box.obj` + `box.mtl` into `dir`: the walls of [`walls`] except those in `omit`;
/// `material(wall, strip)` picks each strip's material from `materials`.
fn write_box_obj(
    dir: &Path,
    size: [f64; 3],
    omit: &[usize],
    materials: &[Material],
    material: impl Fn(usize, usize) -> usize,
) -> PathBuf {
    let mut obj = String::from("mtllib box.mtl\no box\n");
    let mut count = 0;
    for (wall, (c, a, b, cuts)) in walls(size).into_iter().enumerate() {
        if omit.contains(&wall) {
            continue;
        }
        for (strip, w) in cuts.windows(2).enumerate() {
            obj += &format!("usemtl {}\n", materials[material(wall, strip)].0);
            let at = |s: f64, t: f64| [0, 1, 2].map(|k| c[k] + a[k] * s + b[k] * t);
            for p in [at(w[0], 0.0), at(w[1], 0.0), at(w[1], 1.0), at(w[0], 1.0)] {
                obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
            }
            obj += &format!(
                "f {} {} {} {}\n",
                count + 1,
                count + 2,
                count + 3,
                count + 4
            );
            count += 4;
        }
    }
    std::fs::write(dir.join("box.obj"), obj).expect("write obj");
    let mut mtl = String::new();
    for (name, kd, ke) in materials {
        mtl += &format!(
            "newmtl {name}\nKd {} {} {}\nKe {} {} {}\n",
            kd[0], kd[1], kd[2], ke[0], ke[1], ke[2]
        );
    }
    std::fs::write(dir.join("box.mtl"), mtl).expect("write mtl");
    dir.join("box.obj")
}

/// A closed 1 × 0.5 × 2 box, every wall with Kd ρ and Ke e.
fn furnace_box(dir: &Path, rho: f64, e: f64) -> PathBuf {
    let walls = [("wall", [rho; 3], [e; 3])];
    write_box_obj(dir, [1.0, 0.5, 2.0], &[], &walls, |_, _| 0)
}

const FURNACE_RHOS: [f64; 5] = [0.5, 0.9, 0.99, 0.999, 0.9999];

/// Asserts emitted = absorbed + escaped to 1e-9 in every band; returns max |escaped| / emitted.
fn check_energy(name: &str, report: &Report) -> f64 {
    let energy = report
        .energy
        .as_ref()
        .expect("the report has an energy object");
    let mut escaped_fraction = 0.0f64;
    for c in 0..3 {
        eprintln!(
            "  {name} band {c}: emitted {:.9e}, absorbed {:.9e}, escaped {:.3e}, imbalance {:.1e}",
            energy.emitted[c], energy.absorbed[c], energy.escaped[c], energy.imbalance[c]
        );
        assert!(energy.imbalance_relative[c], "{name}: {energy:?}");
        assert!(energy.imbalance[c] < 1e-9, "{name}: {energy:?}");
        escaped_fraction = escaped_fraction.max(energy.escaped[c].abs() / energy.emitted[c]);
    }
    escaped_fraction
}

#[test]
fn furnace_box_gives_e_over_one_minus_rho_with_both_solvers() {
    // b = e + ρ Σ_j F_ij b_j with Σ_j F_ij = 1 everywhere: b = e/(1 − ρ). A row-sum error δ
    // shows up as about ρδ/(1 − ρ), so ρ = 0.9999 needs rows within ~1e-10 for 1e-6.
    // cond_∞(I − ρF) = (1 + ρ)/(1 − ρ) for exactly closed rows.
    let mut table = Vec::new();
    for rho_decimal in FURNACE_RHOS {
        let dir = tempfile::tempdir().expect("tempdir");
        let input = furnace_box(dir.path(), rho_decimal, 1.0);
        // tobj reads MTL numbers as f64 (`use_f64`): the ρ the bake uses is the decimal.
        let rho = rho_decimal;
        let expect = 1.0 / (1.0 - rho);
        let mut direct_b: Option<Vec<[f64; 3]>> = None;
        for solver in ["direct", "iterative"] {
            let mut args = vec!["--max-element-size", "0.2", "--solver", solver, "--quiet"];
            let mut report = {
                let out_dir = tempfile::tempdir().expect("tempdir");
                let out = run(&input, out_dir.path(), &args);
                if out.status.success() {
                    read_report(&out_dir.path().join("report.json")).expect("report")
                } else {
                    // Honest non-convergence at the rounding floor (see --tolerance): only
                    // acceptable for the iterative solver at ρ = 0.9999, with one error line.
                    let lines = error_lines(&out);
                    eprintln!("ρ = {rho_decimal} {solver}: {lines:?}");
                    assert!(
                        solver == "iterative"
                            && rho_decimal == 0.9999
                            && out.status.code() == Some(1)
                            && lines.len() == 1
                            && lines[0].contains("did not converge"),
                        "{lines:?}"
                    );
                    args.extend(["--tolerance", "1e-11"]);
                    bake(&input, &args)
                }
            };
            report.timings.clear();
            report.peak_rss_mib.clear();
            assert!(report
                .elements
                .iter()
                .all(|el| el.rho == [rho; 3] && el.e == [1.0; 3]));
            let areas: Vec<f64> = report.elements.iter().map(|el| el.area).collect();
            let (lo, hi) = (
                areas.iter().cloned().fold(f64::MAX, f64::min),
                areas.iter().cloned().fold(0.0, f64::max),
            );
            assert!(hi / lo > 1.5, "element areas should differ: {lo} .. {hi}");
            let worst = report
                .elements
                .iter()
                .flat_map(|el| el.b)
                .map(|b| (b - expect).abs() / expect)
                .fold(0.0, f64::max);
            let solver_info = &report.solver;
            let cond = solver_info.condition[0].expect("a condition estimate");
            let cond_expect = (1.0 + rho) / (1.0 - rho);
            let escaped = check_energy(&format!("ρ = {rho_decimal} {solver}"), &report);
            let vs_direct = match &direct_b {
                None => {
                    direct_b = Some(report.elements.iter().map(|el| el.b).collect());
                    0.0
                }
                Some(d) => report
                    .elements
                    .iter()
                    .zip(d)
                    .flat_map(|(el, d)| (0..3).map(move |c| (el.b[c] - d[c]).abs() / d[c]))
                    .fold(0.0, f64::max),
            };
            table.push(format!(
                "ρ = {rho_decimal:<6} {solver:<9} n = {} max rel error {worst:.3e}  cond_∞ {cond:.6e} \
                 (vs (1 + ρ)/(1 − ρ): {:+.1e})  iterations {:?}  residual {:.2e}  \
                 |escaped|/emitted {escaped:.1e}  vs direct {vs_direct:.1e}",
                report.elements.len(),
                cond / cond_expect - 1.0,
                solver_info.iterations,
                solver_info.residual[0]
            ));
            let method = if solver == "direct" {
                SolverMethod::Direct
            } else {
                SolverMethod::Iterative
            };
            assert_eq!(solver_info.method, method);
            assert_eq!(report.options["solver"], solver);
            assert!(solver_info.residual_relative.iter().all(|&r| r));
            assert_eq!(solver_info.condition, [Some(cond); 3]);
            assert!(worst < 1e-6, "ρ = {rho_decimal}, {solver}: {worst:.3e}");
            assert!(
                (cond / cond_expect - 1.0).abs() < 1e-5,
                "{cond} vs {cond_expect}"
            );
            // Closed: what "escapes" is the row-sum error, ~δ/(1 − ρ).
            assert!(escaped < 1e-5, "{escaped}");
            if solver == "iterative" {
                assert!(solver_info.iterations[0] > 0 && solver_info.factorizations == 0);
                assert!(vs_direct < 1e-8, "{vs_direct}");
            } else {
                assert_eq!(solver_info.iterations, [0; 3]);
                assert_eq!(solver_info.factorizations, 1);
            }
        }
    }
    eprintln!("furnace box 1 × 0.5 × 2, --max-element-size 0.2:");
    for line in &table {
        eprintln!("  {line}");
    }
}

#[test]
fn closed_box_with_rho_one_bakes_at_the_reflectance_ceiling_with_a_warning() {
    // ρ = 1 is lowered to --max-reflectance (0.98 by default) at import: the furnace box then
    // has b = e / (1 − 0.98) = 50 everywhere (eq. 7 with closed rows), and one warning names
    // the material.
    for (args, ceiling) in [(vec![], 0.98), (vec!["--max-reflectance", "0.9"], 0.9)] {
        let dir = tempfile::tempdir().expect("tempdir");
        let input = furnace_box(dir.path(), 1.0, 1.0);
        let mut all = vec!["--max-element-size", "0.2"];
        all.extend(args.iter().copied());
        let out = run(&input, dir.path(), &all);
        assert_eq!(out.status.code(), Some(0), "{out:?}");
        let report = read_report(&dir.path().join("report.json")).expect("report");
        let expect = 1.0 / (1.0 - ceiling);
        let worst = report
            .elements
            .iter()
            .flat_map(|el| el.b)
            .map(|b| (b - expect).abs() / expect)
            .fold(0.0f64, f64::max);
        eprintln!("ρ = 1 lowered to {ceiling}: worst |b − {expect}| / b = {worst:.2e}");
        assert!(worst < 1e-9, "{worst}");
        let warned: Vec<&String> = report
            .warnings
            .iter()
            .filter(|w| w.contains("--max-reflectance") && w.contains("\"wall\""))
            .collect();
        assert_eq!(warned.len(), 1, "{:?}", report.warnings);
        assert!(warned[0].contains(&format!("{ceiling}")), "{warned:?}");
        let accuracy = report.accuracy.expect("accuracy");
        assert_eq!(accuracy.rho_max, ceiling);
    }
}

#[test]
fn closed_box_with_rho_one_and_an_emitter_is_refused_when_kept() {
    // With --max-reflectance 1 the ρ = 1 stays: light is never absorbed and never escapes,
    // no finite solution. Both solvers (and the default) must say so in one line, exit 1 and
    // write nothing.
    for solver in [None, Some("direct"), Some("iterative")] {
        let dir = tempfile::tempdir().expect("tempdir");
        let input = furnace_box(dir.path(), 1.0, 1.0);
        let mut args = vec!["--max-element-size", "0.2", "--max-reflectance", "1"];
        if let Some(solver) = solver {
            args.extend(["--solver", solver]);
        }
        let out = run(&input, dir.path(), &args);
        let lines = error_lines(&out);
        eprintln!("ρ = 1, {solver:?}: {lines:?}");
        assert_eq!(out.status.code(), Some(1), "{lines:?}");
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert!(lines[0].starts_with("bake: error:"), "{lines:?}");
        assert!(
            lines[0].contains("band 0")
                && (lines[0].contains("singular") || lines[0].contains("did not converge")),
            "{lines:?}"
        );
        assert_eq!(
            file_names(dir.path()),
            ["box.mtl", "box.obj", "report.json"]
        );
        check_failed_report(dir.path(), &lines[0]);
    }
}

/// A failed bake writes no output but its report (issue 34), with the error line it printed
/// and exit code 1.
fn check_failed_report(dir: &Path, line: &str) {
    let failed = read_failed_report(&dir.join("report.json")).expect("the failed bake's report");
    assert_eq!(
        Some(failed.failure.error.as_str()),
        line.strip_prefix("bake: error: ")
    );
    assert_eq!(failed.failure.exit_code, 1);
}

#[test]
fn a_scene_without_emitters_is_dark_with_a_warning() {
    for solver in ["direct", "iterative"] {
        let dir = tempfile::tempdir().expect("tempdir");
        let input = furnace_box(dir.path(), 0.8, 0.0);
        let out = run(&input, dir.path(), &["--subdiv", "2", "--solver", solver]);
        assert_eq!(out.status.code(), Some(0), "{:?}", out);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr
                .lines()
                .any(|l| l.starts_with("bake: warning:") && l.contains("no emitters")),
            "{stderr}"
        );
        let report = read_report(&dir.path().join("report.json")).expect("report");
        assert!(report.elements.iter().all(|el| el.b == [0.0; 3]));
        assert_eq!(report.solver.residual, [0.0; 3]);
        assert_eq!(report.solver.residual_relative, [false; 3]);
        assert_eq!(report.solver.condition, [None; 3]);
        assert_eq!(report.solver.iterations, [0; 3]);
        let energy = report.energy.expect("energy");
        assert_eq!(energy.emitted, [0.0; 3]);
        assert_eq!(energy.imbalance, [0.0; 3]);
        assert_eq!(energy.imbalance_relative, [false; 3]);
        assert!(report.warnings.iter().any(|w| w.contains("no emitters")));
        // Nothing to compute, nothing computed: no form factor, link or ray (a 10 000-polygon
        // level without light writes its outputs as fast as it reads them).
        assert_eq!(report.counts.pairs_evaluated, 0);
        assert_eq!(report.counts.rays_cast, 0);
        for stage in ["form_factors", "links", "occludable_pairs", "solve"] {
            assert!(!report.timings.contains_key(stage), "{:?}", report.timings);
        }
    }
}

#[test]
fn an_exhausted_iteration_budget_fails_in_one_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    // The paper's cube, not a uniform furnace box: there b = e / (1 − ρ) is e's own direction
    // and one iteration can already meet 1e-14 (it does since ρ = 0.9 is read exactly).
    let input = fixture("cube.gltf");
    let out = run(
        &input,
        dir.path(),
        &[
            "--subdiv",
            "3",
            "--solver",
            "iterative",
            "--max-iterations",
            "1",
            "--tolerance",
            "1e-14",
        ],
    );
    let lines = error_lines(&out);
    eprintln!("{lines:?}");
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(lines.len(), 1, "{lines:?}");
    let line = &lines[0];
    assert!(
        line.starts_with("bake: error:")
            && line.contains("did not converge in band 0")
            && line.contains("after 1 iterations")
            && line.contains("relative residual"),
        "{line}"
    );
    assert_eq!(file_names(dir.path()), ["report.json"]);
    check_failed_report(dir.path(), line);
}

#[test]
fn energy_balances_on_the_cube_and_an_open_box() {
    // The paper's cube (closed): nothing escapes.
    let cube = fixture("cube.gltf");
    let direct = bake(&cube, &["--subdiv", "6", "--quiet"]);
    let escaped = check_energy("cube direct", &direct);
    eprintln!(
        "cube: |escaped|/emitted {escaped:.1e}, cond {:?}",
        direct.solver.condition
    );
    assert!(escaped < 1e-8, "{escaped}");
    let iterative = bake(
        &cube,
        &["--subdiv", "6", "--solver", "iterative", "--quiet"],
    );
    check_energy("cube iterative", &iterative);
    let diff = direct
        .elements
        .iter()
        .zip(&iterative.elements)
        .flat_map(|(a, b)| (0..3).map(move |c| (a.b[c] - b.b[c]).abs()))
        .fold(0.0, f64::max);
    eprintln!(
        "cube: iterative vs direct max |Δb| {diff:.1e}, iterations {:?}",
        iterative.solver.iterations
    );
    assert!(diff < 1e-10, "{diff}");
    // Truncated bounces leave light in flight: the books do not balance, and the report shows it.
    let bounces = bake(&cube, &["--subdiv", "6", "--bounces", "1", "--quiet"]);
    let energy = bounces.energy.expect("energy");
    eprintln!("cube, 1 bounce: imbalance {:?}", energy.imbalance);
    assert!(energy.imbalance.iter().all(|&i| i > 1e-3));
    assert_eq!(bounces.solver.condition, [None; 3]);

    // A box without its ceiling, a lamp strip on the floor, coloured walls: light escapes.
    let materials: [Material; 2] = [
        ("wall", [0.8, 0.5, 0.2], [0.0; 3]),
        ("lamp", [0.0; 3], [5.0, 4.0, 3.0]),
    ];
    for solver in ["direct", "iterative"] {
        let dir = tempfile::tempdir().expect("tempdir");
        let input = write_box_obj(dir.path(), [1.0, 0.5, 2.0], &[1], &materials, |w, s| {
            usize::from(w == 0 && s == 0)
        });
        let report = bake(
            &input,
            &["--max-element-size", "0.2", "--solver", solver, "--quiet"],
        );
        let escaped = check_energy(&format!("open box {solver}"), &report);
        eprintln!(
            "open box {solver}: escaped fraction {escaped:.4}, cond {:?}, iterations {:?}",
            report.solver.condition, report.solver.iterations
        );
        assert!(escaped > 0.05, "{escaped}");
    }
}

#[test]
fn iterative_results_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = furnace_box(dir.path(), 0.99, 1.0);
    let reports: Vec<Report> = ["1", "2", "3"]
        .iter()
        .map(|t| {
            let mut r = bake(
                &input,
                &[
                    "--subdiv",
                    "3",
                    "--solver",
                    "iterative",
                    "--threads",
                    t,
                    "--quiet",
                ],
            );
            r.timings.clear();
            r.peak_rss_mib.clear();
            r
        })
        .collect();
    for r in &reports[1..] {
        assert_eq!(r.elements, reports[0].elements);
        assert_eq!(r.solver, reports[0].solver);
        assert_eq!(r.energy, reports[0].energy);
    }
}

#[test]
fn solver_flags_are_documented_and_checked() {
    let help = Command::new(env!("CARGO_BIN_EXE_bake"))
        .arg("--help")
        .output()
        .expect("run bake");
    let help = String::from_utf8_lossy(&help.stdout);
    for flag in [
        "--solver",
        "--tolerance",
        "--max-iterations",
        "iterative",
        "GMRES",
    ] {
        assert!(help.contains(flag), "--help does not mention {flag}");
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let input = furnace_box(dir.path(), 0.5, 1.0);
    for args in [
        &["--bounces", "2", "--solver", "iterative"][..],
        &["--bounces", "2", "--solver", "direct"][..],
        &["--solver", "direct", "--max-iterations", "10"][..],
        &["--solver", "direct", "--tolerance", "1e-6"][..],
        &["--bounces", "2", "--tolerance", "1e-6"][..],
        &["--solver", "iterative", "--tolerance", "0"][..],
        &["--solver", "iterative", "--tolerance", "1.5"][..],
        &["--solver", "iterative", "--tolerance", "NaN"][..],
        &["--solver", "iterative", "--max-iterations", "0"][..],
        &["--solver", "gauss-seidel"][..],
    ] {
        let out = run(&input, dir.path(), args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {out:?}");
        assert_eq!(file_names(dir.path()), ["box.mtl", "box.obj"], "{args:?}");
    }
    // The options are recorded.
    let report = bake(
        &input,
        &[
            "--subdiv",
            "2",
            "--solver",
            "iterative",
            "--tolerance",
            "1e-10",
            "--max-iterations",
            "77",
            "--quiet",
        ],
    );
    assert_eq!(report.options["solver"], "iterative");
    assert_eq!(report.options["tolerance"], 1e-10);
    assert_eq!(report.options["max_iterations"], 77);
    assert!(report.solver.residual.iter().all(|&r| r <= 1e-10));
    // --tolerance alone asks for the iterative solver rather than being ignored.
    let report = bake(&input, &["--subdiv", "2", "--tolerance", "1e-9", "--quiet"]);
    assert_eq!(report.options["solver"], "iterative");
    assert_eq!(report.options["tolerance"], 1e-9);
    let report = bake(&input, &["--subdiv", "2", "--bounces", "3", "--quiet"]);
    assert_eq!(report.options["solver"], "bounces");
    assert_eq!(report.options["tolerance"], serde_json::Value::Null);
}
