//! Real assets as they come (issue 29), on the repros cut from real MGF scenes in
//! `../shared/corpus/repro` (skipped without them, unless `BAKE_REQUIRE_CORPUS=1` or
//! `BAKE_REQUIRE_ALL=1`): overlapping inward-wound boxes whose coincident tops are both seen
//! (rows near 2) and an object of chairs stacked on copies of itself used to be refused as
//! "singular" with every ρ < 1. They bake with default options, every dense row Σ_j F_ij ≤ 1,
//! and the overlapping boxes give the bake of the same file with the duplicate box removed by
//! hand.

use crate::common;

use bake_job::report::{read_report, Report};
use bake_testkit::{shared_dir, skip};
use common::bake_default_in;
use std::path::{Path, PathBuf};

/// `../shared/corpus/repro`.
fn repro_dir() -> PathBuf {
    shared_dir().join("corpus/repro")
}

fn repro(name: &str) -> Option<PathBuf> {
    let path = repro_dir().join(name);
    if path.is_file() {
        Some(path)
    } else {
        skip(
            "BAKE_REQUIRE_CORPUS",
            &format!("{} is missing", path.display()),
        );
        None
    }
}

/// Bakes `input` with exactly `args` (the defaults otherwise); asserts exit 0 and returns the
/// report and the warning lines.
fn bake(input: &Path, dir: &Path, args: &[&str]) -> (Report, Vec<String>) {
    let report = dir.join("report.json");
    let mut all = vec![
        input.to_string_lossy().into_owned(),
        dir.join("out.glb").to_string_lossy().into_owned(),
        "--report".into(),
        report.to_string_lossy().into_owned(),
    ];
    all.extend(args.iter().map(|s| s.to_string()));
    let run = bake_default_in(None, &all).success();
    let warnings = run.warning_lines().iter().map(|s| s.to_string()).collect();
    (read_report(&report).expect("report"), warnings)
}

/// Every dense row of F the solver was given sums to at most 1 + its stated accuracy.
fn assert_rows_bounded(report: &Report) {
    let accuracy = report.accuracy.as_ref().expect("accuracy");
    let rows = accuracy.row_sums.expect("dense row sums");
    assert!(
        rows.largest_after <= 1.0 + accuracy.row_sum_accuracy,
        "{rows:?}"
    );
    for c in 0..3 {
        let energy = report.energy.as_ref().expect("energy");
        assert!(energy.escaped[c] >= 0.0, "{energy:?}");
    }
}

#[test]
fn graz_overlap_bakes_with_default_options_like_the_hand_cleaned_file() {
    let Some(input) = repro("graz_overlap.obj") else {
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let (report, warnings) = bake(&input, dir.path(), &[]);
    eprintln!("{warnings:?}");
    // Small, with occluders: `auto` tries the hierarchy, whose rows (up to 1.9 here) are not
    // limited, finds no solution and bakes it with the dense transport, saying so.
    assert_eq!(report.transport.kind.name(), "dense");
    assert!(
        report.transport.reason.contains("had no solution"),
        "{}",
        report.transport.reason
    );
    assert!(warnings.iter().any(|w| w.contains("had no solution")));
    assert_rows_bounded(&report);
    let rows = report
        .accuracy
        .as_ref()
        .and_then(|a| a.row_sums)
        .expect("rows");
    assert!(rows.largest_before > 1.5 && rows.seen_twice > 0, "{rows:?}");
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("summed past 1") && w.contains("room_l_box_red")),
        "{warnings:?}"
    );

    // By hand: the second box, a copy of the first shifted by 4 and 6 mm whose top and bottom
    // coincide with most of the first's (removing only those two faces would open its 4–6 mm
    // rim and let light into both boxes, which the file keeps dark).
    let text = std::fs::read_to_string(&input).expect("read the repro");
    let second = text
        .find("o room_l_box_red/room_l_box_red.12")
        .expect("the second box");
    let cleaned = text[..second].to_string();
    assert_eq!(text.lines().count() - cleaned.lines().count(), 8);
    let hand = tempfile::tempdir().expect("tempdir");
    std::fs::write(hand.path().join("graz_overlap.obj"), cleaned).expect("write");
    std::fs::copy(
        repro_dir().join("graz_overlap.mtl"),
        hand.path().join("graz_overlap.mtl"),
    )
    .expect("copy the mtl");
    let out = tempfile::tempdir().expect("tempdir");
    let (reference, _) = bake(&hand.path().join("graz_overlap.obj"), out.path(), &[]);
    // Elements of the polygons both bakes have, matched by centroid and normal.
    let key = |e: &bake_job::report::ElementEntry| {
        let q = |v: f64| (v * 1e6).round() as i64;
        (
            e.centroid.map(q),
            e.normal.map(|v| (v * 1e3).round() as i64),
        )
    };
    let scale = reference
        .elements
        .iter()
        .flat_map(|e| e.b)
        .fold(0.0f64, f64::max);
    let mut matched = 0;
    for e in &report.elements {
        if let Some(r) = reference.elements.iter().find(|r| key(r) == key(e)) {
            matched += 1;
            for c in 0..3 {
                let d = (e.b[c] - r.b[c]).abs();
                assert!(d <= 0.02 * r.b[c].max(0.0) + 1e-9 * scale, "{e:?} vs {r:?}");
            }
        }
    }
    eprintln!(
        "graz_overlap: {} elements, {} matched in the hand-cleaned bake",
        report.elements.len(),
        matched
    );
    assert!(matched * 10 >= report.elements.len() * 8, "{matched}");
}

#[test]
fn hospital_chairs_bake_with_rows_at_most_one() {
    let Some(input) = repro("hospital_chairs.obj") else {
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    // The uniform mesh (the default refines it to ~1 100 elements in ~30 s of release time).
    let (report, warnings) = bake(&input, dir.path(), &["--refine", "off"]);
    assert_rows_bounded(&report);
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("718 faces coincide with an earlier face")),
        "{warnings:?}"
    );
    let b_max = report
        .elements
        .iter()
        .flat_map(|e| e.b)
        .fold(0.0f64, f64::max);
    assert!(b_max.is_finite() && b_max > 0.0, "{b_max}");
}
