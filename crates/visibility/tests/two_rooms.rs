//! Two rooms joined by a doorway (fixtures/two-rooms.gltf), lit in room A only: room B's floor
//! behind the partition beside the doorway is hidden from the light exactly; the part in line
//! with the doorway sees some of it.

mod common;

use bake_visibility::{Counters, Occluders, DEFAULT_SAMPLES};
use form_factor::{ContourOptions, FormFactors};
use glam::DVec3;
use mesher::{mesh, ElementMesh, Subdivision};

/// The element of mesh `name` whose centroid is nearest `at`.
fn element(m: &ElementMesh, names: &[String], name: &str, at: DVec3) -> usize {
    (0..m.elements.len())
        .filter(|&e| names[m.elements[e].polygon as usize] == name)
        .min_by(|&a, &b| {
            let d = |e: usize| m.elements[e].centroid.distance(at);
            d(a).total_cmp(&d(b))
        })
        .unwrap()
}

#[test]
fn room_b_sees_the_light_only_through_the_doorway() {
    let scene = importer::load(&bake_testkit::fixture("two-rooms.gltf")).unwrap();
    let names: Vec<String> = scene
        .polygons
        .iter()
        .map(|p| {
            scene.layout.meshes[p.origin.mesh]
                .name
                .clone()
                .unwrap_or_default()
        })
        .collect();
    let occluders = Occluders::new(&scene.polygons).unwrap();
    let pairs = occluders.occludable_pairs();
    let effects = pairs.effects();
    assert!(effects.occlusion);
    println!("two rooms: {}", effects.reason);
    // 0.5 m elements.
    let m = mesh(&scene.polygons, Subdivision::MaxSize(0.5)).unwrap();
    let light = element(&m, &names, "light", DVec3::new(2.0, 2.5, 2.0));
    // Behind the partition, beside the doorway (z 0–0.5, just past x = 4.1).
    let hidden = element(&m, &names, "floor_b", DVec3::new(4.25, 0.0, 0.25));
    let v = occluders.element_pair(&pairs, &m, light, hidden, DEFAULT_SAMPLES);
    assert!(v.occludable && v.rays > 0);
    assert_eq!(v.fraction, 0.0);
    // In line with the doorway.
    let lit = element(&m, &names, "floor_b", DVec3::new(4.75, 0.0, 1.75));
    let v = occluders.element_pair(&pairs, &m, light, lit, DEFAULT_SAMPLES);
    assert!(v.fraction > 0.0, "{v:?}");
    // Room B's floor as a whole receives far less direct light than room A's.
    let ff = FormFactors::new(&m, ContourOptions::default());
    let (mut to_a, mut to_b, mut counters) = (0.0, 0.0, Counters::default());
    for e in 0..m.elements.len() {
        let name = names[m.elements[e].polygon as usize].as_str();
        if name == "floor_a" || name == "floor_b" {
            let v = occluders.element_pair(&pairs, &m, light, e, DEFAULT_SAMPLES);
            counters.add(&v);
            // Light element → e, area-weighted: A_light F_light,e × visible fraction.
            let share = ff.area_weighted(light, e).value * v.fraction;
            if name == "floor_a" {
                to_a += share;
            } else {
                to_b += share;
            }
        }
    }
    println!("direct light from one light element (A F), floor A {to_a:.4}, floor B {to_b:.4}; {counters:?}");
    assert!(to_b < 0.15 * to_a);
}
