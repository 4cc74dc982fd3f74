//! Reads a glTF/GLB file into world-space coloured triangles and the cameras its scene holds.

use crate::math::{self, Mat4, Vec3};
use crate::texture::{self, Texture};
use crate::PreviewError;
use gltf::mesh::Mode;
use gltf::mesh::Semantic;
use std::collections::HashMap;
use std::path::Path;

/// Where vertex colours come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ColorSource {
    /// `COLOR_0` (white where absent) × the material's base colour: what an unlit viewer
    /// shows.
    Color0,
    /// `clamp(_RADIOSITY × exposure, 0, 1)` × the material's base colour; primitives without
    /// `_RADIOSITY` use `clamp(COLOR_0 × exposure, 0, 1)`.
    Radiosity { exposure: f64 },
}

/// One vertex of a world-space triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vertex {
    pub position: Vec3,
    /// Linear RGB.
    pub color: Vec3,
    /// The base-colour texture's coordinates (0 when the triangle has no texture).
    pub uv: [f64; 2],
    /// The lightmap's coordinates (0 when the triangle has no lightmap).
    pub uv1: [f64; 2],
}

/// A triangle in world space. The front side is the counter-clockwise one (glTF's rule); the
/// loader has already reversed the triangles of nodes whose world matrix mirrors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub vertices: [Vertex; 3],
    /// Drawn from both sides (the material's `doubleSided`); otherwise back faces are culled.
    pub double_sided: bool,
    /// Index into [`Scene::textures`]: the base-colour texture that multiplies the colour.
    pub texture: Option<usize>,
    /// A lightmap bake: index into [`Scene::lightmaps`], whose irradiance H (at `uv1`)
    /// multiplies the colour (ρ × exposure), and the material's emission × exposure added to
    /// it: clamp((ρ H + e) × exposure, 0, 1), the radiosity b = e + ρ H exposed as the vertex
    /// bake's `COLOR_0` is.
    pub lightmap: Option<usize>,
    /// Linear RGB added under a lightmap (the material's emission × exposure).
    pub emissive: Vec3,
}

/// A lightmap atlas as a lit viewer reads `MOZ_lightmap`: H = texel × `intensity`.
#[derive(Clone, Debug, PartialEq)]
pub struct Lightmap {
    pub texture: Texture,
    pub intensity: f64,
}

/// A perspective camera placed by a node of the scene. It looks down the node's −Z axis with
/// +Y up (glTF's convention).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraNode {
    pub name: Option<String>,
    pub world: Mat4,
    /// Vertical field of view, radians.
    pub yfov: f64,
    pub znear: f64,
}

/// Everything the rasterizer draws.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    pub triangles: Vec<Triangle>,
    /// Perspective cameras of the scene, in node order (depth first from the scene's roots).
    pub cameras: Vec<CameraNode>,
    /// Primitives that are points or lines, not drawn.
    pub skipped_primitives: usize,
    /// Base-colour textures, one per material that has one.
    pub textures: Vec<Texture>,
    /// Lightmap atlases (`MOZ_lightmap`), one per material that has one.
    pub lightmaps: Vec<Lightmap>,
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min: Vec3,
    pub max: Vec3,
}

impl Scene {
    /// The bounding box of every triangle, or `None` when there is none.
    pub fn bounds(&self) -> Option<Bounds> {
        let mut points = self
            .triangles
            .iter()
            .flat_map(|t| t.vertices.iter().map(|v| v.position));
        let first = points.next()?;
        let mut bounds = Bounds {
            min: first,
            max: first,
        };
        for p in points {
            bounds.min = std::array::from_fn(|axis| bounds.min[axis].min(p[axis]));
            bounds.max = std::array::from_fn(|axis| bounds.max[axis].max(p[axis]));
        }
        Some(bounds)
    }
}

