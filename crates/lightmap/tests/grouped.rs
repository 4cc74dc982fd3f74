//! Grouped charts on a generated scene of ~100 000 triangles (a terrain patch, cylinders,
//! subdivided boxes for furniture): occupancy ≥ 60%, far fewer charts than triangles, no two
//! polygons' TEXCOORD_1 overlapping (sampled 4× per texel, each sample strictly inside at most
//! one triangle; regions of different charts apart), every normal within twice
//! `CHART_CONE_DEGREES` of its chart's mean, and across chart seams the texels differ by no
//! more than the solution itself varies within the filter's reach there (the welded-edge
//! rule of `tests/end_to_end/lightmap.rs`).
//! Prints occupancy, charts, atlas count and time.

use bake_lightmap as lightmap;
use glam::{DVec2, DVec3};
use importer::{Origin, Polygon, Side};
use std::collections::HashMap;
use std::time::Instant;

fn triangle(a: DVec3, b: DVec3, c: DVec3, material: usize, node: usize) -> Polygon {
    let normal = (b - a).cross(c - a).normalize();
    Polygon {
        vertices: vec![a, b, c],
        normal,
        material,
        origin: Origin {
            node,
            mesh: node,
            primitive: 0,
            face: 0,
            side: Side::Front,
        },
    }
}

/// Two triangles per grid cell of the surface `at(u, v)` over [0, 1]², facing along
/// ∂u × ∂v.
fn surface(
    out: &mut Vec<Polygon>,
    nu: usize,
    nv: usize,
    material: usize,
    node: usize,
    at: impl Fn(f64, f64) -> DVec3,
) {
    for j in 0..nv {
        for i in 0..nu {
            let p = |a: usize, b: usize| at(a as f64 / nu as f64, b as f64 / nv as f64);
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            out.push(triangle(a, b, c, material, node));
            out.push(triangle(a, c, d, material, node));
        }
    }
}

fn scene() -> Vec<Polygon> {
    let mut out = Vec::new();
    // Terrain: 40 × 40 m, gentle hills, 150 × 150 cells (45 000 triangles).
    surface(&mut out, 150, 150, 0, 0, |u, v| {
        let (x, y) = (40.0 * u - 20.0, 40.0 * v - 20.0);
        DVec3::new(x, y, 0.6 * (x / 6.0).sin() * (y / 7.0).cos())
    });
    // Ten cylinders (columns, barrels): 64 segments × 30 rings (3 840 triangles each).
    for k in 0..10 {
        let centre = DVec3::new(-15.0 + 3.3 * k as f64, 12.0, 0.0);
        let (r, h) = (0.4 + 0.05 * k as f64, 2.0 + 0.2 * k as f64);
        surface(&mut out, 64, 30, 1, 1 + k, |u, v| {
            let a = std::f64::consts::TAU * u;
            centre + DVec3::new(r * a.cos(), r * a.sin(), h * v)
        });
    }
    // Fourteen boxes (tables, cabinets), each face 10 × 10 cells (1 200 triangles each).
    for k in 0..14 {
        let lo = DVec3::new(-16.0 + 2.3 * k as f64, -10.0, 0.0);
        let size = DVec3::new(1.2, 0.8, 0.75 + 0.05 * k as f64);
        let node = 11 + k;
        let corner = |x: f64, y: f64, z: f64| lo + size * DVec3::new(x, y, z);
        // Each face as (origin, u edge, v edge) with u × v pointing out.
        let faces = [
            (corner(0.0, 0.0, 1.0), DVec3::X, DVec3::Y),
            (corner(0.0, 1.0, 0.0), DVec3::X, -DVec3::Y),
            (corner(0.0, 0.0, 0.0), DVec3::X, DVec3::Z),
            (corner(1.0, 1.0, 0.0), -DVec3::X, DVec3::Z),
            (corner(0.0, 1.0, 0.0), -DVec3::Y, DVec3::Z),
            (corner(1.0, 0.0, 0.0), DVec3::Y, DVec3::Z),
        ];
        for (o, eu, ev) in faces {
            let (eu, ev) = (eu * size, ev * size);
            // Outward: flip v when u × v points into the box.
            let centre = lo + size / 2.0;
            let flip = eu.cross(ev).dot(o + (eu + ev) / 2.0 - centre) < 0.0;
            surface(&mut out, 10, 10, 2, node, |u, v| {
                if flip {
                    o + eu * v + ev * u
                } else {
                    o + eu * u + ev * v
                }
            });
        }
    }
    out
}

fn smooth_h(p: DVec3) -> [f64; 3] {
    [
        2.0 + 0.05 * p.x + 0.03 * p.y + 0.2 * p.z,
        1.5 + 0.02 * p.x,
        1.0 + 0.1 * (p.y / 5.0).sin(),
    ]
}

