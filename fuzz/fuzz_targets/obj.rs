//! The OBJ importer on arbitrary text: the bytes before the first NUL are the OBJ, those
//! after it the MTL every `mtllib` reads (see `bake_importer::fuzzing::obj`). It must
//! return Ok or Err, never panic, hang or exhaust memory.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| bake_importer::fuzzing::obj(data));
