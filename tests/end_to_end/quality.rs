//! `--quality draft|normal|high` through the binary: each preset sets its knobs, explicit
//! options override them, and the presets are ordered by the work they do on the cube. (Their
//! accuracy ordering against the exact solution is tested in `tools/accuracy-report`, which
//! owns the reference comparison.)

use crate::common;

use bake_job::report::{read_report, Report};
use bake_testkit::fixture;
use common::bake;

fn bake_cube(args: &[&str]) -> Report {
    let dir = tempfile::tempdir().expect("tempdir");
    let (out, report) = (dir.path().join("out.glb"), dir.path().join("r.json"));
    let cube = fixture("cube.gltf");
    let mut command: Vec<&std::ffi::OsStr> = vec![
        cube.as_os_str(),
        out.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
        "--target".as_ref(),
        "vertex".as_ref(),
        "--quiet".as_ref(),
    ];
    command.extend(args.iter().map(std::ffi::OsStr::new));
    let run = bake(&command);
    assert_eq!(run.code, Some(0), "{run:#?}");
    read_report(&report).expect("report")
}

#[test]
fn presets_set_their_knobs_and_order_the_work() {
    let mut last_evaluations = 0;
    let mut last_elements = 0;
    for (quality, elements_per_wall, max_error, samples) in [
        ("draft", 5, 3e-2, 49),
        ("normal", 10, 1e-2, 121),
        ("high", 19, 3e-3, 961),
    ] {
        let r = bake_cube(&["--quality", quality]);
        let o = &r.options;
        assert_eq!(o["quality"], quality);
        assert_eq!(o["ff_estimator"], "auto");
        assert_eq!(o["max_error"], max_error);
        let accuracy = r.accuracy.as_ref().expect("an accuracy object");
        assert_eq!(accuracy.max_error, max_error);
        assert_eq!(accuracy.rho_max, 0.75, "the cube's brightest wall");
        assert_eq!(o["visibility_samples"], samples);
        assert_eq!(r.counts.elements, 6 * elements_per_wall * elements_per_wall);
        // The cube needs no shadow rays at any quality.
        assert_eq!(r.counts.rays_cast, 0);
        if r.transport.kind.name() == "dense" {
            // The dense transport's tolerance comes from the target and ρ_max (about 5.6e-3
            // for draft, 1.9e-3 for normal).
            let tau = bake_core::accuracy::pair_tolerance(max_error, 0.75);
            assert_eq!(o["ff_tolerance"], tau);
            assert_eq!(o["ff_tolerance_from_max_error"], true);
            assert_eq!(accuracy.ff_tolerance, Some(tau));
            assert!(r.counts.kernel_evaluations > last_evaluations, "{quality}");
        } else {
            // `normal` refines its 600 elements and `high` has 2 166: by the cost model the
            // hierarchy is the cheaper for both (crates/bake/src/cost.rs), `draft`'s 150 stay
            // dense. The links' tolerance comes from the target: ε = E B̄ / a, a = B̄ / Ē the
            // amplification the last linking pass measured (about 1 / (1 − ρ̄) in the closed
            // cube: 2.16), so the relative link tolerance times a gives E back.
            assert_ne!(quality, "draft");
            assert_eq!(r.transport.kind.name(), "hierarchical");
            assert_eq!(o["link_tolerance"], serde_json::Value::Null);
            assert_eq!(o["link_tolerance_from_max_error"], true);
            let (t, a) = (
                accuracy.link_tolerance.expect("a link tolerance"),
                accuracy.amplification.expect("an amplification"),
            );
            assert!((2.0..2.4).contains(&a), "amplification {a}");
            assert!((t * a / max_error - 1.0).abs() < 1e-9, "{t} × {a}");
            // The hierarchy's links keep the preset's per-pair tolerance.
            let preset_tolerance = if quality == "high" { 1e-4 } else { 1e-3 };
            assert_eq!(o["ff_tolerance"], preset_tolerance);
            assert_eq!(o["ff_tolerance_from_max_error"], false);
            assert!(r.counts.links > 0);
        }
        assert!(r.counts.elements > last_elements);
        assert_eq!(
            r.counts.pairs_contour + r.counts.pairs_point_polygon + r.counts.pairs_point_point,
            r.counts.pairs_evaluated,
            "{quality}: every integrated pair is counted by its estimator"
        );
        last_evaluations = r.counts.kernel_evaluations;
        last_elements = r.counts.elements;
    }
}

#[test]
fn explicit_options_override_the_preset() {
    let r = bake_cube(&[
        "--quality",
        "draft",
        "--ff-estimator",
        "contour",
        "--subdiv",
        "3",
    ]);
    assert_eq!(r.options["quality"], "draft");
    assert_eq!(r.options["ff_estimator"], "contour");
    assert_eq!(r.counts.elements, 54);
    assert_eq!(r.counts.pairs_contour, r.counts.pairs_evaluated);

    let r = bake_cube(&["--ff-tolerance", "0.05"]);
    assert_eq!(r.options["ff_estimator"], "auto");
    assert_eq!(r.options["ff_tolerance"], 0.05);
    assert_eq!(r.options["ff_tolerance_from_max_error"], false);
    assert_eq!(r.accuracy.as_ref().and_then(|a| a.ff_tolerance), None);

    // --max-error sets the per-pair tolerance (ρ_max = 0.75), --ff-tolerance overrides it.
    let r = bake_cube(&["--max-error", "1e-2", "--subdiv", "3"]);
    assert_eq!(r.options["max_error"], 1e-2);
    assert_eq!(
        r.options["ff_tolerance"],
        bake_core::accuracy::pair_tolerance(1e-2, 0.75)
    );
    let r = bake_cube(&[
        "--max-error",
        "1e-2",
        "--ff-tolerance",
        "0.05",
        "--subdiv",
        "3",
    ]);
    assert_eq!(r.options["ff_tolerance"], 0.05);

    let r = bake_cube(&["--ff-estimator", "point-polygon", "--ff-points", "7"]);
    assert_eq!(r.options["ff_points"], 7);
    assert_eq!(r.counts.pairs_point_polygon, r.counts.pairs_evaluated);

    // --link-tolerance overrides the link tolerance --max-error derives.
    let r = bake_cube(&[
        "--transport",
        "hierarchical",
        "--link-tolerance",
        "0.02",
        "--subdiv",
        "4",
    ]);
    assert_eq!(r.options["link_tolerance"], 0.02);
    assert_eq!(r.options["link_tolerance_from_max_error"], false);
    assert_eq!(
        r.accuracy.as_ref().and_then(|a| a.link_tolerance),
        Some(0.02)
    );
}

/// The default bake is `--quality normal`, and `auto` keeps the cube within its tolerance of
/// the exact contour integral (element radiosity, relative).
#[test]
fn default_auto_estimator_stays_close_to_the_contour_integral() {
    let auto = bake_cube(&[]);
    let exact = bake_cube(&["--ff-estimator", "contour"]);
    assert_eq!(auto.options["quality"], "normal");
    let mut worst = 0.0f64;
    for (a, e) in auto.elements.iter().zip(&exact.elements) {
        for band in 0..3 {
            worst = worst.max((a.b[band] - e.b[band]).abs() / e.b[band]);
        }
    }
    // --max-error 1e-3: each F_ij within 1.9e-4 relative (ρ_max = 0.75), b within 1e-3.
    assert!(worst < 1e-3, "{worst:e}");
    eprintln!("default vs contour: {worst:.2e}");
    assert!(auto.counts.kernel_evaluations < exact.counts.kernel_evaluations);
}
