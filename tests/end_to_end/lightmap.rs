//! Lightmap bakes, end to end: the CLI writes them (`--target lightmap|both`), the tests bake
//! the same scene in-process (importer → mesher → form factors → solve → H = F b →
//! `lightmap::build`, the CLI's defaults) and check the files against it:
//!
//! - every element's centroid, looked up through the file's `TEXCOORD_1` and sampled
//!   bilinearly from the EXR, gives the smoothed irradiance there within 1%, and
//!   ρ × that + e the vertex bake's smoothed radiosity within 1%;
//! - footprints are fully written, gutters copy their nearest chart texel, bilinear reads at
//!   full resolution and at mip 1 stay inside their chart, regions never overlap, UVs lie in
//!   [0, 1];
//! - occupancy ≥ 70% on the Cornell-like room;
//! - coplanar same-material neighbours agree along their shared edges;
//! - the EXR reads back identically with `exr` and `image`, the PNG × intensity gives H within
//!   8-bit rounding, the glTF re-reads and passes the Khronos validator.
//!
//! The Cornell-like room (`cornell_like_obj`) stands in for `fixtures/cornell.gltf` until that
//! fixture lands: tests that use it are named `cornell_like_*` so they can be switched.

use crate::common;

use bake_testkit::{file_names, fixture, validator_or_skip, validator_output};
use common::{bake, write_text};
use glam::{DVec2, DVec3};
use lightmap::{Lightmap, Texel};
use std::path::{Path, PathBuf};
use std::time::Instant;

// ---- scenes ----

/// A Cornell-box-like room as OBJ + MTL (31 quads): a 5.5 m room open at the front (z = 5.5),
/// floor and back wall split 2×2, red left and green right walls split in two, the ceiling
/// split 3×3 with the light in the middle (coplanar with the ceiling, another material), and a
/// short and a tall block turned ±17° standing on the floor. With `pyramid`, a four-sided
/// pyramid (triangles) stands in the front left.
fn cornell_like_obj(dir: &Path, pyramid: bool) -> PathBuf {
    let l = 5.5;
    let mut obj = ObjWriter::default();
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let third = l / 3.0;
    let half = l / 2.0;
    obj.material("white");
    for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
        let o = DVec3::new(i as f64 * half, 0.0, j as f64 * half);
        obj.quad(o, z * half, x * half); // floor, +y
        let o = DVec3::new(i as f64 * half, j as f64 * half, 0.0);
        obj.quad(o, x * half, y * half); // back wall, +z
    }
    for i in 0..3 {
        for j in 0..3 {
            if (i, j) != (1, 1) {
                let o = DVec3::new(i as f64 * third, l, j as f64 * third);
                obj.quad(o, x * third, z * third); // ceiling, −y
            }
        }
    }
    obj.material("red");
    for j in 0..2 {
        obj.quad(DVec3::new(0.0, j as f64 * half, 0.0), y * half, z * l); // left, +x
    }
    obj.material("green");
    for j in 0..2 {
        obj.quad(DVec3::new(l, j as f64 * half, 0.0), z * l, y * half); // right, −x
    }
    obj.material("light");
    obj.quad(DVec3::new(third, l, third), x * third, z * third);
    obj.material("white");
    obj.block(DVec3::new(3.7, 0.0, 1.9), 0.8, 1.65, -17f64.to_radians());
    obj.block(DVec3::new(1.8, 0.0, 1.6), 0.8, 3.3, 17f64.to_radians());
    if pyramid {
        obj.material("blue");
        obj.pyramid(DVec3::new(1.2, 0.0, 4.2), 0.7, 1.4);
    }
    let path = dir.join(if pyramid {
        "pyramid.obj"
    } else {
        "cornell-like.obj"
    });
    let mtl = path.with_extension("mtl");
    write_text(
        &mtl,
        "newmtl white\nKd 0.75 0.75 0.75\n\
         newmtl red\nKd 0.63 0.065 0.05\n\
         newmtl green\nKd 0.14 0.45 0.09\n\
         newmtl blue\nKd 0.1 0.2 0.6\n\
         newmtl light\nKd 0 0 0\nKe 8 7 5\n",
    );
    let mtl_name = mtl.file_name().and_then(|n| n.to_str()).expect("a name");
    write_text(&path, &format!("mtllib {mtl_name}\no room\n{}", obj.text));
    path
}

#[derive(Default)]
struct ObjWriter {
    text: String,
    vertices: usize,
}

impl ObjWriter {
    fn material(&mut self, name: &str) {
        self.text.push_str(&format!("usemtl {name}\n"));
    }

    fn face(&mut self, points: &[DVec3]) {
        for p in points {
            self.text.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
        }
        let ids: Vec<String> = (1..=points.len())
            .map(|k| (self.vertices + k).to_string())
            .collect();
        self.text.push_str(&format!("f {}\n", ids.join(" ")));
        self.vertices += points.len();
    }

    /// o, o+u, o+u+v, o+v: counter-clockwise about u × v.
    fn quad(&mut self, o: DVec3, u: DVec3, v: DVec3) {
        self.face(&[o, o + u, o + u + v, o + v]);
    }

    /// A quad facing `outward`.
    fn facing(&mut self, o: DVec3, u: DVec3, v: DVec3, outward: DVec3) {
        if u.cross(v).dot(outward) > 0.0 {
            self.quad(o, u, v);
        } else {
            self.quad(o, v, u);
        }
    }

    /// A square block (side 2a, height h) on the floor at `centre`, turned by `angle` about y;
    /// top and four sides, facing out.
    fn block(&mut self, centre: DVec3, a: f64, h: f64, angle: f64) {
        let d1 = DVec3::new(angle.cos(), 0.0, angle.sin());
        let d2 = DVec3::new(-angle.sin(), 0.0, angle.cos());
        let up = DVec3::Y * h;
        let top = centre + up - d1 * a - d2 * a;
        self.facing(top, d1 * 2.0 * a, d2 * 2.0 * a, DVec3::Y);
        for (dir, side) in [(d1, d2), (-d1, d2), (d2, d1), (-d2, d1)] {
            let o = centre + dir * a - side * a;
            self.facing(o, side * 2.0 * a, up, dir);
        }
    }

    /// A square pyramid (base side 2a, height h) on the floor: four triangles facing out.
    fn pyramid(&mut self, centre: DVec3, a: f64, h: f64) {
        let apex = centre + DVec3::Y * h;
        let corners = [
            centre + DVec3::new(-a, 0.0, -a),
            centre + DVec3::new(a, 0.0, -a),
            centre + DVec3::new(a, 0.0, a),
            centre + DVec3::new(-a, 0.0, a),
        ];
        for k in 0..4 {
            let (p, q) = (corners[k], corners[(k + 1) % 4]);
            let outward = ((p + q) / 2.0 - centre).normalize();
            if (q - p).cross(apex - p).dot(outward) > 0.0 {
                self.face(&[p, q, apex]);
            } else {
                self.face(&[q, p, apex]);
            }
        }
    }
}

