//! The escape estimate (`bake_core::escape`) against closed forms and against the solver's
//! balance: rays from the surfaces that meet nothing left through openings, rays that meet a
//! one-sided surface from behind reached a back face, and the two add up to the solver's
//! `escaped` (`Σ A b (1 − Σ F)`), which is computed from the form factors, not from rays.

use bake_core::{Request, Settings, TransportKind};
use mesher::Subdivision;
use std::path::Path;

/// A unit box open at the top: a floor emitting 1 (ρ = 0 everywhere) and four walls, all
/// facing in; with `blocker`, a one-sided 0.5 × 0.5 square at half height facing up, so the
/// floor sees its back.
fn open_box(dir: &Path, blocker: bool) -> std::path::PathBuf {
    let mut obj = String::from("mtllib box.mtl\n");
    let quads: Vec<(&str, [[f64; 3]; 4])> = {
        let mut q = vec![
            (
                "floor",
                [[0., 0., 0.], [0., 0., 1.], [1., 0., 1.], [1., 0., 0.]],
            ),
            (
                "wall",
                [[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]],
            ),
            (
                "wall",
                [[1., 0., 0.], [1., 0., 1.], [1., 1., 1.], [1., 1., 0.]],
            ),
            (
                "wall",
                [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
            ),
            (
                "wall",
                [[0., 0., 1.], [0., 1., 1.], [1., 1., 1.], [1., 0., 1.]],
            ),
        ];
        if blocker {
            q.push((
                "wall",
                [
                    [0.25, 0.5, 0.25],
                    [0.25, 0.5, 0.75],
                    [0.75, 0.5, 0.75],
                    [0.75, 0.5, 0.25],
                ],
            ));
        }
        q
    };
    for (k, (material, q)) in quads.iter().enumerate() {
        obj.push_str(&format!("usemtl {material}\n"));
        for v in q {
            obj.push_str(&format!("v {} {} {}\n", v[0], v[1], v[2]));
        }
        let b = 4 * k + 1;
        obj.push_str(&format!("f {} {} {} {}\n", b, b + 1, b + 2, b + 3));
    }
    std::fs::write(dir.join("box.obj"), obj).expect("write obj");
    std::fs::write(
        dir.join("box.mtl"),
        "newmtl floor\nKd 0 0 0\nKe 1 1 1\nnewmtl wall\nKd 0 0 0\n",
    )
    .expect("write mtl");
    dir.join("box.obj")
}

fn bake(path: &Path) -> bake_core::Bake {
    let scene = importer::load(path).expect("load");
    let request = Request {
        subdivision: Some(Subdivision::Count(6)),
        transport: TransportKind::Dense,
        refine: Some(false),
        ..Request::default()
    };
    let settings = Settings::resolve(&request, &scene.polygons).expect("settings");
    bake_core::run(&scene, &settings, &bake_core::Silent).expect("bake")
}

/// Three standard errors of a share `p` of `RAYS` rays, plus rounding.
fn allowance(p: f64) -> f64 {
    3.0 * (p.max(1e-3) * (1.0 - p) / bake_core::escape::RAYS as f64).sqrt() + 1e-9
}

#[test]
fn light_leaving_an_open_box_goes_through_its_opening() {
    let dir = tempfile::tempdir().expect("tempdir");
    let b = bake(&open_box(dir.path(), false));
    let e = b.escape;
    assert_eq!(e.rays, bake_core::escape::RAYS);
    // The floor (area 1, b = 1) sends F(floor → opening) of its light out: two unit squares
    // one apart, 0.19982 (Howell's catalogue C-11).
    let f = 0.199_825;
    for c in 0..3 {
        assert!(
            (e.openings[c] - f).abs() <= allowance(f),
            "band {c}: {} vs {f}",
            e.openings[c]
        );
        assert_eq!(e.back_faces[c], 0.0, "no back faces");
        assert!(
            (b.energy.escaped[c] - f).abs() < 2e-3,
            "solver: {:?}",
            b.energy.escaped
        );
    }
}

#[test]
fn light_reaching_a_one_sided_blocker_from_behind_is_told_apart_and_adds_up() {
    let dir = tempfile::tempdir().expect("tempdir");
    let b = bake(&open_box(dir.path(), true));
    let e = b.escape;
    println!("{e:?}, solver {:?}", b.energy.escaped);
    for c in 0..3 {
        // The floor sees the blocker's back: a share of what it sends (0.5 × 0.5 at half
        // height over a unit floor: about 0.13) reaches it from behind.
        assert!(e.back_faces[c] > 0.1 && e.back_faces[c] < 0.2, "{e:?}");
        assert!(e.openings[c] > 0.0 && e.openings[c] < 0.199_825, "{e:?}");
        // Independent of the form factors, the rays add up to the solver's escape.
        let sum = e.openings[c] + e.back_faces[c];
        assert!(
            (sum - b.energy.escaped[c]).abs() <= allowance(sum) + 5e-3,
            "band {c}: rays {sum} vs solver {}",
            b.energy.escaped[c]
        );
    }
}

/// In the closed cube every ray meets a front: nothing leaves (the solver's escape there is
/// only its form factors' tolerance).
#[test]
fn nothing_escapes_a_closed_scene() {
    let b = bake(&bake_testkit::fixture("cube.gltf"));
    assert_eq!(b.escape.openings, [0.0; 3]);
    assert_eq!(b.escape.back_faces, [0.0; 3]);
}
