//! Robustness: deterministic mutations of valid glTF and OBJ scenes (every JSON number,
//! GLB bytes, OBJ tokens) must load or fail with an error, never panic.

use bake_testkit::GltfBuilder;
use serde_json::{json, Value};
use std::path::Path;

/// xorshift64*: a small deterministic generator, so failures reproduce.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// A scene touching every reader path: indexed triangles, a strip, a fan, points, sparse
/// and normalized positions, a node hierarchy with TRS and matrix, materials.
fn rich_scene() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let square = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    let lamp = b.material(json!({
        "emissiveFactor": [1.0, 1.0, 1.0], "doubleSided": true,
        "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 3.0 } }
    }));
    let triangles = b.primitive(&square, Some(&[0, 1, 2, 0, 2, 3]), Some(lamp), 4);
    let strip = b.primitive(&square, Some(&[0, 1, 3, 2]), None, 5);
    let fan = b.primitive(&square, None, None, 6);
    let points = b.primitive(&square, None, None, 0);
    let shorts: Vec<u8> = [0u16, 0, 0, 65535, 0, 0, 0, 65535, 0]
        .iter()
        .flat_map(|s| s.to_le_bytes())
        .collect();
    let quantized = b.accessor(
        &shorts,
        bake_testkit::UNSIGNED_SHORT,
        "VEC3",
        3,
        json!({ "normalized": true, "min": [0, 0, 0], "max": [65535, 65535, 0] }),
    );
    let sparse_indices = b.view(
        &[1u16, 2]
            .iter()
            .flat_map(|s| s.to_le_bytes())
            .collect::<Vec<u8>>(),
    );
    let values: Vec<u8> = [2f32, 0., 0., 0., 2., 0.]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let sparse_values = b.view(&values);
    let base = b.positions(&[[0., 0., 1.], [0., 0., 1.], [0., 0., 1.]]);
    b.root["accessors"][base]["sparse"] = json!({
        "count": 2,
        "indices": { "bufferView": sparse_indices, "componentType": bake_testkit::UNSIGNED_SHORT },
        "values": { "bufferView": sparse_values }
    });
    let mesh = b.mesh(
        "Rich",
        vec![
            triangles,
            strip,
            fan,
            points,
            json!({ "attributes": { "POSITION": quantized } }),
            json!({ "attributes": { "POSITION": base } }),
        ],
    );
    let child = b.node(json!({
        "mesh": mesh,
        "matrix": [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., -1., 0., 5., 0., 0., 1.]
    }));
    let parent = b.node(json!({
        "mesh": mesh, "children": [child],
        "translation": [1., 2., 3.], "rotation": [0., 0., 0.6, 0.8], "scale": [2., 1., 1.]
    }));
    b.scene(&[parent]);
    b.root["extensionsUsed"] = json!(["KHR_materials_emissive_strength", "KHR_mesh_quantization"]);
    b
}

/// JSON pointers to every number in `value`.
fn number_paths(value: &Value, path: String, out: &mut Vec<String>) {
    match value {
        Value::Number(_) => out.push(path),
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                number_paths(item, format!("{path}/{i}"), out);
            }
        }
        Value::Object(map) => {
            for (k, item) in map {
                number_paths(item, format!("{path}/{k}"), out);
            }
        }
        _ => {}
    }
}

const NASTY_NUMBERS: [f64; 16] = [
    0.0,
    1.0,
    2.0,
    3.0,
    4.0,
    5.0,
    7.0,
    -1.0,
    255.0,
    65535.0,
    2147483648.0,
    4294967295.0,
    1e10,
    5120.0,
    5125.0,
    0.5,
];

/// A description and a function writing the mutated file.
type Mutant = (String, Box<dyn Fn(&Path)>);

/// Loads each mutant, returning a description of every one that panicked.
fn panics(mutants: impl Iterator<Item = Mutant>, file: &str) -> Vec<String> {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join(file);
    let mut out = Vec::new();
    for (description, write) in mutants {
        write(&path);
        if std::panic::catch_unwind(|| bake_importer::load(&path)).is_err() {
            out.push(description);
        }
    }
    out
}

