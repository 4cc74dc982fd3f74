//! The workspace's test kit: helpers that more than one package's tests use, each defined
//! once.
//!
//! - [`GltfBuilder`]: glTF documents with one binary buffer, written as a data URI, an
//!   external `.bin`, or a `.glb`; [`GltfBuilder::wall`] is the one-mesh document most
//!   end-to-end tests start from.
//! - [`base64`] and [`data_uri`]; [`glb`] frames and [`glb_chunks`] splits GLB containers.
//! - Paths: [`fixture`] (`fixtures/` at the workspace root), [`shared_dir`] (the `../shared`
//!   corpora next to the workspace), [`tools_dir`], and directory listings.
//! - Optional tools and data: [`skip`] and [`required`] (the `BAKE_REQUIRE_*` variables),
//!   the Khronos validator ([`validator_or_skip`], [`validate_clean`]) and Blender
//!   ([`blender_or_skip`]).
//!
//! What it is not: a dependency of any library's or tool's normal build. Packages list it
//! under `[dev-dependencies]` only, and it depends on nothing in the pipeline (only on
//! `serde_json` and `std`), so helpers that need a pipeline crate's types stay in that
//! package's own `tests/common`.

mod encode;
mod gltf;
mod optional;
mod paths;

pub use encode::{base64, data_uri, glb, glb_chunks, GLB_BIN, GLB_JSON};
pub use gltf::{
    position_bytes, GltfBuilder, FLOAT, POINTS, TRIANGLES, UNSIGNED_INT, UNSIGNED_SHORT,
};
pub use optional::{
    blender_installed, blender_or_skip, chromium_or_skip, required, skip, skip_unless_set,
    validate_clean, validator_available, validator_or_skip, validator_output,
};
pub use paths::{
    file_names, files_with_extensions, fixture, fixtures_dir, shared_dir, tools_dir, workspace_dir,
};
