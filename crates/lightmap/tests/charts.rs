//! Chart counts and atlas occupancy on real meshes (issue 32), measured, and for the smooth
//! and tessellated surfaces the grouping is for, asserted: Debian's `assimp-testmodels`
//! glTF 2.0 models (skipped when absent) print polygons, charts, atlases and occupancy at
//! the default texel size; a ramp that winds over itself (a helicoid: one cone of normals,
//! a projection that covers itself) must get at most one chart per 20 polygons, none
//! overlapping.

mod common;

use bake_lightmap as lightmap;
use common::polygon;
use glam::{DVec2, DVec3};
use importer::Polygon;

/// Builds with one element per polygon and constant light: (charts, atlases, occupancy).
fn measure(polygons: &[Polygon]) -> (usize, usize, f64) {
    let mesh = mesher::mesh(polygons, mesher::Subdivision::Count(1)).expect("mesh");
    let values = vec![[1.0; 3]; mesh.elements.len()];
    let built = lightmap::build(polygons, &mesh, &values, &common::default_options(polygons))
        .expect("build");
    (
        built.stats.charts,
        built.stats.atlases,
        built.stats.occupancy,
    )
}

#[test]
fn real_models_charts_and_occupancy() {
    let Some(files) = common::assimp_models() else {
        return;
    };
    for file in files {
        let Ok(scene) = importer::load(&file) else {
            continue;
        };
        if scene.polygons.is_empty() {
            continue;
        }
        let (charts, atlases, occupancy) = measure(&scene.polygons);
        println!(
            "{}: {} polygons, {charts} charts, {atlases} atlases, occupancy {:.1}%",
            file.file_name().unwrap_or_default().to_string_lossy(),
            scene.polygons.len(),
            100.0 * occupancy
        );
    }
}

/// Two triangles per cell of the surface `at(u, v)` over [0, 1]².
fn surface(nu: usize, nv: usize, at: impl Fn(f64, f64) -> DVec3) -> Vec<Polygon> {
    let mut out = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let p = |a: usize, b: usize| at(a as f64 / nu as f64, b as f64 / nv as f64);
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            out.push(polygon(vec![a, b, c], 0));
            out.push(polygon(vec![a, c, d], 0));
        }
    }
    out
}

/// Whether texel-space point `c` lies strictly inside triangle `t` (either winding).
fn strictly_inside(c: DVec2, t: &[DVec2]) -> bool {
    let side = |a: DVec2, b: DVec2| (b - a).perp_dot(c - a);
    let s = [side(t[0], t[1]), side(t[1], t[2]), side(t[2], t[0])];
    s.iter().all(|&x| x > 1e-9) || s.iter().all(|&x| x < -1e-9)
}

#[test]
fn a_ramp_that_winds_over_itself_gets_few_charts_that_do_not_overlap() {
    // A helicoid ramp of two turns (r from 1 to 2, rising 0.31 a turn): every normal within
    // 6° of every other, so one cone takes it all, and its projection covers itself twice.
    // 256 × 10 cells: 5 120 triangles (grouped: more than GROUPED_ABOVE).
    let polygons = surface(256, 10, |u, v| {
        let (a, r) = (2.0 * std::f64::consts::TAU * u, 1.0 + v);
        DVec3::new(r * a.cos(), r * a.sin(), 0.05 * a)
    });
    assert!(polygons.len() > lightmap::GROUPED_ABOVE);
    let mesh = mesher::mesh(&polygons, mesher::Subdivision::Count(1)).expect("mesh");
    let values = vec![[1.0; 3]; mesh.elements.len()];
    let built = lightmap::build(
        &polygons,
        &mesh,
        &values,
        &common::default_options(&polygons),
    )
    .expect("build");
    let charts = built.stats.charts;
    println!(
        "helicoid: {} polygons, {charts} charts, {} atlases, occupancy {:.1}%",
        polygons.len(),
        built.stats.atlases,
        100.0 * built.stats.occupancy
    );
    assert!(
        charts * 20 <= polygons.len(),
        "{charts} charts for {} polygons",
        polygons.len()
    );
    // No texel centre strictly inside two polygons' TEXCOORD_1 triangles of one atlas.
    let mut owner = vec![u32::MAX; (built.width * built.height) as usize];
    for chart in &built.charts {
        if chart.atlas != 0 {
            continue;
        }
        let t: Vec<DVec2> = chart.uv.iter().map(|&q| DVec2::from_array(q)).collect();
        let lo = t[0].min(t[1]).min(t[2]).floor().max(DVec2::ZERO);
        let hi = t[0].max(t[1]).max(t[2]).ceil();
        for y in lo.y as usize..(hi.y as usize).min(built.height as usize) {
            for x in lo.x as usize..(hi.x as usize).min(built.width as usize) {
                let c = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                if strictly_inside(c, &t) {
                    let slot = &mut owner[y * built.width as usize + x];
                    assert_eq!(
                        *slot,
                        u32::MAX,
                        "polygons {} and {} overlap at ({x}, {y})",
                        *slot,
                        chart.polygon
                    );
                    *slot = chart.polygon as u32;
                }
            }
        }
    }
}

#[test]
fn a_smooth_mesh_beside_many_separate_quads_is_grouped() {
    // 3 600 separate 0.1 m quads (an office's ceiling tiles, 0.05 m apart) and a cylinder of
    // 48 segments × 12 rings (1 152 triangles): grouping takes the count from 4 752 to about
    // 3 610, less than half off, so it used to be left out and the cylinder paid a chart per
    // triangle. Now the cylinder is a few charts and the tiles keep theirs.
    let mut polygons: Vec<Polygon> = (0..3600)
        .map(|k| {
            let o = DVec3::new((k % 60) as f64 * 0.15, (k / 60) as f64 * 0.15, 0.0);
            let corner = |x: f64, y: f64| o + DVec3::new(x, y, 0.0);
            polygon(
                vec![
                    corner(0.0, 0.0),
                    corner(0.1, 0.0),
                    corner(0.1, 0.1),
                    corner(0.0, 0.1),
                ],
                0,
            )
        })
        .collect();
    let cylinder = surface(48, 12, |u, v| {
        let a = std::f64::consts::TAU * u;
        DVec3::new(4.0 + 0.5 * a.cos(), 4.0 + 0.5 * a.sin(), 1.0 + 2.0 * v)
    });
    let triangles = cylinder.len();
    polygons.extend(cylinder);
    assert!(polygons.len() > lightmap::GROUPED_ABOVE);
    let (charts, atlases, occupancy) = measure(&polygons);
    println!(
        "tiles + cylinder: {} polygons, {charts} charts, {atlases} atlases, occupancy {:.1}%",
        polygons.len(),
        100.0 * occupancy
    );
    assert!(
        charts <= 3600 + triangles / 20,
        "{charts} charts for 3 600 tiles and {triangles} cylinder triangles"
    );
}
