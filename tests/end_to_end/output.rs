//! Bakes the paper's cube with the CLI and re-reads the output with the `gltf` crate:
//! attributes, material, names, the radiosity against the bake report (flat and smooth),
//! the exposure clamp, the Khronos validator, and byte-for-byte determinism.
//!
//! The cube's walls are axis-aligned unit squares, so at `--subdiv 4` every element is a
//! square of side h = sqrt(area) = 0.25 centred on its report centroid c, and a point p lies
//! on an element when |p − c|∞ ≤ h/2.

use crate::common;

use bake_job::report::{ElementEntry, Report};
use bake_testkit::{file_names, fixture, validator_or_skip, validator_output};
use common::{bake, bake_in, report_without_timings, CUBE_WALLS};
use gltf::mesh::util::ReadColors;
use gltf::mesh::Semantic;
use std::path::{Path, PathBuf};

const SUBDIV: usize = 4;
/// f32 storage of f64 results.
const F32_TOLERANCE: f64 = 1e-6;
/// Positions on the element grid (multiples of 1/4) are exact in f32; allow some slack.
const POSITION_TOLERANCE: f64 = 1e-6;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Shading {
    Smooth,
    Flat,
}

impl Shading {
    fn flag(self) -> &'static str {
        match self {
            Shading::Smooth => "smooth",
            Shading::Flat => "flat",
        }
    }
}

/// One bake of `cube.gltf` at --subdiv 4 with a report.
struct Case {
    file: &'static str,
    shading: Shading,
    exposure: f64,
}

const CASES: [Case; 4] = [
    Case {
        file: "smooth.gltf",
        shading: Shading::Smooth,
        exposure: 1.0,
    },
    Case {
        file: "flat.gltf",
        shading: Shading::Flat,
        exposure: 1.0,
    },
    Case {
        file: "smooth.glb",
        shading: Shading::Smooth,
        exposure: 2.5,
    },
    Case {
        file: "flat.glb",
        shading: Shading::Flat,
        exposure: 1.0,
    },
];

struct Baked {
    path: PathBuf,
    document: gltf::Document,
    buffers: Vec<gltf::buffer::Data>,
    report: Report,
}

fn bake_case(dir: &Path, case: &Case) -> Baked {
    let path = dir.join(case.file);
    let report = dir.join(format!("{}.json", case.file));
    bake([
        "--subdiv".as_ref(),
        SUBDIV.to_string().as_ref(),
        "--shading".as_ref(),
        case.shading.flag().as_ref(),
        "--exposure".as_ref(),
        case.exposure.to_string().as_ref(),
        "--report".as_ref(),
        report.as_os_str(),
        fixture("cube.gltf").as_os_str(),
        path.as_os_str(),
    ])
    .success();
    let (document, buffers, _images) = gltf::import(&path).expect("re-read the baked glTF");
    let report = bake_job::report::read_report(&report).expect("read the report");
    Baked {
        path,
        document,
        buffers,
        report,
    }
}

#[test]
fn cube_bakes_read_back_with_the_reported_radiosity() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut clamped = 0;
    for case in &CASES {
        let baked = bake_case(dir.path(), case);
        let what = case.file;
        check_report(&baked.report, case);
        check_names(&baked.document);
        check_material(&baked.document);
        for node in baked.document.nodes() {
            let world = world_matrix(&baked.document, node.index());
            let mesh = node.mesh().expect("every wall node keeps a mesh");
            assert_eq!(mesh.primitives().len(), 1, "{what}: one primitive per wall");
            for primitive in mesh.primitives() {
                let data = read_primitive(&primitive, &baked.buffers, what);
                let elements = elements_of(&baked.report, node.index(), primitive.index());
                assert_eq!(elements.len(), SUBDIV * SUBDIV, "{what}: elements per wall");
                let vertices = World::new(&data, &world);
                check_normals(&vertices, &elements, what);
                match case.shading {
                    Shading::Flat => check_flat(&data, &vertices, &elements, what),
                    Shading::Smooth => check_smooth(&data, &vertices, &elements, what),
                }
                clamped += check_colours(&data, case.exposure, what);
                if node.name() == Some("emitter") {
                    // ρ = 0 and e = 1: b = 1 exactly, whatever the shading.
                    assert!(data.radiosity.iter().all(|r| *r == [1.0; 3]), "{what}");
                }
            }
        }
    }
    assert!(clamped > 0, "--exposure 2.5 clamps some colours to 1");
}

