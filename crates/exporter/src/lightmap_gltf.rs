//! Writes the lightmap bake: the input's polygons (not subdivided) in each node's local space
//! with lit materials rebuilt from the input's, `TEXCOORD_1` into the primitive's lightmap
//! atlas wired with `MOZ_lightmap` (what three.js-based viewers such as Hubs read), each atlas
//! as an 8-bit sRGB PNG and as a linear float EXR (several atlases: one material per input
//! material and atlas). Every file is written atomically; the glTF last.
//!
//! Layout of each output primitive: the polygons of one input primitive instance, in the
//! importer's polygon order, each with its own 3 or 4 vertices (in the polygon's vertex
//! order) and the triangles (v0 v1 v2), (v0 v2 v3) — the triangles the lightmap's texels were
//! reconstructed over.

use crate::assets::{embed, reads_set, remap_sets, Assets, TEXTURE_TRANSFORM_EXTENSION};
use crate::document::{check_layout, DocumentWriter};
use crate::files::{self, OutputFormat, OutputSet};
use crate::{encode_glb, encode_json, ExportError};
use glam::{DMat3, DMat4, DVec3};
use gltf::json;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;
use gltf::json::Index;
use lightmap::Lightmap;
use scene::{Material, Scene};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The material extension that carries the lightmap.
pub const LIGHTMAP_EXTENSION: &str = "MOZ_lightmap";
const EMISSIVE_STRENGTH_EXTENSION: &str = "KHR_materials_emissive_strength";
/// The key of the root `extras` object that describes the lightmap.
pub const LIGHTMAP_EXTRAS_KEY: &str = "bake_lightmap";
/// The units sentence written into the glTF and the README.
pub const LIGHTMAP_UNITS: &str = "irradiance H (light arriving at the surface) in the bake's \
intensity units, those of emission e and radiosity b: b = e + rho * H";

/// Where the files of a lightmap bake go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LightmapPaths {
    /// The glTF (`.gltf` with its `.bin` beside it, or `.glb` with the PNG inside).
    pub gltf: PathBuf,
    /// The 8-bit PNG (only written for `.gltf`; a `.glb` embeds it).
    pub png: PathBuf,
    /// The linear float EXR.
    pub exr: PathBuf,
}

impl LightmapPaths {
    /// `--target lightmap`: the glTF is `output`; the images are `<stem>.lightmap.png` and
    /// `<stem>.lightmap.exr` beside it.
    pub fn alone(output: &Path) -> Result<LightmapPaths, ExportError> {
        OutputFormat::from_path(output)?;
        Ok(LightmapPaths {
            gltf: output.to_path_buf(),
            png: sibling(output, "lightmap.png")?,
            exr: sibling(output, "lightmap.exr")?,
        })
    }

    /// `--target both`: `output` holds the vertex bake; the lightmap glTF is
    /// `<stem>.lightmap.gltf` (or `.glb`, as `output`) and the images are named as in
    /// [`LightmapPaths::alone`].
    pub fn beside(output: &Path) -> Result<LightmapPaths, ExportError> {
        let format = OutputFormat::from_path(output)?;
        let extension = match format {
            OutputFormat::Gltf => "lightmap.gltf",
            OutputFormat::Glb => "lightmap.glb",
        };
        Ok(LightmapPaths {
            gltf: sibling(output, extension)?,
            ..LightmapPaths::alone(output)?
        })
    }
}

impl LightmapPaths {
    /// Every file [`write_lightmap_gltf`] may write: the EXR, and the PNG, `.bin` and
    /// `.gltf`, or the `.glb`.
    pub fn files(&self) -> Result<Vec<PathBuf>, ExportError> {
        Ok(match OutputFormat::from_path(&self.gltf)? {
            OutputFormat::Gltf => vec![
                self.exr.clone(),
                self.png.clone(),
                files::bin_path_for(&self.gltf)?,
                self.gltf.clone(),
            ],
            OutputFormat::Glb => vec![self.exr.clone(), self.gltf.clone()],
        })
    }
}

impl LightmapPaths {
    /// The PNG of atlas `k` (0: [`LightmapPaths::png`]; k ≥ 1: `<stem>.lightmap-<k>.png`).
    pub fn atlas_png(&self, k: usize) -> Result<PathBuf, ExportError> {
        numbered(&self.png, k)
    }

