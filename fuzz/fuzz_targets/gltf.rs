//! The glTF importer on arbitrary bytes (JSON, a GLB as given, and the input wrapped in a
//! well-formed GLB; see `bake_importer::fuzzing::gltf`). It must return Ok or Err, never
//! panic, hang or exhaust memory (libFuzzer's -timeout and -rss_limit_mb enforce the last
//! two).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| bake_importer::fuzzing::gltf(data));