/// The report describes this bake: 6 walls × 16 elements, the options given, inward normals.
fn check_report(report: &Report, case: &Case) {
    assert_eq!(report.counts.polygons, CUBE_WALLS.len());
    assert_eq!(report.counts.elements, CUBE_WALLS.len() * SUBDIV * SUBDIV);
    assert_eq!(report.elements.len(), report.counts.elements);
    assert_eq!(report.options["shading"], case.shading.flag());
    assert_eq!(report.options["exposure"], case.exposure);
    assert_eq!(report.options["subdivision"]["subdiv"], SUBDIV);
    let h = 1.0 / SUBDIV as f64;
    for element in &report.elements {
        assert!((element.area - h * h).abs() < 1e-12, "{element:?}");
        // Every wall faces the centre of the unit cube.
        let towards_centre: f64 = (0..3)
            .map(|i| (0.5 - element.centroid[i]) * element.normal[i])
            .sum();
        assert!((towards_centre - 0.5).abs() < 1e-12, "{element:?}");
    }
}

/// Nodes and meshes keep the input's names, in order; every node holds its own mesh.
fn check_names(document: &gltf::Document) {
    let (input, _, _) = gltf::import(fixture("cube.gltf")).expect("read the fixture");
    let input_nodes: Vec<_> = input.nodes().map(|n| n.name().map(str::to_owned)).collect();
    let nodes: Vec<_> = document
        .nodes()
        .map(|n| n.name().map(str::to_owned))
        .collect();
    let expected: Vec<_> = CUBE_WALLS.iter().map(|n| Some(n.to_string())).collect();
    assert_eq!(input_nodes, expected, "the fixture's walls");
    assert_eq!(nodes, expected, "node names kept");
    for node in document.nodes() {
        let mesh = node.mesh().expect("a mesh");
        assert_eq!(mesh.name(), node.name(), "mesh name kept");
    }
    assert_eq!(document.meshes().len(), CUBE_WALLS.len());
    let scene = document.default_scene().expect("a default scene");
    assert_eq!(scene.name(), Some("cube"));
    assert_eq!(scene.nodes().count(), CUBE_WALLS.len());
}

/// One unlit, white material used by every primitive.
fn check_material(document: &gltf::Document) {
    assert_eq!(document.materials().len(), 1);
    let material = document.materials().next().unwrap();
    assert!(material.unlit(), "KHR_materials_unlit");
    assert_eq!(
        material.pbr_metallic_roughness().base_color_factor(),
        [1.0; 4]
    );
    assert!(document
        .extensions_used()
        .any(|e| e == "KHR_materials_unlit"));
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            assert_eq!(primitive.material().index(), Some(0));
            assert_eq!(primitive.mode(), gltf::mesh::Mode::Triangles);
        }
    }
}

/// An output primitive's attributes, as stored.
struct PrimitiveData {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[f32; 3]>,
    radiosity: Vec<[f32; 3]>,
    triangles: Vec<[usize; 3]>,
}

fn read_primitive(
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    what: &str,
) -> PrimitiveData {
    let mut semantics: Vec<String> = primitive
        .attributes()
        .map(|(semantic, _)| semantic.to_string())
        .collect();
    semantics.sort();
    assert_eq!(
        semantics,
        ["COLOR_0", "NORMAL", "POSITION", "_ERROR", "_RADIOSITY"],
        "{what}"
    );
    let radiosity = primitive
        .get(&Semantic::Extras("RADIOSITY".into()))
        .expect("_RADIOSITY");
    for accessor in [
        radiosity.clone(),
        primitive.get(&Semantic::Colors(0)).expect("COLOR_0"),
    ] {
        assert_eq!(
            accessor.data_type(),
            gltf::accessor::DataType::F32,
            "{what}"
        );
        assert_eq!(
            accessor.dimensions(),
            gltf::accessor::Dimensions::Vec3,
            "{what}"
        );
        assert!(!accessor.normalized(), "{what}");
    }
    let get = |buffer: gltf::Buffer| buffers.get(buffer.index()).map(|data| &data[..]);
    let reader = primitive.reader(get);
    let colors = match reader.read_colors(0).expect("COLOR_0") {
        ReadColors::RgbF32(colors) => colors.collect(),
        _ => panic!("{what}: COLOR_0 is not float VEC3"),
    };
    let indices: Vec<usize> = reader
        .read_indices()
        .expect("indices")
        .into_u32()
        .map(|i| i as usize)
        .collect();
    assert_eq!(indices.len() % 3, 0);
    PrimitiveData {
        positions: reader.read_positions().expect("POSITION").collect(),
        normals: reader.read_normals().expect("NORMAL").collect(),
        colors,
        radiosity: gltf::accessor::Iter::<[f32; 3]>::new(radiosity, get)
            .expect("_RADIOSITY data")
            .collect(),
        triangles: indices.chunks(3).map(|t| [t[0], t[1], t[2]]).collect(),
    }
}

