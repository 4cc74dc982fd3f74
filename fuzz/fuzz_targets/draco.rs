//! A `KHR_draco_mesh_compression` bitstream, as the BIN chunk of a GLB whose one primitive
//! points the extension at all of it (`bake_importer::fuzzing::draco`): every input reaches
//! the Draco decoder. It must return Ok or Err, never panic, hang or exhaust memory.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| bake_importer::fuzzing::draco(data));
