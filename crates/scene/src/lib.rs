//! The scene vocabulary every stage shares: polygons, materials, lights, textures and the
//! input's layout, as plain values (f64 world space, glam vectors).
//!
//! A [`Scene`] is what the importer makes of a file and what the mesher, visibility, direct
//! light, texture, transport, lightmap and exporter crates read. This crate is not a reader or
//! a writer: it knows no file format (glTF, OBJ, images) and decodes nothing; authored glTF
//! materials and samplers are kept as JSON values for outputs that write them back.

use glam::{DMat4, DVec2, DVec3};
use std::path::PathBuf;

/// Where a polygon came from, so its results can be written back.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Origin {
    /// Index into [`Layout::nodes`] (the instance: a mesh used by two nodes is baked twice).
    pub node: usize,
    /// Index into [`Layout::meshes`].
    pub mesh: usize,
    /// Index of the primitive inside that mesh.
    pub primitive: usize,
    /// Index of the first source face (triangle, or OBJ face) of the primitive that this polygon
    /// was built from (a merged quad is built from faces `face` and one other).
    pub face: usize,
    /// Which side of a `doubleSided` surface this polygon is. Single-sided faces are `Front`.
    pub side: Side,
}

/// The side of a surface. A `doubleSided` material yields two polygons per face: the front one
/// (the input's winding and normal) and a back one (reversed winding, opposite normal).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Side {
    Front,
    Back,
}

/// A planar convex polygon of 3 or 4 corners, counter-clockwise about its unit normal, stored
/// inline (a triangle repeats its third corner as the fourth): the one convex-polygon value
/// every numerics crate passes around, `Copy`, so nothing is allocated per element pair. A
/// scene [`Polygon`] gives one ([`Polygon::convex`]); an element of the mesh is one
/// (`mesher::ElementMesh::convex`); visibility's `Patch` and form-factor's `Surface` are one
/// with a tag (the polygon it lies on; area and centroid).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Convex {
    pub corners: [DVec3; 4],
    /// 3 or 4.
    pub sides: u8,
    pub normal: DVec3,
}

impl Convex {
    /// From 3 or 4 corners (counter-clockwise about the unit `normal`); `None` for another
    /// count.
    pub fn new(corners: &[DVec3], normal: DVec3) -> Option<Convex> {
        let sides = corners.len();
        if !(3..=4).contains(&sides) {
            return None;
        }
        let mut c = [corners[0]; 4];
        c[..sides].copy_from_slice(corners);
        if sides == 3 {
            c[3] = c[2];
        }
        Some(Convex {
            corners: c,
            sides: sides as u8,
            normal,
        })
    }

    /// The corners actually used (3 or 4).
    pub fn corners(&self) -> &[DVec3] {
        &self.corners[..usize::from(self.sides)]
    }
}

/// A planar convex polygon in world space.
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    /// 3 or 4 vertices, counter-clockwise when seen from the side the normal points to.
    pub vertices: Vec<DVec3>,
    /// Unit normal, pointing into the half-space the surface emits and receives light from.
    pub normal: DVec3,
    /// Index into [`Scene::materials`].
    pub material: usize,
    pub origin: Origin,
}

impl Polygon {
    /// Its corners and normal as a [`Convex`] (`None` unless it has 3 or 4 corners).
    pub fn convex(&self) -> Option<Convex> {
        Convex::new(&self.vertices, self.normal)
    }
}

/// An ideal diffuse (Lambertian) material, per RGB band.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: Option<String>,
    /// Reflectance ρ in [0, 1] per band: the diffuse reflectance the bake uses, glTF
    /// `baseColorFactor` rgb (MTL `Kd`) × (1 − [`Material::transmission`]): glTF's PBR model
    /// blends the diffuse lobe by (1 − transmission), so a surface reflects what it does not
    /// transmit (docs/input-handling.md, "Glass").
    pub rho: [f64; 3],
    /// Emitted intensity e ≥ 0 per band: the e of the paper's eq. 7, in the same units as every
    /// radiosity b (glTF `emissiveFactor` × `KHR_materials_emissive_strength`, MTL `Ke`).
    pub emission: [f64; 3],
    /// Both sides of every face are surfaces (glTF `doubleSided`).
    pub double_sided: bool,
    /// `baseColorTexture`: ρ is `rho` × the texture's mean over each element.
    pub base_color_texture: Option<TextureRef>,
    /// `emissiveTexture`: e is `emission` × the texture's mean over each element.
    pub emissive_texture: Option<TextureRef>,
    /// The share t in [0, 1] of light that passes straight through the surface (thin glass,
    /// no refraction; 0: opaque): `1 − (1 − T) α` with T the glTF
    /// `KHR_materials_transmission` `transmissionFactor` (0 without it) and α the
    /// `baseColorFactor` alpha when `alphaMode` is `BLEND` (1 otherwise: uncovered is
    /// transmitted), MTL `d` (dissolve; `Tr` = 1 − d) the same way. Shadow and visibility
    /// rays crossing the surface are multiplied by t.
    pub transmission: f64,
}

