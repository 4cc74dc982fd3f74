//! glTF 2.0 input (`.gltf` with embedded or external buffers, `.glb`).
//!
//! The document is parsed and validated by the `gltf` crate; buffers are loaded with
//! `gltf::import_buffers` (textures are never decoded). Geometry is read with the
//! bounds-checked readers of [`crate::accessor`].

use crate::accessor;
use crate::files::Files;
use crate::polygon::{self, Instance, SourceFace};
use crate::{
    check_material, describe, ImportError, ImportStats, Layout, Light, LightKind, Material, Mesh,
    Node, Origin, Primitive, Scene, SceneRoots, Side, Transform,
};
use glam::{DMat4, DQuat, DVec3};
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;
use gltf::json::Root;
use std::collections::hash_map::{Entry, HashMap};
use std::path::Path;

/// Reads a `.gltf` or `.glb` file (told apart by the GLB magic, not the extension);
/// external buffers are read from the file's directory.
pub(crate) fn load(path: &Path, files: &Files) -> Result<Scene, ImportError> {
    let bytes = files.read_scene(path)?;
    load_bytes(&bytes, Some(files))
}

/// Reads glTF JSON or a GLB container from memory. With `files`, relative buffer URIs are
/// files in the scene's folder; without it only embedded buffers (data URIs, the GLB's BIN
/// chunk) can be read and an external one is an error.
pub(crate) fn load_bytes(bytes: &[u8], files: Option<&Files>) -> Result<Scene, ImportError> {
    let (json, blob) = split_container(bytes)?;
    let root: Root = gltf::json::deserialize::from_slice(json)
        .map_err(|e| ImportError::Gltf(one_line(&e.to_string())))?;
    check_position_indices(&root)?;
    validate(&root)?;
    crate::memory::check_zero_filled(&root, crate::memory::available())?;
    let document = gltf::Document::from_json_without_validation(root);
    check_buffer_uris(&document)?;
    let mut buffers = read_buffers(&document, files, blob.map(<[u8]>::to_vec))?;
    // Compressed views and primitives become plain ones before any accessor is read.
    let mut root = document.into_json();
    crate::compressed::decode(&mut root, &mut buffers)
        .map_err(|e| ImportError::Gltf(one_line(&e)))?;
    let document = gltf::Document::from_json_without_validation(root);
    build_scene(&document, &buffers, files)
}