    /// The EXR of atlas `k` (0: [`LightmapPaths::exr`]; k ≥ 1: `<stem>.lightmap-<k>.exr`).
    pub fn atlas_exr(&self, k: usize) -> Result<PathBuf, ExportError> {
        numbered(&self.exr, k)
    }
}

/// `path` for k = 0; `<dir>/<stem>-<k>.<ext>` for `<dir>/<stem>.<ext>` otherwise.
pub(crate) fn numbered(path: &Path, k: usize) -> Result<PathBuf, ExportError> {
    if k == 0 {
        return Ok(path.to_path_buf());
    }
    let bad = || ExportError::UnsupportedExtension(path.to_path_buf());
    let stem = path.file_stem().ok_or_else(bad)?;
    let extension = path.extension().ok_or_else(bad)?;
    let mut name = stem.to_os_string();
    name.push(format!("-{k}."));
    name.push(extension);
    Ok(path.with_file_name(name))
}

/// `<dir>/<stem>.<suffix>` for `<dir>/<stem>.<ext>`.
pub(crate) fn sibling(path: &Path, suffix: &str) -> Result<PathBuf, ExportError> {
    let stem = path
        .file_stem()
        .ok_or_else(|| ExportError::UnsupportedExtension(path.to_path_buf()))?;
    let mut name = stem.to_os_string();
    name.push(".");
    name.push(suffix);
    Ok(path.with_file_name(name))
}

/// Everything [`write_lightmap_gltf`] needs.
#[derive(Clone, Copy, Debug)]
pub struct LightmapBake<'a> {
    pub scene: &'a Scene,
    pub lightmap: &'a Lightmap,
    /// Write the scene's punctual lights (`KHR_lights_punctual`) on their nodes. Their light
    /// is already in the lightmap: a lit viewer would count it twice (`--keep-lights`, for
    /// engines that want them for specular only).
    pub keep_lights: bool,
    /// The exposure the vertex bake's `COLOR_0` used (`--exposure`, or `auto`'s choice),
    /// recorded in the extras so a viewer (`bake preview`) shows the lightmap bake as bright
    /// as the vertex bake: displayed value = clamp((e + ρ H) × exposure, 0, 1).
    pub exposure: f64,
    /// Light probes, written as the `BAKE_irradiance_probes` extension on every scene.
    pub probes: Option<&'a crate::ProbeGrid<'a>>,
}

/// What was written.
#[derive(Clone, Debug, PartialEq)]
pub struct LightmapWritten {
    /// `MOZ_lightmap.intensity`: `H = srgb_to_linear(png / 255) × png_scale` (the first
    /// atlas's).
    pub png_scale: f64,
    /// Each atlas's `png_scale`.
    pub png_scales: Vec<f64>,
    /// Every file written, in the order they were renamed into place.
    pub files: Vec<PathBuf>,
}

/// Writes the lightmap bake to `paths`: every file to a temporary first, then renamed into
/// place (the glTF last, so it never names a file that is not there yet).
pub fn write_lightmap_gltf(
    paths: &LightmapPaths,
    bake: &LightmapBake,
) -> Result<LightmapWritten, ExportError> {
    let mut set = OutputSet::new();
    let staged = stage_lightmap_gltf(&mut set, paths, bake)?;
    let files = set.commit()?;
    Ok(LightmapWritten { files, ..staged })
}

