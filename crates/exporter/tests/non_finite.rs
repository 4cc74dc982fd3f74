//! No NaN or infinity reaches a baked glTF: the writer checks every value before writing,
//! names the element and its polygon's origin, and writes nothing (the report's check is
//! bake-job's `tests/report.rs`).

mod common;

use bake_exporter::{write_gltf, Bake, ExportError, Shading};
use bake_testkit::file_names;
use common::{non_finite, sample_bake, Fixture, ELEMENT};

fn bake<'a>(fixture: &'a Fixture, radiosity: &'a [[f64; 3]], shading: Shading) -> Bake<'a> {
    Bake {
        scene: &fixture.scene,
        mesh: &fixture.mesh,
        radiosity,
        irradiance: None,
        error: None,
        shading,
        exposure: 1.0,
        probes: None,
    }
}

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