/// `gltf::import_buffers`, except that external files are read through `files` (regular
/// files only, size-capped, inside the scene's folder unless allowed) and an unreadable one
/// is named.
fn read_buffers(
    document: &gltf::Document,
    files: Option<&Files>,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<gltf::buffer::Data>, ImportError> {
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let index = buffer.index();
        let source = buffer.source();
        let external = match source {
            gltf::buffer::Source::Uri(uri) if uri.starts_with("file:") => Some(Err(uri)),
            gltf::buffer::Source::Uri(uri) if !uri.contains(':') => Some(Ok(uri)),
            _ => None,
        };
        let data = match (external, files) {
            // EXT_meshopt_compression: a fallback buffer has no data to read.
            _ if document
                .as_json()
                .buffers
                .get(index)
                .is_some_and(crate::meshopt::is_fallback) =>
            {
                buffers.push(gltf::buffer::Data(Vec::new()));
                continue;
            }
            (None, _) => {
                let named = match &source {
                    gltf::buffer::Source::Uri(uri) => format!(" (URI {})", short_uri(uri)),
                    gltf::buffer::Source::Bin => " (the GLB's BIN chunk)".into(),
                };
                gltf::buffer::Data::from_source_and_blob(source, None, &mut blob).map_err(|e| {
                    let ImportError::Gltf(text) = gltf_error(&e) else {
                        return gltf_error(&e);
                    };
                    ImportError::Gltf(format!("buffer {index}{named}: {text}"))
                })?
            }
            (Some(_), None) => {
                return Err(ImportError::Gltf(
                    "a buffer refers to an external file, which cannot be read without a \
                     directory"
                        .into(),
                ))
            }
            (Some(reference), Some(files)) => {
                let path = match reference {
                    Ok(relative) => files.resolve(&percent_decoded_path(relative)),
                    Err(uri) => files.file_uri(uri),
                }
                .map_err(|e| ImportError::Refused(format!("buffer {index}: {e}")))?;
                let mut bytes = files.read(&path).map_err(|e| {
                    ImportError::Gltf(format!(
                        "buffer {index}: cannot read {}: {e}",
                        path.display()
                    ))
                })?;
                bytes.resize(bytes.len().next_multiple_of(4), 0);
                gltf::buffer::Data(bytes)
            }
        };
        if data.len() < buffer.length() {
            return Err(ImportError::Gltf(format!(
                "buffer {index}: {} bytes, shorter than its byteLength {}",
                data.len(),
                buffer.length()
            )));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// A URI as an error line shows it: quoted, and cut after 60 characters (a data URI can
/// be megabytes long).
fn short_uri(uri: &str) -> String {
    const SHOWN: usize = 60;
    match uri.char_indices().nth(SHOWN) {
        Some((cut, _)) => format!("{:?}… ({} bytes)", &uri[..cut], uri.len()),
        None => format!("{uri:?}"),
    }
}

/// Splits a GLB container (glTF 2.0, "GLB File Format": 12-byte header, JSON chunk,
/// optional BIN chunk) into its JSON and binary parts; any other input is the JSON itself.
fn split_container(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), ImportError> {
    if !bytes.starts_with(b"glTF") {
        // A UTF-8 byte-order mark before the JSON (some Windows editors write one): the
        // glTF spec forbids it, but what follows is the document.
        return Ok((bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes), None));
    }
    let bad = |what: &str| ImportError::Gltf(format!("malformed GLB container: {what}"));
    let word = |at: usize| -> Option<u32> {
        let b = bytes.get(at..at.checked_add(4)?)?;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let version = word(4).ok_or_else(|| bad("truncated header"))?;
    if version != 2 {
        return Err(bad(&format!("version {version}, expected 2")));
    }
    let length = word(8).ok_or_else(|| bad("truncated header"))? as usize;
    let bytes = bytes
        .get(..length)
        .ok_or_else(|| bad("header length exceeds the file"))?;
    let chunk = |at: usize| -> Option<(u32, &[u8], usize)> {
        let len = bytes.get(at..at + 4)?;
        let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]) as usize;
        let kind = bytes.get(at + 4..at + 8)?;
        let kind = u32::from_le_bytes([kind[0], kind[1], kind[2], kind[3]]);
        let start = at + 8;
        let end = start.checked_add(len)?;
        Some((kind, bytes.get(start..end)?, end))
    };
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    let (kind, json, next) = chunk(12).ok_or_else(|| bad("truncated JSON chunk"))?;
    if kind != JSON {
        return Err(bad("the first chunk is not JSON"));
    }
    if json.is_empty() {
        return Err(bad("the JSON chunk is empty (its length is 0)"));
    }
    let bin = if next >= bytes.len() {
        None
    } else {
        match chunk(next) {
            Some((BIN, data, _)) => Some(data),
            Some(_) => None, // an unknown chunk type is ignored (glTF 2.0, "Chunks")
            None => return Err(bad("truncated BIN chunk")),
        }
    };
    Ok((json, bin))
}

/// The `gltf` crate's validation, less two kinds of error that do not make a file
/// unusable here: an accessor without a buffer view or sparse values (valid glTF 2.0:
/// "the accessor MUST be initialized with zeros"), and anything inside the objects the
/// importer never reads (textures, images, samplers, animations, skins, cameras).
fn validate(root: &Root) -> Result<(), ImportError> {
    use gltf::json::validation::Validate;
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        let path = path();
        if !tolerated(path.as_str(), error) {
            errors.push((path, error));
        }
    });
    if errors.is_empty() {
        Ok(())
    } else {
        Err(gltf_error(&gltf::Error::Validation(errors)))
    }
}

/// See [`validate`].
fn tolerated(path: &str, error: gltf::json::validation::Error) -> bool {
    const UNREAD: [&str; 6] = [
        "textures[",
        "images[",
        "samplers[",
        "animations[",
        "skins[",
        "cameras[",
    ];
    let zero_accessor = error == gltf::json::validation::Error::Missing
        && path.starts_with("accessors[")
        && path.ends_with("].bufferView");
    zero_accessor
        || UNREAD.iter().any(|object| path.starts_with(object))
        || crate::compressed::handled_requirement(path, error)
}

/// One line for a `gltf` error (validation errors list the first and count the rest).
fn gltf_error(e: &gltf::Error) -> ImportError {
    let text = match e {
        gltf::Error::Validation(errors) => match errors.first() {
            Some((path, error)) if errors.len() > 1 => format!(
                "{path}: {error} (and {} more validation errors)",
                errors.len() - 1
            ),
            Some((path, error)) => format!("{path}: {error}"),
            None => "validation failed".into(),
        },
        other => other.to_string(),
    };
    ImportError::Gltf(one_line(&text))
}

fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// `gltf-json`'s validation indexes the accessor list with each POSITION index unchecked:
/// refuse a dangling one before validating.
fn check_position_indices(root: &Root) -> Result<(), ImportError> {
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = primitive
                .attributes
                .get(&Checked::Valid(Semantic::Positions));
            if let Some(index) = position.filter(|i| i.value() >= root.accessors.len()) {
                return Err(ImportError::Gltf(format!(
                    "meshes[{m}].primitives[{p}]: POSITION accessor {} does not exist",
                    index.value()
                )));
            }
        }
    }
    Ok(())
}

/// `gltf::import_buffers` percent-decodes relative URIs with an `unwrap`: refuse those that
/// do not decode to UTF-8 before calling it.
fn check_buffer_uris(document: &gltf::Document) -> Result<(), ImportError> {
    for buffer in document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source() {
            if !uri.contains(':') && String::from_utf8(percent_decode(uri)).is_err() {
                return Err(ImportError::Gltf(format!(
                    "buffer {}: URI {uri:?} is not valid percent-encoded UTF-8",
                    buffer.index()
                )));
            }
        }
    }
    Ok(())
}