/// [`write_lightmap_gltf`] as part of a larger set: the EXR, PNG and `.bin` are staged
/// before the glTF; `files` lists them in that order (they appear when `set` is committed).
pub fn stage_lightmap_gltf(
    set: &mut OutputSet,
    paths: &LightmapPaths,
    bake: &LightmapBake,
) -> Result<LightmapWritten, ExportError> {
    let format = OutputFormat::from_path(&paths.gltf)?;
    let scene = bake.scene;
    let lightmap = bake.lightmap;
    let mut writer = start_document(scene, lightmap)?;
    let encode = |e: lightmap::LightmapError| ExportError::Encode {
        what: "lightmap",
        message: e.to_string(),
    };
    // One EXR, PNG and texture per atlas.
    let atlases = lightmap.atlases();
    let mut exrs = Vec::with_capacity(atlases.len());
    let mut pngs = Vec::with_capacity(atlases.len());
    for atlas in &atlases {
        exrs.push(lightmap::encode_exr_atlas(*atlas).map_err(encode)?);
        pngs.push(lightmap::encode_png_atlas(*atlas).map_err(encode)?);
    }
    let mut png_paths = Vec::with_capacity(atlases.len());
    let mut exr_paths = Vec::with_capacity(atlases.len());
    for k in 0..atlases.len() {
        png_paths.push(paths.atlas_png(k)?);
        exr_paths.push(paths.atlas_exr(k)?);
    }

    let mut textures = Vec::with_capacity(atlases.len());
    for (k, png) in pngs.iter().enumerate() {
        let name = if k == 0 {
            "lightmap".to_string()
        } else {
            format!("lightmap-{k}")
        };
        let image = png_image(&mut writer, format, name, &png.bytes, &png_paths[k]);
        textures.push(add_texture(&mut writer.root, image));
    }
    let mut assets = Assets::new(&scene.authored);
    add_meshes(
        &mut writer,
        scene,
        lightmap,
        false,
        |writer, material_index, atlas| {
            let (texture, scale) = (textures[atlas as usize], pngs[atlas as usize].scale);
            let source = scene.materials.get(material_index).ok_or_else(|| {
                ExportError::InvalidData(format!("missing material {material_index}"))
            })?;
            let made = match assets.material(writer, material_index, false)? {
                Some(authored) => kept_material(authored, texture, scale),
                None => (lit_material(source, texture, scale), UvNeeds::default()),
            };
            Ok((writer.root.push(made.0), made.1))
        },
    )?;
    if bake.keep_lights && !scene.lights.is_empty() {
        add_lights(&mut writer.root, scene);
    }
    writer.root.extensions_used.push(LIGHTMAP_EXTENSION.into());
    if let Some(probes) = bake.probes {
        crate::probes::add(&mut writer, probes)?;
    }
    if assets.uses_transform {
        writer.use_extension(TEXTURE_TRANSFORM_EXTENSION);
    }
    let strength = |m: &json::Material| {
        m.extensions
            .as_ref()
            .is_some_and(|e| e.emissive_strength.is_some())
    };
    if writer.root.materials.iter().any(strength) {
        writer
            .root
            .extensions_used
            .push(EMISSIVE_STRENGTH_EXTENSION.into());
    }
    let png_uris: Vec<Option<String>> = png_paths
        .iter()
        .map(|p| match format {
            OutputFormat::Gltf => Some(files::uri_for_file_name(p)),
            OutputFormat::Glb => None,
        })
        .collect();
    let scales: Vec<f64> = pngs.iter().map(|p| p.scale).collect();
    let clipped: Vec<u64> = pngs.iter().map(|p| p.clipped).collect();
    let extras = extras(
        lightmap,
        bake.exposure,
        (&scales, &clipped),
        &png_uris,
        &exr_paths,
    )
    .to_string();
    let extras =
        serde_json::value::RawValue::from_string(extras).map_err(|e| ExportError::Encode {
            what: "glTF extras",
            message: e.to_string(),
        })?;
    writer.root.extras = Some(extras);

    // Per atlas its EXR (and PNG for .gltf), then the .bin and the glTF.
    let mut staged: Vec<(&Path, &[u8])> = Vec::new();
    for k in 0..atlases.len() {
        staged.push((exr_paths[k].as_path(), &exrs[k]));
        if format == OutputFormat::Gltf {
            staged.push((png_paths[k].as_path(), &pngs[k].bytes));
        }
    }
    let written = stage_document(set, &paths.gltf, format, writer, staged)?;
    Ok(LightmapWritten {
        png_scale: pngs[0].scale,
        png_scales: scales,
        files: written,
    })
}

/// A document holding `scene`'s nodes and scenes, for polygons laid out by `lightmap`.
pub(crate) fn start_document(
    scene: &Scene,
    lightmap: &Lightmap,
) -> Result<DocumentWriter, ExportError> {
    if lightmap.charts.len() != scene.polygons.len() {
        return Err(ExportError::InvalidData(format!(
            "{} lightmap charts for {} polygons",
            lightmap.charts.len(),
            scene.polygons.len()
        )));
    }
    check_layout(&scene.layout)?;
    let mut writer = DocumentWriter::default();
    writer.root.asset.generator = Some(format!("bake {}", env!("CARGO_PKG_VERSION")));
    writer.add_layout(&scene.layout);
    Ok(writer)
}