// ---- the same bake in-process ----

struct Solved {
    scene: importer::Scene,
    mesh: mesher::ElementMesh,
    b: Vec<[f64; 3]>,
    h: Vec<[f64; 3]>,
}

/// The CLI's default bake of `path`, with H = F b: the library's one bake, as `bake` runs it.
fn solve(path: &Path) -> Solved {
    solve_with(path, bake_core::TransportKind::Auto)
}

fn solve_with(path: &Path, transport: bake_core::TransportKind) -> Solved {
    let scene = importer::load(path).expect("load the scene");
    let request = bake_core::Request {
        irradiance: true,
        // The uniform mesh this test is about.
        refine: Some(false),
        transport,
        ..bake_core::Request::default()
    };
    let settings = bake_core::Settings::resolve(&request, &scene.polygons).expect("settings");
    let bake = bake_core::run(&scene, &settings, &bake_core::Silent).expect("bake");
    Solved {
        h: bake.irradiance.expect("irradiance"),
        b: bake.solution.b,
        mesh: bake.mesh,
        scene,
    }
}

fn build(solved: &Solved, texel: Option<f64>) -> Lightmap {
    let options = lightmap::Options {
        texel_size: texel.unwrap_or_else(|| lightmap::default_texel_size(&solved.scene.polygons)),
        max_size: lightmap::DEFAULT_MAX_SIZE,
        shading: lightmap::Shading::Smooth,
        max_atlases: lightmap::DEFAULT_MAX_ATLASES,
    };
    lightmap::build(&solved.scene.polygons, &solved.mesh, &solved.h, &options)
        .expect("build the lightmap")
}

// ---- reading the files back ----

/// A float RGB image, row-major from the top.
struct Rgb {
    width: u32,
    height: u32,
    texels: Vec<[f32; 3]>,
}

fn read_exr_with_exr(path: &Path) -> Rgb {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| {
            (
                resolution.width(),
                vec![[0.0f32; 3]; resolution.width() * resolution.height()],
            )
        },
        |(width, texels), position, (r, g, b, _a): (f32, f32, f32, f32)| {
            texels[position.y() * *width + position.x()] = [r, g, b];
        },
    )
    .expect("exr reads the EXR");
    let size = image.layer_data.size;
    Rgb {
        width: size.width() as u32,
        height: size.height() as u32,
        texels: image.layer_data.channel_data.pixels.1,
    }
}

fn read_exr_with_image(path: &Path) -> Rgb {
    let image = image::open(path).expect("image reads the EXR").to_rgb32f();
    Rgb {
        width: image.width(),
        height: image.height(),
        texels: image.pixels().map(|p| p.0).collect(),
    }
}

/// The lightmap glTF re-read: per polygon (scene order) its vertices' TEXCOORD_1, found
/// through the documented layout (each primitive holds its polygons in order, 3–4 vertices
/// each), after checking positions against the polygon.
fn read_texcoords(path: &Path, scene: &importer::Scene) -> (gltf::Document, Vec<Vec<[f64; 2]>>) {
    let (document, buffers, _images) = gltf::import(path).expect("re-read the lightmap glTF");
    let mut texcoords = vec![Vec::new(); scene.polygons.len()];
    for node in document.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let world = scene.layout.nodes[node.index()].world;
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
            let positions: Vec<[f32; 3]> = reader.read_positions().expect("POSITION").collect();
            let uv1: Vec<[f32; 2]> = reader
                .read_tex_coords(1)
                .expect("TEXCOORD_1")
                .into_f32()
                .collect();
            let uv0: Vec<[f32; 2]> = reader
                .read_tex_coords(0)
                .expect("TEXCOORD_0")
                .into_f32()
                .collect();
            assert_eq!(uv0.len(), uv1.len());
            let mut next = 0;
            for (p, polygon) in scene.polygons.iter().enumerate() {
                let o = polygon.origin;
                if o.node != node.index() || o.primitive != primitive.index() {
                    continue;
                }
                for v in &polygon.vertices {
                    let stored =
                        world.transform_point3(DVec3::from_array(positions[next].map(f64::from)));
                    assert!(stored.distance(*v) < 1e-5, "{stored} vs {v}");
                    let uv = uv1[next].map(f64::from);
                    assert!(uv.iter().all(|c| (0.0..=1.0).contains(c)), "UV {uv:?}");
                    texcoords[p].push(uv);
                    next += 1;
                }
            }
            assert_eq!(next, positions.len(), "every vertex belongs to a polygon");
        }
    }
    assert!(texcoords
        .iter()
        .zip(&scene.polygons)
        .all(|(t, p)| t.len() == p.vertices.len()));
    (document, texcoords)
}

/// TEXCOORD_1 at world point `point` of polygon `polygon`, interpolated over the triangle
/// (v0 v1 v2) or (v0 v2 v3) that holds it — as a renderer does.
fn texcoord_at(polygon: &importer::Polygon, uv: &[[f64; 2]], point: DVec3) -> [f64; 2] {
    let v = &polygon.vertices;
    let n = polygon.normal;
    let mut best = (f64::NEG_INFINITY, [0.0; 2]);
    for k in 1..v.len() - 1 {
        let (a, b, c) = (v[0], v[k], v[k + 1]);
        let area = (b - a).cross(c - a).dot(n);
        let l1 = (point - a).cross(c - a).dot(n) / area;
        let l2 = (b - a).cross(point - a).dot(n) / area;
        let l = [1.0 - l1 - l2, l1, l2];
        let worst = l[0].min(l[1]).min(l[2]);
        if worst > best.0 {
            let t = [uv[0], uv[k], uv[k + 1]];
            best = (
                worst,
                std::array::from_fn(|i| l[0] * t[0][i] + l[1] * t[1][i] + l[2] * t[2][i]),
            );
        }
    }
    best.1
}

fn relative(a: f64, b: f64, floor: f64) -> f64 {
    (a - b).abs() / b.abs().max(floor)
}

/// Mean of the element's corner values: the bilinear (quad) or linear (triangle) interpolant
/// at the centroid of a parallelogram or triangle element.
fn at_centroid(element: &mesher::Element, values: &[[f64; 3]]) -> [f64; 3] {
    let corners = element.corner_indices();
    std::array::from_fn(|c| {
        corners.iter().map(|&k| values[k as usize][c]).sum::<f64>() / corners.len() as f64
    })
}

fn is_parallelogram_or_triangle(element: &mesher::Element, mesh: &mesher::ElementMesh) -> bool {
    let c = element.corner_indices();
    c.len() == 3 || {
        let v = |k: usize| mesh.vertices[c[k] as usize];
        (v(0) + v(2) - v(1) - v(3)).length() < 1e-6 * (v(2) - v(0)).length()
    }
}