/// A relative URI's file name, percent-decoded.
pub(crate) fn percent_decoded_path(uri: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(String::from_utf8_lossy(&percent_decode(uri)).into_owned())
}

/// RFC 3986 percent-decoding; malformed escapes are kept literally.
fn percent_decode(text: &str) -> Vec<u8> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = bytes
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (bytes[i], hex) {
            (b'%', Some(byte)) => {
                out.push(byte);
                i += 3;
            }
            (b, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    out
}

/// The glTF default material (glTF 2.0, "Default Material"): white, not emissive,
/// single-sided.
fn default_material() -> Material {
    Material {
        name: None,
        rho: [1.0; 3],
        emission: [0.0; 3],
        double_sided: false,
        base_color_texture: None,
        emissive_texture: None,
        transmission: 0.0,
    }
}

/// Layout, materials and polygons of a validated document.
fn build_scene(
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    files: Option<&Files>,
) -> Result<Scene, ImportError> {
    let root = document.as_json();
    let nodes = read_nodes(root)?;
    let (mut materials, material_of) = read_materials(document);
    let mut layout = Layout {
        nodes,
        meshes: read_meshes(root, &material_of),
        scenes: read_scenes(root),
        scene: root.scene.map(|s| s.value()),
    };
    let baked_nodes = nodes_to_bake(root, &layout)?;

    if uses_default(root) {
        materials.push(default_material());
    }
    let mut stats = ImportStats::default();
    let mut warnings = Vec::new();
    let lights = read_lights(root, &layout, &baked_nodes, &mut warnings);
    let probe_points = read_probe_points(root, &layout, &baked_nodes, &mut warnings);
    let mut cache: HashMap<(usize, usize), Option<LocalPrimitive>> = HashMap::new();
    let mut checked = vec![false; materials.len()];
    let mut instances = Vec::new();
    let mut face_count = 0;
    for &node_index in &baked_nodes {
        let node = &layout.nodes[node_index];
        let Some(mesh_index) = node.mesh else {
            continue;
        };
        let mesh = root.meshes.get(mesh_index).ok_or_else(|| {
            ImportError::Gltf(format!(
                "node {node_index}: mesh {mesh_index} does not exist"
            ))
        })?;
        let mesh_name = describe("mesh", mesh.name.as_deref(), mesh_index);
        let node_name = describe("node", node.name.as_deref(), node_index);
        if !placeable(node, &node_name, &mut warnings)? {
            continue;
        }
        // Skinning and morph targets move vertices at run time; the bake has one pose.
        let skinned = root.nodes.get(node_index).is_some_and(|n| n.skin.is_some());
        let morphed = mesh.primitives.iter().any(|p| p.targets.is_some());
        if skinned || morphed {
            warnings.push(format!(
                "{mesh_name} in {node_name} is {}: baked in its bind pose (the light will not \
                 follow the animation)",
                match (skinned, morphed) {
                    (true, true) => "skinned and has morph targets",
                    (true, false) => "skinned",
                    _ => "morphed (morph targets)",
                }
            ));
        }
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let label = format!("{mesh_name}, primitive {p}");
            let key = (mesh_index, p);
            let local = match cache.entry(key) {
                Entry::Occupied(entry) => entry.into_mut(),
                Entry::Vacant(entry) => entry.insert(read_primitive(
                    root,
                    buffers,
                    primitive,
                    &label,
                    &mut stats,
                    &mut warnings,
                )?),
            };
            let Some(local) = local.as_ref() else {
                continue;
            };
            polygon::count_faces(&mut face_count, local.triangles.len())?;
            let material_index = material_of(primitive.material.map(|m| m.value()));
            let material = materials.get(material_index).ok_or_else(|| {
                ImportError::Gltf(format!("{label}: material {material_index} does not exist"))
            })?;
            if !std::mem::replace(&mut checked[material_index], true) {
                let name = describe("material", material.name.as_deref(), material_index);
                check_material(material, &format!("{name} used by {label}"))?;
                // Blending and transmission are baked as a transmission factor
                // (`transmission`); a texture's share of them is not read.
                if let Some(json) = root.materials.get(material_index) {
                    let blend =
                        json.alpha_mode == Checked::Valid(gltf::json::material::AlphaMode::Blend);
                    let textured = json.pbr_metallic_roughness.base_color_texture.is_some();
                    if blend && textured {
                        warnings.push(format!(
                            "{name}: alphaMode BLEND transmits 1 − the baseColorFactor alpha; the base colour texture's alpha is not read"
                        ));
                    }
                    let texture = json
                        .extensions
                        .as_ref()
                        .and_then(|e| e.transmission.as_ref())
                        .is_some_and(|t| t.transmission_texture.is_some());
                    if texture {
                        warnings.push(format!(
                            "{name}: KHR_materials_transmission's transmissionTexture is not read (transmissionFactor {} is used everywhere)",
                            material.transmission
                        ));
                    }
                }
            }
            instances.push(Instance {
                label,
                place: format!(" in {node_name}"),
                origin: Origin {
                    node: node_index,
                    mesh: mesh_index,
                    primitive: p,
                    face: 0,
                    side: Side::Front,
                },
                material: material_index,
                double_sided: material.double_sided,
                faces: local.place(node.world),
            });
        }
    }

    let polygons = polygon::bake(&instances, &mut stats, &mut warnings)?;
    for p in &polygons {
        if let Some(primitive) = layout
            .meshes
            .get_mut(p.origin.mesh)
            .and_then(|m| m.primitives.get_mut(p.origin.primitive))
        {
            primitive.baked = true;
        }
    }
    if polygons.is_empty() {
        return Err(ImportError::Empty);
    }
    let mut loaded = crate::texture::load(root, buffers, files, &mut materials, &checked)?;
    warnings.extend(std::mem::take(&mut loaded.warnings));
    let alpha_masks = alpha_masks(root, &mut materials, &mut loaded);
    let uvs = polygon_uvs(&polygons, &materials, &loaded.authored, &layout, &cache)?;
    Ok(Scene {
        polygons,
        materials,
        lights,
        probe_points,
        textures: loaded.textures,
        images: loaded.images,
        uvs,
        authored: loaded.authored,
        alpha_masks,
        layout,
        stats,
        warnings,
        input_files: Vec::new(),
    })
}

