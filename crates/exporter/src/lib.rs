//! Writes the result of a bake: the baked glTF (`.gltf` + `.bin`, or `.glb`), the
//! lightmap glTF and the baked-texture glTF ([`stage_baked_texture_gltf`]: unlit, the bake
//! as a base-colour texture), all through one output transaction ([`OutputSet`]). The last module of the
//! pipeline (Goral et al. 1984, §3: the computed intensities are displayed), here written
//! out for any glTF viewer. (The bake report's schema is `bake-job`'s: it is made of the
//! bake's own result values, which this crate does not know.)
//!
//! Public API: [`write_gltf`] with a [`Bake`]; [`OutputSet`] for a set of files renamed into
//! place together, and [`recover_interrupted_commits`] for a set a crash left half renamed.
//!
//! The baked glTF keeps the input's nodes (same order and indices), names, transforms,
//! children and scenes. Meshes are written un-instanced: every node whose mesh has baked
//! elements gets its own mesh, whose primitives hold the element mesh of that instance
//! (positions and normals in the node's local space), the clamped colour (`COLOR_0`) and the
//! unclamped radiosity (`_RADIOSITY`), with one shared `KHR_materials_unlit` material.
//! A material with a base-colour texture (and no emission) instead keeps that texture in its
//! own unlit material (factor, sampler, image embedded, `KHR_texture_transform`), its
//! primitives carry `TEXCOORD_0` and their `COLOR_0` holds the irradiance H: a viewer shows
//! factor × texture × H, the reflected light with the texture's detail.

mod assets;
mod baked_texture;
mod document;
mod files;
mod geometry;
mod journal;
mod lightmap_gltf;
mod probes;
mod same_file;

pub use files::{
    abandon_temporaries, check_target, live_temporaries, remove_stale_temporaries, Abandoned,
    FileOps, OutputSet, RealFiles,
};
pub use journal::{recover_interrupted_commits, Recovered};
pub use probes::{ProbeGrid, PROBES_EXTENSION, PROBE_COEFFICIENTS};
pub use same_file::{check_distinct, SameFile};

pub use baked_texture::{
    stage_baked_texture_gltf, surface_alpha, surface_texels, BakedTextureBake, BakedTexturePaths,
    BAKED_TEXTURE_EXTRAS_KEY,
};
pub use lightmap_gltf::{
    stage_lightmap_gltf, write_lightmap_gltf, LightmapBake, LightmapPaths, LightmapWritten,
    LIGHTMAP_EXTENSION, LIGHTMAP_EXTRAS_KEY, LIGHTMAP_UNITS,
};

use std::path::{Path, PathBuf};

/// How radiosity is shown across an element (`--shading`).
pub use mesher::Shading;

/// Everything [`write_gltf`] needs.
#[derive(Clone, Copy, Debug)]
pub struct Bake<'a> {
    pub scene: &'a scene::Scene,
    pub mesh: &'a mesher::ElementMesh,
    /// Radiosity b per element (unclamped, linear, same units as emission).
    pub radiosity: &'a [[f64; 3]],
    /// Irradiance H per element (`b = e + ρ H`): required when a material keeps its
    /// base-colour texture (its `COLOR_0` is H, so a viewer shows factor × texture × H).
    pub irradiance: Option<&'a [[f64; 3]]>,
    /// Per element: the estimated bound on the error of b, written as the `_ERROR` vertex
    /// attribute (unclamped, per band; the largest of the elements around each vertex, or the
    /// element's own with flat shading). `None`: no `_ERROR`.
    pub error: Option<&'a [[f64; 3]]>,
    pub shading: Shading,
    /// `COLOR_0 = clamp(value × exposure, 0, 1)`.
    pub exposure: f64,
    /// Light probes, written as the `BAKE_irradiance_probes` extension on every scene.
    pub probes: Option<&'a ProbeGrid<'a>>,
}

/// Whether some material of `scene` keeps its base-colour texture in the vertex bake (then
/// [`Bake::irradiance`] is required).
pub fn keeps_textures(scene: &scene::Scene) -> bool {
    (0..scene.materials.len()).any(|m| geometry::textured_set(scene, m).is_some())
}

/// `--exposure auto`: the exposure that maps the 99th percentile, by area, of the elements'
/// brightest band of `b` to 0.8, so that at most about 1% of the surface saturates
/// `COLOR_0` (light panels, a spot's hot spot) while the rest keeps its gradations. 1 when
/// that percentile is 0 (a dark scene). `areas` and `radiosity` are per element.
pub fn auto_exposure(areas: &[f64], radiosity: &[[f64; 3]]) -> f64 {
    let mut values: Vec<(f64, f64)> = radiosity
        .iter()
        .zip(areas)
        .map(|(b, &a)| (b[0].max(b[1]).max(b[2]), a))
        .filter(|(v, a)| v.is_finite() && a.is_finite() && *a > 0.0)
        .collect();
    values.sort_by(|x, y| x.0.total_cmp(&y.0));
    let total: f64 = values.iter().map(|(_, a)| a).sum();
    let mut below = 0.0;
    let mut p99 = 0.0;
    for (v, a) in &values {
        below += a;
        p99 = *v;
        if below >= 0.99 * total {
            break;
        }
    }
    if p99 > 0.0 {
        AUTO_EXPOSURE_WHITE / p99
    } else {
        1.0
    }
}

