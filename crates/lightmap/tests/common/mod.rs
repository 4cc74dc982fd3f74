//! Helpers the lightmap crate's integration tests share.

#![allow(dead_code)] // each test binary uses its own subset

use bake_lightmap as lightmap;
use glam::DVec3;
use importer::{Origin, Polygon, Side};

/// The CLI's default lightmap options for `polygons`: the default texel size, atlas limits,
/// smooth shading.
pub fn default_options(polygons: &[Polygon]) -> lightmap::Options {
    lightmap::Options {
        texel_size: lightmap::default_texel_size(polygons),
        max_size: lightmap::DEFAULT_MAX_SIZE,
        shading: lightmap::Shading::Smooth,
        max_atlases: lightmap::DEFAULT_MAX_ATLASES,
    }
}

/// A polygon of `material` in node, mesh and primitive 0, facing by its winding.
pub fn polygon(vertices: Vec<DVec3>, material: usize) -> Polygon {
    let normal = (vertices[1] - vertices[0])
        .cross(vertices[2] - vertices[0])
        .normalize();
    let origin = Origin {
        node: 0,
        mesh: 0,
        primitive: 0,
        face: 0,
        side: Side::Front,
    };
    Polygon {
        vertices,
        normal,
        material,
        origin,
    }
}

/// Debian's `assimp-testmodels` glTF 2.0 models (`/usr/share/assimp/models/glTF2`, as
/// `tests/corpora/real_corpus.rs` finds them), sorted; `None`, after saying `skipped: …`, when the
/// package is not installed.
pub fn assimp_models() -> Option<Vec<std::path::PathBuf>> {
    let dir = std::path::Path::new("/usr/share/assimp/models/glTF2");
    let Ok(entries) = std::fs::read_dir(dir) else {
        println!(
            "skipped: {} is not there (assimp-testmodels)",
            dir.display()
        );
        return None;
    };
    let mut files: Vec<std::path::PathBuf> = entries
        .flatten()
        .flat_map(|e| std::fs::read_dir(e.path()).into_iter().flatten().flatten())
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "gltf" || x == "glb"))
        .collect();
    files.sort();
    Some(files)
}
