//! OBJ + MTL input via `tobj`, with quads and larger polygons kept as written
//! (`triangulate: false, single_index: true`).
//!
//! The text is checked line by line before `tobj` sees it, because `tobj` 4.0.5 panics on
//! some malformed input (a face index of 0 or far out of range overflows its index
//! arithmetic; a colour with two numbers fails an `unwrap`). The check also drops point
//! and line elements (`p`, `l`: `tobj` reads a 3-vertex `l` as a face) and faces with
//! fewer than 3 vertices, and normalises whitespace so `mtllib`/`usemtl` names parse.

use crate::files::{count_obj_faces, Files, Refused};
use crate::polygon::{self, Instance, SourceFace};
use crate::{
    check_material, describe, ImportError, ImportStats, Layout, Material, Mesh, Node, Origin,
    Primitive, Scene, SceneRoots, Side, Transform,
};
use glam::{DMat4, DVec3};
use std::cell::{Cell, RefCell};
use std::path::Path;

/// Reflectance of the material used by OBJ faces without one (no `usemtl`, a missing MTL
/// file, or an unknown material name), and of MTL materials without `Kd`.
pub(crate) const DEFAULT_RHO: f64 = 0.8;

/// The most vertices one face may have: ear clipping is quadratic to cubic in it.
const MAX_FACE_VERTICES: usize = 1024;

/// Reads an OBJ file and the MTL libraries it names (relative to the file's folder, and
/// inside it unless outside paths are allowed). Faces are counted by a byte scan first, so a
/// file with more than the scene's face limit is refused before it is read and parsed.
pub(crate) fn load(path: &Path, files: &Files) -> Result<Scene, ImportError> {
    let faces = count_obj_faces(path).map_err(|source| ImportError::Io {
        path: path.to_owned(),
        source,
    })?;
    polygon::count_faces(&mut 0, usize::try_from(faces).unwrap_or(usize::MAX))?;
    let bytes = files.read_scene(path)?;
    let read_mtl = |name: &Path| match files.resolve(name) {
        Ok(path) => (path.display().to_string(), files.read(&path)),
        Err(refused) => (
            name.display().to_string(),
            Err(std::io::Error::other(Refused(refused))),
        ),
    };
    load_with(&bytes, &path.display().to_string(), &read_mtl)
}

/// Reads OBJ text from memory; every `mtllib` it names reads `mtl` (none: every material
/// library is missing, and faces fall back to the default material).
pub(crate) fn load_bytes(obj: &[u8], mtl: Option<&[u8]>) -> Result<Scene, ImportError> {
    let read_mtl = |name: &Path| {
        let bytes = mtl.map(<[u8]>::to_vec).ok_or_else(|| {
            std::io::Error::new(std::io::ErrorKind::NotFound, "no material library given")
        });
        (name.display().to_string(), bytes)
    };
    load_with(obj, "the OBJ", &read_mtl)
}

/// Reads a material library by the name an OBJ gives it: the name to show in messages, and
/// its bytes.
type ReadMtl<'a> = dyn Fn(&Path) -> (String, std::io::Result<Vec<u8>>) + 'a;

/// Reads OBJ bytes, named `source` in messages, and the MTL libraries `read_mtl` returns.
fn load_with(bytes: &[u8], source: &str, read_mtl: &ReadMtl) -> Result<Scene, ImportError> {
    let checked = check_obj(&String::from_utf8_lossy(bytes))?;
    let mtl_error = RefCell::new(None);
    let mtl_warnings = RefCell::new(Vec::new());
    let missing = Cell::new(0);
    let libraries = Libraries {
        read_mtl,
        error: &mtl_error,
        warnings: &mtl_warnings,
        missing: &missing,
    };
    // `..Default::default()` covers fields that other crates' `tobj` features may add.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: false,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let (models, mtl) = tobj::load_obj_buf(&mut checked.text.as_bytes(), &options, |name| {
        libraries.load_line(name)
    })
    .map_err(|e| ImportError::Obj(format!("{source}: {e}")))?;
    if let Some(error) = mtl_error.into_inner() {
        return Err(error);
    }
    let mut warnings = mtl_warnings.into_inner();
    let stats = ImportStats {
        faces_read: checked.short_faces,
        degenerate_dropped: checked.short_faces,
        material_libraries_missing: missing.get(),
        ..Default::default()
    };
    if checked.short_faces > 0 {
        warnings.push(format!(
            "dropped {} face(s) with fewer than 3 vertices",
            checked.short_faces
        ));
    }
    if checked.non_surfaces > 0 {
        warnings.push(format!(
            "skipped {} point/line element(s) (not surfaces)",
            checked.non_surfaces
        ));
    }
    let mtl = mtl.unwrap_or_default();
    let materials = mtl.iter().map(convert_material).collect();
    let mut scene = build_scene(&models, materials, stats, warnings)?;
    // `map_Kd`: read beside the OBJ, as its material libraries are.
    let maps: Vec<Option<String>> = mtl.iter().map(|m| m.diffuse_texture.clone()).collect();
    crate::obj_texture::attach(&mut scene, &models, &maps, &|name| read_mtl(name))?;
    Ok(scene)
}