/// Every baked node's mesh: per input primitive instance its polygons with `TEXCOORD_1` into
/// their atlas, and the material `material(writer, input material, atlas)` makes (asked once
/// per pair). `plain`: no input `COLOR_0` (a material that already holds it, or one that
/// ignores it). A primitive's polygons must share an atlas.
pub(crate) fn add_meshes(
    writer: &mut DocumentWriter,
    scene: &Scene,
    lightmap: &Lightmap,
    plain: bool,
    mut material: impl FnMut(
        &mut DocumentWriter,
        usize,
        u32,
    ) -> Result<(Index<json::Material>, UvNeeds), ExportError>,
) -> Result<(), ExportError> {
    // (Scene material, atlas) → (output material, what its primitives need).
    let mut materials: BTreeMap<(usize, u32), (Index<json::Material>, UvNeeds)> = BTreeMap::new();
    for ((node, mesh), primitives) in group_polygons(scene) {
        let space = NodeSpace::new(&scene.layout.nodes[node].world, node)?;
        let mut output = Vec::with_capacity(primitives.len());
        for (primitive, polygons) in primitives {
            let material_index = scene.layout.meshes[mesh].primitives[primitive].material;
            // A primitive is drawn with one lightmap: its polygons share an atlas.
            let atlas = polygons.first().map_or(0, |&p| lightmap.charts[p].atlas);
            if polygons.iter().any(|&p| lightmap.charts[p].atlas != atlas) {
                return Err(ExportError::InvalidData(format!(
                    "node {node} mesh {mesh} primitive {primitive}: its polygons are in several lightmap atlases"
                )));
            }
            let (index, mut needs) = match materials.get(&(material_index, atlas)) {
                Some(&m) => m,
                None => {
                    let m = material(writer, material_index, atlas)?;
                    materials.insert((material_index, atlas), m);
                    m
                }
            };
            needs.plain |= plain;
            let data = primitive_data(scene, lightmap, &space, &polygons, needs)?;
            output.push(add_primitive(writer, &data, index));
        }
        let mesh_index = writer.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: scene.layout.meshes[mesh].name.clone(),
            primitives: output,
            weights: None,
        });
        writer.root.nodes[node].mesh = Some(mesh_index);
    }
    Ok(())
}

/// A PNG image: beside a `.gltf` (its file name as the URI), inside a `.glb`.
pub(crate) fn png_image(
    writer: &mut DocumentWriter,
    format: OutputFormat,
    name: String,
    bytes: &[u8],
    path: &Path,
) -> json::Image {
    let (buffer_view, uri) = match format {
        OutputFormat::Gltf => (None, Some(files::uri_for_file_name(path))),
        OutputFormat::Glb => (Some(embed(writer, bytes)), None),
    };
    json::Image {
        buffer_view,
        mime_type: Some(json::image::MimeType("image/png".into())),
        name: Some(name),
        uri,
        extensions: None,
        extras: Default::default(),
    }
}

/// Stages `images` (written beside a `.gltf` only), then the `.bin` and `.gltf`, or the `.glb`;
/// returns every target in that order.
pub(crate) fn stage_document(
    set: &mut OutputSet,
    gltf: &Path,
    format: OutputFormat,
    writer: DocumentWriter,
    images: Vec<(&Path, &[u8])>,
) -> Result<Vec<PathBuf>, ExportError> {
    let mut written = stage_all(set, &images)?;
    match format {
        OutputFormat::Gltf => {
            let bin_path = files::bin_path_for(gltf)?;
            let (root, bin) = writer.finish(Some(files::uri_for_file_name(&bin_path)));
            let json = encode_json(&root)?;
            written.extend(stage_all(set, &[(&bin_path, &bin), (gltf, &json)])?);
        }
        OutputFormat::Glb => {
            let (root, bin) = writer.finish(None);
            let glb = encode_glb(&root, &bin)?;
            written.extend(stage_all(set, &[(gltf, &glb)])?);
        }
    }
    Ok(written)
}

