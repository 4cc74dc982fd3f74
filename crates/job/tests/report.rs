//! The bake report: contents, key order, exact float round trip, atomic writes, no NaN or
//! infinity written.

// The exporter's hand-built sample bake (one fixture for both crates' tests).
#[path = "../../exporter/tests/common/mod.rs"]
mod common;

use bake_core::{Counts, EnergyBalance};
use bake_job::report::{
    read_report, write_report, ElementsIncluded, Report, SideName, SolverInfo, SolverMethod,
};
use bake_testkit::file_names;
use common::{non_finite, sample_bake, ELEMENT};
use exporter::ExportError;
use std::path::Path;

fn solver() -> SolverInfo {
    SolverInfo {
        method: SolverMethod::Bounces,
        bounces: Some(8),
        residual: [1.0e-9, 0.1 + 0.2, f64::MIN_POSITIVE],
        residual_relative: [true, false, true],
        factorizations: 0,
        condition: [Some(1.0 / 3.0), None, Some(19_999.000_000_001)],
        iterations: [0, 7, 123],
    }
}

fn report() -> Report {
    let mut fixture = sample_bake();
    // Values whose shortest decimal form is long or extreme.
    fixture.radiosity[0] = [1.0 / 3.0, 1e-300, 123_456_789.123_456_78];
    fixture.radiosity[1] = [0.1 + 0.2, 5e-324, 2.0_f64.sqrt()];
    let mut report = Report::new(
        Path::new("scenes/cube.gltf"),
        &fixture.scene,
        &fixture.mesh,
        &fixture.radiosity,
        solver(),
    )
    .expect("a report");
    report.options = serde_json::json!({"subdivision": 2, "exposure": 0.9});
    report.counts.pairs_evaluated = 91;
    report.energy = Some(EnergyBalance {
        delivered: [0.0; 3],
        emitted: [1.0, 0.0, 2.5],
        absorbed: [0.7, 0.0, 2.5 - 1e-12],
        escaped: [0.3 - 1e-17, 0.0, 0.0],
        imbalance: [1e-17, 0.0, 4e-13],
        imbalance_relative: [true, false, true],
    });
    report.timings.insert("import".into(), 0.001_25);
    report.timings.insert("form_factors".into(), 1.0 / 7.0);
    report
}

#[test]
fn report_holds_the_scene_and_results() {
    let fixture = sample_bake();
    let report = report();
    assert_eq!(report.schema_version, 8);
    assert_eq!(report.input, "scenes/cube.gltf");
    assert_eq!(
        report.counts,
        Counts {
            polygons: 8,
            elements: 14,
            pairs_evaluated: 91,
            degenerate_dropped: 1,
            quads_merged: 4,
            primitives_skipped: 1,
            ngons_split: 0,
            faces_read: 12,
            duplicates_dropped: 2,
            coincident_dropped: 0,
            against_winding: 3,
            pairs_tested: 0,
            pairs_occludable: 0,
            rays_cast: 0,
            kernel_evaluations: 0,
            pairs_contour: 0,
            pairs_point_polygon: 0,
            pairs_point_point: 0,
            links: 0,
            nodes: 0,
            refinement_passes: 0,
            blocked_links: 0,
            polygon_pairs: 0,
            cluster_pairs_dropped: 0,
            masked_nodes: 0,
            mask_rays: 0,
        }
    );
    assert_eq!(report.warnings, fixture.scene.warnings);
    assert_eq!(report.polygons.len(), 8);
    // Polygon 3 is the back side D of node 1's doubleSided quad.
    let back = report.polygons[3];
    assert_eq!(
        (back.node, back.mesh, back.primitive, back.face),
        (1, 0, 1, 0)
    );
    assert_eq!(back.side, SideName::Back);
    assert_eq!(report.polygons[2].side, SideName::Front);

    assert_eq!(report.elements.len(), 14);
    for (entry, element) in report.elements.iter().zip(&fixture.mesh.elements) {
        assert_eq!(entry.polygon, element.polygon);
        assert_eq!(entry.centroid, element.centroid.to_array());
        assert_eq!(entry.normal, element.normal.to_array());
        assert_eq!(entry.area, element.area);
        let material =
            &fixture.scene.materials[fixture.scene.polygons[element.polygon as usize].material];
        assert_eq!(entry.rho, material.rho);
        assert_eq!(entry.e, material.emission);
    }
    // Elements 4 (triangle B, material 0) and 5 (quad C, material 1, emitting).
    assert_eq!(report.elements[4].rho, [0.8, 0.5, 0.3]);
    assert_eq!(report.elements[5].e, [1.0, 0.9, 0.8]);
    assert_eq!(report.elements[2].b, fixture.radiosity[2]);
    // Quad A's 2×2 elements are 1×1 squares.
    // (node 1's f32 quaternion is unit only to ~1e-7)
    assert!((report.elements[0].area - 1.0).abs() < 1e-6);
}