/// Per polygon whose material has a texture (decoded for ρ/e, or kept for the outputs) or
/// whose primitive has COLOR_0 or TEXCOORD_1: the source triangles it was made of, in world space, with
/// their texture coordinates (every set the primitive has) and colours. A glTF polygon is source triangle `face`, or the quad merged from
/// `face` and `face + 1`.
fn polygon_uvs(
    polygons: &[crate::Polygon],
    materials: &[Material],
    authored: &crate::Authored,
    layout: &Layout,
    cache: &HashMap<(usize, usize), Option<LocalPrimitive>>,
) -> Result<Vec<Option<crate::PolygonUv>>, ImportError> {
    polygons
        .iter()
        .map(|p| {
            let material = &materials[p.material];
            let sets: Vec<u32> = [&material.base_color_texture, &material.emissive_texture]
                .iter()
                .filter_map(|t| t.as_ref().map(|t| t.tex_coord))
                .collect();
            let kept = authored
                .materials
                .get(p.material)
                .and_then(Option::as_ref)
                .map_or([false; 2], crate::texture::authored_sets);
            let o = p.origin;
            let local = cache
                .get(&(o.mesh, o.primitive))
                .and_then(Option::as_ref)
                .ok_or_else(|| ImportError::Gltf(format!("mesh {} lost its primitive", o.mesh)))?;
            let present = [0, 1].map(|set| local.uvs.get(set).is_some_and(Option::is_some));
            // A TEXCOORD_1 may be the authored lightmap layout (`--lightmap-uv`): kept for
            // every polygon whose primitive has one.
            if sets.is_empty() && kept == [false; 2] && local.colors.is_none() && !present[1] {
                return Ok(None);
            }
            let world = layout.nodes[o.node].world;
            let count = if p.vertices.len() == 4 { 2 } else { 1 };
            let mut triangles = Vec::with_capacity(count);
            for f in o.face..o.face + count {
                let Some(t) = local.triangles.get(f) else {
                    break;
                };
                let positions = t.map(|i| world.transform_point3(local.positions[i as usize]));
                let mut uv = [[glam::DVec2::ZERO; 3]; 2];
                for &set in &sets {
                    let values = local
                        .uvs
                        .get(set as usize)
                        .and_then(Option::as_ref)
                        .ok_or_else(|| ImportError::InvalidValue {
                            what: format!("mesh {} primitive {}", o.mesh, o.primitive),
                            problem: format!(
                                "its material is textured but TEXCOORD_{set} is missing or unreadable"
                            ),
                        })?;
                    uv[set as usize] = t.map(|i| values[i as usize]);
                }
                for set in 0..2 {
                    if let (true, Some(values)) = (present[set], &local.uvs[set]) {
                        uv[set] = t.map(|i| values[i as usize]);
                    }
                }
                let color = local
                    .colors
                    .as_ref()
                    .map(|c| t.map(|i| c[i as usize]));
                triangles.push(crate::UvTriangle {
                    positions,
                    uv,
                    color,
                });
            }
            Ok(Some(crate::PolygonUv {
                triangles,
                sets: present,
            }))
        })
        .collect()
}

