//! OBJ + MTL import: files written into a temp dir, results checked against hand-computed
//! numbers.

use bake_importer::{load, ImportError, Polygon, Scene, Transform};
use glam::DVec3;
use std::path::Path;

const TOL: f64 = 1e-9;

fn d(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < TOL
}

/// Area about the polygon's normal (> 0 when counter-clockwise).
fn ccw_area(polygon: &Polygon) -> f64 {
    let v = &polygon.vertices;
    let n = v.len();
    (0..n)
        .map(|i| (v[i] - v[0]).cross(v[(i + 1) % n] - v[0]))
        .sum::<DVec3>()
        .dot(polygon.normal)
        / 2.0
}

/// Every corner turns left about the normal.
fn is_convex(polygon: &Polygon) -> bool {
    let v = &polygon.vertices;
    let n = v.len();
    (0..n).all(|i| {
        let e1 = v[i] - v[(i + n - 1) % n];
        let e2 = v[(i + 1) % n] - v[i];
        e1.cross(e2).dot(polygon.normal) > 0.0
    })
}

fn write(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(name), text).expect("write");
}

fn load_obj(obj: &str, mtl: Option<&str>) -> Result<Scene, ImportError> {
    let dir = tempfile::tempdir().expect("tempdir");
    if let Some(mtl) = mtl {
        write(dir.path(), "scene.mtl", mtl);
    }
    write(dir.path(), "scene.obj", obj);
    load(&dir.path().join("scene.obj"))
}

const MTL: &str = "\
newmtl wall
Kd 0.5 0.25 0.125
newmtl lamp
Kd 0.1 0.1 0.1
Ke 1 2 3
";

#[test]
fn quads_stay_quads_and_mtl_colours_are_read() {
    let obj = "\
mtllib scene.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
o floor
usemtl wall
f 1 2 3 4
o light
usemtl lamp
f 1 5 6 2
";
    let scene = load_obj(obj, Some(MTL)).unwrap();
    assert_eq!(scene.polygons.len(), 2);
    let (floor, light) = (&scene.polygons[0], &scene.polygons[1]);
    assert_eq!(
        floor.vertices,
        vec![d(0., 0., 0.), d(1., 0., 0.), d(1., 1., 0.), d(0., 1., 0.)]
    );
    assert!(close(floor.normal, d(0., 0., 1.)));
    assert_eq!(light.vertices.len(), 4);
    assert!(close(light.normal, d(0., 1., 0.)));

    assert_eq!(scene.materials.len(), 2);
    let wall = &scene.materials[floor.material];
    assert_eq!(wall.name.as_deref(), Some("wall"));
    assert_eq!(wall.rho, [0.5, 0.25, 0.125]);
    assert_eq!(wall.emission, [0.0; 3]);
    let lamp = &scene.materials[light.material];
    assert_eq!(lamp.emission, [1.0, 2.0, 3.0]);
    assert!((lamp.rho[0] - 0.1).abs() < 1e-7);
    assert!(!lamp.double_sided);

    // Layout: one mesh and one identity node per model, one scene with every node.
    let layout = &scene.layout;
    assert_eq!(layout.meshes.len(), 2);
    assert_eq!(layout.meshes[0].name.as_deref(), Some("floor"));
    assert_eq!(layout.meshes[1].primitives[0].material, light.material);
    assert_eq!(layout.nodes.len(), 2);
    assert_eq!(layout.nodes[1].mesh, Some(1));
    assert_eq!(
        layout.nodes[0].transform,
        Transform::Trs {
            translation: [0.0; 3],
            rotation: [0.0, 0.0, 0.0, 1.0],
            scale: [1.0; 3]
        }
    );
    assert_eq!(layout.scenes.len(), 1);
    assert_eq!(layout.scenes[0].nodes, vec![0, 1]);
    assert_eq!(layout.scene, Some(0));
    assert_eq!(light.origin.mesh, 1);
    assert_eq!(light.origin.node, 1);
    assert_eq!(scene.stats.faces_read, 2);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}

#[test]
fn convex_pentagon_is_split_into_a_quad_and_a_triangle() {
    let obj = "\
v 0 0 0
v 2 0 0
v 3 1 0
v 1 2 0
v -1 1 0
f 1 2 3 4 5
";
    let scene = load_obj(obj, None).unwrap();
    assert_eq!(scene.stats.ngons_split, 1);
    assert_eq!(scene.polygons.len(), 2);
    assert_eq!(
        scene.polygons[0].vertices,
        vec![d(0., 0., 0.), d(2., 0., 0.), d(3., 1., 0.), d(1., 2., 0.)]
    );
    assert_eq!(
        scene.polygons[1].vertices,
        vec![d(0., 0., 0.), d(1., 2., 0.), d(-1., 1., 0.)]
    );
    // Shoelace area of the pentagon: 5.
    let total: f64 = scene.polygons.iter().map(ccw_area).sum();
    assert!((total - 5.0).abs() < TOL, "{total}");
    assert!(scene
        .polygons
        .iter()
        .all(|p| p.origin.face == 0 && is_convex(p)));
}

