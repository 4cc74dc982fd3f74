//! Bounded reconstruction (issue 32): every texel of a lightmap lies within the range of the
//! element values it is reconstructed from. The reference range is computed here, not by the
//! crate: for a texel owned by polygon p (chart or gutter), the elements of p and of every
//! polygon the weld may average p's edge vertices with (same material and facing, in p's
//! plane, bounding boxes touching). Meshes with slivers (a needle of area ~1e-9, sheared thin
//! quads, a fan with a flat member) and fields with steep gradients (exponential ramps and a
//! checkerboard of 1e-2 and 1e2 per element), on the mesher's grids and on a refined mesh,
//! smooth and flat. Prints the worst overshoot (relative to the range's top).

mod common;

use bake_lightmap as lightmap;
use common::polygon;
use glam::DVec3;
use importer::Polygon;
use lightmap::{Options, Shading, Texel};
use mesher::{ElementMesh, Subdivision};

fn v(x: f64, y: f64) -> DVec3 {
    DVec3::new(x, y, 0.0)
}

/// Slivers in the plane z = 0 (each on its own material unless said) and a few
/// well-shaped neighbours of one material, so the weld joins slivers to them.
fn slivers() -> Vec<Polygon> {
    let mut out = vec![
        // A needle: longest edge 1, height 1e-5, apex near one end (sheared chart).
        polygon(vec![v(0.0, 0.0), v(1.0, 0.0), v(0.999, 1e-5)], 1),
        // Area ~1e-9: apex in the middle.
        polygon(vec![v(0.0, 2.0), v(1.0, 2.0), v(0.5, 2.0 + 2e-9)], 2),
        // A thin quad and a thin, strongly sheared parallelogram.
        polygon(
            vec![v(2.0, 0.0), v(3.0, 0.0), v(3.0, 1e-3), v(2.0, 1e-3)],
            3,
        ),
        polygon(
            vec![
                v(2.0, 1.0),
                v(2.5, 1.0),
                v(3.5, 1.0 + 2e-3),
                v(3.0, 1.0 + 2e-3),
            ],
            4,
        ),
    ];
    // A fan of one material around (5, 5) with one nearly flat member: the weld averages
    // the sliver's edge with its neighbours'.
    let centre = v(5.0, 5.0);
    let angles = [0.0, 1.0, 2.0, 3.0, 3.0005, 4.5, std::f64::consts::TAU];
    for w in angles.windows(2) {
        let at = |a: f64| centre + DVec3::new(a.cos(), a.sin(), 0.0);
        out.push(polygon(vec![centre, at(w[0]), at(w[1])], 5));
    }
    // A strip of one material: a square, then a sliver sharing its edge.
    out.push(polygon(
        vec![v(0.0, 4.0), v(1.0, 4.0), v(1.0, 5.0), v(0.0, 5.0)],
        6,
    ));
    out.push(polygon(
        vec![v(1.0, 4.0), v(1.0 + 1e-4, 4.5), v(1.0, 5.0)],
        6,
    ));
    out
}

/// Steep per-element fields: an exponential ramp per band and a checkerboard.
fn fields(mesh: &ElementMesh) -> Vec<Vec<[f64; 3]>> {
    let ramp = mesh
        .elements
        .iter()
        .map(|e| {
            let c = e.centroid;
            [
                (6.0 * c.x).exp(),
                (-5.0 * c.y).exp() + 1e-3,
                1.0 + 1e3 * (c.x - 2.5).powi(2),
            ]
        })
        .collect();
    let checker = (0..mesh.elements.len())
        .map(|k| {
            let hi = k % 2 == 0;
            [
                if hi { 1e2 } else { 1e-2 },
                if hi { 1e-2 } else { 1e2 },
                1.0 + (k % 7) as f64,
            ]
        })
        .collect();
    vec![ramp, checker]
}