/// A material's alpha cut-out (glTF `alphaMode` `MASK`): the surface is absent wherever
/// `factor` × the base-colour texture's alpha (1 without a texture, or without an alpha
/// channel) is below `cutoff`. Absent texels neither reflect nor block light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaMask {
    /// `alphaCutoff` (glTF default 0.5).
    pub cutoff: f64,
    /// `baseColorFactor`'s alpha.
    pub factor: f64,
}

/// One source triangle of a textured polygon: world positions and, per TEXCOORD set (0, 1),
/// its corners' texture coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct UvTriangle {
    pub positions: [DVec3; 3],
    pub uv: [[DVec2; 3]; 2],
    /// The corners' `COLOR_0` (linear RGB), when the primitive has one.
    pub color: Option<[DVec3; 3]>,
}

/// How a textured polygon maps to texture space: the source triangles that cover it (1, or 2
/// for a quad merged from two triangles), each affine.
#[derive(Clone, Debug, PartialEq)]
pub struct PolygonUv {
    pub triangles: Vec<UvTriangle>,
    /// Which TEXCOORD sets (0, 1) the primitive has; the other's `uv` are zeros.
    pub sets: [bool; 2],
}

impl PolygonUv {
    /// TEXCOORD set `set` (0 or 1) at a point of the polygon: the affine map of the source
    /// triangle that holds it (the one whose smallest barycentric coordinate is largest, so a
    /// point on a shared edge or just outside by rounding still gets the nearest triangle's
    /// value). `None` without triangles or when the primitive has no such set.
    pub fn at(&self, set: usize, point: DVec3) -> Option<DVec2> {
        if !self.sets.get(set).copied().unwrap_or(false) {
            return None;
        }
        self.interpolate(point, |t| Some(t.uv[set]))
    }

    /// `COLOR_0` at a point of the polygon (as [`PolygonUv::at`]); `None` without colours.
    pub fn color_at(&self, point: DVec3) -> Option<DVec3> {
        self.interpolate(point, |t| t.color)
    }

    /// The barycentric interpolation of `corners` over the source triangle holding `point`.
    fn interpolate<T>(
        &self,
        point: DVec3,
        corners: impl Fn(&UvTriangle) -> Option<[T; 3]>,
    ) -> Option<T>
    where
        T: Copy + std::ops::Mul<f64, Output = T> + std::ops::Add<Output = T>,
    {
        let mut best: Option<(f64, T)> = None;
        for t in &self.triangles {
            let [a, b, c] = t.positions;
            let n = (b - a).cross(c - a);
            let area = n.length_squared();
            if area <= 0.0 || !area.is_finite() {
                continue;
            }
            let la = (b - point).cross(c - point).dot(n) / area;
            let lb = (c - point).cross(a - point).dot(n) / area;
            let lc = 1.0 - la - lb;
            let worst = la.min(lb).min(lc);
            let [ua, ub, uc] = corners(t)?;
            let value = ua * la + ub * lb + uc * lc;
            if best.is_none_or(|(w, _)| worst > w) {
                best = Some((worst, value));
            }
        }
        best.map(|(_, value)| value)
    }
}

/// A node of the input hierarchy, kept so the output has the same structure.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    pub name: Option<String>,
    /// The node's local transform exactly as the input gave it.
    pub transform: Transform,
    pub children: Vec<usize>,
    /// Index into [`Layout::meshes`].
    pub mesh: Option<usize>,
    /// Parent-to-world composed transform (f64) used to place this node's polygons.
    pub world: DMat4,
}

/// A punctual light (glTF `KHR_lights_punctual`) placed in world space by its node.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    /// The light's own name (not the node's).
    pub name: Option<String>,
    /// Index into [`Layout::nodes`] of the node that carries it.
    pub node: usize,
    pub kind: LightKind,
    /// World position of the node's origin (where a point or spot light sits).
    pub position: DVec3,
    /// Unit world direction the light travels: the node's local −Z (spot axis, sun rays).
    pub direction: DVec3,
    /// Linear RGB colour, as written (each band finite and ≥ 0).
    pub color: [f64; 3],
    /// Candela (point, spot: luminous intensity) or lux (directional: illuminance on a
    /// surface facing the light), as written.
    pub intensity: f64,
    /// Distance beyond which a point or spot light gives no light (`range`), if given.
    pub range: Option<f64>,
}