/// Per material: its alpha cut-out (`alphaMode` `MASK`). A masked material's decoded
/// base-colour image is replaced by a copy that is 0 where factor × alpha < cutoff, so an
/// element's ρ averages only its opaque texels, weighted by their coverage; the copy keeps
/// the alpha for the visibility test.
fn alpha_masks(
    root: &Root,
    materials: &mut [Material],
    loaded: &mut crate::texture::Loaded,
) -> Vec<Option<crate::AlphaMask>> {
    let mut masks = vec![None; materials.len()];
    for (k, material) in materials.iter_mut().enumerate() {
        let Some(json) = root.materials.get(k) else {
            continue;
        };
        if json.alpha_mode != Checked::Valid(gltf::json::material::AlphaMode::Mask) {
            continue;
        }
        let mask = crate::AlphaMask {
            cutoff: f64::from(json.alpha_cutoff.map_or(0.5, |c| c.0)),
            factor: f64::from(json.pbr_metallic_roughness.base_color_factor.0[3]),
        };
        masks[k] = Some(mask);
        let Some(reference) = material.base_color_texture.as_mut() else {
            if mask.factor < mask.cutoff {
                // Cut out everywhere: reflects nothing (and blocks nothing).
                material.rho = [0.0; 3];
            }
            continue;
        };
        let Some(texture) = loaded.textures.get(reference.texture).cloned() else {
            continue;
        };
        let Some(image) = loaded.images.get(texture.image) else {
            continue;
        };
        let mut masked = image.clone();
        for (k, t) in masked.texels.iter_mut().enumerate() {
            let alpha = f64::from(masked.alpha.get(k).copied().unwrap_or(1.0)) * mask.factor;
            if alpha < mask.cutoff {
                *t = [0.0; 3];
            }
        }
        loaded.images.push(masked);
        loaded.textures.push(crate::Texture {
            image: loaded.images.len() - 1,
            ..texture
        });
        reference.texture = loaded.textures.len() - 1;
    }
    masks
}

/// Whether a node's mesh can be baked in place. A singular world matrix (a scale of 0
/// on some axis) flattens the mesh: what is left cannot be written back in the node's
/// local space, so the node is skipped with a warning. A non-finite one is an error.
fn placeable(node: &Node, name: &str, warnings: &mut Vec<String>) -> Result<bool, ImportError> {
    let determinant = node.world.determinant();
    if !determinant.is_finite() {
        return Err(ImportError::InvalidValue {
            what: name.to_owned(),
            problem: "world transform is not finite".into(),
        });
    }
    if determinant == 0.0 {
        warnings.push(format!(
            "{name}: skipped (its world transform is singular: a scale of 0 flattens it)"
        ));
        return Ok(false);
    }
    Ok(true)
}

/// The `KHR_lights_punctual` lights of the baked nodes, in world space. A light that cannot
/// be used is skipped with a warning (never silently): see [`crate::load`].
fn read_lights(
    root: &Root,
    layout: &Layout,
    baked: &[usize],
    warnings: &mut Vec<String>,
) -> Vec<Light> {
    use gltf::json::extensions::scene::khr_lights_punctual as khr;
    let definitions: &[khr::Light] = root.as_ref();
    let mut lights = Vec::new();
    for &n in baked {
        let Some(index) = root
            .nodes
            .get(n)
            .and_then(|json| json.extensions.as_ref())
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .map(|l| l.light.value())
        else {
            continue;
        };
        let node = &layout.nodes[n];
        let node_name = describe("node", node.name.as_deref(), n);
        let Some(light) = definitions.get(index) else {
            warnings.push(format!(
                "{node_name}: light {index} does not exist; no light used"
            ));
            continue;
        };
        let name = describe("light", light.name.as_deref(), index);
        match place_light(light, node) {
            Ok((kind, position, direction)) => lights.push(Light {
                name: light.name.clone(),
                node: n,
                kind,
                position,
                direction,
                color: light.color.map(f64::from),
                intensity: f64::from(light.intensity),
                range: light.range.map(f64::from),
            }),
            Err(why) => warnings.push(format!("{name} on {node_name}: skipped ({why})")),
        }
    }
    lights
}

/// The world origins of the baked nodes whose `extras` hold `"bake_probe": true` (marked
/// light probes, docs/probes.md), in the order `baked` walks them (depth first from the
/// scene's roots). Extras that are not JSON objects, or whose
/// `bake_probe` is anything but `true`, mark nothing; a marked node whose world origin is not
/// finite is skipped with a warning.
fn read_probe_points(
    root: &Root,
    layout: &Layout,
    baked: &[usize],
    warnings: &mut Vec<String>,
) -> Vec<DVec3> {
    let mut points = Vec::new();
    for &n in baked {
        let Some(extras) = root.nodes.get(n).and_then(|json| json.extras.as_ref()) else {
            continue;
        };
        let marked = serde_json::from_str::<serde_json::Value>(extras.get())
            .ok()
            .and_then(|v| v.get("bake_probe").and_then(serde_json::Value::as_bool))
            == Some(true);
        if !marked {
            continue;
        }
        let node = &layout.nodes[n];
        let position = node.world.transform_point3(DVec3::ZERO);
        if position.is_finite() {
            points.push(position);
        } else {
            let name = describe("node", node.name.as_deref(), n);
            warnings.push(format!(
                "{name}: probe skipped (its world origin is not finite)"
            ));
        }
    }
    points
}