/// The `COLOR_0` value `--exposure auto` gives the 99th-percentile element.
pub const AUTO_EXPOSURE_WHITE: f64 = 0.8;

#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("cannot write {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Two of the paths a bake would read or write are one file (`bake` refuses before
    /// writing anything).
    #[error(transparent)]
    SameFile(#[from] SameFile),
    #[error("unsupported output extension for {0} (expected .gltf or .glb)")]
    UnsupportedExtension(PathBuf),
    /// The scene, element mesh and radiosity do not fit together (a bug upstream).
    #[error("invalid bake data: {0}")]
    InvalidData(String),
    /// An interrupted commit's set could not all be put back
    /// ([`recover_interrupted_commits`]): every step that failed, and where its previous file
    /// is; its journal is kept, so that the next start tries again.
    #[error("cannot put back the outputs of an interrupted bake: {0}")]
    Recovery(String),
    #[error("cannot encode {what}: {message}")]
    Encode { what: &'static str, message: String },
    /// A value about to be written is NaN or infinite (as stored: f32 in the glTF). `what`
    /// names the element, its polygon's origin, the attribute and the value. Nothing is
    /// written.
    #[error("{what} is not finite")]
    NonFinite { what: String },
}

/// Writes the baked scene to `path`: `.gltf` (JSON plus `<stem>.bin` beside it) or `.glb`,
/// chosen by the extension (case-insensitive). Files are written to temporaries in the same
/// directory and renamed into place; on error no partial output is left.
///
/// Every radiosity value, and every position, normal, `COLOR_0` and `_RADIOSITY` value as
/// it will be stored (f32), is checked before anything is written: a NaN or infinity is an
/// [`ExportError::NonFinite`] naming the element and its polygon's origin.
pub fn write_gltf(path: &Path, bake: &Bake) -> Result<(), ExportError> {
    let mut set = OutputSet::new();
    stage_gltf(&mut set, path, bake)?;
    set.commit().map(drop)
}

/// [`write_gltf`] as part of a larger set: the files are staged in `set` (the `.bin` before
/// the `.gltf` that names it) and appear only when the set is committed.
pub fn stage_gltf(set: &mut OutputSet, path: &Path, bake: &Bake) -> Result<(), ExportError> {
    let format = files::OutputFormat::from_path(path)?;
    let primitives = geometry::build(bake)?;
    match format {
        files::OutputFormat::Gltf => {
            let bin_path = files::bin_path_for(path)?;
            let bin_uri = files::uri_for_file_name(&bin_path);
            let (root, bin) = document::build(bake.scene, &primitives, Some(bin_uri), bake.probes)?;
            let json = encode_json(&root)?;
            if !bin.is_empty() {
                set.stage(&bin_path, &bin)?;
            }
            set.stage(path, &json)
        }
        files::OutputFormat::Glb => {
            let (root, bin) = document::build(bake.scene, &primitives, None, bake.probes)?;
            let glb = encode_glb(&root, &bin)?;
            set.stage(path, &glb)
        }
    }
}

/// Every file [`write_gltf`] may write for `path`: `<stem>.bin` and the `.gltf`, or the
/// `.glb`.
pub fn gltf_files(path: &Path) -> Result<Vec<PathBuf>, ExportError> {
    Ok(match files::OutputFormat::from_path(path)? {
        files::OutputFormat::Gltf => vec![files::bin_path_for(path)?, path.to_path_buf()],
        files::OutputFormat::Glb => vec![path.to_path_buf()],
    })
}

fn encode_json(root: &gltf::json::Root) -> Result<Vec<u8>, ExportError> {
    let mut json = Vec::new();
    root.to_writer_pretty(&mut json)
        .map_err(|e| ExportError::Encode {
            what: "glTF JSON",
            message: e.to_string(),
        })?;
    Ok(json)
}

/// GLB lengths are u32; leave room for the header, chunk headers and padding.
const GLB_MAX_PAYLOAD: usize = u32::MAX as usize - 64;

fn encode_glb(root: &gltf::json::Root, bin: &[u8]) -> Result<Vec<u8>, ExportError> {
    let json = root.to_vec().map_err(|e| ExportError::Encode {
        what: "glTF JSON",
        message: e.to_string(),
    })?;
    if json.len() + bin.len() > GLB_MAX_PAYLOAD {
        return Err(ExportError::Encode {
            what: "GLB",
            message: "the scene is too large for a GLB file (4 GiB); write .gltf instead".into(),
        });
    }
    let bin = if bin.is_empty() {
        None
    } else {
        Some(bin.into())
    };
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            // `to_writer` computes the real length.
            length: 0,
        },
        json: json.into(),
        bin,
    };
    glb.to_vec().map_err(|e| ExportError::Encode {
        what: "GLB",
        message: e.to_string(),
    })
}