impl Light {
    /// Intensity per band: `color × intensity` (candela or lux per band).
    pub fn band_intensity(&self) -> [f64; 3] {
        self.color.map(|c| c * self.intensity)
    }
}

/// What kind of punctual light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// Light in all directions from a point.
    Point,
    /// A point light limited to a cone about [`Light::direction`]: full intensity inside
    /// `inner` (radians from the axis), none outside `outer`, 0 ≤ inner < outer ≤ π/2.
    Spot { inner: f64, outer: f64 },
    /// Parallel light along [`Light::direction`] (the sun).
    Directional,
}

impl LightKind {
    /// The extension's name for it.
    pub fn name(&self) -> &'static str {
        match self {
            LightKind::Point => "point",
            LightKind::Spot { .. } => "spot",
            LightKind::Directional => "directional",
        }
    }
}

/// A node's local transform, as written in the input.
#[derive(Clone, Debug, PartialEq)]
pub enum Transform {
    /// Column-major 4×4 matrix.
    Matrix([f32; 16]),
    Trs {
        translation: [f32; 3],
        /// Unit quaternion x, y, z, w.
        rotation: [f32; 4],
        scale: [f32; 3],
    },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    pub name: Option<String>,
    pub primitives: Vec<Primitive>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Primitive {
    /// Index into [`Scene::materials`].
    pub material: usize,
    /// False for primitives that were skipped (points, lines, or nothing left after cleaning).
    pub baked: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct SceneRoots {
    pub name: Option<String>,
    pub nodes: Vec<usize>,
}

/// The input's structure: nodes, meshes and scenes.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Layout {
    pub nodes: Vec<Node>,
    pub meshes: Vec<Mesh>,
    pub scenes: Vec<SceneRoots>,
    /// The default scene (glTF `scene`), if any.
    pub scene: Option<usize>,
}

/// Counts of what was dropped or changed on import.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ImportStats {
    /// Source faces read (triangles and OBJ faces), before cleaning.
    pub faces_read: usize,
    /// Pairs of triangles merged back into a planar convex quad.
    pub quads_merged: usize,
    /// Faces dropped for zero area or repeated vertices.
    pub degenerate_dropped: usize,
    /// Primitives skipped because their mode is points or lines.
    pub primitives_skipped: usize,
    /// Polygons with more than 4 vertices split into triangles/quads.
    pub ngons_split: usize,
    /// Faces dropped because an earlier face of the same primitive has the same vertices in
    /// the same order (either order for a double-sided material).
    pub duplicates_dropped: usize,
    /// Faces wound opposite to their neighbours (kept as authored; see the importer).
    pub against_winding: usize,
    /// Polygons dropped because an earlier polygon of another primitive or node has the same
    /// corners in the same cyclic order (coincident, facing the same way; see the importer).
    pub coincident_dropped: usize,
    /// OBJ material libraries (`mtllib`) that could not be read: their materials fell back
    /// to the default grey (a warning names each; the summary line counts them).
    pub material_libraries_missing: usize,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub polygons: Vec<Polygon>,
    pub materials: Vec<Material>,
    /// Punctual lights of the baked nodes, in node order (empty for OBJ).
    pub lights: Vec<Light>,
    /// Light probes marked in the input: the world origin of every baked node whose glTF
    /// `extras` hold `"bake_probe": true`, depth first from the scene's roots (empty for OBJ;
    /// docs/probes.md).
    pub probe_points: Vec<DVec3>,
    /// Textures referenced by materials in use, and their decoded images.
    pub textures: Vec<Texture>,
    pub images: Vec<Image>,
    /// Per polygon: its texture mapping when its material has a texture in any slot the
    /// outputs keep (base colour, emissive, metallic-roughness, normal), or when its
    /// primitive has `COLOR_0` or `TEXCOORD_1` (a lightmap layout the lightmap may keep).
    pub uvs: Vec<Option<PolygonUv>>,
    /// The materials, textures and encoded images as authored, for outputs that keep them.
    pub authored: Authored,
    /// Per [`Scene::materials`] entry: its alpha cut-out, for `alphaMode` `MASK`. The
    /// material's decoded base-colour image then holds 0 where it is cut out (so ρ averages
    /// the opaque texels) and its alpha in [`Image::alpha`].
    pub alpha_masks: Vec<Option<AlphaMask>>,
    pub layout: Layout,
    pub stats: ImportStats,
    /// One line per thing the user should know about (dropped faces, skipped primitives).
    pub warnings: Vec<String>,
    /// Every file read, in order: the scene file, then its external buffers, images and
    /// material libraries (empty for the importer's `load_bytes`). Outputs must not be any of them.
    pub input_files: Vec<PathBuf>,
}