/// The scene's lights as `KHR_lights_punctual`, each on its node (same node indices).
fn add_lights(root: &mut json::Root, scene: &Scene) {
    use json::extensions::scene::khr_lights_punctual as khr;
    use json::validation::Checked;
    let mut lights = Vec::with_capacity(scene.lights.len());
    for (i, light) in scene.lights.iter().enumerate() {
        let (type_, spot) = match light.kind {
            scene::LightKind::Point => (khr::Type::Point, None),
            scene::LightKind::Directional => (khr::Type::Directional, None),
            scene::LightKind::Spot { inner, outer } => (
                khr::Type::Spot,
                Some(khr::Spot {
                    inner_cone_angle: inner as f32,
                    outer_cone_angle: outer as f32,
                }),
            ),
        };
        lights.push(khr::Light {
            color: light.color.map(|c| c as f32),
            extensions: None,
            extras: Default::default(),
            intensity: light.intensity as f32,
            name: light.name.clone(),
            range: light.range.map(|r| r as f32),
            spot,
            type_: Checked::Valid(type_),
        });
        if let Some(node) = root.nodes.get_mut(light.node) {
            node.extensions
                .get_or_insert_with(Default::default)
                .khr_lights_punctual = Some(khr::KhrLightsPunctual {
                light: Index::new(i as u32),
            });
        }
    }
    root.extensions
        .get_or_insert_with(Default::default)
        .khr_lights_punctual = Some(json::extensions::root::KhrLightsPunctual { lights });
    root.extensions_used.push("KHR_lights_punctual".into());
}

/// The root `extras`: what the lightmap is, its units and its files.
fn extras(
    lightmap: &Lightmap,
    exposure: f64,
    (png_scales, png_clipped): (&[f64], &[u64]),
    png_uris: &[Option<String>],
    exrs: &[PathBuf],
) -> serde_json::Value {
    let (png_scale, png_uri, exr) = (png_scales[0], png_uris[0].clone(), &exrs[0]);
    let atlases: Vec<serde_json::Value> = lightmap
        .atlases()
        .iter()
        .enumerate()
        .map(|(k, a)| {
            serde_json::json!({
                "exr": files::uri_for_file_name(&exrs[k]),
                "png": png_uris[k],
                "png_scale": png_scales[k],
                "png_clipped": png_clipped[k],
                "atlas": [a.width, a.height],
            })
        })
        .collect();
    serde_json::json!({
        LIGHTMAP_EXTRAS_KEY: {
            "quantity": "irradiance",
            "units": LIGHTMAP_UNITS,
            "texcoord": 1,
            "exposure": exposure,
            "exr": files::uri_for_file_name(exr),
            "exr_encoding": "linear RGB, 32-bit float, H per texel",
            "png": png_uri,
            "png_encoding": "8-bit sRGB-encoded; H = srgb_to_linear(value / 255) * png_scale \
                             (MOZ_lightmap intensity); png_clipped texels are above png_scale \
                             (255 in the PNG, exact in the EXR)",
            "png_scale": png_scale,
            "png_clipped": png_clipped[0],
            "texel_size": lightmap.texel_size,
            "requested_texel_size": lightmap.requested_texel_size,
            "atlas": [lightmap.width, lightmap.height],
            "occupancy": lightmap.stats.occupancy,
            "atlases": atlases,
        }
    })
}

pub(crate) fn add_texture(root: &mut json::Root, image: json::Image) -> Index<json::Texture> {
    use json::texture::{MagFilter, MinFilter, WrappingMode};
    let image = root.push(image);
    let sampler = root.push(json::texture::Sampler {
        mag_filter: Some(Checked::Valid(MagFilter::Linear)),
        min_filter: Some(Checked::Valid(MinFilter::LinearMipmapLinear)),
        name: None,
        wrap_s: Checked::Valid(WrappingMode::ClampToEdge),
        wrap_t: Checked::Valid(WrappingMode::ClampToEdge),
        extensions: None,
        extras: Default::default(),
    });
    root.push(json::Texture {
        name: Some("lightmap".into()),
        sampler: Some(sampler),
        source: image,
        extensions: None,
        extras: Default::default(),
    })
}

fn max3(v: [f64; 3]) -> f64 {
    v[0].max(v[1]).max(v[2])
}