/// The OBJ text as `tobj` will read it, and what was taken out.
struct CheckedObj {
    text: String,
    short_faces: usize,
    non_surfaces: usize,
}

/// Checks every face's vertex references and rewrites each line as `keyword rest`.
fn check_obj(text: &str) -> Result<CheckedObj, ImportError> {
    let mut out = CheckedObj {
        text: String::with_capacity(text.len()),
        short_faces: 0,
        non_surfaces: 0,
    };
    let totals = count_vertex_data(text);
    let mut running = [0usize; 3];
    for (n, line) in text.lines().enumerate() {
        let (keyword, rest) = split_keyword(line);
        match keyword {
            "v" => running[0] += 1,
            "vt" => running[1] += 1,
            "vn" => running[2] += 1,
            "l" | "p" => {
                out.non_surfaces += 1;
                continue;
            }
            "f" => {
                let vertices: Vec<&str> = rest.split_whitespace().collect();
                for (j, vertex) in vertices.iter().enumerate() {
                    check_face_vertex(j, vertex, &running, &totals)
                        .map_err(|e| ImportError::Obj(format!("line {}: {e}", n + 1)))?;
                }
                if vertices.len() < 3 {
                    out.short_faces += 1;
                    continue;
                }
            }
            _ => {}
        }
        push_line(&mut out.text, keyword, rest);
    }
    Ok(out)
}

/// The first word of a line and the rest, trimmed.
fn split_keyword(line: &str) -> (&str, &str) {
    let line = line.trim();
    match line.split_once(char::is_whitespace) {
        Some((keyword, rest)) => (keyword, rest.trim()),
        None => (line, ""),
    }
}

/// How many positions, texture coordinates and normals the file has.
fn count_vertex_data(text: &str) -> [usize; 3] {
    let mut totals = [0; 3];
    for line in text.lines() {
        match split_keyword(line).0 {
            "v" => totals[0] += 1,
            "vt" => totals[1] += 1,
            "vn" => totals[2] += 1,
            _ => {}
        }
    }
    totals
}

/// One `v`, `v/vt`, `v//vn` or `v/vt/vn` reference: 1-based, or negative (relative to the
/// data read so far), and in range. Texture and normal references are ignored by `tobj`
/// when the file has none, so they are only checked when it has some. Messages say which
/// vertex (`j`, from 0) of the line and at most the index it parsed to, never its text: a
/// file that is no OBJ at all is not echoed.
fn check_face_vertex(
    j: usize,
    vertex: &str,
    running: &[usize; 3],
    totals: &[usize; 3],
) -> Result<(), String> {
    const KINDS: [&str; 3] = ["position", "texture coordinate", "normal"];
    let parts: Vec<&str> = vertex.split('/').collect();
    if parts.len() > 3 {
        return Err(format!("face vertex {} has more than 3 parts", j + 1));
    }
    for (k, part) in parts.iter().enumerate() {
        if part.is_empty() || (k > 0 && totals[k] == 0) {
            continue;
        }
        let x: i64 = part
            .parse()
            .map_err(|_| format!("face vertex {} is not a number", j + 1))?;
        let valid = match x {
            x if x > 0 => (x as u64) <= totals[k] as u64,
            x if x < 0 => x.unsigned_abs() <= running[k] as u64,
            _ => false,
        };
        if !valid {
            return Err(format!(
                "face vertex {} refers to {} {x}, which does not exist ({} in the file)",
                j + 1,
                KINDS[k],
                totals[k]
            ));
        }
    }
    Ok(())
}

/// The material loader handed to `tobj`, with what it records: the first malformed or
/// refused library (an error), missing libraries (warnings, and their count).
struct Libraries<'a> {
    read_mtl: &'a ReadMtl<'a>,
    error: &'a RefCell<Option<ImportError>>,
    warnings: &'a RefCell<Vec<String>>,
    missing: &'a Cell<usize>,
}