/// A light's kind and world placement, or why it cannot be used.
fn place_light(
    light: &gltf::json::extensions::scene::khr_lights_punctual::Light,
    node: &Node,
) -> Result<(LightKind, DVec3, DVec3), String> {
    use gltf::json::extensions::scene::khr_lights_punctual::Type;
    if !(light.intensity.is_finite() && light.intensity >= 0.0) {
        return Err(format!(
            "intensity {} is not a finite value ≥ 0",
            light.intensity
        ));
    }
    if !light.color.iter().all(|c| c.is_finite() && *c >= 0.0) {
        return Err(format!("colour {:?} is not finite and ≥ 0", light.color));
    }
    if let Some(range) = light.range {
        if !(range.is_finite() && range > 0.0) {
            return Err(format!("range {range} is not a finite value > 0"));
        }
    }
    let determinant = node.world.determinant();
    if !determinant.is_finite() || determinant == 0.0 {
        return Err("its node's world transform is singular or not finite".into());
    }
    let position = node.world.transform_point3(DVec3::ZERO);
    // The extension: lights shine along the node's local −Z.
    let direction = node
        .world
        .transform_vector3(DVec3::NEG_Z)
        .normalize_or_zero();
    if direction == DVec3::ZERO || !position.is_finite() {
        return Err("its node's world transform gives no direction".into());
    }
    let kind = match &light.type_ {
        Checked::Valid(Type::Point) => LightKind::Point,
        Checked::Valid(Type::Directional) => LightKind::Directional,
        Checked::Valid(Type::Spot) => {
            let spot = light.spot.clone().unwrap_or_default();
            let (inner, outer) = (
                f64::from(spot.inner_cone_angle),
                f64::from(spot.outer_cone_angle),
            );
            // π/2 written as f32 is 4e-8 above the f64 value: allow that much.
            let quarter_turn = std::f64::consts::FRAC_PI_2;
            if !(0.0 <= inner && inner <= outer && outer > 0.0 && outer <= quarter_turn + 1e-6) {
                return Err(format!(
                    "spot cone angles inner {inner} and outer {outer} are not 0 ≤ inner ≤ outer ≤ π/2"
                ));
            }
            LightKind::Spot {
                inner: inner.min(quarter_turn),
                outer: outer.min(quarter_turn),
            }
        }
        Checked::Invalid => return Err("unknown light type".into()),
    };
    Ok((kind, position, direction))
}

/// True when some primitive has no material (and so uses the glTF default material).
fn uses_default(root: &Root) -> bool {
    root.meshes
        .iter()
        .flat_map(|m| &m.primitives)
        .any(|p| p.material.is_none())
}

/// All materials in glTF order, and the map from a primitive's material to its index
/// (a primitive without one gets the default material, appended after the others).
fn read_materials(document: &gltf::Document) -> (Vec<Material>, impl Fn(Option<usize>) -> usize) {
    let materials: Vec<Material> = document
        .materials()
        .map(|m| {
            let base = m.pbr_metallic_roughness().base_color_factor();
            let strength = f64::from(m.emissive_strength().unwrap_or(1.0));
            let emissive = m.emissive_factor();
            let transmission = transmission(&m, f64::from(base[3]));
            let authored = [base[0], base[1], base[2]].map(f64::from);
            Material {
                name: m.name().map(str::to_owned),
                rho: crate::reflected(authored, transmission),
                // `+ 0.0` turns a 0 × negative strength (−0) into 0.
                emission: emissive.map(|e| f64::from(e) * strength + 0.0),
                double_sided: m.double_sided(),
                base_color_texture: None,
                emissive_texture: None,
                transmission,
            }
        })
        .collect();
    let count = materials.len();
    (materials, move |m: Option<usize>| m.unwrap_or(count))
}

/// A material's transmission t (`scene::Material::transmission`): the share a thin surface
/// passes straight through, `1 − (1 − T) α`, T = `KHR_materials_transmission`'s
/// `transmissionFactor` (its `transmissionTexture` is not read: the importer warns) and α the
/// `baseColorFactor` alpha under `alphaMode` `BLEND` (the uncovered share passes). A value
/// outside [0, 1] is refused by `check_material`.
fn transmission(m: &gltf::Material, alpha: f64) -> f64 {
    let factor = m
        .transmission()
        .map_or(0.0, |t| f64::from(t.transmission_factor()));
    let coverage = if m.alpha_mode() == gltf::material::AlphaMode::Blend {
        alpha
    } else {
        1.0
    };
    // `+ 0.0`: an opaque surface's 1 − 1 is +0. A factor or alpha outside [0, 1] gives a t
    // outside it (or NaN), which `check_material` refuses.
    1.0 - (1.0 - factor) * coverage + 0.0
}

/// Every mesh, with each primitive's material; `baked` is set once polygons exist.
fn read_meshes(root: &Root, material_of: &impl Fn(Option<usize>) -> usize) -> Vec<Mesh> {
    root.meshes
        .iter()
        .map(|mesh| Mesh {
            name: mesh.name.clone(),
            primitives: mesh
                .primitives
                .iter()
                .map(|p| Primitive {
                    material: material_of(p.material.map(|m| m.value())),
                    baked: false,
                })
                .collect(),
        })
        .collect()
}

fn read_scenes(root: &Root) -> Vec<SceneRoots> {
    root.scenes
        .iter()
        .map(|s| SceneRoots {
            name: s.name.clone(),
            nodes: s.nodes.iter().map(|n| n.value()).collect(),
        })
        .collect()
}