/// Per polygon, the polygons whose elements its texels may draw on: itself and those the
/// weld may average with (same material, same facing, coplanar, boxes touching).
fn sources(polygons: &[Polygon]) -> Vec<Vec<usize>> {
    let bounds = |p: &Polygon| {
        p.vertices
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), q| {
                (lo.min(*q), hi.max(*q))
            })
    };
    let tol = weld_tolerance(polygons);
    (0..polygons.len())
        .map(|a| {
            let (pa, (lo_a, hi_a)) = (&polygons[a], bounds(&polygons[a]));
            (0..polygons.len())
                .filter(|&b| {
                    let (pb, (lo_b, hi_b)) = (&polygons[b], bounds(&polygons[b]));
                    b == a
                        || (pa.material == pb.material
                            && pa.normal.dot(pb.normal) > 1.0 - 1e-9
                            && (0..3).all(|k| lo_a[k] <= hi_b[k] + tol && lo_b[k] <= hi_a[k] + tol)
                            && pb
                                .vertices
                                .iter()
                                .all(|q| (*q - pa.vertices[0]).dot(pa.normal).abs() <= tol))
                })
                .collect()
        })
        .collect()
}

/// The worst relative overshoot of any texel over the range of its sources' elements.
fn worst_overshoot(polygons: &[Polygon], mesh: &ElementMesh, values: &[[f64; 3]]) -> f64 {
    overshoot_with(polygons, mesh, values, &sources(polygons), Some(0.01))
}

/// [`worst_overshoot`] with given sources, at a texel size (default: the crate's).
fn overshoot_with(
    polygons: &[Polygon],
    mesh: &ElementMesh,
    values: &[[f64; 3]],
    sources: &[Vec<usize>],
    texel: Option<f64>,
) -> f64 {
    let mut range = vec![[(f64::INFINITY, f64::NEG_INFINITY); 3]; polygons.len()];
    for (e, value) in mesh.elements.iter().zip(values) {
        let r = &mut range[e.polygon as usize];
        for c in 0..3 {
            r[c] = (r[c].0.min(value[c]), r[c].1.max(value[c]));
        }
    }
    let mut worst = 0.0f64;
    for shading in [Shading::Smooth, Shading::Flat] {
        let options = Options {
            texel_size: texel.unwrap_or_else(|| lightmap::default_texel_size(polygons)),
            max_size: 4096,
            shading,
            max_atlases: lightmap::DEFAULT_MAX_ATLASES,
        };
        let built = lightmap::build(polygons, mesh, values, &options).expect("build");
        let mut checked = 0;
        for atlas in built.atlases() {
            for (t, cover) in atlas.texels.iter().zip(atlas.coverage) {
                let p = match cover {
                    Texel::Chart(p) | Texel::Gutter(p) => *p as usize,
                    Texel::Unused => continue,
                };
                checked += 1;
                for c in 0..3 {
                    let (lo, hi) = sources[p]
                        .iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &q| {
                            (lo.min(range[q][c].0), hi.max(range[q][c].1))
                        });
                    let x = f64::from(t[c]);
                    worst = worst.max((x - hi) / hi).max((lo - x) / hi);
                }
            }
        }
        assert!(checked > 100, "{checked} texels");
    }
    worst
}

#[test]
fn texels_stay_within_their_elements_range() {
    let polygons = slivers();
    let mut worst = 0.0f64;
    for subdivision in [
        Subdivision::Count(1),
        Subdivision::Count(3),
        Subdivision::MaxSize(0.15),
    ] {
        let mesh = mesher::mesh(&polygons, subdivision).expect("mesh");
        // And a refined mesh (conforming triangles, not the grids): every other element split.
        let split: Vec<bool> = (0..mesh.elements.len()).map(|k| k % 2 == 0).collect();
        let refined = mesh.refine(&split).expect("refine").mesh;
        for m in [&mesh, &refined] {
            for values in fields(m) {
                let w = worst_overshoot(&polygons, m, &values);
                println!(
                    "{subdivision:?}, {} elements: worst overshoot {w:.3e}",
                    m.elements.len()
                );
                worst = worst.max(w);
            }
        }
    }
    println!("worst overshoot over all: {worst:.3e} of the range's top");
    assert!(
        worst <= 1e-6,
        "a texel leaves its elements' range by {worst:.3e}"
    );
}