/// An undirected edge by its ends' bits.
type Edge = ([u64; 3], [u64; 3]);

fn key(p: DVec3) -> [u64; 3] {
    [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits())
}

fn inside_strictly(c: DVec2, t: &[DVec2]) -> bool {
    let cross = |a: DVec2, b: DVec2| a.perp_dot(b);
    let s: Vec<f64> = (0..3)
        .map(|k| cross(t[(k + 1) % 3] - t[k], c - t[k]))
        .collect();
    let area = cross(t[1] - t[0], t[2] - t[0]).abs();
    let eps = 1e-9 * area.max(1e-300);
    s.iter().all(|&x| x > eps) || s.iter().all(|&x| x < -eps)
}

#[test]
fn grouped_charts_on_a_hundred_thousand_triangles() {
    let polygons = scene();
    let triangles = polygons.len();
    assert!(triangles >= 100_000, "{triangles}");
    assert!(triangles > lightmap::GROUPED_ABOVE);
    let mesh = mesher::mesh(&polygons, mesher::Subdivision::Count(1)).expect("mesh");
    let h: Vec<[f64; 3]> = mesh.elements.iter().map(|e| smooth_h(e.centroid)).collect();
    // 25 texels per metre, a common lightmap density for furniture-sized objects (the
    // default, diagonal / 256, gives the 1.2 m boxes 5 texels a side: all gutter).
    let options = lightmap::Options {
        texel_size: 0.04,
        max_size: lightmap::DEFAULT_MAX_SIZE,
        shading: lightmap::Shading::Smooth,
        max_atlases: lightmap::DEFAULT_MAX_ATLASES,
    };
    let started = Instant::now();
    let map = lightmap::build(&polygons, &mesh, &h, &options).expect("build");
    let seconds = started.elapsed().as_secs_f64();
    let stats = &map.stats;
    println!(
        "{triangles} triangles: {} charts, {} atlas {}×{}, occupancy {:.1}%, texel {:.4} \
         (asked {:.4}), built in {seconds:.2} s",
        stats.charts,
        stats.atlases,
        map.width,
        map.height,
        100.0 * stats.occupancy,
        map.texel_size,
        map.requested_texel_size
    );
    assert!(stats.occupancy >= 0.60, "occupancy {}", stats.occupancy);
    assert!(stats.charts * 50 <= triangles, "{} charts", stats.charts);

    // Charts: polygons sharing a region. Normals within 2 × cone of the chart's mean.
    let mut charts: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for c in &map.charts {
        charts
            .entry((c.region.x, c.region.y))
            .or_default()
            .push(c.polygon);
    }
    assert_eq!(charts.len(), stats.charts);
    let limit = (2.0 * lightmap::CHART_CONE_DEGREES).to_radians().cos();
    for members in charts.values() {
        let mean = members
            .iter()
            .map(|&p| {
                let v = &polygons[p].vertices;
                polygons[p].normal * (v[1] - v[0]).cross(v[2] - v[0]).length()
            })
            .sum::<DVec3>()
            .normalize();
        for &p in members {
            assert!(polygons[p].normal.dot(mean) >= limit - 1e-12, "polygon {p}");
        }
    }
    // Regions of different charts apart.
    let rects: Vec<lightmap::Rect> = charts.values().map(|m| map.charts[m[0]].region).collect();
    let mut by_row: Vec<&lightmap::Rect> = rects.iter().collect();
    by_row.sort_by_key(|r| (r.y, r.x));
    for (i, a) in by_row.iter().enumerate() {
        assert!(a.x + a.width <= map.width && a.y + a.height <= map.height);
        for b in &by_row[i + 1..] {
            if b.y >= a.y + a.height {
                break;
            }
            let apart = a.x + a.width <= b.x || b.x + b.width <= a.x || a.y + a.height <= b.y;
            assert!(apart, "regions {a:?} and {b:?} overlap");
        }
    }
    // No overlap between any two triangles: 2 × 2 samples per texel, each strictly inside at
    // most one polygon's texel-space triangle.
    let (w, hgt) = (map.width as usize * 2, map.height as usize * 2);
    let mut hits = vec![0u8; w * hgt];
    for c in &map.charts {
        let t: Vec<DVec2> = c.uv.iter().map(|&q| DVec2::from_array(q)).collect();
        let lo = t[0].min(t[1]).min(t[2]);
        let hi = t[0].max(t[1]).max(t[2]);
        let (x0, x1) = (
            (lo.x * 2.0).floor() as usize,
            ((hi.x * 2.0).ceil() as usize).min(w),
        );
        let (y0, y1) = (
            (lo.y * 2.0).floor() as usize,
            ((hi.y * 2.0).ceil() as usize).min(hgt),
        );
        for y in y0..y1 {
            for x in x0..x1 {
                let s = DVec2::new((x as f64 + 0.5) / 2.0, (y as f64 + 0.5) / 2.0);
                if inside_strictly(s, &t) {
                    hits[y * w + x] += 1;
                    assert!(hits[y * w + x] == 1, "two triangles cover sample {s}");
                }
            }
        }
    }
    // Seams across charts: shared edges between polygons of different charts, sampled along
    // the edge through each side's TEXCOORD_1, differ by no more than the solution itself
    // varies where bilinear filtering reads (elements of that material within 2 texels and
    // an element's size of the point; the rule of `tests/end_to_end/lightmap.rs`' welded edges, at the
    // filter's reach since a chart's texels near a seam also serve its other polygons), plus
    // f32 rounding.
    let reach = 2.0 * map.texel_size + 0.1;
    let cell = |p: DVec3| (p / reach).floor().as_ivec3();
    let mut near: HashMap<glam::IVec3, Vec<usize>> = HashMap::new();
    for (e, el) in mesh.elements.iter().enumerate() {
        near.entry(cell(el.centroid)).or_default().push(e);
    }
    let spread = |p: DVec3, material: usize| {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let c = cell(p);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(list) = near.get(&(c + glam::IVec3::new(dx, dy, dz))) else {
                        continue;
                    };
                    for &e in list {
                        let el = &mesh.elements[e];
                        if el.centroid.distance(p) > reach
                            || polygons[el.polygon as usize].material != material
                        {
                            continue;
                        }
                        for k in 0..3 {
                            lo[k] = lo[k].min(h[e][k]);
                            hi[k] = hi[k].max(h[e][k]);
                        }
                    }
                }
            }
        }
        [0, 1, 2].map(|k| hi[k] - lo[k])
    };
    let chart_of: HashMap<usize, (u32, u32)> = map
        .charts
        .iter()
        .map(|c| (c.polygon, (c.region.x, c.region.y)))
        .collect();
    let mut edges: HashMap<Edge, Vec<(usize, usize)>> = HashMap::new();
    for (p, polygon) in polygons.iter().enumerate() {
        let v = &polygon.vertices;
        for k in 0..v.len() {
            let (a, b) = (key(v[k]), key(v[(k + 1) % v.len()]));
            edges
                .entry(if a <= b { (a, b) } else { (b, a) })
                .or_default()
                .push((p, k));
        }
    }
    let uv_at = |p: usize, k: usize, t: f64| {
        let c = &map.charts[p];
        let n = c.uv.len();
        let a = DVec2::from_array(c.uv[k]);
        let b = DVec2::from_array(c.uv[(k + 1) % n]);
        let q = a.lerp(b, t);
        [q.x / f64::from(map.width), q.y / f64::from(map.height)]
    };
    let (mut seams, mut worst) = (0usize, 0.0f64);
    for sides in edges.values() {
        let [(a, ka), (b, kb)] = sides[..] else {
            continue;
        };
        if chart_of[&a] == chart_of[&b] || polygons[a].material != polygons[b].material {
            continue;
        }
        seams += 1;
        // Edge k of a runs v_k → v_k+1; on b the same edge runs the other way.
        for s in 1..8 {
            let t = s as f64 / 8.0;
            let va = map.sample(uv_at(a, ka, t));
            let vb = map.sample(uv_at(b, kb, 1.0 - t));
            let v = &polygons[a].vertices;
            let point = v[ka].lerp(v[(ka + 1) % v.len()], t);
            let spread = spread(point, polygons[a].material);
            for c in 0..3 {
                let variation = spread[c];
                let jump = (va[c] - vb[c]).abs();
                let scale = va[c].abs().max(1e-12);
                // f32 texels: their rounding is part of the tolerance.
                assert!(
                    jump <= variation + 1e-6 * scale + 2.0 * f64::from(f32::EPSILON) * scale,
                    "polygons {a}/{b}: texels differ by {jump}, the solution by {variation}"
                );
                worst = worst.max(jump / variation.max(1e-6 * scale));
            }
        }
    }
    println!("{seams} seams across charts: texel jump / solution jump ≤ {worst:.3}");
    assert!(seams > 100, "{seams}");
}

