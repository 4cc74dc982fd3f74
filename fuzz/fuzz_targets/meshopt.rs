//! An `EXT_meshopt_compression` buffer view (`bake_importer::fuzzing::meshopt`: the first
//! byte picks mode and stride, the next two the count, the rest is the stream): every input
//! reaches the meshopt decoder. It must return Ok or Err, never panic, hang or exhaust memory.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| bake_importer::fuzzing::meshopt(data));
