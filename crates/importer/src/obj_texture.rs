//! OBJ `map_Kd`: the diffuse texture of an MTL material, treated as a glTF `baseColorTexture`
//! with the default sampler (linear, repeat) and no transform, on the OBJ's `vt` coordinates
//! (V flipped: OBJ's v = 0 is the image's bottom row, glTF's its top). Its image is decoded for
//! ρ and kept encoded, with a glTF form of the material, for the outputs.

use crate::texture::{decode_image, mime_type, AuthoredTexture, EncodedImage, Texture, TextureRef};
use crate::{ImportError, PolygonUv, Scene, UvTriangle, Wrap};
use glam::{DVec2, DVec3};
use std::path::Path;

/// Reads a file named in the OBJ or MTL: the name to show in messages, and its bytes.
type ReadFile<'a> = dyn Fn(&Path) -> (String, std::io::Result<Vec<u8>>) + 'a;

/// Attaches the `map_Kd` textures of the materials in use (`maps[m]` for MTL material m) to
/// `scene`: decoded textures, each textured polygon's UVs, and the authored materials. A
/// texture that cannot be read or decoded, or a textured mesh without `vt`, is an error.
pub(crate) fn attach(
    scene: &mut Scene,
    models: &[tobj::Model],
    maps: &[Option<String>],
    read: &ReadFile,
) -> Result<(), ImportError> {
    let meshes: Vec<&tobj::Mesh> = models
        .iter()
        .filter(|m| !m.mesh.indices.is_empty())
        .map(|m| &m.mesh)
        .collect();
    // Each material in use with a map, once, in order of first use.
    let mut used: Vec<usize> = Vec::new();
    for polygon in &scene.polygons {
        let m = polygon.material;
        if matches!(maps.get(m), Some(Some(_))) && !used.contains(&m) {
            used.push(m);
        }
    }
    for &m in &used {
        if let Some(Some(name)) = maps.get(m) {
            load_texture(name, read, m, scene)?;
        }
    }
    let uvs = scene
        .polygons
        .iter()
        .map(|polygon| {
            let Some(Some(name)) = maps.get(polygon.material) else {
                return Ok(None);
            };
            let mesh = meshes.get(polygon.origin.mesh).ok_or_else(|| {
                ImportError::Obj(format!("mesh {} lost its model", polygon.origin.mesh))
            })?;
            polygon_uv(mesh, polygon.origin.face, &polygon.vertices)
                .map(Some)
                .ok_or_else(|| ImportError::InvalidValue {
                    what: format!("mesh {}", polygon.origin.mesh),
                    problem: format!("its material has map_Kd {name:?} but the mesh has no vt"),
                })
        })
        .collect::<Result<Vec<_>, ImportError>>()?;
    for (slot, uv) in scene.uvs.iter_mut().zip(uvs) {
        if uv.is_some() {
            *slot = uv;
        }
    }
    Ok(())
}

/// Decodes `name` for material `m`, records it in `scene` (texture, image, authored forms) and
/// sets the material's `base_color_texture`.
fn load_texture(
    name: &str,
    read: &ReadFile,
    m: usize,
    scene: &mut Scene,
) -> Result<(), ImportError> {
    let what = format!("map_Kd {name:?}");
    let fail = |problem: String| ImportError::InvalidValue {
        what: what.clone(),
        problem,
    };
    let (shown, bytes) = read(Path::new(name));
    let bytes = bytes.map_err(|e| fail(format!("cannot read {shown}: {e}")))?;
    let mime_type = mime_type(&bytes, &shown).map_err(&fail)?;
    let image = decode_image(&bytes, 0).map_err(&fail)?;
    scene.images.push(image);
    scene.textures.push(Texture {
        name: what.clone(),
        image: scene.images.len() - 1,
        wrap: [Wrap::Repeat; 2],
        nearest: false,
    });
    let texture = scene.textures.len() - 1;
    let authored = &mut scene.authored;
    authored.images.push(EncodedImage {
        name: Some(name.to_owned()),
        mime_type,
        bytes,
    });
    authored.textures.push(AuthoredTexture {
        name: Some(name.to_owned()),
        sampler: None,
        image: authored.images.len() - 1,
    });
    let material = scene
        .materials
        .get_mut(m)
        .ok_or_else(|| ImportError::Obj(format!("material {m} does not exist")))?;
    material.base_color_texture = Some(TextureRef {
        texture,
        tex_coord: 0,
        transform: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    });
    // The glTF form: Kd as the factor, the texture, fully rough dielectric, Ke as emission.
    let peak = material.emission.iter().copied().fold(0.0, f64::max);
    let mut json = serde_json::json!({
        "pbrMetallicRoughness": {
            "baseColorFactor": [material.rho[0], material.rho[1], material.rho[2], 1.0],
            "baseColorTexture": { "index": authored.textures.len() - 1 },
            "metallicFactor": 0.0,
            "roughnessFactor": 1.0,
        },
    });
    if let Some(n) = &material.name {
        json["name"] = serde_json::json!(n);
    }
    if peak > 0.0 {
        let scale = peak.max(1.0);
        json["emissiveFactor"] = serde_json::json!(material.emission.map(|e| e / scale));
        if peak > 1.0 {
            json["extensions"] = serde_json::json!({
                "KHR_materials_emissive_strength": { "emissiveStrength": peak } });
        }
    }
    if authored.materials.len() <= m {
        authored.materials.resize(m + 1, None);
    }
    authored.materials[m] = Some(json);
    Ok(())
}

/// The UVs of OBJ face `face` of `mesh` over the polygon `vertices` (a piece of that face):
/// each vertex's `vt` found by its exact position among the face's vertices, the polygon fanned
/// into triangles (0 1 2), (0 2 3). `None` when the mesh has no `vt`.
fn polygon_uv(mesh: &tobj::Mesh, face: usize, vertices: &[DVec3]) -> Option<PolygonUv> {
    if mesh.texcoords.is_empty() {
        return None;
    }
    let arity = |f: usize| -> usize {
        if mesh.face_arities.is_empty() {
            3
        } else {
            mesh.face_arities.get(f).map_or(0, |&n| n as usize)
        }
    };
    let start: usize = (0..face).map(arity).sum();
    let indices = mesh.indices.get(start..start + arity(face))?;
    let position = |i: u32| -> Option<DVec3> {
        let p = mesh.positions.get(i as usize * 3..i as usize * 3 + 3)?;
        Some(DVec3::new(p[0], p[1], p[2]))
    };
    let texcoord = |i: u32| -> Option<DVec2> {
        let t = mesh.texcoords.get(i as usize * 2..i as usize * 2 + 2)?;
        Some(DVec2::new(t[0], 1.0 - t[1]))
    };
    let uvs: Vec<DVec2> = vertices
        .iter()
        .map(|v| {
            indices
                .iter()
                .find(|&&i| position(i) == Some(*v))
                .and_then(|&i| texcoord(i))
        })
        .collect::<Option<_>>()?;
    let triangles = (1..vertices.len().saturating_sub(1))
        .map(|k| UvTriangle {
            positions: [vertices[0], vertices[k], vertices[k + 1]],
            uv: [[uvs[0], uvs[k], uvs[k + 1]], [DVec2::ZERO; 3]],
            color: None,
        })
        .collect();
    Some(PolygonUv {
        triangles,
        sets: [true, false],
    })
}