// ---- the checks ----

struct Case {
    name: &'static str,
    input: PathBuf,
}

fn cases(dir: &Path) -> Vec<Case> {
    vec![
        Case {
            name: "cube",
            input: fixture("cube.gltf"),
        },
        Case {
            name: "cornell-like",
            input: cornell_like_obj(dir, false),
        },
        Case {
            name: "cornell-like + pyramid",
            input: cornell_like_obj(dir, true),
        },
    ]
}

/// `bake --target lightmap --shading SHADING` of the case: its EXR, checked equal to
/// `lightmap` (the same build in-process), and every polygon's TEXCOORD_1.
fn bake_lightmap(
    case: &Case,
    solved: &Solved,
    lightmap: &Lightmap,
    dir: &Path,
    shading: &str,
) -> (Rgb, Vec<Vec<[f64; 2]>>) {
    let out = dir.join(format!("{shading}.gltf"));
    bake([
        "--quiet".as_ref(),
        "--target".as_ref(),
        "lightmap".as_ref(),
        "--shading".as_ref(),
        shading.as_ref(),
        case.input.as_os_str(),
        out.as_os_str(),
    ])
    .success();
    let exr = read_exr_with_exr(&dir.join(format!("{shading}.lightmap.exr")));
    assert_eq!((exr.width, exr.height), (lightmap.width, lightmap.height));
    assert!(
        exr.texels == lightmap.texels,
        "{}: the CLI's texels",
        case.name
    );
    (exr, read_texcoords(&out, &solved.scene).1)
}

#[test]
fn element_centroids_sample_the_smoothed_irradiance_within_one_percent() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    for case in cases(dir.path()) {
        let solved = solve(&case.input);
        let lightmap = build(&solved, None);
        let (exr, texcoords) = bake_lightmap(&case, &solved, &lightmap, dir.path(), "smooth");
        let smoothed_h = solved.mesh.smooth(&solved.h);
        // The per-polygon smoothing before the weld, to show what the weld changes; the vertex
        // bake itself is welded (`welded_b`).
        let smoothed_b = solved.mesh.smooth(&solved.b);
        let welded_b =
            lightmap::welded_vertex_values(&solved.scene.polygons, &solved.mesh, &solved.b)
                .expect("weld b");
        let peak = solved.h.iter().flatten().fold(0.0f64, |m, v| m.max(*v));
        let (mut worst_h, mut worst_unwelded) = (0.0f64, 0.0f64);
        // ρH + e against the vertex bake (per-polygon smoothing) away from welded edges, and
        // against the same smoothing with the lightmap's weld everywhere; and how far the
        // vertex bake is from the lightmap at elements touching a welded edge.
        let (mut worst_b, mut worst_b_welded, mut worst_at_welds) = (0.0f64, 0.0f64, 0.0f64);
        for element in &solved.mesh.elements {
            assert!(
                is_parallelogram_or_triangle(element, &solved.mesh),
                "{}: {element:?}",
                case.name
            );
            let p = element.polygon as usize;
            let polygon = &solved.scene.polygons[p];
            let uv = texcoord_at(polygon, &texcoords[p], element.centroid);
            let sampled = lightmap::sample_bilinear(&exr.texels, exr.width, exr.height, uv);
            let expected = at_centroid(element, &lightmap.vertex_values);
            let unwelded = at_centroid(element, &smoothed_h);
            let material = &solved.scene.materials[polygon.material];
            let vertex_bake = at_centroid(element, &smoothed_b);
            let vertex_bake_welded = at_centroid(element, &welded_b);
            let touches_weld = element
                .corner_indices()
                .iter()
                .any(|&k| welded_b[k as usize] != smoothed_b[k as usize]);
            for c in 0..3 {
                let floor = 1e-6 * peak;
                worst_h = worst_h.max(relative(sampled[c], expected[c], floor));
                worst_unwelded = worst_unwelded.max(relative(sampled[c], unwelded[c], floor));
                let rebuilt = material.rho[c] * sampled[c] + material.emission[c];
                let error = relative(rebuilt, vertex_bake[c], floor);
                if touches_weld {
                    worst_at_welds = worst_at_welds.max(error);
                } else {
                    worst_b = worst_b.max(error);
                }
                worst_b_welded =
                    worst_b_welded.max(relative(rebuilt, vertex_bake_welded[c], floor));
            }
        }
        println!(
            "{}: {} elements; lightmap at centroids vs smoothed (welded) H: max {:.2e} relative \
             (vs unwelded: {:.2e}); ρH + e vs the vertex bake away from welded edges: {:.2e}, \
             vs the (welded) vertex bake everywhere: {:.2e}, vs unwelded smoothing at welded edges: \
             {:.2e}",
            case.name,
            solved.mesh.elements.len(),
            worst_h,
            worst_unwelded,
            worst_b,
            worst_b_welded,
            worst_at_welds
        );
        assert!(worst_h < 0.01, "{}: {worst_h}", case.name);
        assert!(worst_b < 0.01, "{}: {worst_b}", case.name);
        assert!(worst_b_welded < 0.01, "{}: {worst_b_welded}", case.name);
    }
}

/// `--shading flat`: every texel holds its element's own H, so bilinear sampling at an
/// element's centroid (at least a texel inside it: elements here span ~15 texels) reads the
/// element's H exactly, to f32 rounding (the EXR stores f32).
#[test]
fn flat_lightmap_texels_at_element_centroids_are_the_elements_h() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    for case in cases(dir.path()) {
        let solved = solve(&case.input);
        let options = lightmap::Options {
            texel_size: lightmap::default_texel_size(&solved.scene.polygons),
            max_size: lightmap::DEFAULT_MAX_SIZE,
            shading: lightmap::Shading::Flat,
            max_atlases: lightmap::DEFAULT_MAX_ATLASES,
        };
        let lightmap = lightmap::build(&solved.scene.polygons, &solved.mesh, &solved.h, &options)
            .expect("build the flat lightmap");
        let (exr, texcoords) = bake_lightmap(&case, &solved, &lightmap, dir.path(), "flat");
        let peak = solved.h.iter().flatten().fold(0.0f64, |m, v| m.max(*v));
        let mut worst = 0.0f64;
        for (i, element) in solved.mesh.elements.iter().enumerate() {
            let p = element.polygon as usize;
            let uv = texcoord_at(&solved.scene.polygons[p], &texcoords[p], element.centroid);
            let sampled = lightmap::sample_bilinear(&exr.texels, exr.width, exr.height, uv);
            let at = lightmap.irradiance_at(p, element.centroid);
            for c in 0..3 {
                worst = worst.max(relative(sampled[c], solved.h[i][c], 1e-6 * peak));
                assert_eq!(
                    at[c], solved.h[i][c],
                    "{}: irradiance_at, element {i}",
                    case.name
                );
            }
        }
        println!(
            "{}: {} elements, flat lightmap at centroids vs H: max {worst:.2e} relative",
            case.name,
            solved.mesh.elements.len()
        );
        // f32 rounding is 6e-8 relative; any neighbour's value would differ by far more.
        assert!(worst <= 1.2e-7, "{}: {worst}", case.name);
    }
}

