//! No NaN or infinity reaches an output file: the glTF writer and the report writer check
//! every value before writing, name the element and its polygon's origin, and write
//! nothing.

mod common;

use bake_exporter::report::{write_report, EnergyInfo, Report, SolverInfo, SolverMethod};
use bake_exporter::{write_gltf, Bake, ExportError, Shading};
use bake_testkit::file_names;
use common::{sample_bake, Fixture};
use std::path::Path;

fn bake<'a>(fixture: &'a Fixture, radiosity: &'a [[f64; 3]], shading: Shading) -> Bake<'a> {
    Bake {
        scene: &fixture.scene,
        mesh: &fixture.mesh,
        radiosity,
        irradiance: None,
        error: None,
        shading,
        exposure: 1.0,
    }
}

/// The error's message, asserting it is a one-line `NonFinite`.
fn non_finite(result: Result<(), ExportError>) -> String {
    let error = result.expect_err("a non-finite value is refused");
    assert!(matches!(error, ExportError::NonFinite { .. }), "{error:?}");
    let message = error.to_string();
    assert!(!message.contains('\n'), "{message}");
    message
}

/// An element of node 2's instance of quad A (polygon 4).
const ELEMENT: usize = 8;

#[test]
fn infinite_or_nan_radiosity_is_refused_naming_the_element() {
    let fixture = sample_bake();
    let dir = tempfile::tempdir().expect("a temporary directory");
    for (bad, shading, name) in [
        (f64::INFINITY, Shading::Flat, "out.glb"),
        (f64::NAN, Shading::Smooth, "out.gltf"),
        (f64::NEG_INFINITY, Shading::Smooth, "out.glb"),
    ] {
        let mut radiosity = fixture.radiosity.clone();
        radiosity[ELEMENT][2] = bad;
        let message = non_finite(write_gltf(
            &dir.path().join(name),
            &bake(&fixture, &radiosity, shading),
        ));
        let polygon = fixture.mesh.elements[ELEMENT].polygon;
        let origin = fixture.scene.polygons[polygon as usize].origin;
        for part in [
            format!("element {ELEMENT} "),
            format!("polygon {polygon}: node {}", origin.node),
            format!("face {}", origin.face),
            "radiosity".into(),
        ] {
            assert!(message.contains(&part), "{part:?} in {message}");
        }
    }
    assert!(file_names(dir.path()).is_empty(), "nothing written");
}

#[test]
fn radiosity_too_large_for_f32_is_refused_as_stored() {
    // Finite in f64, infinite as the f32 `_RADIOSITY` holds it (COLOR_0 clamps to 1).
    let fixture = sample_bake();
    let mut radiosity = fixture.radiosity.clone();
    radiosity[ELEMENT][0] = 1e300;
    let dir = tempfile::tempdir().expect("a temporary directory");
    let message = non_finite(write_gltf(
        &dir.path().join("out.glb"),
        &bake(&fixture, &radiosity, Shading::Flat),
    ));
    assert!(
        message.contains(&format!("element {ELEMENT} ")),
        "{message}"
    );
    assert!(message.contains("_RADIOSITY"), "{message}");
    assert!(file_names(dir.path()).is_empty(), "nothing written");
}

#[test]
fn nan_vertex_position_is_refused_naming_the_element() {
    let mut fixture = sample_bake();
    let corner = fixture.mesh.elements[ELEMENT].corner_indices()[0] as usize;
    fixture.mesh.vertices[corner].y = f64::NAN;
    let radiosity = fixture.radiosity.clone();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let message = non_finite(write_gltf(
        &dir.path().join("out.gltf"),
        &bake(&fixture, &radiosity, Shading::Flat),
    ));
    assert!(message.contains("POSITION"), "{message}");
    assert!(message.contains("element "), "{message}");
    assert!(file_names(dir.path()).is_empty(), "nothing written");
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
    report.energy = Some(EnergyInfo {
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
