//! The generated atrium read back through the baker's own importer: one polygon per quad,
//! one sun along `atrium::SUN`, every column face turned away from its axis, the courtyard
//! open to the sky (a ray straight up from its floor meets nothing) and the galleries roofed
//! (a ray straight up from a gallery meets the underside of a slab, from its front).

use bake_walkthrough::atrium::{self, Atrium};
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::process::Command;

fn small() -> Atrium {
    Atrium {
        courtyard: 12.0,
        storeys: 2,
        facets: 8,
        segments: 4,
        ..Atrium::default()
    }
}

/// Runs `walkthrough atrium` with the small atrium's options and returns the written .gltf.
fn generate(dir: &Path) -> PathBuf {
    let out = dir.join("atrium.gltf");
    let a = small();
    let status = Command::new(env!("CARGO_BIN_EXE_walkthrough"))
        .args(["atrium", "--courtyard", &a.courtyard.to_string()])
        .args(["--storeys", &a.storeys.to_string()])
        .args(["--facets", &a.facets.to_string()])
        .args(["--segments", &a.segments.to_string()])
        .arg(&out)
        .status()
        .expect("running walkthrough");
    assert!(status.success(), "walkthrough atrium failed");
    out
}

/// Whether the ray o + t d (t > 1e-6) meets a polygon, and the normal of the nearest.
fn first_hit(polygons: &[importer::Polygon], o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
    let mut best: Option<(f64, DVec3)> = None;
    for p in polygons {
        let denom = p.normal.dot(d);
        if denom.abs() < 1e-12 {
            continue;
        }
        let t = p.normal.dot(p.vertices[0] - o) / denom;
        if t <= 1e-6 || best.is_some_and(|(b, _)| t >= b) {
            continue;
        }
        let x = o + d * t;
        let v = &p.vertices;
        let inside = (0..v.len()).all(|k| {
            let (a, b) = (v[k], v[(k + 1) % v.len()]);
            (b - a).cross(x - a).dot(p.normal) >= -1e-9
        });
        if inside {
            best = Some((t, p.normal));
        }
    }
    best
}

#[test]
fn the_atrium_reads_back_open_to_the_sky_with_its_sun() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = generate(dir.path());
    let scene = importer::load(&path).expect("the atrium imports");
    let floor = atrium::atrium(&small()).expect("the atrium");
    assert_eq!(
        scene.polygons.len(),
        floor.quad_count(),
        "one polygon per quad"
    );
    assert!(scene.polygons.iter().all(|p| p.vertices.len() == 4));
    // Columns: 12 m / 3 m = 4 per side, 4 sides, 2 storeys, 8 × 4 faces each.
    let columns = 4 * 4 * 2 * 8 * 4;
    // Per storey 4 floor strips, 4 ceiling strips, 4 back walls, 4 slab edges; the courtyard
    // floor; the roof's 4 strips.
    assert_eq!(floor.quad_count(), columns + 2 * 16 + 1 + 4);
    assert_eq!(scene.lights.len(), 1);
    let sun = DVec3::from(atrium::SUN);
    assert!((scene.lights[0].direction - sun).length() < 1e-6);
    // Column faces (horizontal normals off the axes) face away from their column's axis:
    // the nearest of the columns' centres, (t, ±6.5) and (±6.5, t) for t = −4.5 … 4.5.
    let offset = 6.0 + atrium::COLUMN_SETBACK;
    let ts = [-4.5, -1.5, 1.5, 4.5];
    let axes: Vec<DVec3> = ts
        .iter()
        .flat_map(|&t| {
            [
                DVec3::new(t, 0.0, -offset),
                DVec3::new(t, 0.0, offset),
                DVec3::new(-offset, 0.0, t),
                DVec3::new(offset, 0.0, t),
            ]
        })
        .collect();
    let mut slanted = 0;
    for p in &scene.polygons {
        let n = p.normal;
        if n.y.abs() < 1e-9 && n.x.abs() > 1e-3 && n.z.abs() > 1e-3 {
            slanted += 1;
            let c = p.vertices.iter().copied().sum::<DVec3>() / 4.0;
            let flat = DVec3::new(c.x, 0.0, c.z);
            let axis = axes
                .iter()
                .copied()
                .min_by(|a, b| (flat - *a).length().total_cmp(&(flat - *b).length()))
                .expect("columns");
            assert!((flat - axis).length() < atrium::COLUMN_RADIUS + 1e-3);
            assert!(
                n.dot(flat - axis) > 0.0,
                "a column face at {c} faces its axis"
            );
        }
    }
    assert!(slanted > 0);
    // Open to the sky over the courtyard; under a slab in the gallery.
    assert!(first_hit(&scene.polygons, DVec3::new(0.5, 0.1, 0.3), DVec3::Y).is_none());
    let (_, n) = first_hit(&scene.polygons, DVec3::new(7.5, 0.1, 0.3), DVec3::Y)
        .expect("the gallery is roofed");
    assert!(n.y < -0.999, "the slab's underside faces down");
}

#[test]
fn the_atrium_is_deterministic() {
    let (a, b) = (
        tempfile::tempdir().expect("tempdir"),
        tempfile::tempdir().expect("tempdir"),
    );
    for dir in [&a, &b] {
        generate(dir.path());
    }
    for name in ["atrium.gltf", "atrium.bin"] {
        let read = |d: &tempfile::TempDir| std::fs::read(d.path().join(name)).expect("read");
        assert!(read(&a) == read(&b), "{name} differs between runs");
    }
}