/// Whether the closed square of half-side `r` around `c` meets the convex polygon `uv`.
fn square_meets(c: DVec2, r: f64, uv: &[DVec2]) -> bool {
    let mut axes = vec![DVec2::X, DVec2::Y];
    for k in 0..uv.len() {
        let e = uv[(k + 1) % uv.len()] - uv[k];
        axes.push(DVec2::new(-e.y, e.x));
    }
    axes.iter().all(|a| {
        let (lo, hi) = uv
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                (l.min(p.dot(*a)), h.max(p.dot(*a)))
            });
        let reach = r * (a.x.abs() + a.y.abs());
        let centre = c.dot(*a);
        centre - reach <= hi + 1e-9 && centre + reach >= lo - 1e-9
    })
}

/// Footprints written, gutters = nearest chart texel, mip-0/mip-1 reads inside the chart
/// (so regions never read each other), UVs inside [0, 1]. Returns (occupancy, chart texels).
fn check_atlas(lightmap: &Lightmap, what: &str) -> f64 {
    let w = lightmap.width as usize;
    let at = |x: usize, y: usize| y * w + x;
    let uvs: Vec<Vec<DVec2>> = lightmap
        .charts
        .iter()
        .map(|c| c.uv.iter().map(|&p| DVec2::from_array(p)).collect())
        .collect();
    // Regions inside the atlas; UVs in [0, 1] and inside their region. Regions are not
    // asked to be apart as rectangles (mask-packed charts fit into each other's corners):
    // what must hold is that every texel a region's polygons read is its own (below).
    for (a, chart) in lightmap.charts.iter().enumerate() {
        let r = chart.region;
        assert!(r.x + r.width <= lightmap.width && r.y + r.height <= lightmap.height);
        for (k, p) in uvs[a].iter().enumerate() {
            let t = lightmap.texcoord(a, k);
            assert!(t.iter().all(|c| (0.0..=1.0).contains(c)), "{what}: {t:?}");
            assert!(p.x >= f64::from(r.x) && p.x <= f64::from(r.x + r.width));
            assert!(p.y >= f64::from(r.y) && p.y <= f64::from(r.y + r.height));
        }
    }
    // The polygons of one region: a grouped chart's, or two triangles sharing a rectangle, or
    // one polygon alone; texels of any of them are the region's own.
    let mut regions: Vec<(lightmap::Rect, Vec<usize>)> = Vec::new();
    for (p, chart) in lightmap.charts.iter().enumerate() {
        match regions.iter_mut().find(|(r, _)| *r == chart.region) {
            Some((_, members)) => members.push(p),
            None => regions.push((chart.region, vec![p])),
        }
    }
    let mut chart_texels = 0u64;
    for (r, members) in &regions {
        let own = |c: u32| members.contains(&(c as usize));
        let mut footprint = Vec::new();
        for y in r.y as usize..(r.y + r.height) as usize {
            for x in r.x as usize..(r.x + r.width) as usize {
                let c = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let coverage = lightmap.coverage[at(x, y)];
                // Read by bilinear filtering at full resolution for some point of the chart.
                if members.iter().any(|&p| square_meets(c, 1.0, &uvs[p])) {
                    assert!(
                        matches!(coverage, Texel::Chart(q) if own(q)),
                        "{what}: texel ({x}, {y}) is {coverage:?}, read by {members:?}"
                    );
                    let v = lightmap.texels[at(x, y)];
                    assert!(v.iter().all(|c| c.is_finite() && *c > 0.0), "{what}: {v:?}");
                    footprint.push((x, y));
                    chart_texels += 1;
                }
                // Read at mip 1 (a 2×2 block whose centre lies within 2 texels of a chart
                // point: the mip-1 texels bilinear filtering takes around it): its own.
                let block = DVec2::new((x - x % 2) as f64 + 1.0, (y - y % 2) as f64 + 1.0);
                if members.iter().any(|&p| square_meets(block, 2.0, &uvs[p])) {
                    assert!(
                        matches!(coverage, Texel::Chart(q) | Texel::Gutter(q) if own(q)),
                        "{what}: texel ({x}, {y}) is {coverage:?}, read by {members:?} at mip 1"
                    );
                }
            }
        }
        // Gutter texels equal their nearest footprint texel (any of the nearest on a tie); a
        // region of several polygons (a grouped chart's) may grow its gutter ring by ring
        // from its neighbours' sources, so one within a texel and a half of the nearest.
        let grouped = members.len() > 1;
        for y in r.y as usize..(r.y + r.height) as usize {
            for x in r.x as usize..(r.x + r.width) as usize {
                if !matches!(lightmap.coverage[at(x, y)], Texel::Gutter(q) if own(q)) {
                    continue;
                }
                let d2 = |&(fx, fy): &(usize, usize)| {
                    let (dx, dy) = (fx as i64 - x as i64, fy as i64 - y as i64);
                    dx * dx + dy * dy
                };
                let nearest = footprint.iter().map(d2).min().expect("a footprint");
                let reach = if grouped {
                    ((nearest as f64).sqrt() + 1.5).powi(2)
                } else {
                    nearest as f64
                };
                assert!(
                    footprint
                        .iter()
                        .filter(|f| d2(f) as f64 <= reach)
                        .any(|&(fx, fy)| lightmap.texels[at(fx, fy)] == lightmap.texels[at(x, y)]),
                    "{what}: gutter texel ({x}, {y}) = {:?} of {members:?} (nearest footprint at \
                     distance² {nearest}: {:?})",
                    lightmap.texels[at(x, y)],
                    footprint
                        .iter()
                        .filter(|f| d2(f) as f64 <= reach + 4.0)
                        .map(|&(fx, fy)| ((fx, fy), lightmap.texels[at(fx, fy)]))
                        .collect::<Vec<_>>()
                );
            }
        }
        // Mip 1 (2×2 box) sampled bilinearly at points of the chart reads only own texels.
        for &p in members {
            let (lo, hi) = uvs[p].iter().fold(
                (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
                |(l, h), q| (l.min(*q), h.max(*q)),
            );
            for i in 0..=20 {
                for j in 0..=20 {
                    let q = lo + (hi - lo) * DVec2::new(i as f64 / 20.0, j as f64 / 20.0);
                    if !square_meets(q, 0.0, &uvs[p]) {
                        continue;
                    }
                    let m = q / 2.0 - DVec2::splat(0.5);
                    let (mx, my) = (m.x.floor() as i64, m.y.floor() as i64);
                    for (bx, by) in [(mx, my), (mx + 1, my), (mx, my + 1), (mx + 1, my + 1)] {
                        for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            let (tx, ty) = ((2 * bx + x) as usize, (2 * by + y) as usize);
                            let coverage = lightmap.coverage[at(tx, ty)];
                            assert!(
                                matches!(coverage, Texel::Chart(c) | Texel::Gutter(c) if own(c)),
                                "{what}: mip 1 at {q} reads ({tx}, {ty}) = {coverage:?}"
                            );
                        }
                    }
                }
            }
        }
    }
    assert_eq!(chart_texels, lightmap.stats.chart_texels, "{what}");
    chart_texels as f64 / (lightmap.width as f64 * lightmap.height as f64)
}