/// Every node with its local transform as written, and its world matrix composed
/// parent-to-child in f64. A node with two parents or a cycle is an error.
fn read_nodes(root: &Root) -> Result<Vec<Node>, ImportError> {
    let count = root.nodes.len();
    let mut parent: Vec<Option<usize>> = vec![None; count];
    let mut nodes = Vec::with_capacity(count);
    for (i, json) in root.nodes.iter().enumerate() {
        let children: Vec<usize> = json.children.iter().flatten().map(|c| c.value()).collect();
        for &child in &children {
            let slot = parent.get_mut(child).ok_or_else(|| {
                ImportError::Gltf(format!("node {i}: child {child} does not exist"))
            })?;
            if let Some(first) = slot.replace(i) {
                return Err(ImportError::Gltf(format!(
                    "node {child} has two parents (nodes {first} and {i})"
                )));
            }
        }
        nodes.push(Node {
            name: json.name.clone(),
            transform: local_transform(json),
            children,
            mesh: json.mesh.map(|m| m.value()),
            world: DMat4::IDENTITY,
        });
    }
    compose_worlds(&mut nodes, &parent)?;
    Ok(nodes)
}

/// A node's transform exactly as written (TRS defaults filled in).
fn local_transform(json: &gltf::json::Node) -> Transform {
    match json.matrix {
        Some(m) => Transform::Matrix(m),
        None => Transform::Trs {
            translation: json.translation.unwrap_or([0.0; 3]),
            rotation: json.rotation.map_or([0.0, 0.0, 0.0, 1.0], |r| r.0),
            scale: json.scale.unwrap_or([1.0; 3]),
        },
    }
}

/// The local matrix in f64: the matrix itself, or T·R·S (glTF 2.0, "Transformations")
/// with the quaternion normalized.
fn local_matrix(index: usize, transform: &Transform) -> Result<DMat4, ImportError> {
    match transform {
        Transform::Matrix(m) => Ok(DMat4::from_cols_array(&m.map(f64::from))),
        Transform::Trs {
            translation,
            rotation,
            scale,
        } => {
            let [x, y, z, w] = rotation.map(f64::from);
            let q = DQuat::from_xyzw(x, y, z, w);
            let length = q.length();
            if !(length.is_finite() && length > 0.0) {
                return Err(ImportError::Gltf(format!(
                    "node {index}: rotation {rotation:?} is not a unit quaternion"
                )));
            }
            Ok(DMat4::from_scale_rotation_translation(
                DVec3::from(scale.map(f64::from)),
                q / length,
                DVec3::from(translation.map(f64::from)),
            ))
        }
    }
}

/// World = parent world × local, walking down from the roots with an explicit stack.
/// Every node has at most one parent here, so a node no root reaches is in a cycle.
fn compose_worlds(nodes: &mut [Node], parent: &[Option<usize>]) -> Result<(), ImportError> {
    let mut reached = vec![false; nodes.len()];
    let mut stack: Vec<(usize, DMat4)> = (0..nodes.len())
        .rev()
        .filter(|&i| parent[i].is_none())
        .map(|i| (i, DMat4::IDENTITY))
        .collect();
    while let Some((i, parent_world)) = stack.pop() {
        let world = parent_world * local_matrix(i, &nodes[i].transform)?;
        nodes[i].world = world;
        reached[i] = true;
        stack.extend(nodes[i].children.iter().rev().map(|&c| (c, world)));
    }
    match reached.iter().position(|&r| !r) {
        Some(i) => Err(ImportError::Gltf(format!(
            "node {i} is part of a cycle in the node hierarchy"
        ))),
        None => Ok(()),
    }
}