/// A decoded image: linear RGB per texel, row-major, the first row at v = 0 (glTF's UV origin
/// is the image's top-left corner).
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[f32; 3]>,
    /// Linear alpha per texel when the file has an alpha channel (else empty: opaque).
    pub alpha: Vec<f32>,
}

/// How texture coordinates outside [0, 1] wrap (glTF sampler `wrapS`/`wrapT`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    ClampToEdge,
    MirroredRepeat,
}

/// A glTF texture: an image and how it is sampled.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Names the texture in messages.
    pub name: String,
    /// Index into [`Scene::images`].
    pub image: usize,
    /// `wrapS`, `wrapT`.
    pub wrap: [Wrap; 2],
    /// Magnification filter `NEAREST` (else linear, the default).
    pub nearest: bool,
}

/// A material's use of a texture.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into [`Scene::textures`].
    pub texture: usize,
    /// Which `TEXCOORD_n` set (after `KHR_texture_transform`'s override).
    pub tex_coord: u32,
    /// `KHR_texture_transform` as a 2 × 3 matrix: uv' = M (u, v, 1) = T R S (u, v, 1).
    pub transform: [[f64; 3]; 2],
}

impl TextureRef {
    /// The transformed coordinates of `uv`.
    pub fn apply(&self, uv: DVec2) -> DVec2 {
        let m = &self.transform;
        DVec2::new(
            m[0][0] * uv.x + m[0][1] * uv.y + m[0][2],
            m[1][0] * uv.x + m[1][1] * uv.y + m[1][2],
        )
    }
}

/// The input's materials as authored, with the textures and encoded images they use, so the
/// outputs can keep the asset (glTF input; OBJ `map_Kd` likewise).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Authored {
    /// Per [`Scene::materials`] entry: the material as written (glTF JSON, a
    /// `gltf::json::Material`) with its texture indices rewritten into [`Authored::textures`];
    /// the occlusion texture (a bake has the occlusion in its light already) and material
    /// extensions other than `KHR_materials_emissive_strength` are left out. `None` for
    /// materials no baked primitive uses and for the default material.
    pub materials: Vec<Option<serde_json::Value>>,
    pub textures: Vec<AuthoredTexture>,
    pub images: Vec<EncodedImage>,
}

/// A texture of [`Authored`]: its sampler as written (glTF JSON `gltf::json::texture::Sampler`)
/// and its image.
#[derive(Clone, Debug, PartialEq)]
pub struct AuthoredTexture {
    pub name: Option<String>,
    pub sampler: Option<serde_json::Value>,
    /// Index into [`Authored::images`].
    pub image: usize,
}

/// An image file's bytes as read (PNG or JPEG).
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedImage {
    pub name: Option<String>,
    /// `image/png` or `image/jpeg`.
    pub mime_type: &'static str,
    pub bytes: Vec<u8>,
}

/// The TEXCOORD sets the kept textures of an authored material use (after
/// `KHR_texture_transform`'s override), as flags for sets 0 and 1.
pub fn authored_sets(material: &serde_json::Value) -> [bool; 2] {
    let mut sets = [false; 2];
    let slots = [
        &material["pbrMetallicRoughness"]["baseColorTexture"],
        &material["pbrMetallicRoughness"]["metallicRoughnessTexture"],
        &material["normalTexture"],
        &material["emissiveTexture"],
    ];
    for info in slots.into_iter().filter(|i| i.is_object()) {
        let set = info["extensions"]["KHR_texture_transform"]["texCoord"]
            .as_u64()
            .or_else(|| info["texCoord"].as_u64())
            .unwrap_or(0);
        if let Some(flag) = sets.get_mut(set as usize) {
            *flag = true;
        }
    }
    sets
}

/// The scene's world-space bounding box (min, max) over all polygon vertices.
pub fn bounds(polygons: &[Polygon]) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in polygons {
        for v in &p.vertices {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    (lo, hi)
}

/// Most texels a sky map (`--sky map:FILE`) may have (16384 × 8192): a larger file is refused
/// before it is decoded.
pub const MAX_SKY_MAP_TEXELS: u64 = 16384 * 8192;

/// A decoded equirectangular sky map: linear RGB radiance, row-major, row 0 at the zenith
/// (the importer reads it; `bake-direct`'s `EnvironmentMap` samples it).
#[derive(Clone, Debug, PartialEq)]
pub struct SkyImage {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<[f32; 3]>,
}