#[test]
fn atlases_are_written_dilated_and_apart_at_two_texel_sizes() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    for case in cases(dir.path()) {
        let solved = solve(&case.input);
        let default = lightmap::default_texel_size(&solved.scene.polygons);
        for texel in [default, 2.0 * default] {
            let started = Instant::now();
            let lightmap = build(&solved, Some(texel));
            let seconds = started.elapsed().as_secs_f64();
            let occupancy = check_atlas(&lightmap, case.name);
            println!(
                "{}: texel {texel:.5}: atlas {}×{}, occupancy {:.1}% (interior {:.1}%), \
                 {} welded vertices, built in {:.3} s (this profile)",
                case.name,
                lightmap.width,
                lightmap.height,
                100.0 * occupancy,
                100.0 * lightmap.stats.interior_texels as f64
                    / (lightmap.width as f64 * lightmap.height as f64),
                lightmap.stats.welded_vertices,
                seconds
            );
            assert!((lightmap.texel_size - texel).abs() < 1e-15, "no reduction");
        }
    }
}

#[test]
fn cornell_like_occupancy_is_at_least_seventy_percent() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let solved = solve(&cornell_like_obj(dir.path(), false));
    assert_eq!(solved.scene.polygons.len(), 31);
    let default = lightmap::default_texel_size(&solved.scene.polygons);
    for texel in [default, 2.0 * default] {
        let lightmap = build(&solved, Some(texel));
        println!(
            "cornell-like, texel {texel:.5}: occupancy {:.1}%",
            100.0 * lightmap.stats.occupancy
        );
        assert!(
            lightmap.stats.occupancy >= 0.70,
            "{}",
            lightmap.stats.occupancy
        );
    }
}

#[test]
fn texel_size_grows_to_fit_the_maximum_atlas() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let solved = solve(&cornell_like_obj(dir.path(), false));
    let options = lightmap::Options {
        texel_size: lightmap::default_texel_size(&solved.scene.polygons) / 8.0,
        max_size: 512,
        shading: lightmap::Shading::Smooth,
        max_atlases: 1,
    };
    let lightmap =
        lightmap::build(&solved.scene.polygons, &solved.mesh, &solved.h, &options).expect("fits");
    assert!(lightmap.width <= 512 && lightmap.height <= 512);
    assert!(lightmap.texel_size > options.texel_size && lightmap.stats.reductions > 0);
    check_atlas(&lightmap, "reduced");
}

#[test]
fn cornell_like_coplanar_neighbours_agree_along_shared_edges() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let input = cornell_like_obj(dir.path(), false);
    // The dense solve of the uniform mesh (a small room with occluders would get the
    // refined hierarchy by default): element values whose jumps across a seam bound the
    // texels'.
    let solved = solve_with(&input, bake_core::TransportKind::Dense);
    let out = dir.path().join("room.gltf");
    bake([
        "--quiet".as_ref(),
        "--target".as_ref(),
        "lightmap".as_ref(),
        "--refine".as_ref(),
        "off".as_ref(),
        "--transport".as_ref(),
        "dense".as_ref(),
        input.as_os_str(),
        out.as_os_str(),
    ])
    .success();
    let exr = read_exr_with_exr(&dir.path().join("room.lightmap.exr"));
    let (_, texcoords) = read_texcoords(&out, &solved.scene);
    let polygons = &solved.scene.polygons;
    let smoothed = solved.mesh.smooth(&solved.h);
    let (mut edges, mut worst_ratio, mut worst_unwelded_ratio) = (0, 0.0f64, 0.0f64);
    for a in 0..polygons.len() {
        for b in a + 1..polygons.len() {
            let (pa, pb) = (&polygons[a], &polygons[b]);
            if pa.material != pb.material || pa.normal.dot(pb.normal) < 1.0 - 1e-9 {
                continue;
            }
            for (s, e) in shared_edges(pa, pb) {
                edges += 1;
                for k in 1..40 {
                    let point = s.lerp(e, k as f64 / 40.0);
                    let side = |p: usize| {
                        let uv = texcoord_at(&polygons[p], &texcoords[p], point);
                        lightmap::sample_bilinear(&exr.texels, exr.width, exr.height, uv)
                    };
                    let (va, vb) = (side(a), side(b));
                    // The solution's own variation: the element values touching the point on
                    // each side.
                    let ea = touching_element(&solved.mesh, a, point);
                    let eb = touching_element(&solved.mesh, b, point);
                    let unwelded = |p: usize, el: usize| {
                        at_point(&solved.mesh, &polygons[p], el, point, &smoothed)
                    };
                    for c in 0..3 {
                        let variation = (solved.h[ea][c] - solved.h[eb][c]).abs();
                        let jump = (va[c] - vb[c]).abs();
                        let scale = va[c].abs().max(1e-12);
                        assert!(
                            jump <= variation + 1e-6 * scale,
                            "polygons {a}/{b} at {point}: texels differ by {jump}, the \
                             solution by {variation}"
                        );
                        worst_ratio = worst_ratio.max(jump / variation.max(1e-6 * scale));
                        let before = (unwelded(a, ea)[c] - unwelded(b, eb)[c]).abs();
                        worst_unwelded_ratio =
                            worst_unwelded_ratio.max(before / variation.max(1e-6 * scale));
                    }
                }
            }
        }
    }
    println!(
        "{edges} shared edges: texel jump / solution variation ≤ {worst_ratio:.3} \
         (per-polygon smoothing without the weld: {worst_unwelded_ratio:.3})"
    );
    assert!(edges >= 12, "the room has shared edges ({edges})");
}