#[test]
fn concave_quad_is_split_along_its_inner_diagonal() {
    // A dart: corner 3 at (1, 0.5) is reflex, so the inner diagonal is 3-1.
    let obj = "\
v 0 0 0
v 1 2 0
v 2 0 0
v 1 0.5 0
f 1 3 4 2
";
    let scene = load_obj(obj, None).unwrap();
    assert_eq!(scene.polygons.len(), 2);
    assert_eq!(scene.stats.ngons_split, 0);
    let total: f64 = scene.polygons.iter().map(ccw_area).sum();
    assert!((total - 1.25).abs() < TOL, "{total}");
    for p in &scene.polygons {
        assert_eq!(p.vertices.len(), 3);
        assert_eq!(p.vertices[0], d(1., 0.5, 0.));
        assert!(close(p.normal, d(0., 0., 1.)));
    }
    // Only the no-material note: a concave quad is split silently.
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
}

#[test]
fn non_planar_quad_is_split_with_a_warning() {
    let obj = "\
v 0 0 0
v 1 0 0
v 1 1 0.5
v 0 1 0
f 1 2 3 4
";
    let scene = load_obj(obj, None).unwrap();
    assert_eq!(scene.polygons.len(), 2);
    assert!(scene.polygons.iter().all(|p| p.vertices.len() == 3));
    assert_eq!(scene.warnings.len(), 2, "{:?}", scene.warnings); // + no-material warning
    assert!(
        scene.warnings.iter().any(|w| w.contains("1 non-planar")),
        "{:?}",
        scene.warnings
    );
}

/// Millimetre quads 1 km from the origin, in a tilted plane: planar in f64 (the text's
/// 12 decimals are 1e-12 m), but f32 positions (6e-5 m apart at 1 km) would warp each by
/// far more than its planarity tolerance (1e-6 × its 1.4 mm size) and split it.
#[test]
fn millimetre_quads_a_kilometre_away_stay_quads() {
    let origin = d(1000.0, 1000.0, 1000.0);
    let u = d(1.0, -1.0, 0.0).normalize() * 1e-3;
    let v = d(1.0, 1.0, -2.0).normalize() * 1e-3;
    let mut obj = String::new();
    let mut faces = String::new();
    for k in 0..10 {
        let o = origin + u * (2.0 * k as f64);
        for p in [o, o + u, o + u + v, o + v] {
            obj += &format!("v {:.12} {:.12} {:.12}\n", p.x, p.y, p.z);
        }
        let b = 4 * k + 1;
        faces += &format!("f {} {} {} {}\n", b, b + 1, b + 2, b + 3);
    }
    obj += &faces;
    let scene = load_obj(&obj, None).unwrap();
    assert_eq!(scene.polygons.len(), 10, "{:?}", scene.warnings);
    assert!(scene.polygons.iter().all(|p| p.vertices.len() == 4));
    assert!(
        !scene.warnings.iter().any(|w| w.contains("non-planar")),
        "{:?}",
        scene.warnings
    );
}

#[test]
fn consecutive_obj_triangles_merge_into_a_quad() {
    let obj = "\
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
f 1 2 3
f 1 3 4
";
    let scene = load_obj(obj, None).unwrap();
    assert_eq!(scene.polygons.len(), 1);
    assert_eq!(scene.stats.quads_merged, 1);
    assert_eq!(scene.stats.faces_read, 2);
}

#[test]
fn missing_material_library_uses_the_default_grey() {
    let obj = "\
mtllib nowhere.mtl
v 0 0 0
v 1 0 0
v 0 1 0
usemtl wall
f 1 2 3
";
    let scene = load_obj(obj, None).unwrap();
    assert_eq!(scene.materials.len(), 1);
    assert_eq!(scene.materials[0].rho, [0.8; 3]);
    assert_eq!(scene.materials[0].emission, [0.0; 3]);
    assert!(
        scene.warnings.iter().any(|w| w.contains("nowhere.mtl")),
        "{:?}",
        scene.warnings
    );
}

#[test]
fn malformed_input_is_an_error_not_a_panic() {
    let triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n";
    for (obj, mtl) in [
        (format!("{triangle}f 0 1 2\n"), None),
        (format!("{triangle}f 1/0 2/1 3/1\n"), None),
        (
            format!("{triangle}f 1/-9223372036854775808 2/1 3/1\n"),
            None,
        ),
        (format!("{triangle}f 1 2 4\n"), None),
        (
            format!("mtllib scene.mtl\n{triangle}usemtl a\nf 1 2 3\n"),
            Some("newmtl a\nKd 0.5 0.5\n"),
        ),
        (
            format!("mtllib scene.mtl\n{triangle}usemtl a\nf 1 2 3\n"),
            Some("newmtl a\nKd nan 0 0\n"),
        ),
        (
            format!("mtllib scene.mtl\n{triangle}usemtl a\nf 1 2 3\n"),
            Some("newmtl a\nKe -1 0 0\n"),
        ),
        (
            format!("mtllib scene.mtl\n{triangle}usemtl a\nf 1 2 3\n"),
            Some("newmtl a\nKd 1.5 0 0\n"),
        ),
        ("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n".to_string(), None),
    ] {
        let result = load_obj(&obj, mtl);
        assert!(result.is_err(), "{obj:?} {mtl:?} gave {result:?}");
    }
}