/// The report elements of one output primitive: those of the polygons that node's
/// primitive produced.
fn elements_of(report: &Report, node: usize, primitive: usize) -> Vec<ElementEntry> {
    report
        .elements
        .iter()
        .filter(|e| {
            let origin = &report.polygons[e.polygon as usize];
            origin.node == node && origin.primitive == primitive
        })
        .copied()
        .collect()
}

type Mat4 = [[f64; 4]; 4];

/// The node's world matrix (column-major, f64), composed from the scene roots down.
fn world_matrix(document: &gltf::Document, node: usize) -> Mat4 {
    fn find(node: gltf::Node, target: usize, parent: Mat4) -> Option<Mat4> {
        let local = node.transform().matrix().map(|c| c.map(f64::from));
        let world = multiply(&parent, &local);
        if node.index() == target {
            return Some(world);
        }
        node.children().find_map(|child| find(child, target, world))
    }
    let identity = std::array::from_fn(|c| std::array::from_fn(|r| f64::from(u8::from(c == r))));
    document
        .scenes()
        .flat_map(|s| s.nodes())
        .find_map(|root| find(root, node, identity))
        .expect("the node is in a scene")
}

fn multiply(a: &Mat4, b: &Mat4) -> Mat4 {
    std::array::from_fn(|c| std::array::from_fn(|r| (0..4).map(|k| a[k][r] * b[c][k]).sum()))
}

/// An output primitive's vertices in world space.
struct World {
    positions: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
}

impl World {
    fn new(data: &PrimitiveData, m: &Mat4) -> World {
        let point = |p: &[f32; 3]| -> [f64; 3] {
            std::array::from_fn(|r| {
                (0..3).map(|k| m[k][r] * f64::from(p[k])).sum::<f64>() + m[3][r]
            })
        };
        // The cube's nodes are rotations at most, so the linear part maps normals too.
        let normal = |n: &[f32; 3]| -> [f64; 3] {
            let v: [f64; 3] =
                std::array::from_fn(|r| (0..3).map(|k| m[k][r] * f64::from(n[k])).sum());
            let length = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            v.map(|x| x / length)
        };
        World {
            positions: data.positions.iter().map(point).collect(),
            normals: data.normals.iter().map(normal).collect(),
        }
    }
}

/// |a − b|∞
fn max_distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

/// Whether world point `p` lies on the square element `e` (see the module comment).
fn on_element(p: &[f64; 3], e: &ElementEntry) -> bool {
    max_distance(p, &e.centroid) <= e.area.sqrt() / 2.0 + POSITION_TOLERANCE
}

/// Every vertex normal is its wall's normal, as the report gives it.
fn check_normals(vertices: &World, elements: &[ElementEntry], what: &str) {
    let wall = elements[0].normal;
    assert!(
        elements.iter().all(|e| e.normal == wall),
        "{what}: one plane"
    );
    for n in &vertices.normals {
        assert!(
            max_distance(n, &wall) < F32_TOLERANCE,
            "{what}: {n:?} vs {wall:?}"
        );
    }
}

