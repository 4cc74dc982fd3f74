//! Walkthrough scenes for scale tests of the baker: [`office::office`] builds an office floor,
//! [`atrium::atrium`] an open atrium under a sun, [`gltf::write`] writes either as glTF 2.0.
//! The `walkthrough` binary adds the benchmark.

pub mod atrium;
pub mod gltf;
pub mod office;