#[test]
fn mtl_values_are_checked_and_named() {
    let obj = "mtllib scene.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\no box\nusemtl a\nf 1 2 3\n";
    match load_obj(obj, Some("newmtl a\nKd 0.5 0.5 2\n")) {
        Err(ImportError::InvalidValue { what, problem }) => {
            assert!(
                what.contains("material \"a\" (0)") && what.contains("mesh \"box\" (0)"),
                "{what}"
            );
            assert!(problem.contains("outside [0, 1]"), "{problem}");
        }
        other => panic!("expected InvalidValue, got {other:?}"),
    }
    // A single number means grey.
    let scene = load_obj(obj, Some("newmtl a\nKd 0.25\n")).unwrap();
    assert_eq!(scene.materials[0].rho, [0.25; 3]);
}

#[test]
fn points_lines_and_short_faces_are_skipped() {
    let obj = "\
v 0 0 0
v 1 0 0
v 0 1 0
p 1
l 1 2 3
f 1 2
f 1 2 3
";
    let scene = load_obj(obj, None).unwrap();
    assert_eq!(scene.polygons.len(), 1);
    assert_eq!(scene.stats.degenerate_dropped, 1);
    assert_eq!(scene.stats.faces_read, 2);
    assert!(
        scene.warnings.iter().any(|w| w.contains("2 point/line")),
        "{:?}",
        scene.warnings
    );
}

/// `mtllib a.mtl b.mtl` names two libraries (the OBJ format separates them by whitespace):
/// both are read and the faces get the materials of each (before, the line was read as one
/// missing file "a.mtl b.mtl" and every face baked as the default grey, the lamp dark).
#[test]
fn mtllib_with_several_files_reads_every_library() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "walls.mtl", "newmtl wall\nKd 0.5 0.25 0.125\n");
    write(
        dir.path(),
        "lamps.mtl",
        "newmtl lamp\nKd 0.1 0.1 0.1\nKe 1 2 3\n",
    );
    write(
        dir.path(),
        "scene.obj",
        "mtllib walls.mtl  lamps.mtl\n\
         v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
         o wall\nusemtl wall\nf 1 2 3\n\
         o lamp\nusemtl lamp\nf 1 4 2\n",
    );
    let scene = load(&dir.path().join("scene.obj")).expect("loads");
    let material = |name: &str| {
        scene
            .polygons
            .iter()
            .map(|p| &scene.materials[p.material])
            .find(|m| m.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("no polygon with material {name}: {:?}", scene.materials))
    };
    assert_eq!(material("wall").rho, [0.5, 0.25, 0.125]);
    assert_eq!(material("lamp").emission, [1.0, 2.0, 3.0]);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.stats.material_libraries_missing, 0);
    let read: Vec<_> = scene
        .input_files
        .iter()
        .filter_map(|p| p.file_name())
        .collect();
    assert!(read.contains(&"walls.mtl".as_ref()), "{read:?}");
    assert!(read.contains(&"lamps.mtl".as_ref()), "{read:?}");
}

/// A lamp triangle whose material comes from the library `lamp_file` (written when given)
/// named on the line `mtllib {libraries}`; the scene as loaded.
fn lamp_scene(libraries: &str, lamp_file: &str) -> Scene {
    let dir = tempfile::tempdir().expect("tempdir");
    write(
        dir.path(),
        lamp_file,
        "newmtl lamp\nKd 0.1 0.1 0.1\nKe 1 2 3\n",
    );
    let obj = format!("mtllib {libraries}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\n");
    write(dir.path(), "scene.obj", &obj);
    load(&dir.path().join("scene.obj")).expect("loads")
}

/// One of two libraries on the line is missing: the other's materials are kept, and the
/// missing one is a warning naming it and counted for the summary line.
#[test]
fn one_missing_library_of_several_warns_and_keeps_the_others() {
    let scene = lamp_scene("gone.mtl lamps.mtl", "lamps.mtl");
    assert_eq!(
        scene.materials[scene.polygons[0].material].emission,
        [1.0, 2.0, 3.0]
    );
    assert_eq!(scene.stats.material_libraries_missing, 1);
    let named: Vec<_> = scene
        .warnings
        .iter()
        .filter(|w| w.contains("gone.mtl") && w.contains("missing"))
        .collect();
    assert_eq!(named.len(), 1, "{:?}", scene.warnings);
}

/// A library whose name has a space (Blender writes such names unquoted) is still read as
/// one file when it exists.
#[test]
fn mtllib_name_with_a_space_is_one_file_when_it_exists() {
    let scene = lamp_scene("my lamps.mtl", "my lamps.mtl");
    assert_eq!(
        scene.materials[scene.polygons[0].material].emission,
        [1.0, 2.0, 3.0]
    );
    assert_eq!(scene.stats.material_libraries_missing, 0);
}