/// Loads the default scene of a `.gltf` or `.glb` file (the first scene when none is the
/// default). Base-colour textures are decoded (with their sampler and transform) and
/// multiply the vertex colours as a viewer's do.
pub fn load(path: &Path, source: ColorSource) -> Result<Scene, PreviewError> {
    let read_error = |source: gltf::Error| PreviewError::Read {
        path: path.to_path_buf(),
        source,
    };
    let gltf = gltf::Gltf::open(path).map_err(read_error)?;
    let base = path.parent().filter(|p| !p.as_os_str().is_empty());
    let buffers = gltf::import_buffers(&gltf.document, base.or(Some(Path::new("."))), gltf.blob)
        .map_err(read_error)?;
    let document = &gltf.document;
    let invalid = |message: String| PreviewError::Invalid {
        path: path.to_path_buf(),
        message,
    };
    let scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| invalid("the file has no scene".to_string()))?;

    let mut out = Scene::default();
    let mut textures = TextureCache {
        base: base.or(Some(Path::new("."))),
        of_material: HashMap::new(),
        lightmap_of_material: HashMap::new(),
        exposure: match source {
            ColorSource::Color0 => bake_exposure(document).unwrap_or(1.0),
            ColorSource::Radiosity { exposure } => exposure,
        },
    };
    let mut stack: Vec<(gltf::Node, Mat4)> = scene
        .nodes()
        .map(|n| (n, math::IDENTITY))
        .collect::<Vec<_>>();
    // Depth first, in the file's order: the stack pops the last pushed first.
    stack.reverse();
    // glTF's hierarchy is a strict tree: a node reached twice means a cycle or a shared child.
    let mut visited = vec![false; document.nodes().len()];
    while let Some((node, parent)) = stack.pop() {
        match visited.get_mut(node.index()) {
            Some(seen) if !*seen => *seen = true,
            _ => {
                return Err(invalid(format!(
                    "node {} appears twice in the scene's hierarchy (a cycle or a shared child)",
                    node.index()
                )))
            }
        }
        let local = node.transform().matrix().map(|c| c.map(f64::from));
        let world = math::multiply(&parent, &local);
        if let Some(camera) = node.camera() {
            if let gltf::camera::Projection::Perspective(p) = camera.projection() {
                out.cameras.push(CameraNode {
                    name: node.name().or(camera.name()).map(str::to_owned),
                    world,
                    yfov: f64::from(p.yfov()),
                    znear: f64::from(p.znear()),
                });
            }
        }
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                let what = || {
                    format!(
                        "mesh {} primitive {}",
                        mesh.name()
                            .map_or_else(|| mesh.index().to_string(), |n| format!("{n:?}")),
                        primitive.index()
                    )
                };
                add_primitive(
                    &primitive,
                    document,
                    &buffers,
                    &world,
                    source,
                    &mut textures,
                    &mut out,
                )
                .map_err(|message| invalid(format!("{}: {message}", what())))?;
            }
        }
        let children: Vec<_> = node.children().collect();
        for child in children.into_iter().rev() {
            stack.push((child, world));
        }
    }
    Ok(out)
}

/// The exposure a lightmap bake records for its vertex bake (`extras.bake_lightmap.exposure`).
fn bake_exposure(document: &gltf::Document) -> Option<f64> {
    let extras = document.as_json().extras.as_ref()?;
    let value: serde_json::Value = serde_json::from_str(extras.get()).ok()?;
    value
        .get("bake_lightmap")?
        .get("exposure")?
        .as_f64()
        .filter(|x| x.is_finite() && *x >= 0.0)
}

/// Each material's decoded base-colour texture (index into [`Scene::textures`]) and the
/// TEXCOORD set it reads, and its lightmap (index into [`Scene::lightmaps`]) and set.
struct TextureCache<'a> {
    base: Option<&'a Path>,
    of_material: HashMap<Option<usize>, Option<(usize, u32)>>,
    lightmap_of_material: HashMap<Option<usize>, Option<(usize, u32)>>,
    /// What a lightmap's b is multiplied by: `--exposure`, else the bake's recorded one.
    exposure: f64,
}