/// Flat: the three corners of every triangle carry exactly (in f32) the b of the one
/// element containing the triangle; each element is covered by two triangles of its area.
fn check_flat(data: &PrimitiveData, vertices: &World, elements: &[ElementEntry], what: &str) {
    assert_eq!(
        data.positions.len(),
        4 * elements.len(),
        "{what}: 4 corners per element"
    );
    assert_eq!(
        data.triangles.len(),
        2 * elements.len(),
        "{what}: 2 triangles per element"
    );
    let mut covered = vec![0.0; elements.len()];
    for triangle in &data.triangles {
        let corners = triangle.map(|v| vertices.positions[v]);
        let containing: Vec<usize> = (0..elements.len())
            .filter(|&k| corners.iter().all(|p| on_element(p, &elements[k])))
            .collect();
        assert_eq!(containing.len(), 1, "{what}: triangle {corners:?}");
        let element = &elements[containing[0]];
        for &v in triangle {
            assert_eq!(
                data.radiosity[v],
                element.b.map(|b| b as f32),
                "{what}: vertex {v} of element at {:?}",
                element.centroid
            );
        }
        covered[containing[0]] += triangle_area(&corners);
    }
    for (k, area) in covered.iter().enumerate() {
        assert!(
            (area - elements[k].area).abs() < 1e-9,
            "{what}: element {k} covered {area}"
        );
    }
}

/// Smooth: one shared vertex per grid point, whose value is the area-weighted average of the
/// b of the elements touching it (1, 2 or 4 of them on a square grid).
fn check_smooth(data: &PrimitiveData, vertices: &World, elements: &[ElementEntry], what: &str) {
    assert_eq!(
        data.positions.len(),
        (SUBDIV + 1) * (SUBDIV + 1),
        "{what}: shared grid vertices"
    );
    assert_eq!(data.triangles.len(), 2 * elements.len(), "{what}");
    for (v, p) in vertices.positions.iter().enumerate() {
        let touching: Vec<&ElementEntry> = elements.iter().filter(|e| on_element(p, e)).collect();
        assert!(
            [1, 2, 4].contains(&touching.len()),
            "{what}: vertex {p:?} touches {} elements",
            touching.len()
        );
        let weight: f64 = touching.iter().map(|e| e.area).sum();
        for band in 0..3 {
            let expected = touching.iter().map(|e| e.area * e.b[band]).sum::<f64>() / weight;
            let got = f64::from(data.radiosity[v][band]);
            assert!(
                (got - expected).abs() <= F32_TOLERANCE * expected.abs(),
                "{what}: vertex {p:?} band {band}: {got} vs {expected}"
            );
        }
    }
}

/// COLOR_0 = clamp(_RADIOSITY × exposure, 0, 1). Returns how many components were clamped.
fn check_colours(data: &PrimitiveData, exposure: f64, what: &str) -> usize {
    let mut clamped = 0;
    for (color, radiosity) in data.colors.iter().zip(&data.radiosity) {
        for band in 0..3 {
            let c = f64::from(color[band]);
            assert!((0.0..=1.0).contains(&c), "{what}: colour {color:?}");
            let scaled = f64::from(radiosity[band]) * exposure;
            clamped += usize::from(scaled > 1.0);
            let expected = scaled.clamp(0.0, 1.0);
            assert!(
                (c - expected).abs() <= F32_TOLERANCE * expected.max(1e-30),
                "{what}: colour {c} vs clamp({scaled})"
            );
        }
    }
    clamped
}

fn triangle_area(p: &[[f64; 3]; 3]) -> f64 {
    let u: [f64; 3] = std::array::from_fn(|i| p[1][i] - p[0][i]);
    let v: [f64; 3] = std::array::from_fn(|i| p[2][i] - p[0][i]);
    let cross = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    cross.iter().map(|x| x * x).sum::<f64>().sqrt() / 2.0
}

// ---- the Khronos validator ----

#[test]
fn outputs_pass_the_khronos_validator() {
    if !validator_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut files: Vec<PathBuf> = CASES
        .iter()
        .map(|c| bake_case(dir.path(), c).path)
        .collect();
    for (input, output) in [("cube.glb", "from-glb.glb"), ("cube.obj", "from-obj.gltf")] {
        let path = dir.path().join(output);
        bake([
            "--subdiv".as_ref(),
            "2".as_ref(),
            fixture(input).as_os_str(),
            path.as_os_str(),
        ])
        .success();
        files.push(path);
    }
    let output = validator_output(&files);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!("{stdout}{stderr}");
    assert!(
        output.status.success(),
        "the validator found errors or warnings:\n{stdout}{stderr}"
    );
    let clean = stdout
        .lines()
        .filter(|line| line.contains(": 0 errors, 0 warnings, "))
        .count();
    assert_eq!(clean, files.len(), "one clean summary per file:\n{stdout}");
}