/// The nodes to bake, depth-first: those under the default scene, else scene 0, else
/// under every root node. A node listed twice is baked once.
fn nodes_to_bake(root: &Root, layout: &Layout) -> Result<Vec<usize>, ImportError> {
    let scene = layout.scene.or(if layout.scenes.is_empty() {
        None
    } else {
        Some(0)
    });
    let starts: Vec<usize> = match scene {
        Some(s) => layout
            .scenes
            .get(s)
            .ok_or_else(|| ImportError::Gltf(format!("scene {s} does not exist")))?
            .nodes
            .clone(),
        None => {
            let mut is_child = vec![false; root.nodes.len()];
            for node in &layout.nodes {
                for &c in &node.children {
                    if let Some(slot) = is_child.get_mut(c) {
                        *slot = true;
                    }
                }
            }
            (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
        }
    };
    let mut seen = vec![false; layout.nodes.len()];
    let mut order = Vec::new();
    let mut stack: Vec<usize> = starts.into_iter().rev().collect();
    while let Some(i) = stack.pop() {
        let Some(slot) = seen.get_mut(i) else {
            return Err(ImportError::Gltf(format!("node {i} does not exist")));
        };
        if std::mem::replace(slot, true) {
            continue;
        }
        order.push(i);
        stack.extend(layout.nodes[i].children.iter().rev());
    }
    Ok(order)
}

/// A primitive's triangles in its mesh's space (read once, placed per node).
struct LocalPrimitive {
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// TEXCOORD_0 and TEXCOORD_1, where present.
    uvs: Vec<Option<Vec<glam::DVec2>>>,
    /// COLOR_0 (linear RGB in [0, 1]), where present: it multiplies ρ.
    colors: Option<Vec<DVec3>>,
}

impl LocalPrimitive {
    /// The triangles in world space, counter-clockwise from the front: a mirroring world
    /// matrix (negative determinant) reverses the winding (glTF 2.0, "Transformations").
    fn place(&self, world: DMat4) -> Vec<SourceFace> {
        let positions: Vec<DVec3> = self
            .positions
            .iter()
            .map(|&p| world.transform_point3(p))
            .collect();
        let mirrored = world.determinant() < 0.0;
        self.triangles
            .iter()
            .enumerate()
            .map(|(face, t)| {
                let [a, b, c] = t.map(|i| positions[i as usize]);
                SourceFace {
                    face,
                    vertices: if mirrored {
                        vec![a, c, b]
                    } else {
                        vec![a, b, c]
                    },
                }
            })
            .collect()
    }
}

/// Reads one primitive's triangles, or `None` (with a warning) when it has nothing to
/// bake: points and lines, or no POSITION.
fn read_primitive(
    root: &Root,
    buffers: &[gltf::buffer::Data],
    primitive: &gltf::json::mesh::Primitive,
    label: &str,
    stats: &mut ImportStats,
    warnings: &mut Vec<String>,
) -> Result<Option<LocalPrimitive>, ImportError> {
    let fail = |e: String| ImportError::Gltf(format!("{label}: {e}"));
    let mode = match primitive.mode {
        Checked::Valid(mode) => mode,
        Checked::Invalid => return Err(fail("invalid primitive mode".into())),
    };
    if !matches!(
        mode,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        stats.primitives_skipped += 1;
        warnings.push(format!("{label}: skipped ({mode:?} are not surfaces)"));
        return Ok(None);
    }
    let Some(position) = primitive
        .attributes
        .get(&Checked::Valid(Semantic::Positions))
    else {
        warnings.push(format!("{label}: skipped (no POSITION attribute)"));
        return Ok(None);
    };
    let positions = accessor::read_vec3(root, buffers, position.value()).map_err(fail)?;
    let indices = match primitive.indices {
        Some(index) => accessor::read_indices(root, buffers, index.value()).map_err(fail)?,
        // Not indexed: the vertices in order (count ≤ accessor::MAX_COUNT).
        None => (0..positions.len() as u32).collect(),
    };
    // The message says where, not the value read: an index buffer that is not one (a file
    // of another kind) would otherwise show its bytes as a number.
    if let Some(k) = indices.iter().position(|&i| i as usize >= positions.len()) {
        return Err(fail(format!(
            "index {k} of the index list is out of range (the primitive has {} vertices)",
            positions.len()
        )));
    }
    // TEXCOORD_0 and _1 (for textures; a set that cannot be read is left out, and a texture
    // that needs it is then refused where it is used).
    let uvs = (0..2)
        .map(|set| {
            primitive
                .attributes
                .get(&Checked::Valid(Semantic::TexCoords(set)))
                .and_then(|a| accessor::read_vec2(root, buffers, a.value()).ok())
                .filter(|uv| uv.len() == positions.len())
        })
        .collect();
    // COLOR_0 multiplies the base colour (glTF 2.0, "Metallic-Roughness Material"), so it
    // is part of ρ: one that cannot be read, or lies outside [0, 1], is refused.
    let colors = match primitive
        .attributes
        .get(&Checked::Valid(Semantic::Colors(0)))
    {
        None => None,
        Some(a) => {
            let colors = accessor::read_colors(root, buffers, a.value())
                .map_err(|e| fail(format!("COLOR_0: {e}")))?;
            if colors.len() != positions.len() {
                return Err(fail(format!(
                    "COLOR_0 has {} values for {} positions",
                    colors.len(),
                    positions.len()
                )));
            }
            if let Some(bad) = colors
                .iter()
                .find(|c| !c.is_finite() || c.min_element() < 0.0 || c.max_element() > 1.0)
            {
                return Err(fail(format!("COLOR_0 value {bad} is outside [0, 1]")));
            }
            Some(colors)
        }
    };
    Ok(Some(LocalPrimitive {
        positions,
        triangles: triangles(mode, &indices),
        uvs,
        colors,
    }))
}

/// Triangles of a triangle list, strip or fan (glTF 2.0, "Topology Types"):
/// strip triangle i is (i, i+1, i+2) for even i and (i, i+2, i+1) for odd i;
/// fan triangle i is (i+1, i+2, 0).
fn triangles(mode: Mode, indices: &[u32]) -> Vec<[u32; 3]> {
    let strip_len = indices.len().saturating_sub(2);
    match mode {
        Mode::TriangleStrip => (0..strip_len)
            .map(|i| {
                let (a, b, c) = (indices[i], indices[i + 1], indices[i + 2]);
                if i % 2 == 0 {
                    [a, b, c]
                } else {
                    [a, c, b]
                }
            })
            .collect(),
        Mode::TriangleFan => (0..strip_len)
            .map(|i| [indices[i + 1], indices[i + 2], indices[0]])
            .collect(),
        _ => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    }
}