impl TextureCache<'_> {
    /// The material's `MOZ_lightmap` atlas, decoded, and the TEXCOORD set it reads.
    fn lightmap(
        &mut self,
        material: &gltf::Material,
        document: &gltf::Document,
        buffers: &[gltf::buffer::Data],
        out: &mut Scene,
    ) -> Result<Option<(usize, u32)>, String> {
        if let Some(known) = self.lightmap_of_material.get(&material.index()) {
            return Ok(*known);
        }
        let made = match material.extension_value("MOZ_lightmap") {
            None => None,
            Some(value) => {
                let index = value.get("index").and_then(|v| v.as_u64());
                let texture = index
                    .and_then(|k| document.textures().nth(k as usize))
                    .ok_or("MOZ_lightmap names no texture of the file")?;
                let set = value.get("texCoord").and_then(|v| v.as_u64()).unwrap_or(0);
                let intensity = value
                    .get("intensity")
                    .and_then(|v| v.as_f64())
                    .unwrap_or(1.0);
                if !(intensity.is_finite() && intensity >= 0.0) {
                    return Err(format!("MOZ_lightmap intensity {intensity} is not ≥ 0"));
                }
                let texture = texture::decode(&texture, "lightmap texture", buffers, self.base)?;
                out.lightmaps.push(Lightmap { texture, intensity });
                Some((out.lightmaps.len() - 1, set as u32))
            }
        };
        self.lightmap_of_material.insert(material.index(), made);
        Ok(made)
    }

    fn get(
        &mut self,
        material: &gltf::Material,
        buffers: &[gltf::buffer::Data],
        out: &mut Scene,
    ) -> Result<Option<(usize, u32)>, String> {
        if let Some(known) = self.of_material.get(&material.index()) {
            return Ok(*known);
        }
        let made = texture::base_colour(material, buffers, self.base)?.map(|(t, set)| {
            out.textures.push(t);
            (out.textures.len() - 1, set)
        });
        self.of_material.insert(material.index(), made);
        Ok(made)
    }
}