/// A lit (metallic-roughness) material from the input's: base colour ρ, fully rough
/// dielectric, emission e (above 1 through `KHR_materials_emissive_strength`), single-sided
/// (both sides of a double-sided surface are written as their own triangles), and the
/// lightmap through `MOZ_lightmap`.
fn lit_material(source: &Material, texture: Index<json::Texture>, scale: f64) -> json::Material {
    let rho = source.rho.map(|r| r as f32);
    let peak = max3(source.emission);
    let (emissive, strength) = if peak > 1.0 {
        (
            source.emission.map(|e| (e / peak) as f32),
            Some(peak as f32),
        )
    } else {
        (source.emission.map(|e| e as f32), None)
    };
    let mut extensions = json::extensions::material::Material {
        emissive_strength: strength.map(|s| json::extensions::material::EmissiveStrength {
            emissive_strength: json::extensions::material::EmissiveStrengthFactor(s),
        }),
        ..Default::default()
    };
    extensions.others.insert(
        LIGHTMAP_EXTENSION.into(),
        serde_json::json!({ "index": texture.value(), "texCoord": 1, "intensity": scale }),
    );
    json::Material {
        name: source.name.clone(),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([rho[0], rho[1], rho[2], 1.0]),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(1.0),
            ..Default::default()
        },
        emissive_factor: json::material::EmissiveFactor(emissive),
        double_sided: false,
        extensions: Some(extensions),
        ..Default::default()
    }
}

/// The input's own material, as authored (textures, normal, metallic-roughness, emission;
/// no occlusion texture, which would darken twice), single-sided like every output triangle,
/// with the lightmap through `MOZ_lightmap`. Texture references to the input's TEXCOORD_1
/// move to TEXCOORD_2 (the lightmap's set is 1); the flag says whether any did.
fn kept_material(
    mut material: json::Material,
    texture: Index<json::Texture>,
    scale: f64,
) -> (json::Material, UvNeeds) {
    let second_set = reads_set(&material, 1);
    let normal_set = material.normal_texture.as_ref().map(|n| n.tex_coord);
    if second_set {
        remap_sets(&mut material, |set| if set == 1 { 2 } else { set });
    }
    material.double_sided = false;
    material
        .extensions
        .get_or_insert_with(Default::default)
        .others
        .insert(
            LIGHTMAP_EXTENSION.into(),
            serde_json::json!({ "index": texture.value(), "texCoord": 1, "intensity": scale }),
        );
    (
        material,
        UvNeeds {
            second_set,
            normal_set,
            plain: false,
        },
    )
}

/// What a kept material needs of its primitives beyond positions, normals and the lightmap.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct UvNeeds {
    /// Its textures read the input's TEXCOORD_1 (written as TEXCOORD_2).
    second_set: bool,
    /// Its normal map reads this input TEXCOORD set: the primitive gets `TANGENT`s.
    normal_set: Option<u32>,
    /// Leave out the input's `COLOR_0` (the baked texture already holds it).
    plain: bool,
}

/// The tangent (xyz, handedness w) of a planar polygon for a normal map: the direction of
/// increasing u in the plane (node-local space), orthogonal to `normal`, with w = ±1 the sign
/// that makes `cross(normal, tangent) × w` the direction of increasing v — constant over a
/// polygon whose UVs are affine, as every output polygon's are (MikkTSpace's value for a
/// face whose vertices are not shared). A degenerate mapping gets any unit tangent, w = 1.
fn polygon_tangent(p: [DVec3; 3], uv: [glam::DVec2; 3], normal: DVec3) -> [f64; 4] {
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let det = d1.x * d2.y - d2.x * d1.y;
    let fallback = || {
        let t = normal.any_orthonormal_vector();
        [t.x, t.y, t.z, 1.0]
    };
    if det == 0.0 || !det.is_finite() {
        return fallback();
    }
    let t = (e1 * d2.y - e2 * d1.y) / det;
    let b = (e2 * d1.x - e1 * d2.x) / det;
    let Some(t) = (t - normal * normal.dot(t)).try_normalize() else {
        return fallback();
    };
    let w = if normal.cross(t).dot(b) < 0.0 {
        -1.0
    } else {
        1.0
    };
    [t.x, t.y, t.z, w]
}

/// node → (mesh, [(primitive, polygon indices in polygon order)]), in node then primitive order.
type Groups = BTreeMap<(usize, usize), BTreeMap<usize, Vec<usize>>>;

fn group_polygons(scene: &Scene) -> Groups {
    let mut groups = Groups::new();
    for (index, polygon) in scene.polygons.iter().enumerate() {
        let o = polygon.origin;
        groups
            .entry((o.node, o.mesh))
            .or_default()
            .entry(o.primitive)
            .or_default()
            .push(index);
    }
    groups
}