/// Segments shared by the boundaries of two coplanar polygons (collinear overlapping edges).
fn shared_edges(a: &importer::Polygon, b: &importer::Polygon) -> Vec<(DVec3, DVec3)> {
    let mut out = Vec::new();
    let edges = |p: &importer::Polygon| -> Vec<(DVec3, DVec3)> {
        let v = &p.vertices;
        (0..v.len()).map(|k| (v[k], v[(k + 1) % v.len()])).collect()
    };
    for (p, q) in edges(a) {
        for (r, s) in edges(b) {
            let d = (q - p).normalize();
            let off = |x: DVec3| (x - p - d * (x - p).dot(d)).length();
            if off(r) > 1e-9 || off(s) > 1e-9 {
                continue;
            }
            let (t0, t1) = ((r - p).dot(d), (s - p).dot(d));
            let (lo, hi) = (t0.min(t1).max(0.0), t0.max(t1).min((q - p).length()));
            if hi - lo > 1e-9 {
                out.push((p + d * lo, p + d * hi));
            }
        }
    }
    out
}

/// An element of polygon `p` whose closure holds `point` (on the polygon's boundary).
fn touching_element(mesh: &mesher::ElementMesh, p: usize, point: DVec3) -> usize {
    let range = mesh.patches[p].elements.clone();
    range
        .map(|e| e as usize)
        .min_by(|&x, &y| {
            let d = |e: usize| {
                let el = &mesh.elements[e];
                let c = el.corner_indices();
                let r = c
                    .iter()
                    .map(|&k| mesh.vertices[k as usize].distance(el.centroid))
                    .fold(0.0, f64::max);
                el.centroid.distance(point) / r
            };
            d(x).total_cmp(&d(y))
        })
        .expect("the polygon has elements")
}

/// The unwelded smoothed field at a boundary point of element `e` (linear along its edge).
fn at_point(
    mesh: &mesher::ElementMesh,
    _polygon: &importer::Polygon,
    e: usize,
    point: DVec3,
    values: &[[f64; 3]],
) -> [f64; 3] {
    let c = mesh.elements[e].corner_indices();
    let mut best = (f64::INFINITY, [0.0; 3]);
    for k in 0..c.len() {
        let (a, b) = (c[k] as usize, c[(k + 1) % c.len()] as usize);
        let (pa, pb) = (mesh.vertices[a], mesh.vertices[b]);
        let t = ((point - pa).dot(pb - pa) / (pb - pa).length_squared()).clamp(0.0, 1.0);
        let d = (pa.lerp(pb, t) - point).length();
        if d < best.0 {
            best = (
                d,
                std::array::from_fn(|m| values[a][m] + t * (values[b][m] - values[a][m])),
            );
        }
    }
    best.1
}

// ---- files ----

#[test]
fn targets_write_their_files() {
    let cube = fixture("cube.gltf");
    for (target, output, expected) in [
        ("vertex", "a.gltf", vec!["a.bin", "a.gltf"]),
        (
            "lightmap",
            "a.gltf",
            vec!["a.bin", "a.gltf", "a.lightmap.exr", "a.lightmap.png"],
        ),
        ("lightmap", "a.glb", vec!["a.glb", "a.lightmap.exr"]),
        (
            "both",
            "a.glb",
            vec!["a.glb", "a.lightmap.exr", "a.lightmap.glb"],
        ),
        (
            "both",
            "a.gltf",
            vec![
                "a.bin",
                "a.gltf",
                "a.lightmap.bin",
                "a.lightmap.exr",
                "a.lightmap.gltf",
                "a.lightmap.png",
            ],
        ),
    ] {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let out = dir.path().join(output);
        bake([
            "--quiet".as_ref(),
            "--subdiv".as_ref(),
            "3".as_ref(),
            "--target".as_ref(),
            target.as_ref(),
            cube.as_os_str(),
            out.as_os_str(),
        ])
        .success();
        assert_eq!(
            file_names(dir.path()),
            expected,
            "--target {target} {output}"
        );
    }
}

#[test]
fn bad_lightmap_options_are_refused() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out = dir.path().join("a.gltf");
    let cube = fixture("cube.gltf");
    for (args, code) in [
        (vec!["--lightmap-texel", "0"], 1),
        (vec!["--lightmap-texel", "-1"], 1),
        (vec!["--lightmap-texel", "nan"], 1),
        (vec!["--lightmap-max", "8"], 2),
        (vec!["--target", "texture"], 2),
    ] {
        let mut all: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
        all.extend([cube.as_os_str(), out.as_os_str()]);
        let run = bake(all);
        assert_eq!(run.code, Some(code), "{args:?}: {run:#?}");
        if code == 1 {
            assert_eq!(run.error_lines().len(), 1, "{args:?}: {run:#?}");
        }
        assert!(
            file_names(dir.path()).is_empty(),
            "{args:?}: nothing written"
        );
    }
}

/// Charts that cannot fit the atlas limits are the input's problem (exit 1, one line that
/// names the file and what to change), not an internal error (3), and nothing is written.
#[test]
fn charts_past_the_atlas_limits_are_refused_as_input() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out = dir.path().join("a.gltf");
    let cube = fixture("cube.gltf");
    // Six walls of at least 64 texels each cannot share one 16 × 16 atlas.
    let run = bake([
        "--lightmap-max".as_ref(),
        "16".as_ref(),
        "--lightmap-atlases".as_ref(),
        "1".as_ref(),
        cube.as_os_str(),
        out.as_os_str(),
    ]);
    assert_eq!(run.code, Some(1), "{run:#?}");
    let lines = run.error_lines();
    assert_eq!(lines.len(), 1, "{run:#?}");
    assert!(
        lines[0].contains("cube.gltf") && lines[0].contains("--lightmap-max"),
        "{lines:?}"
    );
    assert!(file_names(dir.path()).is_empty(), "nothing written");
}

