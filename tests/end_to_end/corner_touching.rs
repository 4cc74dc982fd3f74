//! Issue 14's hang, end to end: the two cone quads that touch at one corner, plus a lamp, as
//! the report gave them (decimal OBJ text, read as f64), bake through `bake_core::run` with
//! every estimator at `--subdiv 1` and at the default element size, within the form-factor
//! crate's stated work bound per integrated pair (`max_pair_evaluations`). The f32-rounded
//! variant that hung, and the per-pair property tests, are in
//! crates/form-factor/tests/{corner_slivers,bounded_work}.rs.

use bake_core::{EstimatorKind, Request, Settings};
use form_factor::{max_pair_evaluations, ContourOptions};
use mesher::Subdivision;

/// The report's vertices as decimals; the faces (and material library) are the f32 file's.
const DECIMAL_VERTICES: &str = "v 0.0382683432 0.0923879533 1
v 0.0306146746 0.0739103626 1.1
v 0.0565685425 0.0565685425 1.1
v 0.0707106781 0.0707106781 1
v 0 0.08 1.1
v 0 0.05 1.2
v 0.0191341716 0.0461939766 1.2
v -0.5 -0.5 3
v -0.5 0.5 3
v 0.5 0.5 3
v 0.5 -0.5 3
";
/// The same scene with every coordinate rounded to f32 (as the importer read it when the
/// report was filed): each quad's shared corner is then 1.5e-9 in front of the other's plane,
/// both are clipped to 1.6e-8 slivers, and this pair is integrated (the one that hung).
const OBJ_F32: &str = include_str!("../../crates/form-factor/tests/data/cone-pair-f32.obj");
const MTL: &str = include_str!("../../crates/form-factor/tests/data/cone-pair.mtl");

/// The decimal scene: the f32 file with its `v` lines replaced.
fn decimal_obj() -> String {
    let mut text = String::from("mtllib pair.mtl\n");
    text += DECIMAL_VERTICES;
    for line in OBJ_F32
        .lines()
        .filter(|l| !l.starts_with("v ") && !l.starts_with("mtllib"))
    {
        text += line;
        text.push('\n');
    }
    text
}

#[test]
fn the_corner_touching_cone_quads_bake_with_bounded_work_for_every_estimator() {
    let per_pair = max_pair_evaluations(&ContourOptions::default());
    for (name, obj) in [("decimal", decimal_obj()), ("f32", OBJ_F32.to_string())] {
        let scene = importer::load_obj_bytes(obj.as_bytes(), Some(MTL.as_bytes()))
            .unwrap_or_else(|e| panic!("the scene does not import: {e}"));
        assert_eq!(scene.polygons.len(), 3);
        for estimator in [
            EstimatorKind::Auto,
            EstimatorKind::Contour,
            EstimatorKind::PointPolygon,
            EstimatorKind::PointPoint,
        ] {
            for subdivision in [Some(Subdivision::Count(1)), None] {
                let request = Request {
                    ff_estimator: Some(estimator),
                    subdivision,
                    // The uniform mesh this test is about.
                    refine: Some(false),
                    ..Request::default()
                };
                let settings = Settings::resolve(&request, &scene.polygons).expect("settings");
                let bake = bake_core::run(&scene, &settings, &bake_core::Silent)
                    .unwrap_or_else(|e| panic!("{estimator:?} {subdivision:?}: {e}"));
                let c = bake.counts;
                eprintln!(
                "{name} {estimator:?} {subdivision:?}: {} elements, {} pairs, {} kernel evaluations \
                 (bound {})",
                bake.mesh.elements.len(),
                c.pairs_evaluated,
                c.kernel_evaluations,
                c.pairs_evaluated * per_pair
            );
                // Both quads see the lamp; the f32 quads also see each other's slivers.
                if subdivision.is_some() {
                    let pairs = if name == "f32" { 3 } else { 2 };
                    assert_eq!(c.pairs_evaluated, pairs, "{name} {estimator:?}");
                }
                assert!(
                    c.kernel_evaluations <= c.pairs_evaluated * per_pair,
                    "{estimator:?} {subdivision:?}: {c:?}"
                );
                // The quads see the lamp: lit, finite, and they emit nothing themselves.
                for (b, rho) in bake.solution.b.iter().zip(&bake.rho) {
                    assert!(b.iter().all(|v| v.is_finite() && *v >= 0.0), "{b:?}");
                    if rho[0] > 0.0 {
                        assert!(b[0] > 0.0, "{b:?}");
                    }
                }
            }
        }
    }
}