#[test]
fn report_round_trips_exactly_with_keys_in_field_order() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir.path().join("report.json");
    let report = report();
    write_report(&path, &report).expect("write the report");
    assert_eq!(
        file_names(dir.path()),
        vec!["report.json"],
        "no temporaries left"
    );

    let back = read_report(&path).expect("read the report back");
    assert_eq!(back, report);
    assert_eq!(
        back.elements[0].b[2].to_bits(),
        123_456_789.123_456_78_f64.to_bits()
    );
    assert_eq!(back.elements[1].b[1], 5e-324);

    let text = std::fs::read_to_string(&path).expect("read the text");
    let keys = [
        "schema_version",
        "input",
        "options",
        "counts",
        "timings",
        "solver",
        "energy",
        "warnings",
        "polygons",
        "elements",
    ];
    // Top-level keys are indented by two spaces.
    let positions: Vec<usize> = keys
        .iter()
        .map(|k| {
            let top_level = format!("\n  \"{k}\":");
            text.find(&top_level)
                .unwrap_or_else(|| panic!("{k} missing"))
        })
        .collect();
    assert!(
        positions.windows(2).all(|w| w[0] < w[1]),
        "key order {positions:?}"
    );
    assert!(text.contains("\"method\": \"bounces\""));
    // A band without a condition estimate is `null`.
    assert!(text.contains("\"condition\": [\n      0.3333333333333333,\n      null,"));
    assert!(text.contains("\"side\": \"back\""));
    // Deterministic: the same report gives the same bytes.
    let again = dir.path().join("again.json");
    write_report(&again, &report).expect("write again");
    assert_eq!(std::fs::read(&again).expect("read"), text.into_bytes());
}

#[test]
fn report_rejects_mismatched_radiosity_and_failed_writes_leave_nothing() {
    let fixture = sample_bake();
    let result = Report::new(
        Path::new("x.gltf"),
        &fixture.scene,
        &fixture.mesh,
        &fixture.radiosity[..3],
        solver(),
    );
    assert!(matches!(result, Err(ExportError::InvalidData(_))));

    let dir = tempfile::tempdir().expect("a temporary directory");
    let result = write_report(&dir.path().join("missing/report.json"), &report());
    assert!(matches!(result, Err(ExportError::Io { .. })));
    assert!(file_names(dir.path()).is_empty());
}

#[test]
fn a_summary_report_keeps_the_range_and_mean_of_b_and_drops_the_list() {
    let full = report();
    let mut summary = report();
    summary.keep_elements(ElementsIncluded::Summary);
    assert!(summary.elements.is_empty());
    assert_eq!(summary.elements_included, ElementsIncluded::Summary);
    let s = summary.element_summary.expect("a summary");
    assert_eq!(s.count, full.elements.len());
    // Against a direct computation over the full list.
    let area: f64 = full.elements.iter().map(|e| e.area).sum();
    assert!((s.area - area).abs() <= 1e-12 * area);
    for band in 0..3 {
        let values: Vec<f64> = full.elements.iter().map(|e| e.b[band]).collect();
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        assert_eq!(s.b_max[band], max);
        assert_eq!(s.b_min[band], min);
        assert_eq!(values[s.b_max_element[band] as usize], max);
        let mean = full
            .elements
            .iter()
            .map(|e| e.area * e.b[band])
            .sum::<f64>()
            / area;
        assert!((s.b_mean[band] - mean).abs() <= 1e-12 * mean.abs().max(1.0));
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir.path().join("summary.json");
    write_report(&path, &summary).expect("write the report");
    assert_eq!(read_report(&path).expect("read back"), summary);
    let mut none = report();
    none.keep_elements(ElementsIncluded::None);
    assert!(none.elements.is_empty() && none.element_summary.is_none());
    let mut all = report();
    all.keep_elements(ElementsIncluded::All);
    assert_eq!(all.elements, full.elements);
    assert!(all.element_summary.is_some());
}

fn report_with(radiosity: &[[f64; 3]]) -> Report {
    let fixture = sample_bake();
    let solver = SolverInfo {
        method: SolverMethod::Direct,
        bounces: None,
        residual: [0.0; 3],
        residual_relative: [false; 3],
        factorizations: 1,
        condition: [Some(3.0), None, Some(2.5)],
        iterations: [0; 3],
    };
    Report::new(
        Path::new("in.gltf"),
        &fixture.scene,
        &fixture.mesh,
        radiosity,
        solver,
    )
    .expect("a report")
}

#[test]
fn report_with_nan_is_refused_not_written_as_null() {
    let fixture = sample_bake();
    let mut radiosity = fixture.radiosity.clone();
    radiosity[ELEMENT][1] = f64::NAN;
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir.path().join("report.json");

    let message = non_finite(write_report(&path, &report_with(&radiosity)));
    let polygon = fixture.mesh.elements[ELEMENT].polygon;
    for part in [
        format!("element {ELEMENT} (polygon {polygon}: node "),
        "b [".into(),
    ] {
        assert!(message.contains(&part), "{part:?} in {message}");
    }

    let mut report = report_with(&fixture.radiosity);
    report.timings.insert("solve".into(), f64::INFINITY);
    let message = non_finite(write_report(&path, &report));
    assert!(message.contains("timing \"solve\""), "{message}");

    let mut report = report_with(&fixture.radiosity);
    report.solver.residual[2] = f64::NAN;
    let message = non_finite(write_report(&path, &report));
    assert!(message.contains("residual"), "{message}");

    let mut report = report_with(&fixture.radiosity);
    report.solver.condition[0] = Some(f64::INFINITY);
    let message = non_finite(write_report(&path, &report));
    assert!(message.contains("condition"), "{message}");

    let mut report = report_with(&fixture.radiosity);
    report.energy = Some(EnergyBalance {
        delivered: [0.0; 3],
        emitted: [1.0; 3],
        absorbed: [0.5, f64::NAN, 0.5],
        escaped: [0.5; 3],
        imbalance: [0.0; 3],
        imbalance_relative: [true; 3],
    });
    let message = non_finite(write_report(&path, &report));
    assert!(message.contains("energy absorbed"), "{message}");

    assert!(file_names(dir.path()).is_empty(), "nothing written");
    write_report(&path, &report_with(&fixture.radiosity)).expect("a finite report is written");
}