#[test]
fn images_read_back_and_the_gltf_re_reads() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let input = cornell_like_obj(dir.path(), true);
    let solved = solve(&input);
    let lightmap = build(&solved, None);
    let out = dir.path().join("room.gltf");
    bake(["--quiet".as_ref(), input.as_os_str(), out.as_os_str()]).success();
    let exr_path = dir.path().join("room.lightmap.exr");
    // EXR: the same values through both readers.
    let with_exr = read_exr_with_exr(&exr_path);
    let with_image = read_exr_with_image(&exr_path);
    for read in [&with_exr, &with_image] {
        assert_eq!((read.width, read.height), (lightmap.width, lightmap.height));
        assert!(
            read.texels == lightmap.texels,
            "the EXR holds the texels exactly"
        );
    }
    // The lightmap glTF: structure, lit materials with MOZ_lightmap, extras.
    let lightmap_gltf = dir.path().join("room.lightmap.gltf");
    let (document, _) = read_texcoords(&lightmap_gltf, &solved.scene);
    let text = std::fs::read_to_string(&lightmap_gltf).expect("read the glTF");
    let json: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    let extras = &json["extras"][exporter::LIGHTMAP_EXTRAS_KEY];
    assert_eq!(extras["exr"], "room.lightmap.exr");
    assert_eq!(extras["png"], "room.lightmap.png");
    assert_eq!(extras["quantity"], "irradiance");
    assert_eq!(extras["units"], exporter::LIGHTMAP_UNITS);
    assert_eq!(
        extras["atlas"],
        serde_json::json!([lightmap.width, lightmap.height])
    );
    let scale = extras["png_scale"].as_f64().expect("png_scale");
    assert!(document.extensions_used().any(|e| e == "MOZ_lightmap"));
    assert!(!document
        .extensions_used()
        .any(|e| e == "KHR_materials_unlit"));
    for (k, material) in json["materials"]
        .as_array()
        .expect("materials")
        .iter()
        .enumerate()
    {
        let moz = &material["extensions"]["MOZ_lightmap"];
        assert_eq!(moz["texCoord"], 1, "material {k}");
        assert_eq!(moz["intensity"].as_f64(), Some(scale), "material {k}");
        assert!(material["extensions"].get("KHR_materials_unlit").is_none());
    }
    let emitters = document
        .materials()
        .filter(|m| m.emissive_factor() != [0.0; 3])
        .count();
    assert_eq!(emitters, 1, "the light keeps its emission");
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            assert!(primitive.get(&gltf::Semantic::TexCoords(0)).is_some());
            assert!(primitive.get(&gltf::Semantic::TexCoords(1)).is_some());
            assert!(primitive.get(&gltf::Semantic::Colors(0)).is_none());
        }
    }
    // PNG × intensity = H within 8-bit rounding.
    let png = image::open(dir.path().join("room.lightmap.png"))
        .expect("read the PNG")
        .to_rgb8();
    assert_eq!(
        (png.width(), png.height()),
        (lightmap.width, lightmap.height)
    );
    let mut worst = 0.0f64;
    for (pixel, texel) in png.pixels().zip(&lightmap.texels) {
        for (value, h) in pixel.0.iter().zip(texel) {
            let decoded = lightmap::srgb_to_linear(f64::from(*value) / 255.0) * scale;
            worst = worst.max((decoded - f64::from(*h)).abs() / scale);
        }
    }
    println!("PNG × intensity vs H: max error {worst:.2e} of the scale");
    assert!(worst <= 2.4 * 0.5 / 255.0, "{worst}");
}

// ---- the Khronos validator ----

#[test]
fn lightmap_outputs_pass_the_khronos_validator() {
    if !validator_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let room = cornell_like_obj(dir.path(), true);
    let mut files = Vec::new();
    for (input, output) in [
        (fixture("cube.gltf"), "cube.gltf"),
        (fixture("cube.glb"), "cube.glb"),
        (room.clone(), "room.gltf"),
        (room, "room.glb"),
    ] {
        let out = dir.path().join(output);
        bake(["--quiet".as_ref(), input.as_os_str(), out.as_os_str()]).success();
        let stem = output.split('.').next().expect("a stem");
        let extension = output.rsplit('.').next().expect("an extension");
        files.push(out);
        files.push(dir.path().join(format!("{stem}.lightmap.{extension}")));
    }
    let output = validator_output(&files);
    let stdout = String::from_utf8_lossy(&output.stdout);
    println!("{stdout}{}", String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "errors or warnings:\n{stdout}");
    let clean = stdout
        .lines()
        .filter(|line| line.contains(": 0 errors, 0 warnings, "))
        .count();
    assert_eq!(clean, files.len(), "one clean summary per file:\n{stdout}");
}

// ---- pictures for the README ----

/// Writes `docs/images/cube-atlas.png`, `docs/images/cornell-like-atlas.png` (the PNG
/// lightmaps as baked) and `docs/images/cornell-like-render.png` (the room seen through its
/// open front, each pixel ρ × the bilinearly sampled lightmap + e: what a viewer shows with
/// the lightmap set up as the README says). Run with
/// `cargo test --release --test end_to_end -- --ignored lightmap::readme_pictures`.
#[test]
#[ignore]
fn readme_pictures() {
    let images = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/images");
    std::fs::create_dir_all(&images).expect("create docs/images");
    let dir = tempfile::tempdir().expect("a temporary directory");
    let room = cornell_like_obj(dir.path(), false);
    for (input, name) in [
        (fixture("cube.gltf"), "cube-atlas.png"),
        (room.clone(), "cornell-like-atlas.png"),
    ] {
        let lightmap = build(&solve(&input), None);
        let png = lightmap::encode_png(&lightmap).expect("encode");
        std::fs::write(images.join(name), png.bytes).expect("write the atlas");
    }
    let solved = solve(&room);
    let lightmap = build(&solved, None);
    let view = View {
        eye: DVec3::new(2.75, 2.75, 12.5),
        forward: -1.0,
        exposure: 0.6,
    };
    render_with_lightmap(
        &solved,
        &lightmap,
        view,
        &images.join("cornell-like-render.png"),
    );
    // The Cornell box fixture (millimetres, open towards −z), seen from Cornell's camera.
    let cornell = solve(&fixture("cornell.gltf"));
    let lightmap = build(&cornell, None);
    let atlas = lightmap::encode_png(&lightmap).expect("encode");
    std::fs::write(images.join("cornell-atlas.png"), atlas.bytes).expect("write the atlas");
    let view = View {
        eye: DVec3::new(278.0, 273.0, -800.0),
        forward: 1.0,
        exposure: 1.0,
    };
    render_with_lightmap(
        &cornell,
        &lightmap,
        view,
        &images.join("cornell-render.png"),
    );
}

/// A pinhole camera looking along ±z (`forward`), up +y.
struct View {
    eye: DVec3,
    forward: f64,
    exposure: f64,
}

/// Ray-casts the scene's polygons and shades each hit with ρ × (the lightmap sampled at its
/// TEXCOORD_1) + e: what an engine shows from the lightmap bake.
fn render_with_lightmap(solved: &Solved, lightmap: &lightmap::Lightmap, view: View, path: &Path) {
    let (width, height) = (360u32, 360u32);
    let eye = view.eye;
    let focal = 1.0 / (20f64.to_radians()).tan();
    let polygons = &solved.scene.polygons;
    let mut pixels = Vec::with_capacity((width * height * 3) as usize);
    for j in 0..height {
        for i in 0..width {
            let x = (2.0 * (i as f64 + 0.5) / width as f64) - 1.0;
            let y = 1.0 - (2.0 * (j as f64 + 0.5) / height as f64);
            // Looking along +z, image right is world −x (right-handed, up +y).
            let d = DVec3::new(-view.forward * x, y, view.forward * focal).normalize();
            let mut hit: Option<(f64, usize, DVec3)> = None;
            for (p, polygon) in polygons.iter().enumerate() {
                let n = polygon.normal;
                let facing = d.dot(n);
                if facing >= 0.0 {
                    continue;
                }
                let t = (polygon.vertices[0] - eye).dot(n) / facing;
                let point = eye + d * t;
                let v = &polygon.vertices;
                let inside = (0..v.len())
                    .all(|k| (v[(k + 1) % v.len()] - v[k]).cross(point - v[k]).dot(n) >= 0.0);
                if t > 0.0 && inside && hit.is_none_or(|(best, _, _)| t < best) {
                    hit = Some((t, p, point));
                }
            }
            let colour = match hit {
                Some((_, p, point)) => {
                    let uv: Vec<[f64; 2]> = (0..polygons[p].vertices.len())
                        .map(|k| lightmap.texcoord(p, k).map(f64::from))
                        .collect();
                    let h = lightmap.sample(texcoord_at(&polygons[p], &uv, point));
                    let m = &solved.scene.materials[polygons[p].material];
                    std::array::from_fn(|c| m.rho[c] * h[c] + m.emission[c])
                }
                None => [0.0; 3],
            };
            // Exposed, clamped, sRGB-encoded for the screen.
            for c in colour {
                let v = lightmap::linear_to_srgb((view.exposure * c).clamp(0.0, 1.0));
                pixels.push((v * 255.0).round() as u8);
            }
        }
    }
    image::save_buffer(path, &pixels, width, height, image::ColorType::Rgb8)
        .expect("write the render");
}

