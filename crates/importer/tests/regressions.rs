//! Inputs that once crashed, hung or exhausted memory (found by `tools/fuzz`, or written
//! by hand for bugs found otherwise), replayed through the fuzz targets' own harnesses:
//! each must load or fail with an error, never panic.
//!
//! `regressions/NAME.gltf-bytes` runs the `gltf` target's harness, `NAME.obj-bytes` the
//! `obj` one's (OBJ text, then a NUL and the MTL), `NAME.image-bytes`, `NAME.draco-bytes` and
//! `NAME.meshopt-bytes` the `image`, `draco` and `meshopt` ones'.

use std::path::Path;

const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/regressions");

#[test]
fn every_saved_input_loads_or_fails_without_panicking() {
    let mut entries: Vec<_> = std::fs::read_dir(DIR)
        .expect("the regressions directory")
        .flatten()
        .map(|e| e.path())
        .collect();
    entries.sort();
    let mut replayed = 0;
    let mut panicked = Vec::new();
    for path in &entries {
        let harness: fn(&[u8]) = match extension(path) {
            Some("gltf-bytes") => bake_importer::fuzzing::gltf,
            Some("obj-bytes") => bake_importer::fuzzing::obj,
            Some("image-bytes") => bake_importer::fuzzing::image,
            Some("draco-bytes") => bake_importer::fuzzing::draco,
            Some("meshopt-bytes") => bake_importer::fuzzing::meshopt,
            _ => continue,
        };
        let bytes = std::fs::read(path).expect("read a saved input");
        replayed += 1;
        if std::panic::catch_unwind(|| harness(&bytes)).is_err() {
            panicked.push(path.display().to_string());
        }
    }
    println!("replayed {replayed} saved inputs");
    assert!(replayed > 0, "no saved inputs in {DIR}");
    assert!(panicked.is_empty(), "panicked on:\n{}", panicked.join("\n"));
}

/// `a.gltf-bytes` → `gltf-bytes`.
fn extension(path: &Path) -> Option<&str> {
    path.file_name()?.to_str()?.split_once('.').map(|(_, e)| e)
}