/// The generated layout of the 100k-triangle scene, given back as an authored TEXCOORD_1,
/// passes the authored-layout checks (no overlaps, inside [0, 1]) and is kept as it is: two
/// independent overlap tests agree, and a kept layout of 100k triangles is checked quickly.
#[test]
fn a_generated_layout_is_a_valid_authored_one() {
    let polygons = scene();
    let mesh = mesher::mesh(&polygons, mesher::Subdivision::Count(1)).expect("mesh");
    let h: Vec<[f64; 3]> = mesh.elements.iter().map(|e| smooth_h(e.centroid)).collect();
    let options = lightmap::Options {
        texel_size: 0.04,
        max_size: lightmap::DEFAULT_MAX_SIZE,
        shading: lightmap::Shading::Smooth,
        max_atlases: lightmap::DEFAULT_MAX_ATLASES,
    };
    let generated = lightmap::build(&polygons, &mesh, &h, &options).expect("build");
    let authored = lightmap::AuthoredUv {
        polygons: (0..polygons.len())
            .map(|p| {
                Ok((0..polygons[p].vertices.len())
                    .map(|k| DVec2::from_array(generated.texcoord(p, k).map(f64::from)))
                    .collect())
            })
            .collect(),
    };
    let started = Instant::now();
    let kept = lightmap::build_with(
        &polygons,
        &mesh,
        &h,
        &options,
        &authored,
        lightmap::UvMode::Keep,
    )
    .expect("the generated layout is a usable authored one");
    println!(
        "kept {} triangles' layout: {}×{} atlas, occupancy {:.1}%, {:.2} s",
        polygons.len(),
        kept.width,
        kept.height,
        100.0 * kept.stats.occupancy,
        started.elapsed().as_secs_f64()
    );
    assert!(kept.uv_decisions.iter().all(|d| d.kept));
    assert!(kept.warnings.is_empty(), "{:?}", kept.warnings);
    for (p, polygon) in polygons.iter().enumerate() {
        for k in 0..polygon.vertices.len() {
            let (a, b) = (kept.texcoord(p, k), generated.texcoord(p, k));
            assert!(
                (a[0] - b[0]).abs() <= f32::EPSILON && (a[1] - b[1]).abs() <= f32::EPSILON,
                "{p}/{k}: {a:?} vs {b:?}"
            );
        }
    }
}