// ---- charts, seams and overshoot on real rooms (issue 32) ----

/// The range of H over the elements a texel of polygon `p` may be reconstructed from: p's
/// own, and those of every polygon its edge vertices may be welded with (same material,
/// same facing, in p's plane, bounding boxes touching) — computed here from the mesh, not
/// by the lightmap crate.
fn source_ranges(solved: &Solved) -> Vec<([f64; 3], [f64; 3])> {
    let polygons = &solved.scene.polygons;
    let mut own = vec![([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]); polygons.len()];
    for (e, el) in solved.mesh.elements.iter().enumerate() {
        let r = &mut own[el.polygon as usize];
        for c in 0..3 {
            r.0[c] = r.0[c].min(solved.h[e][c]);
            r.1[c] = r.1[c].max(solved.h[e][c]);
        }
    }
    let (lo, hi) = importer::bounds(polygons);
    let tolerance = 1e-6 * (hi - lo).length();
    let boxes: Vec<(DVec3, DVec3)> = polygons
        .iter()
        .map(|p| {
            p.vertices.iter().fold(
                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                |(l, h), v| (l.min(*v), h.max(*v)),
            )
        })
        .collect();
    (0..polygons.len())
        .map(|p| {
            let mut range = own[p];
            for q in 0..polygons.len() {
                let (a, b) = (&polygons[p], &polygons[q]);
                let touching = boxes[p].0.cmple(boxes[q].1 + tolerance).all()
                    && boxes[q].0.cmple(boxes[p].1 + tolerance).all();
                let coplanar = a.material == b.material
                    && a.normal.dot(b.normal) > 1.0 - 1e-9
                    && b.vertices
                        .iter()
                        .all(|v| (*v - a.vertices[0]).dot(a.normal).abs() <= tolerance);
                if q != p && touching && coplanar {
                    for c in 0..3 {
                        range.0[c] = range.0[c].min(own[q].0[c]);
                        range.1[c] = range.1[c].max(own[q].1[c]);
                    }
                }
            }
            range
        })
        .collect()
}

/// The worst texel overshoot past its sources' range, relative to the range's top (0 when
/// every texel lies within it), over every atlas.
fn worst_overshoot(solved: &Solved, map: &Lightmap) -> f64 {
    let ranges = source_ranges(solved);
    let mut worst = 0.0f64;
    for atlas in map.atlases() {
        for (t, c) in atlas.texels.iter().zip(atlas.coverage) {
            let (Texel::Chart(p) | Texel::Gutter(p)) = *c else {
                continue;
            };
            let (lo, hi) = ranges[p as usize];
            for k in 0..3 {
                let v = f64::from(t[k]);
                let scale = hi[k].abs().max(1e-30);
                let past = (v - hi[k]).max(lo[k] - v).max(0.0) / scale;
                // f32 storage.
                worst = worst.max((past - f64::from(f32::EPSILON)).max(0.0));
            }
        }
    }
    worst
}

/// A room from Blender's own exporter (`tools/blender-room`, lit by a point light and a spot)
/// and a 2 × 2 office floor (`tools/walkthrough`, lit by ceiling panels), baked for real: the
/// atlas passes `check_atlas` (every texel a chart reads is its own), no texel lies outside the
/// range of the elements it is reconstructed from (beyond f32 rounding), the PNG clips under
/// 1% of chart texels, and no seam jumps past the field's variation within a bilinear read's
/// footprint. Prints charts, occupancy and seam figures. The Blender room is skipped without
/// Blender (unless `BAKE_REQUIRE_BLENDER=1`).
#[test]
fn real_rooms_charts_seams_and_overshoot() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut inputs = Vec::new();
    let floor =
        bake_walkthrough::office::office(bake_walkthrough::office::Rooms { x: 2, z: 2 }, 4.0, 2.8)
            .expect("an office floor");
    let office = dir.path().join("office.gltf");
    bake_walkthrough::gltf::write(&floor, &office).expect("write the office floor");
    inputs.push(("office floor 2 × 2", office));
    if bake_testkit::blender_or_skip() {
        let room = dir.path().join("room.gltf");
        let made = std::process::Command::new(bake_testkit::tools_dir().join("blender-room"))
            .arg(&room)
            .output()
            .expect("run tools/blender-room");
        assert!(
            made.status.success(),
            "{}",
            String::from_utf8_lossy(&made.stdout)
        );
        inputs.push(("Blender room", room));
    }
    for (name, input) in inputs {
        let solved = solve(&input);
        let map = build(&solved, None);
        check_atlas(&map, name);
        let overshoot = worst_overshoot(&solved, &map);
        let png = lightmap::encode_png(&map).expect("encode the PNG");
        let seams = map.seams(&solved.scene.polygons);
        let stats = &map.stats;
        println!(
            "{name}: {} polygons, {} charts, {} atlases {}×{}, occupancy {:.1}%, worst \
             overshoot {overshoot:.1e}, PNG clips {} of {} chart texels, {} seams of {} shared \
             edges, worst jump / bound {:.3}",
            solved.scene.polygons.len(),
            stats.charts,
            stats.atlases,
            map.width,
            map.height,
            100.0 * stats.occupancy,
            png.clipped,
            png.covered,
            seams.seam_edges,
            seams.shared_edges,
            seams.worst_ratio,
        );
        assert!(overshoot <= 1e-6, "{name}: {overshoot}");
        assert!(
            png.clipped * 100 < png.covered,
            "{name}: {} of {}",
            png.clipped,
            png.covered
        );
        assert_eq!(seams.over, 0, "{name}: {seams:?}");
    }
}