#[test]
fn the_unmutated_scenes_load() {
    let dir = tempfile::tempdir().unwrap();
    let scene = bake_importer::load(&rich_scene().write_glb(&dir.path().join("rich.glb"))).unwrap();
    assert_eq!(scene.stats.primitives_skipped, 1);
    // Every primitive was read; the strip and fan repeat the lamp's square in other
    // primitives, so those copies are dropped as coincident.
    assert!(scene.stats.coincident_dropped > 0);
    assert!(scene.polygons.len() + scene.stats.coincident_dropped > 10);
}

#[test]
fn every_json_number_replaced_by_nasty_values_never_panics() {
    let base = rich_scene();
    let mut paths = Vec::new();
    number_paths(&base.root, String::new(), &mut paths);
    let mut mutants: Vec<Mutant> = Vec::new();
    for path in &paths {
        for nasty in NASTY_NUMBERS {
            let mut b = GltfBuilder {
                root: base.root.clone(),
                bin: base.bin.clone(),
            };
            if let Some(slot) = b.root.pointer_mut(path) {
                *slot = json!(nasty);
            }
            let description = format!("{path} = {nasty}");
            mutants.push((
                description,
                Box::new(move |p: &Path| {
                    b.write_glb(p);
                }),
            ));
        }
    }
    let failed = panics(mutants.into_iter(), "mutant.glb");
    assert!(failed.is_empty(), "panicked on:\n{}", failed.join("\n"));
}

#[test]
fn random_glb_byte_flips_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let original = std::fs::read(rich_scene().write_glb(&dir.path().join("rich.glb"))).unwrap();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut mutants: Vec<Mutant> = Vec::new();
    for round in 0..400 {
        let mut bytes = original.clone();
        let flips = 1 + rng.below(4);
        for _ in 0..flips {
            let at = rng.below(bytes.len());
            bytes[at] = rng.next() as u8;
        }
        mutants.push((
            format!("round {round}"),
            Box::new(move |p: &Path| {
                std::fs::write(p, &bytes).unwrap();
            }),
        ));
    }
    let failed = panics(mutants.into_iter(), "flipped.glb");
    assert!(failed.is_empty(), "panicked on:\n{}", failed.join("\n"));
}

#[test]
fn random_obj_token_swaps_never_panic() {
    let obj = "mtllib m.mtl\n\
               v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 1\nvt 0 0\nvt 1 0\nvn 0 0 1\n\
               o a\nusemtl red\nf 1/1/1 2/2/1 3/1/1 4/2/1\nf 1 2 5\nf -1 -2 -3 -4 -5\n\
               g b\nf 1//1 3//1 4//1\n";
    let mtl = "newmtl red\nKd 0.5 0.1 0.1\nKe 0 0 0\nNs 10\nillum 2\nmap_Kd tex.png\n";
    const NASTY: [&str; 14] = [
        "0",
        "-0",
        "-1",
        "-99",
        "99999999999999999999",
        "nan",
        "inf",
        "1/2/3/4",
        "//",
        "/",
        "-9223372036854775808",
        "9223372036854775807",
        "",
        "f",
    ];
    let mut rng = Rng(0x1234_5678_9ABC_DEF1);
    let dir = tempfile::tempdir().unwrap();
    let mut failed = Vec::new();
    for round in 0..600 {
        let mutate = |text: &str, rng: &mut Rng| -> String {
            let mut tokens: Vec<String> = text.split(' ').map(str::to_owned).collect();
            let at = rng.below(tokens.len());
            let nasty = NASTY[rng.below(NASTY.len())];
            // Keep the line break if the token ended a line.
            let keeps_newline = tokens[at].contains('\n');
            tokens[at] = if keeps_newline {
                tokens[at].replacen(tokens[at].split('\n').next().unwrap_or(""), nasty, 1)
            } else {
                nasty.to_owned()
            };
            tokens.join(" ")
        };
        let (obj, mtl) = if round % 3 == 0 {
            (obj.to_owned(), mutate(mtl, &mut rng))
        } else {
            (mutate(obj, &mut rng), mtl.to_owned())
        };
        std::fs::write(dir.path().join("m.mtl"), &mtl).unwrap();
        let path = dir.path().join("scene.obj");
        std::fs::write(&path, &obj).unwrap();
        if std::panic::catch_unwind(|| bake_importer::load(&path)).is_err() {
            failed.push(format!("round {round}:\n{obj}\n{mtl}"));
        }
    }
    assert!(
        failed.is_empty(),
        "panicked on:\n{}",
        failed.join("\n---\n")
    );
}