/// Appends one primitive's triangles (in world space) to `out`.
fn add_primitive(
    primitive: &gltf::Primitive,
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    world: &Mat4,
    source: ColorSource,
    textures: &mut TextureCache,
    out: &mut Scene,
) -> Result<(), String> {
    if !matches!(
        primitive.mode(),
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        out.skipped_primitives += 1;
        return Ok(());
    }
    let get = |buffer: gltf::Buffer| buffers.get(buffer.index()).map(|data| &data[..]);
    let reader = primitive.reader(get);
    let positions: Vec<[f32; 3]> = reader.read_positions().ok_or("no POSITION data")?.collect();
    let n = positions.len();
    let color0: Option<Vec<[f32; 3]>> = reader
        .read_colors(0)
        .map(|colors| colors.into_rgb_f32().collect());
    let radiosity: Option<Vec<[f32; 3]>> = match source {
        ColorSource::Color0 => None,
        ColorSource::Radiosity { .. } => read_radiosity(primitive, buffers)?,
    };
    for (name, values) in [("COLOR_0", &color0), ("_RADIOSITY", &radiosity)] {
        if let Some(values) = values {
            if values.len() != n {
                return Err(format!(
                    "{name} has {} values for {n} positions",
                    values.len()
                ));
            }
        }
    }
    let material = primitive.material();
    let base = material.pbr_metallic_roughness().base_color_factor();
    let base = [base[0], base[1], base[2]].map(f64::from);
    let double_sided = material.double_sided();
    let texture = textures.get(&material, buffers, out)?;
    let uvs: Option<Vec<[f32; 2]>> = match texture {
        Some((_, set)) => Some(
            reader
                .read_tex_coords(set)
                .ok_or_else(|| {
                    format!("its base-colour texture reads TEXCOORD_{set}, which is missing")
                })?
                .into_f32()
                .collect(),
        ),
        None => None,
    };
    if uvs.as_ref().is_some_and(|uv| uv.len() != n) {
        return Err(format!(
            "TEXCOORD has a different count from POSITION ({n})"
        ));
    }
    let texture = texture.map(|(k, _)| k);
    let lightmap = textures.lightmap(&material, document, buffers, out)?;
    let uv1: Option<Vec<[f32; 2]>> = match lightmap {
        Some((_, set)) => Some(
            reader
                .read_tex_coords(set)
                .ok_or_else(|| format!("its lightmap reads TEXCOORD_{set}, which is missing"))?
                .into_f32()
                .collect(),
        ),
        None => None,
    };
    if uv1.as_ref().is_some_and(|uv| uv.len() != n) {
        return Err(format!(
            "the lightmap's TEXCOORD has a different count from POSITION ({n})"
        ));
    }
    // Under a lightmap the vertex colour is ρ's factor × the exposure; the pixel multiplies
    // in the textures and adds the emission: clamp((ρ H + e) × exposure, 0, 1).
    let exposure = textures.exposure;
    let emissive = match lightmap {
        Some(_) => {
            let strength = material.emissive_strength().map_or(1.0, f64::from);
            material
                .emissive_factor()
                .map(|e| f64::from(e) * strength * exposure)
        }
        None => [0.0; 3],
    };
    let lightmap = lightmap.map(|(k, _)| k);

    let mirrored = math::linear_determinant(world) < 0.0;
    let mut vertices = Vec::with_capacity(n);
    for (k, p) in positions.iter().enumerate() {
        let position = math::transform_point(world, p.map(f64::from));
        let color = match (source, &radiosity, &color0) {
            _ if lightmap.is_some() => color0
                .as_ref()
                .map_or([exposure; 3], |c| c[k].map(|v| f64::from(v) * exposure)),
            (ColorSource::Color0, _, Some(c)) => c[k].map(f64::from),
            (ColorSource::Color0, _, None) => [1.0; 3],
            (ColorSource::Radiosity { exposure }, Some(r), _) => {
                r[k].map(|v| (f64::from(v) * exposure).clamp(0.0, 1.0))
            }
            (ColorSource::Radiosity { exposure }, None, Some(c)) => {
                c[k].map(|v| (f64::from(v) * exposure).clamp(0.0, 1.0))
            }
            (ColorSource::Radiosity { .. }, None, None) => [1.0; 3],
        };
        let color = [color[0] * base[0], color[1] * base[1], color[2] * base[2]];
        if !position.iter().chain(&color).all(|v| v.is_finite()) {
            return Err(format!("vertex {k} has a non-finite position or colour"));
        }
        let uv = uvs.as_ref().map_or([0.0; 2], |uv| uv[k].map(f64::from));
        let uv1 = uv1.as_ref().map_or([0.0; 2], |uv| uv[k].map(f64::from));
        vertices.push(Vertex {
            position,
            color,
            uv,
            uv1,
        });
    }

    let indices: Vec<usize> = match reader.read_indices() {
        Some(indices) => indices.into_u32().map(|i| i as usize).collect(),
        None => (0..n).collect(),
    };
    if let Some(bad) = indices.iter().find(|&&i| i >= n) {
        return Err(format!("index {bad} is out of range ({n} vertices)"));
    }
    let corners: Vec<[usize; 3]> = match primitive.mode() {
        Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
            .map(|i| {
                let odd = i % 2;
                [indices[i], indices[i + 1 + odd], indices[i + 2 - odd]]
            })
            .collect(),
        Mode::TriangleFan => (1..indices.len().saturating_sub(1))
            .map(|i| [indices[i], indices[i + 1], indices[0]])
            .collect(),
        _ => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    };
    for [a, b, c] in corners {
        // A mirroring transform turns counter-clockwise into clockwise: restore the front.
        let order = if mirrored { [a, c, b] } else { [a, b, c] };
        out.triangles.push(Triangle {
            vertices: order.map(|i| vertices[i]),
            double_sided,
            texture,
            lightmap,
            emissive,
        });
    }
    Ok(())
}

/// The primitive's `_RADIOSITY` values (float VEC3), if it has them.
fn read_radiosity(
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
) -> Result<Option<Vec<[f32; 3]>>, String> {
    let Some(accessor) = primitive.get(&Semantic::Extras("RADIOSITY".into())) else {
        return Ok(None);
    };
    if accessor.data_type() != gltf::accessor::DataType::F32
        || accessor.dimensions() != gltf::accessor::Dimensions::Vec3
        || accessor.normalized()
    {
        return Err("_RADIOSITY is not a float VEC3 accessor".to_string());
    }
    let get = |buffer: gltf::Buffer| buffers.get(buffer.index()).map(|data| &data[..]);
    let values = gltf::accessor::Iter::<[f32; 3]>::new(accessor, get)
        .ok_or("_RADIOSITY has no readable data")?;
    Ok(Some(values.collect()))
}
