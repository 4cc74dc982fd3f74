//! The end-to-end tests of the `bake` command and of `bake_core::run`, in one test binary.
//!
//! One binary instead of one per file: each of these links the whole pipeline (faer, image, exr,
//! gltf…), and 26 copies of it cost CI minutes of linking and gigabytes of disk (a CI run ran out of
//! space). A file's tests are named after it: `cargo test --test end_to_end lightmap::`. The
//! corpus tests, whose limits are wall time, are a binary of their own (`tests/corpora`).

mod common;

mod alpha;
mod baked_texture;
mod blender_textures;
mod cli_errors;
mod compressed;
mod corner_touching;
mod glass;
mod hierarchical;
mod lightmap;
mod lightmap_uv;
mod lights;
mod links;
mod max_error;
mod occlusion;
mod output;
mod output_set;
mod physics;
mod preview_lightmap;
mod probe_viewer;
mod probes;
mod quality;
mod real_assets;
mod refine;
mod reliability3;
mod sky;
mod solver_stress;
mod textures;
mod validator_all;
mod viewers;