/// One output primitive's vertex data (node-local, f32).
struct PrimitiveData {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    texcoords: Vec<[f32; 2]>,
    /// The input's TEXCOORD_0 where the importer kept it (a textured material, or a
    /// primitive with TEXCOORD_1); else the lightmap's UVs, so TEXCOORD_1 has its TEXCOORD_0.
    input_uv0: Option<Vec<[f32; 2]>>,
    /// The input's TEXCOORD_1, written as TEXCOORD_2, when the material's textures read it.
    input_uv1: Option<Vec<[f32; 2]>>,
    /// Unit tangents with handedness, when the material has a normal map.
    tangents: Option<Vec<[f32; 4]>>,
    /// The input's COLOR_0 (a lit viewer multiplies the base colour by it, as the bake did).
    colors: Option<Vec<[f32; 3]>>,
    indices: Vec<u32>,
}

fn primitive_data(
    scene: &Scene,
    lightmap: &Lightmap,
    space: &NodeSpace,
    polygons: &[usize],
    needs: UvNeeds,
) -> Result<PrimitiveData, ExportError> {
    let second_set = needs.second_set;
    let has_set = |set: usize| {
        polygons.iter().all(|&p| {
            scene
                .uvs
                .get(p)
                .and_then(Option::as_ref)
                .is_some_and(|uv| uv.sets[set])
        })
    };
    let mut data = PrimitiveData {
        positions: Vec::new(),
        normals: Vec::new(),
        texcoords: Vec::new(),
        input_uv0: has_set(0).then(Vec::new),
        input_uv1: (second_set && has_set(1)).then(Vec::new),
        tangents: needs.normal_set.map(|_| Vec::new()),
        colors: (!needs.plain
            && polygons.iter().all(|&p| {
                scene
                    .uvs
                    .get(p)
                    .and_then(Option::as_ref)
                    .and_then(|uv| uv.triangles.first())
                    .is_some_and(|t| t.color.is_some())
            }))
        .then(Vec::new),
        indices: Vec::new(),
    };
    if second_set && data.input_uv1.is_none() {
        return Err(ExportError::InvalidData(
            "a material reads TEXCOORD_1 but its primitive has none".into(),
        ));
    }
    for &p in polygons {
        let polygon = &scene.polygons[p];
        let normal = space
            .normal(polygon.normal)
            .ok_or_else(|| ExportError::InvalidData(format!("polygon {p} has no usable normal")))?;
        let first = u32::try_from(data.positions.len())
            .map_err(|_| ExportError::InvalidData("too many vertices".into()))?;
        for (k, vertex) in polygon.vertices.iter().enumerate() {
            let local = space.position(*vertex).to_array().map(|x| x as f32);
            if !local.iter().all(|x| x.is_finite()) {
                return Err(ExportError::InvalidData(format!(
                    "vertex {k} of polygon {p} does not fit in f32 in its node's space"
                )));
            }
            data.positions.push(local);
            data.normals.push(normal.to_array().map(|x| x as f32));
            data.texcoords.push(lightmap.texcoord(p, k));
            let uv = scene.uvs.get(p).and_then(Option::as_ref);
            if let Some(colors) = data.colors.as_mut() {
                let c = uv.and_then(|uv| uv.color_at(*vertex)).ok_or_else(|| {
                    ExportError::InvalidData(format!("polygon {p} has no COLOR_0"))
                })?;
                colors.push(c.to_array().map(|x| x.clamp(0.0, 1.0) as f32));
            }
            for (set, out) in [(0, &mut data.input_uv0), (1, &mut data.input_uv1)] {
                if let Some(out) = out.as_mut() {
                    let value = uv.and_then(|uv| uv.at(set, *vertex)).ok_or_else(|| {
                        ExportError::InvalidData(format!("polygon {p} has no TEXCOORD_{set}"))
                    })?;
                    let value = [value.x as f32, value.y as f32];
                    if !value.iter().all(|x| x.is_finite()) {
                        return Err(ExportError::NonFinite {
                            what: format!("TEXCOORD_{set} {value:?} of polygon {p}"),
                        });
                    }
                    out.push(value);
                }
            }
        }
        if let (Some(tangents), Some(set)) = (data.tangents.as_mut(), needs.normal_set) {
            let uv = scene.uvs.get(p).and_then(Option::as_ref);
            let corner = |k: usize| polygon.vertices[k];
            let uvs = [0, 1, 2].map(|k| {
                uv.and_then(|uv| uv.at(set as usize, corner(k)))
                    .unwrap_or_default()
            });
            let local = [0, 1, 2].map(|k| space.position(corner(k)));
            let t = polygon_tangent(local, uvs, normal).map(|x| x as f32);
            if !t.iter().all(|x| x.is_finite()) {
                return Err(ExportError::NonFinite {
                    what: format!("the tangent of polygon {p}"),
                });
            }
            tangents.extend(std::iter::repeat_n(t, polygon.vertices.len()));
        }
        for k in 1..polygon.vertices.len() as u32 - 1 {
            let (a, b, c) = (first, first + k, first + k + 1);
            if space.mirrored {
                data.indices.extend([a, c, b]);
            } else {
                data.indices.extend([a, b, c]);
            }
        }
    }
    Ok(data)
}

