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
use lightmap::Lightmap;
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

/// Whether the square of half-side `half` around `c` meets the triangle `t` (separating axes).
fn meets_square(c: DVec2, half: f64, t: &[DVec2]) -> bool {
    let lo = t[0].min(t[1]).min(t[2]);
    let hi = t[0].max(t[1]).max(t[2]);
    if lo.x > c.x + half || hi.x < c.x - half || lo.y > c.y + half || hi.y < c.y - half {
        return false;
    }
    (0..3).all(|k| {
        let e = t[(k + 1) % 3] - t[k];
        let n = DVec2::new(-e.y, e.x);
        let (a, b) = t
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.dot(n)), b.max(p.dot(n)))
            });
        let reach = half * (n.x.abs() + n.y.abs());
        c.dot(n) - reach <= b && c.dot(n) + reach >= a
    })
}

/// Every texel filtering reads for a chart point, at full resolution and at mip 1 (the 2×2
/// blocks whose centres lie within 2 texels of it), holds its own chart's values.
fn reads_stay_in_their_charts(map: &Lightmap) {
    let region_of = |p: usize| {
        let c = &map.charts[p];
        (c.atlas, c.region.x, c.region.y)
    };
    let mut reads = 0u64;
    for c in &map.charts {
        let atlas = map.atlas(c.atlas as usize);
        let t: Vec<DVec2> = c.uv.iter().map(|&q| DVec2::from_array(q)).collect();
        let lo = t[0].min(t[1]).min(t[2]);
        let hi = t[0].max(t[1]).max(t[2]);
        let block = |x: f64| (x / 2.0).floor().max(0.0) as u32;
        for by in block(lo.y - 3.0)..=block(hi.y + 3.0).min(atlas.height / 2 - 1) {
            for bx in block(lo.x - 3.0)..=block(hi.x + 3.0).min(atlas.width / 2 - 1) {
                let centre = DVec2::new(2.0 * f64::from(bx) + 1.0, 2.0 * f64::from(by) + 1.0);
                if !meets_square(centre, 2.0, &t) {
                    continue;
                }
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let k = ((2 * by + dy) * atlas.width + 2 * bx + dx) as usize;
                    let owner = match atlas.coverage[k] {
                        lightmap::Texel::Chart(q) | lightmap::Texel::Gutter(q) => q as usize,
                        lightmap::Texel::Unused => {
                            panic!("polygon {} reads an unused texel", c.polygon)
                        }
                    };
                    assert_eq!(
                        region_of(owner),
                        region_of(c.polygon),
                        "polygon {} reads polygon {owner}'s texel",
                        c.polygon
                    );
                    reads += 1;
                }
            }
        }
    }
    assert!(reads > 0);
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

    // Charts: polygons sharing a region. Normals within the cone of the chart's first
    // polygon (its seed).
    let mut charts: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for c in &map.charts {
        charts
            .entry((c.region.x, c.region.y))
            .or_default()
            .push(c.polygon);
    }
    assert_eq!(charts.len(), stats.charts);
    let limit = lightmap::CHART_CONE_DEGREES.to_radians().cos();
    for members in charts.values() {
        let seed = polygons[*members.iter().min().expect("a member")].normal;
        for &p in members {
            assert!(polygons[p].normal.dot(seed) >= limit - 1e-12, "polygon {p}");
        }
    }
    reads_stay_in_their_charts(&map);
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
    // Seams across charts: at points of every edge two charts share, the two sides'
    // bilinear samples differ by no more than the reconstructed field varies within a
    // bilinear read's footprint there (`Lightmap::seams`).
    let seams = map.seams_at(&polygons, 4);
    println!(
        "{} seams of {} shared edges: worst jump / bound {:.3}",
        seams.seam_edges, seams.shared_edges, seams.worst_ratio
    );
    assert_eq!(seams.over, 0, "{seams:?}");
    assert!(seams.seam_edges > 100, "{seams:?}");
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

/// The 100k-triangle scene at 40 texels per metre under 1700-texel atlases: the charts need
/// more than one atlas, so they get several (whole primitives — here nodes — per atlas) at the
/// requested texel size: each atlas within 1700 (the 40 m terrain, unfolded at its true area,
/// takes most of one), reads inside their charts, every node in one atlas,
/// occupancy over all atlases ≥ 60%. Prints atlas count, occupancy, charts and time.
#[test]
fn a_hundred_thousand_triangles_in_several_atlases() {
    let polygons = scene();
    let mesh = mesher::mesh(&polygons, mesher::Subdivision::Count(1)).expect("mesh");
    let h: Vec<[f64; 3]> = mesh.elements.iter().map(|e| smooth_h(e.centroid)).collect();
    let options = lightmap::Options {
        texel_size: 0.025,
        max_size: 1700,
        shading: lightmap::Shading::Smooth,
        max_atlases: lightmap::DEFAULT_MAX_ATLASES,
    };
    let started = Instant::now();
    let map = lightmap::build(&polygons, &mesh, &h, &options).expect("build");
    let seconds = started.elapsed().as_secs_f64();
    let atlases = map.atlases();
    println!(
        "{} triangles at texel 0.025, 1700 max: {} charts, {} atlases {:?}, occupancy {:.1}%, \
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
    assert_eq!((map.stats.reductions, map.texel_size), (0, 0.025));
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
    reads_stay_in_their_charts(&map);
}