impl Libraries<'_> {
    /// One `mtllib` line. The OBJ format lets it name several libraries, separated by
    /// whitespace (`mtllib a.mtl b.mtl`), but `tobj` passes the rest of the line as one name
    /// (to allow names with spaces, which Blender writes unquoted). So the whole rest is read
    /// as one name when it is a readable file, and otherwise each word is a library: the
    /// materials of every library read are merged in order (a later library's material
    /// replaces an earlier one of the same name, as a later `mtllib` line's does in `tobj`).
    fn load_line(&self, line: &Path) -> tobj::MTLLoadResult {
        let text = line.to_string_lossy();
        let words: Vec<&str> = text.split_whitespace().collect();
        let whole = (self.read_mtl)(line);
        if words.len() < 2 || whole.1.is_ok() {
            return self.load(whole);
        }
        let mut merged: tobj::MTLLoadResult = Err(tobj::LoadError::OpenFileFailed);
        for word in words {
            let Ok((materials, names)) = self.load((self.read_mtl)(Path::new(word))) else {
                continue;
            };
            match &mut merged {
                Ok((all, map)) => {
                    let offset = all.len();
                    all.extend(materials);
                    for (name, i) in names {
                        map.insert(name, i + offset);
                    }
                }
                Err(_) => merged = Ok((materials, names)),
            }
        }
        merged
    }

    /// Takes what `read_mtl` returned for one library (its name for messages, its bytes),
    /// checks its colour lines, and records a missing library as a warning and a malformed
    /// one as an error.
    fn load(&self, (name, bytes): (String, std::io::Result<Vec<u8>>)) -> tobj::MTLLoadResult {
        let bytes = match bytes {
            Ok(bytes) => bytes,
            Err(e) if e.get_ref().is_some_and(|inner| inner.is::<Refused>()) => {
                self.error
                    .borrow_mut()
                    .get_or_insert(ImportError::Refused(format!("mtllib {e}")));
                return Err(tobj::LoadError::OpenFileFailed);
            }
            Err(e) => {
                self.missing.set(self.missing.get() + 1);
                self.warnings.borrow_mut().push(format!(
                    "material library {name} is missing ({e}): its materials fall back to the \
                     default grey (ρ = {DEFAULT_RHO}, no emission)"
                ));
                return Err(tobj::LoadError::OpenFileFailed);
            }
        };
        let fail = |message: String| {
            self.error
                .borrow_mut()
                .get_or_insert(ImportError::Obj(format!("{name}: {message}")));
            tobj::LoadError::MaterialParseError
        };
        let text = check_mtl(&String::from_utf8_lossy(&bytes)).map_err(fail)?;
        tobj::load_mtl_buf(&mut text.as_bytes()).map_err(|e| fail(e.to_string()))
    }
}

/// Checks the colour lines the importer uses, `Kd` and `Ke`: three numbers, or one
/// meaning grey (as the MTL format allows). Unused colours (`Ka`, `Ks`) that `tobj` could
/// not read are dropped. Rewrites each line as `keyword rest`.
fn check_mtl(text: &str) -> Result<String, String> {
    let mut out = String::with_capacity(text.len());
    for (n, line) in text.lines().enumerate() {
        let (keyword, rest) = split_keyword(line);
        let mut rest = rest.to_owned();
        if matches!(keyword, "Ka" | "Kd" | "Ks" | "Ke") {
            match read_colour(&rest) {
                Some(rgb) => rest = rgb,
                None if matches!(keyword, "Ka" | "Ks") => continue,
                None => {
                    return Err(format!(
                        "line {}: cannot read colour {keyword} (expected r g b)",
                        n + 1
                    ))
                }
            }
        }
        push_line(&mut out, keyword, &rest);
    }
    Ok(out)
}

/// `r g b` (extra words ignored, as `tobj` does) or a single grey value, as `r g b`.
fn read_colour(text: &str) -> Option<String> {
    let numbers: Vec<&str> = text.split_whitespace().collect();
    let parses = |s: &str| s.parse::<f32>().is_ok();
    match numbers.as_slice() {
        [grey] if parses(grey) => Some(format!("{grey} {grey} {grey}")),
        [r, g, b, ..] if [r, g, b].iter().all(|s| parses(s)) => Some(format!("{r} {g} {b}")),
        _ => None,
    }
}

/// Appends `keyword rest` as one line (nothing for a blank line).
fn push_line(out: &mut String, keyword: &str, rest: &str) {
    if keyword.is_empty() {
        return;
    }
    out.push_str(keyword);
    out.push(' ');
    out.push_str(rest);
    out.push('\n');
}

/// ρ from `Kd` (default grey when absent), e from `Ke` (default 0); single-sided.
fn convert_material(m: &tobj::Material) -> Material {
    Material {
        name: Some(m.name.clone()),
        rho: m.diffuse.unwrap_or([DEFAULT_RHO; 3]),
        emission: m.emissive.unwrap_or([0.0; 3]),
        double_sided: false,
        base_color_texture: None,
        emissive_texture: None,
        transmission: 0.0,
    }
}