/// The 100k-triangle scene at 50 texels per metre under 2048-texel atlases: the charts need
/// more than one atlas, so they get several (whole primitives — here nodes — per atlas) at the
/// requested texel size: each atlas within 2048, its regions apart, every node in one atlas,
/// occupancy over all atlases ≥ 60%. Prints atlas count, occupancy, charts and time.
#[test]
fn a_hundred_thousand_triangles_in_several_atlases() {
    let polygons = scene();
    let mesh = mesher::mesh(&polygons, mesher::Subdivision::Count(1)).expect("mesh");
    let h: Vec<[f64; 3]> = mesh.elements.iter().map(|e| smooth_h(e.centroid)).collect();
    let options = lightmap::Options {
        texel_size: 0.02,
        max_size: 2048,
        shading: lightmap::Shading::Smooth,
        max_atlases: lightmap::DEFAULT_MAX_ATLASES,
    };
    let started = Instant::now();
    let map = lightmap::build(&polygons, &mesh, &h, &options).expect("build");
    let seconds = started.elapsed().as_secs_f64();
    let atlases = map.atlases();
    println!(
        "{} triangles at texel 0.02, 2048 max: {} charts, {} atlases {:?}, occupancy {:.1}%, \
         texel {:.4}, built in {seconds:.2} s",
        polygons.len(),
        map.stats.charts,
        atlases.len(),
        atlases
            .iter()
            .map(|a| (a.width, a.height))
            .collect::<Vec<_>>(),
        100.0 * map.stats.occupancy,
        map.texel_size
    );
    assert!(atlases.len() >= 2, "{:?}", map.stats);
    assert_eq!((map.stats.reductions, map.texel_size), (0, 0.02));
    assert!(map.stats.occupancy >= 0.60, "{}", map.stats.occupancy);
    let mut atlas_of_node: HashMap<usize, u32> = HashMap::new();
    for c in &map.charts {
        let node = polygons[c.polygon].origin.node;
        assert_eq!(
            *atlas_of_node.entry(node).or_insert(c.atlas),
            c.atlas,
            "node {node}"
        );
        let a = atlases[c.atlas as usize];
        let r = c.region;
        assert!(r.x + r.width <= a.width && r.y + r.height <= a.height);
        for q in &c.uv {
            assert!(q[0] >= 0.0 && q[1] >= 0.0);
            assert!(q[0] <= f64::from(a.width) && q[1] <= f64::from(a.height));
        }
    }
    // Regions of different charts in one atlas apart.
    let mut regions: Vec<(u32, lightmap::Rect)> =
        map.charts.iter().map(|c| (c.atlas, c.region)).collect();
    regions.sort_by_key(|(k, r)| (*k, r.y, r.x));
    regions.dedup();
    for (i, (ka, a)) in regions.iter().enumerate() {
        for (kb, b) in &regions[i + 1..] {
            if kb != ka || b.y >= a.y + a.height {
                break;
            }
            let apart = a.x + a.width <= b.x || b.x + b.width <= a.x || a.y + a.height <= b.y;
            assert!(apart, "atlas {ka}: regions {a:?} and {b:?} overlap");
        }
    }
}
