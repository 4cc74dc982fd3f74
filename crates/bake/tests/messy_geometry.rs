//! Geometry never creates light (issue 29): coincident, overlapping, interpenetrating and
//! inward-wound solids bake on the dense transport with every row Σ_j F_ij ≤ 1, a finite
//! non-negative b below the bound `max e / (1 − ρ_max)` that rows ≤ 1 imply (eq. 7's Neumann
//! series), and no negative escape; exact duplicates are dropped at import, so a doubled
//! solid bakes like a single one.

use bake_core::{Request, Settings, TransportKind};
use mesher::Subdivision;
use proptest::prelude::*;

/// One axis-aligned box as OBJ faces (outward counter-clockwise unless `inward`).
fn box_faces(obj: &mut String, lo: [f64; 3], hi: [f64; 3], inward: bool, material: &str) {
    let base = obj.lines().filter(|l| l.starts_with("v ")).count();
    for k in 0..8 {
        let x = if k & 1 == 0 { lo[0] } else { hi[0] };
        let y = if k & 2 == 0 { lo[1] } else { hi[1] };
        let z = if k & 4 == 0 { lo[2] } else { hi[2] };
        obj.push_str(&format!("v {x} {y} {z}\n"));
    }
    obj.push_str(&format!("usemtl {material}\n"));
    // Outward counter-clockwise quads of the unit cube's corner numbering (bit 0 = x, …).
    const FACES: [[usize; 4]; 6] = [
        [0, 2, 3, 1], // -z
        [4, 5, 7, 6], // +z
        [0, 1, 5, 4], // -y
        [2, 6, 7, 3], // +y
        [0, 4, 6, 2], // -x
        [1, 3, 7, 5], // +x
    ];
    for face in FACES {
        let mut f: Vec<usize> = face.iter().map(|&k| base + k + 1).collect();
        if inward {
            f.reverse();
        }
        let f: Vec<String> = f.iter().map(usize::to_string).collect();
        obj.push_str(&format!("f {}\n", f.join(" ")));
    }
}

/// A lamp: a square at height `y` facing down, and with `two_sided` a second one 0.5 mm above
/// facing up (the MGF lamps of `graz_overlap.obj`).
fn lamp(obj: &mut String, centre: [f64; 2], y: f64, size: f64, two_sided: bool) {
    let base = obj.lines().filter(|l| l.starts_with("v ")).count();
    let (x0, x1, z0, z1) = (
        centre[0] - size,
        centre[0] + size,
        centre[1] - size,
        centre[1] + size,
    );
    for yy in [y, y + 5e-4] {
        for (x, z) in [(x0, z0), (x1, z0), (x1, z1), (x0, z1)] {
            obj.push_str(&format!("v {x} {yy} {z}\n"));
        }
    }
    obj.push_str("usemtl lamp\n");
    // Facing −y: (x0,z0) → (x1,z0) → (x1,z1) → (x0,z1) turns about −y.
    obj.push_str(&format!(
        "f {} {} {} {}\n",
        base + 1,
        base + 2,
        base + 3,
        base + 4
    ));
    if two_sided {
        obj.push_str(&format!(
            "f {} {} {} {}\n",
            base + 8,
            base + 7,
            base + 6,
            base + 5
        ));
    }
}

fn mtl(rho: f64) -> String {
    format!("newmtl paint\nKd {rho} {rho} {rho}\nnewmtl lamp\nKd 0 0 0\nKe 1 1 1\n")
}

fn dense(scene: &importer::Scene, count: u32) -> bake_core::Bake {
    let request = Request {
        transport: TransportKind::Dense,
        subdivision: Some(Subdivision::Count(count)),
        refine: Some(false),
        ..Request::default()
    };
    let settings = Settings::resolve(&request, &scene.polygons).expect("settings");
    bake_core::run(scene, &settings, &bake_core::Silent).expect("the scene bakes")
}

/// Rows ≤ 1, b finite and within `max e / (1 − ρ_max)`, escape ≥ 0, energy balanced.
fn check_no_light_created(bake: &bake_core::Bake, rho_max: f64) {
    let rows = bake.accuracy.row_sums.expect("dense row sums");
    assert!(rows.largest_after <= 1.0 + 1e-12, "{rows:?}");
    let e_max = bake
        .emission
        .iter()
        .flatten()
        .copied()
        .fold(0.0f64, f64::max);
    let bound = e_max / (1.0 - rho_max) * (1.0 + 1e-9);
    for b in bake.solution.b.iter().flatten() {
        assert!(
            b.is_finite() && *b >= -1e-12 && *b <= bound,
            "b {b}, bound {bound}"
        );
    }
    for c in 0..3 {
        let e = &bake.energy;
        assert!(e.escaped[c] >= -1e-9 * e.emitted[c].max(1e-300), "{e:?}");
        assert!(e.imbalance[c] < 1e-6, "{e:?}");
    }
}

/// A box of `graz_overlap.obj`'s kind: thin (2 mm), wound inward, top and bottom seen from
/// each other; the second one shifted by (−4, 0, −6) mm so the tops overlap partly.
fn overlapping_thin_boxes(obj: &mut String) {
    box_faces(obj, [0.0, 0.422, 0.0], [0.248, 0.424, 0.04], true, "paint");
    box_faces(
        obj,
        [-0.004, 0.422, -0.006],
        [0.244, 0.424, 0.034],
        true,
        "paint",
    );
}