// ---- determinism ----

/// Bakes `cube.gltf` into `dir` (relative paths, so the report's options match) and returns
/// the output files' bytes by name and the report without timings.
fn bake_for_determinism(
    dir: &Path,
    output: &str,
    threads: Option<&str>,
) -> (Vec<(String, Vec<u8>)>, Report) {
    let cube = fixture("cube.gltf");
    let mut args = vec![
        "--subdiv",
        "12",
        "--quiet",
        "--report",
        "report.json",
        cube.to_str().expect("a UTF-8 path"),
        output,
    ];
    if let Some(n) = threads {
        args.extend(["--threads", n]);
    }
    bake_in(Some(dir), &args).success();
    let report = report_without_timings(&dir.join("report.json"));
    let files = file_names(dir)
        .into_iter()
        .filter(|name| name != "report.json")
        .map(|name| {
            let bytes = std::fs::read(dir.join(&name)).expect("read an output");
            (name, bytes)
        })
        .collect();
    (files, report)
}

#[test]
fn bakes_are_deterministic_across_runs_and_thread_counts() {
    for (output, names) in [
        // The default --target both: the vertex bake and the lightmap bake with its images.
        (
            "baked.glb",
            vec!["baked.glb", "baked.lightmap.exr", "baked.lightmap.glb"],
        ),
        (
            "baked.gltf",
            vec![
                "baked.bin",
                "baked.gltf",
                "baked.lightmap.bin",
                "baked.lightmap.exr",
                "baked.lightmap.gltf",
                "baked.lightmap.png",
            ],
        ),
    ] {
        let runs: Vec<_> = [None, None, Some("1"), Some("2")]
            .iter()
            .map(|threads| {
                let dir = tempfile::tempdir().expect("a temporary directory");
                (threads, bake_for_determinism(dir.path(), output, *threads))
            })
            .collect();
        let (_, (first_files, first_report)) = &runs[0];
        let written: Vec<&str> = first_files.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(written, names, "{output}: the files written");
        for (threads, (files, report)) in &runs[1..] {
            assert!(
                files == first_files,
                "{output} with --threads {threads:?} differs"
            );
            assert!(
                report == first_report,
                "{output} report with --threads {threads:?} differs"
            );
        }
    }
}

#[test]
fn report_elements_summary_and_none_describe_the_same_bake() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let cube = fixture("cube.gltf");
    let mut reports = Vec::new();
    for which in ["all", "summary", "none"] {
        let out = dir.path().join(format!("{which}.gltf"));
        let json = dir.path().join(format!("{which}.json"));
        let run = bake([
            cube.as_os_str(),
            out.as_os_str(),
            "--subdiv".as_ref(),
            "4".as_ref(),
            "--target".as_ref(),
            "vertex".as_ref(),
            "--report-elements".as_ref(),
            which.as_ref(),
            "--report".as_ref(),
            json.as_os_str(),
        ]);
        assert_eq!(run.code, Some(0), "{which}: {}", run.stderr);
        reports.push(report_without_timings(&json));
    }
    let (all, summary, none) = (&reports[0], &reports[1], &reports[2]);
    assert_eq!(all.elements.len(), 96);
    assert!(summary.elements.is_empty() && none.elements.is_empty());
    assert!(none.element_summary.is_none());
    // The summary is that of the full list (the same bake: same bytes of b).
    let s = summary.element_summary.expect("a summary");
    assert_eq!(Some(s), bake_job::report::ElementSummary::of(&all.elements));
    assert_eq!(all.element_summary, Some(s));
    assert_eq!(s.count, 96);
    assert!((s.area - 6.0).abs() < 1e-9);
    // The emitter's b is 1 exactly; the mean is between the darkest wall and 1.
    assert_eq!(s.b_max, [1.0; 3]);
    assert!(s
        .b_mean
        .iter()
        .zip(&s.b_min)
        .all(|(m, lo)| lo < m && *m < 1.0));
}
