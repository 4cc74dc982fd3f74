//! The generated floors read back through the baker's own importer and mesher: element counts
//! on target, quads only, emission where the panels are, floors and ceilings of the right area,
//! and every room closed (rays from inside always hit a surface from its front).

use bake_walkthrough::office::{self, Rooms};
use glam::DVec3;
use importer::{Polygon, Scene};
use std::path::{Path, PathBuf};
use std::process::Command;

const SIZE: f64 = 4.0;
const HEIGHT: f64 = 3.0;
const ELEMENT: f64 = 0.25;

/// Runs `walkthrough office` and returns the written .gltf.
fn generate(dir: &Path, rooms: &str) -> PathBuf {
    let out = dir.join(format!("office-{rooms}.gltf"));
    let status = Command::new(env!("CARGO_BIN_EXE_walkthrough"))
        .args(["office", "--rooms", rooms])
        .arg(&out)
        .status()
        .expect("running walkthrough");
    assert!(
        status.success(),
        "walkthrough office --rooms {rooms} failed"
    );
    out
}

fn area(p: &Polygon) -> f64 {
    let v = &p.vertices;
    (1..v.len() - 1)
        .map(|k| (v[k] - v[0]).cross(v[k + 1] - v[0]).length() / 2.0)
        .sum()
}

fn material<'a>(scene: &'a Scene, p: &Polygon) -> &'a str {
    scene.materials[p.material].name.as_deref().unwrap_or("")
}

/// Sum of the areas of polygons of material `name` whose normal is `normal`.
fn area_of(scene: &Scene, name: &str, normal: DVec3) -> f64 {
    scene
        .polygons
        .iter()
        .filter(|p| material(scene, p) == name && p.normal.dot(normal) > 1.0 - 1e-12)
        .map(area)
        .sum()
}

/// Nearest polygon hit by the ray `o + t d`, t > 1e-9: (t, polygon).
fn first_hit(polygons: &[Polygon], o: DVec3, d: DVec3) -> Option<(f64, &Polygon)> {
    let mut best: Option<(f64, &Polygon)> = None;
    for p in polygons {
        let denom = p.normal.dot(d);
        if denom.abs() < 1e-12 {
            continue;
        }
        let t = p.normal.dot(p.vertices[0] - o) / denom;
        if t <= 1e-9 || best.is_some_and(|(b, _)| t >= b) {
            continue;
        }
        let x = o + d * t;
        let n = p.vertices.len();
        let inside = (0..n).all(|k| {
            let (a, b) = (p.vertices[k], p.vertices[(k + 1) % n]);
            (b - a).cross(x - a).dot(p.normal) >= -1e-12
        });
        if inside {
            best = Some((t, p));
        }
    }
    best
}

/// From points inside room (i, j) (above the furniture, below the panels), every ray hits a
/// surface first from the side it faces: nothing leaks out, nothing is seen from behind.
fn assert_closed(scene: &Scene, rooms: Rooms, i: usize, j: usize) {
    let pitch = SIZE + office::WALL;
    let base = DVec3::new(i as f64 * pitch, 0.0, j as f64 * pitch);
    let dirs = probes::place::fibonacci(400);
    for (u, v) in [(0.5, 0.5), (0.2, 0.3), (0.8, 0.75), (0.1, 0.9)] {
        let o = base + DVec3::new(u * SIZE, 2.0, v * SIZE);
        for &d in &dirs {
            let Some((_, p)) = first_hit(&scene.polygons, o, d) else {
                panic!("{rooms} room ({i}, {j}): the ray from {o} along {d} escapes");
            };
            assert!(
                p.normal.dot(d) < 0.0,
                "{rooms} room ({i}, {j}): the ray from {o} along {d} hits the back of a {} face",
                material(scene, p)
            );
        }
    }
}

