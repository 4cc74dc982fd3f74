//! Office-floor walkthrough scenes for scale tests of the baker: [`office::office`] builds the
//! floor, [`gltf::write`] writes it as glTF 2.0. The `walkthrough` binary adds the benchmark.

pub mod gltf;
pub mod office;
