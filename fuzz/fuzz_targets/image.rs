//! A texture's bytes through the importer's image decoding (`bake_importer::fuzzing::image`:
//! PNG or JPEG by their magic, the size check, the `image` crate's decoders). It must return
//! Ok or Err, never panic, hang or exhaust memory.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| bake_importer::fuzzing::image(data));