fn check(rooms: &str, target: f64) {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(dir.path(), rooms);
    let r: Rooms = rooms.parse().unwrap();
    let scene = importer::load(&path).unwrap();
    let floor = office::office(r, SIZE, HEIGHT).unwrap();

    // Quads only, one polygon per generated quad.
    assert_eq!(
        scene.polygons.len(),
        floor.quad_count(),
        "{rooms}: polygons"
    );
    assert!(
        scene.polygons.iter().all(|p| p.vertices.len() == 4),
        "{rooms}: a polygon is not a quad"
    );
    let per_room = floor.quad_count() as f64 / r.count() as f64;
    assert!(
        (20.0..=40.0).contains(&per_room),
        "{rooms}: {per_room} quads per room"
    );

    // Element count on target, and exactly as predicted.
    let mesh = mesher::mesh(&scene.polygons, mesher::Subdivision::MaxSize(ELEMENT)).unwrap();
    let elements = mesh.elements.len();
    assert_eq!(
        elements as u64,
        floor.elements(ELEMENT),
        "{rooms}: prediction"
    );
    assert!(
        (elements as f64 / target - 1.0).abs() <= 0.1,
        "{rooms}: {elements} elements, target {target} ± 10 %"
    );

    // Emission: two 0.6 m × 1.2 m panels of e = 5 per room, facing down, nothing else emits.
    let emitted: f64 = scene
        .polygons
        .iter()
        .map(|p| area(p) * scene.materials[p.material].emission[0])
        .sum();
    // (Corners are snapped to 1/1024 m, which moves a panel's area by up to 0.3 %.)
    let want = r.count() as f64 * 2.0 * 0.72 * 5.0;
    assert!(
        (emitted - want).abs() < 5e-3 * want,
        "{rooms}: emitted {emitted}, want {want}"
    );
    assert!(scene
        .polygons
        .iter()
        .filter(|p| scene.materials[p.material].emission[0] > 0.0)
        .all(|p| p.normal.y < -0.999 && material(&scene, p) == "light"));

    // Floors and ceilings cover every room exactly; the floor also closes each doorway.
    let room_area = r.count() as f64 * SIZE * SIZE;
    let doors = (r.x - 1) * r.z + r.x * (r.z - 1);
    let floor_area = room_area + doors as f64 * office::DOOR_WIDTH * office::WALL;
    let up = area_of(&scene, "floor", DVec3::Y);
    let down = area_of(&scene, "ceiling", -DVec3::Y);
    assert!(
        (up - floor_area).abs() < 1e-6 * floor_area,
        "{rooms}: floor {up}"
    );
    assert!(
        (down - room_area).abs() < 1e-6 * room_area,
        "{rooms}: ceiling {down}"
    );

    // Rooms closed: the corners and, on big floors, one room in the middle.
    let mut probe = vec![(0, 0), (r.x - 1, r.z - 1), (r.x - 1, 0), (0, r.z - 1)];
    probe.push((r.x / 2, r.z / 2));
    probe.dedup();
    for (i, j) in probe {
        assert_closed(&scene, r, i, j);
    }
}

#[test]
fn two_by_two_floor_has_about_5700_elements() {
    check("2x2", 5700.0);
}

#[test]
fn eight_by_eight_floor_has_about_88000_elements() {
    check("8x8", 88_000.0);
}

/// Same options, same bytes.
#[test]
fn output_is_deterministic() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    for dir in [&a, &b] {
        generate(dir.path(), "3x2");
    }
    for name in ["office-3x2.gltf", "office-3x2.bin"] {
        let read = |d: &tempfile::TempDir| std::fs::read(d.path().join(name)).unwrap();
        assert!(read(&a) == read(&b), "{name} differs between runs");
    }
}

/// Bad options are one-line errors, not panics.
#[test]
fn bad_options_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        vec!["office", "--rooms", "0x2", "a.gltf"],
        vec!["office", "--room-size", "1", "a.gltf"],
        vec!["office", "a.txt"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_walkthrough"))
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?} succeeded");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}