fn add_primitive(
    writer: &mut DocumentWriter,
    data: &PrimitiveData,
    material: Index<json::Material>,
) -> json::mesh::Primitive {
    let mut attributes = BTreeMap::new();
    let position = writer.add_vec3(&data.positions, true);
    attributes.insert(Checked::Valid(Semantic::Positions), position);
    let normal = writer.add_vec3(&data.normals, false);
    attributes.insert(Checked::Valid(Semantic::Normals), normal);
    let uv1 = writer.add_vec2(&data.texcoords);
    // glTF numbers UV sets from 0 without gaps: the input's TEXCOORD_0 where its material is
    // textured, else the lightmap's own UVs again, makes TEXCOORD_1 valid.
    let uv0 = match &data.input_uv0 {
        Some(uv) => writer.add_vec2(uv),
        None => uv1,
    };
    attributes.insert(Checked::Valid(Semantic::TexCoords(0)), uv0);
    attributes.insert(Checked::Valid(Semantic::TexCoords(1)), uv1);
    if let Some(uv) = &data.input_uv1 {
        let uv2 = writer.add_vec2(uv);
        attributes.insert(Checked::Valid(Semantic::TexCoords(2)), uv2);
    }
    if let Some(colors) = &data.colors {
        let color = writer.add_vec3(colors, false);
        attributes.insert(Checked::Valid(Semantic::Colors(0)), color);
    }
    if let Some(tangents) = &data.tangents {
        let tangent = writer.add_vec4(tangents);
        attributes.insert(Checked::Valid(Semantic::Tangents), tangent);
    }
    let indices = writer.add_indices(&data.indices, data.positions.len());
    json::mesh::Primitive {
        attributes,
        extensions: None,
        extras: Default::default(),
        indices: Some(indices),
        material: Some(material),
        mode: Checked::Valid(Mode::Triangles),
        targets: None,
    }
}

/// World → one node's local space (the vertex exporter's rule).
struct NodeSpace {
    world_to_local: DMat4,
    normal_to_local: DMat3,
    mirrored: bool,
}

impl NodeSpace {
    fn new(world: &DMat4, node: usize) -> Result<Self, ExportError> {
        let determinant = world.determinant();
        if determinant == 0.0 || !determinant.is_finite() {
            return Err(ExportError::InvalidData(format!(
                "node {node} has a singular world transform"
            )));
        }
        Ok(NodeSpace {
            world_to_local: world.inverse(),
            normal_to_local: DMat3::from_mat4(*world).transpose(),
            mirrored: determinant < 0.0,
        })
    }

    fn position(&self, world: DVec3) -> DVec3 {
        self.world_to_local.transform_point3(world)
    }

    fn normal(&self, world: DVec3) -> Option<DVec3> {
        (self.normal_to_local * world).try_normalize()
    }
}

/// Stages every file in order; returns their targets.
pub(crate) fn stage_all(
    set: &mut OutputSet,
    files_to_write: &[(&Path, &[u8])],
) -> Result<Vec<PathBuf>, ExportError> {
    for (path, bytes) in files_to_write {
        set.stage(path, bytes)?;
    }
    Ok(files_to_write
        .iter()
        .map(|(p, _)| p.to_path_buf())
        .collect())
}