/// The weld's reach: 1e-6 × the scene's bounding-box diagonal (docs/lightmaps.md).
fn weld_tolerance(polygons: &[Polygon]) -> f64 {
    let (lo, hi) = polygons
        .iter()
        .flat_map(|p| &p.vertices)
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), q| {
            (lo.min(*q), hi.max(*q))
        });
    1e-6 * (hi - lo).length()
}

/// Per polygon, its source polygons as [`sources`] finds them, by a sweep over x (real
/// models have tens of thousands of polygons).
fn sources_swept(polygons: &[Polygon]) -> Vec<Vec<usize>> {
    let tol = weld_tolerance(polygons);
    let boxes: Vec<(DVec3, DVec3)> = polygons
        .iter()
        .map(|p| {
            p.vertices
                .iter()
                .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), q| {
                    (lo.min(*q), hi.max(*q))
                })
        })
        .collect();
    let mut order: Vec<usize> = (0..polygons.len()).collect();
    order.sort_by(|&a, &b| boxes[a].0.x.total_cmp(&boxes[b].0.x));
    let mut out: Vec<Vec<usize>> = (0..polygons.len()).map(|a| vec![a]).collect();
    for (k, &a) in order.iter().enumerate() {
        for &b in &order[k + 1..] {
            if boxes[b].0.x > boxes[a].1.x + tol {
                break;
            }
            let (pa, pb) = (&polygons[a], &polygons[b]);
            let touch = (0..3).all(|i| {
                boxes[a].0[i] <= boxes[b].1[i] + tol && boxes[b].0[i] <= boxes[a].1[i] + tol
            });
            let plane = |p: &Polygon, q: &Polygon| {
                q.vertices
                    .iter()
                    .all(|v| (*v - p.vertices[0]).dot(p.normal).abs() <= tol)
            };
            if touch
                && pa.material == pb.material
                && pa.normal.dot(pb.normal) > 1.0 - 1e-9
                && (plane(pa, pb) || plane(pb, pa))
            {
                out[a].push(b);
                out[b].push(a);
            }
        }
    }
    out
}

/// Real geometry (Debian's `assimp-testmodels` glTF 2.0 models, as `tests/corpora/real_corpus.rs`
/// finds them; skipped when absent): the slivers and thin triangles of real meshes, with a
/// pseudo-random field per element (ratio 20 between neighbours: the steepest a bake
/// shows). Models above 100 000 polygons are left out (debug-build time). Prints each
/// model's worst overshoot.
#[test]
fn real_models_texels_stay_within_their_elements_range() {
    let Some(files) = common::assimp_models() else {
        return;
    };
    let mut measured = 0;
    let mut worst_all = 0.0f64;
    for file in files {
        let Ok(scene) = importer::load(&file) else {
            continue;
        };
        let polygons = &scene.polygons;
        if polygons.is_empty() || polygons.len() > 100_000 {
            continue;
        }
        let Ok(mesh) = mesher::mesh(polygons, Subdivision::Count(2)) else {
            continue;
        };
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let values: Vec<[f64; 3]> = (0..mesh.elements.len())
            .map(|_| {
                std::array::from_fn(|_| {
                    state = state
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1_442_695_040_888_963_407);
                    0.1 + 1.9 * ((state >> 11) as f64 / (1u64 << 53) as f64)
                })
            })
            .collect();
        let sources = sources_swept(polygons);
        let w = overshoot_with(polygons, &mesh, &values, &sources, None);
        println!(
            "{}: {} polygons, worst overshoot {w:.3e}",
            file.file_name().unwrap_or_default().to_string_lossy(),
            polygons.len()
        );
        worst_all = worst_all.max(w);
        measured += 1;
    }
    println!("{measured} models, worst overshoot {worst_all:.3e}");
    assert!(
        worst_all <= 1e-6,
        "a texel leaves its elements' range by {worst_all:.3e}"
    );
}