/// The neutral grey used where a face has no material.
fn default_material() -> Material {
    Material {
        name: None,
        rho: [DEFAULT_RHO; 3],
        emission: [0.0; 3],
        double_sided: false,
        base_color_texture: None,
        emissive_texture: None,
        transmission: 0.0,
    }
}

/// One mesh, node and instance per non-empty model; one scene holding every node.
fn build_scene(
    models: &[tobj::Model],
    mut materials: Vec<Material>,
    mut stats: ImportStats,
    mut warnings: Vec<String>,
) -> Result<Scene, ImportError> {
    let from_mtl = materials.len();
    let mut layout = Layout::default();
    let mut instances = Vec::new();
    let mut without_material = 0;
    let mut face_count = 0;
    for model in models.iter().filter(|m| !m.mesh.indices.is_empty()) {
        let index = layout.meshes.len();
        let label = format!(
            "{}, primitive 0",
            describe("mesh", Some(&model.name), index)
        );
        let material = match model.mesh.material_id.filter(|&m| m < from_mtl) {
            Some(m) => m,
            None => {
                without_material += 1;
                if materials.len() == from_mtl {
                    materials.push(default_material());
                }
                from_mtl
            }
        };
        let name = describe("material", materials[material].name.as_deref(), material);
        check_material(&materials[material], &format!("{name} used by {label}"))?;
        layout.meshes.push(Mesh {
            name: Some(model.name.clone()),
            primitives: vec![Primitive {
                material,
                baked: false,
            }],
        });
        layout.nodes.push(Node {
            name: Some(model.name.clone()),
            transform: Transform::Trs {
                translation: [0.0; 3],
                rotation: [0.0, 0.0, 0.0, 1.0],
                scale: [1.0; 3],
            },
            children: Vec::new(),
            mesh: Some(index),
            world: DMat4::IDENTITY,
        });
        let faces =
            model_faces(&model.mesh).map_err(|e| ImportError::Obj(format!("{label}: {e}")))?;
        polygon::count_faces(&mut face_count, faces.len())?;
        instances.push(Instance {
            faces,
            label,
            place: String::new(),
            origin: Origin {
                node: index,
                mesh: index,
                primitive: 0,
                face: 0,
                side: Side::Front,
            },
            material,
            double_sided: false,
        });
    }
    if without_material > 0 {
        warnings.push(format!(
            "{without_material} mesh(es) have no material: \
             using the default grey (ρ = {DEFAULT_RHO}, e = 0)"
        ));
    }
    layout.scenes.push(SceneRoots {
        name: None,
        nodes: (0..layout.nodes.len()).collect(),
    });
    layout.scene = Some(0);

    let polygons = polygon::bake(&instances, &mut stats, &mut warnings)?;
    for p in &polygons {
        if let Some(primitive) = layout
            .meshes
            .get_mut(p.origin.mesh)
            .and_then(|m| m.primitives.first_mut())
        {
            primitive.baked = true;
        }
    }
    if polygons.is_empty() {
        return Err(ImportError::Empty);
    }
    let polygon_count = polygons.len();
    let alpha_masks = vec![None; materials.len()];
    Ok(Scene {
        polygons,
        materials,
        lights: Vec::new(),
        probe_points: Vec::new(),
        textures: Vec::new(),
        images: Vec::new(),
        uvs: vec![None; polygon_count],
        authored: Default::default(),
        alpha_masks,
        layout,
        stats,
        warnings,
        input_files: Vec::new(),
    })
}

/// The model's faces as position lists (`face_arities` is empty when all are triangles).
fn model_faces(mesh: &tobj::Mesh) -> Result<Vec<SourceFace>, String> {
    let position = |i: u32| -> Option<DVec3> {
        let i = i as usize * 3;
        let p = mesh.positions.get(i..i + 3)?;
        Some(DVec3::new(p[0], p[1], p[2]))
    };
    let arities: Vec<usize> = if mesh.face_arities.is_empty() {
        vec![3; mesh.indices.len() / 3]
    } else {
        mesh.face_arities.iter().map(|&n| n as usize).collect()
    };
    let mut faces = Vec::with_capacity(arities.len());
    let mut start = 0;
    for (face, n) in arities.into_iter().enumerate() {
        if n > MAX_FACE_VERTICES {
            return Err(format!(
                "face {face} has {n} vertices, more than the importer's limit of {MAX_FACE_VERTICES}"
            ));
        }
        let indices = mesh
            .indices
            .get(start..start + n)
            .ok_or_else(|| format!("face {face} runs past the index list"))?;
        let vertices = indices
            .iter()
            .map(|&i| position(i))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| format!("face {face} refers to a missing vertex"))?;
        faces.push(SourceFace { face, vertices });
        start += n;
    }
    Ok(faces)
}