#[test]
fn overlapping_inward_boxes_bake_with_rows_at_most_one() {
    // Without the limit these rows sum to ~1.9 (both coincident tops are seen in full) and
    // ρ = 0.95 makes the system diverge.
    let mut obj = String::from("mtllib m.mtl\no boxes\n");
    overlapping_thin_boxes(&mut obj);
    // Light inside the boxes: the room around them is open, a lamp between the plates.
    lamp(&mut obj, [0.12, 0.02], 0.4232, 0.01, true);
    let scene =
        importer::load_obj_bytes(obj.as_bytes(), Some(mtl(0.95).as_bytes())).expect("import");
    let bake = dense(&scene, 2);
    let rows = bake.accuracy.row_sums.expect("row sums");
    eprintln!("{rows:?}; warnings {:?}", bake.warnings);
    assert!(rows.largest_before > 1.5, "{rows:?}");
    assert!(rows.seen_twice > 0, "{rows:?}");
    assert!(
        bake.warnings
            .iter()
            .any(|w| w.contains("summed past 1") && w.contains("mesh \"boxes\"")),
        "{:?}",
        bake.warnings
    );
    check_no_light_created(&bake, 0.95);
}

#[test]
fn a_doubled_box_bakes_like_a_single_one() {
    // A closed room (inward), a lamp under its ceiling and a box on the floor; the same box
    // pasted a second time in another object at the same place is dropped at import (same
    // corners, same facing), so every element matches the single-box bake.
    let room = |obj: &mut String| {
        box_faces(obj, [0.0, 0.0, 0.0], [2.0, 2.0, 2.0], true, "paint");
        lamp(obj, [1.0, 1.0], 1.9, 0.3, false);
    };
    let mut single = String::from("mtllib m.mtl\no room\n");
    room(&mut single);
    single.push_str("o box\n");
    box_faces(
        &mut single,
        [0.5, 0.0, 0.5],
        [1.1, 0.6, 1.1],
        false,
        "paint",
    );
    let mut doubled = single.clone();
    doubled.push_str("o box_copy\n");
    box_faces(
        &mut doubled,
        [0.5, 0.0, 0.5],
        [1.1, 0.6, 1.1],
        false,
        "paint",
    );
    let mtl = mtl(0.7);
    let one = importer::load_obj_bytes(single.as_bytes(), Some(mtl.as_bytes())).expect("one");
    let two = importer::load_obj_bytes(doubled.as_bytes(), Some(mtl.as_bytes())).expect("two");
    assert_eq!(two.stats.coincident_dropped, 6);
    assert_eq!(one.polygons.len(), two.polygons.len());
    assert!(
        two.warnings.iter().any(|w| w.contains("6 faces coincide")),
        "{:?}",
        two.warnings
    );
    let (a, b) = (dense(&one, 3), dense(&two, 3));
    assert_eq!(a.solution.b, b.solution.b);
    check_no_light_created(&b, 0.7);
}

/// What the property test builds: boxes (maybe thin, inward, doubled, shifted to overlap or
/// through one another), lamps (maybe two-sided sheets), maybe inside a closed room.
#[derive(Clone, Debug)]
struct Case {
    boxes: Vec<([f64; 3], [f64; 3], bool, u8)>,
    lamps: Vec<([f64; 2], f64, bool)>,
    closed: bool,
    rho: f64,
}

fn case() -> impl Strategy<Value = Case> {
    let corner = [0.1f64..1.5, 0.0f64..1.2, 0.1f64..1.5];
    let size = [0.002f64..0.6, 0.002f64..0.6, 0.002f64..0.6];
    let one_box = (corner, size, any::<bool>(), 0u8..4).prop_map(|(lo, size, inward, copy)| {
        let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
        (lo, hi, inward, copy)
    });
    let one_lamp = ([0.2f64..1.8, 0.2f64..1.8], 0.3f64..1.9, any::<bool>());
    (
        prop::collection::vec(one_box, 1..4),
        prop::collection::vec(one_lamp, 1..3),
        any::<bool>(),
        0.3f64..0.99,
    )
        .prop_map(|(boxes, lamps, closed, rho)| Case {
            boxes,
            lamps,
            closed,
            rho,
        })
}

fn obj_of(case: &Case) -> String {
    let mut obj = String::from("mtllib m.mtl\n");
    if case.closed {
        obj.push_str("o room\n");
        box_faces(&mut obj, [0.0; 3], [2.0; 3], true, "paint");
    }
    for (k, &(lo, hi, inward, copy)) in case.boxes.iter().enumerate() {
        obj.push_str(&format!("o box{k}\n"));
        box_faces(&mut obj, lo, hi, inward, "paint");
        // 0: alone; 1: an exact copy (coincident); 2: shifted by a third of its size
        // (overlapping, interpenetrating); 3: a copy wound the other way.
        let shift = [(hi[0] - lo[0]) / 3.0, 0.0, (hi[2] - lo[2]) / 3.0];
        match copy {
            1 => box_faces(&mut obj, lo, hi, inward, "paint"),
            2 => box_faces(
                &mut obj,
                [lo[0] + shift[0], lo[1], lo[2] + shift[2]],
                [hi[0] + shift[0], hi[1], hi[2] + shift[2]],
                inward,
                "paint",
            ),
            3 => box_faces(&mut obj, lo, hi, !inward, "paint"),
            _ => {}
        }
    }
    for (k, &(centre, y, two_sided)) in case.lamps.iter().enumerate() {
        obj.push_str(&format!("o lamp{k}\n"));
        lamp(&mut obj, centre, y, 0.15, two_sided);
    }
    obj
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn messy_boxes_and_lamps_never_create_light(case in case()) {
        let obj = obj_of(&case);
        let scene = importer::load_obj_bytes(obj.as_bytes(), Some(mtl(case.rho).as_bytes()))
            .expect("import");
        let bake = dense(&scene, 2);
        check_no_light_created(&bake, case.rho);
    }
}
