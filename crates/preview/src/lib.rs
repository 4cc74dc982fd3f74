//! `bake preview`: renders a baked glTF/GLB to a PNG with a small software rasterizer, so a
//! bake can be checked with no viewer installed.
//!
//! The file is drawn as an unlit viewer draws it: each vertex shows `COLOR_0` × the material's
//! base colour (or `_RADIOSITY` × an exposure), interpolated across triangles, times the
//! base-colour texture at each pixel's interpolated UV (sampler and `KHR_texture_transform`
//! honoured) — so a
//! `--shading flat` bake shows constant elements (the paper's Figure 6) and a smooth one shows
//! the interpolated vertex values (Figure 8). Single-sided triangles are culled from the back,
//! as glTF requires; that is how the camera looks into a closed room from outside through its
//! near wall. Colours are interpolated in linear space and sRGB-encoded into 8-bit RGB.
//!
//! A lightmap bake (a material with `MOZ_lightmap`) is drawn through its lightmap as a lit
//! viewer shows it: clamp((e + ρ H) × exposure, 0, 1), H the lightmap's texel × its
//! `intensity` at the lightmap's TEXCOORD, ρ the base colour (factor × texture), e the
//! emission, and the exposure the bake recorded in `extras.bake_lightmap.exposure` (or
//! `--exposure`): the same values the vertex bake's `COLOR_0` shows.
//!
//! The camera is `--eye` looking at `--look-at` when given (to look around inside a room),
//! else a camera node of the file's scene when there is one, otherwise a 45° pinhole looking
//! along a view direction (default −Z: from the +Z side, glTF's "front") and backed off until
//! the scene's bounding box fits the image.
//!
//! Public API: [`render_file`] (or [`scene::load`] + [`render_scene`]) and [`write_png`].
//! Output is deterministic: one sample per pixel centre, f64 throughout, file order.

mod camera;
mod math;
mod raster;
pub mod scene;
pub mod texture;

pub use camera::{Camera, FRAMING_YFOV};
/// The `image` crate this one writes with (for reading PNGs back in tests).
pub use image;
pub use raster::{render, srgb8, srgb_encode, Frame, RenderStats};
pub use scene::{load, Bounds, CameraNode, ColorSource, Lightmap, Scene, Triangle, Vertex};

use image::ImageEncoder;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The default view direction of the framing camera: looking down −Z.
pub const DEFAULT_VIEW: [f64; 3] = [0.0, 0.0, -1.0];
/// Linear RGB behind the scene (a dark grey, so black surfaces still show).
pub const BACKGROUND: [f64; 3] = [0.02; 3];
/// Largest width or height accepted.
pub const MAX_SIZE: u32 = 8192;

/// How to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub width: u32,
    pub height: u32,
    pub colors: ColorSource,
    /// Frame the scene looking along this direction, even when the file has a camera.
    pub view: Option<[f64; 3]>,
    /// Stand here and look at `look_at` (both needed; overrides `view` and the file's camera),
    /// e.g. inside a room.
    pub eye: Option<[f64; 3]>,
    pub look_at: Option<[f64; 3]>,
    /// Vertical field of view in degrees for `eye`/`look_at` (default 60).
    pub fov: Option<f64>,
    /// Linear RGB.
    pub background: [f64; 3],
}

impl Default for Options {
    fn default() -> Self {
        Options {
            width: 512,
            height: 512,
            colors: ColorSource::Color0,
            view: None,
            eye: None,
            look_at: None,
            fov: None,
            background: BACKGROUND,
        }
    }
}

/// Which camera a render used.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraChoice {
    /// The framing camera looking along this direction.
    Framing { view: [f64; 3] },
    /// The file's camera node of this name (the first perspective camera of the scene).
    Node { name: Option<String> },
    /// `--eye` looking at `--look-at`.
    LookAt { eye: [f64; 3], look_at: [f64; 3] },
}

impl std::fmt::Display for CameraChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CameraChoice::Framing { view } => {
                write!(f, "framing, view {},{},{}", view[0], view[1], view[2])
            }
            CameraChoice::Node { name: Some(name) } => write!(f, "camera node {name:?}"),
            CameraChoice::Node { name: None } => write!(f, "the file's camera"),
            CameraChoice::LookAt { eye, look_at } => write!(
                f,
                "eye {},{},{} looking at {},{},{}",
                eye[0], eye[1], eye[2], look_at[0], look_at[1], look_at[2]
            ),
        }
    }
}

/// A finished render.
#[derive(Clone, Debug)]
pub struct Preview {
    /// sRGB, 8 bits per channel.
    pub image: image::RgbImage,
    pub camera: Camera,
    pub choice: CameraChoice,
    /// Triangles in the scene.
    pub triangles: usize,
    /// Points and lines, not drawn.
    pub skipped_primitives: usize,
    pub stats: RenderStats,
}

#[derive(Debug, thiserror::Error)]
pub enum PreviewError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: gltf::Error,
    },
    /// The file is readable glTF but cannot be drawn (no scene, bad accessors, …).
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
    #[error("{0}")]
    Options(String),
    #[error("cannot write {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot encode {path}: {message}")]
    Encode { path: PathBuf, message: String },
}

impl PreviewError {
    /// Whether the input file or the options are at fault (rather than the output).
    pub fn is_input_error(&self) -> bool {
        matches!(
            self,
            PreviewError::Read { .. } | PreviewError::Invalid { .. } | PreviewError::Options(_)
        )
    }
}

/// The vertical field of view of an `--eye`/`--look-at` camera unless `--fov` says (degrees).
pub const DEFAULT_FOV_DEGREES: f64 = 60.0;

/// The camera [`render_scene`] uses: `options.eye` looking at `options.look_at` when given,
/// else the framing camera along `options.view` when given, else the scene's first camera
/// node, else the framing camera along [`DEFAULT_VIEW`].
pub fn choose_camera(
    scene: &Scene,
    options: &Options,
) -> Result<(Camera, CameraChoice), PreviewError> {
    check_size(options)?;
    let aspect = f64::from(options.width) / f64::from(options.height);
    match (options.eye, options.look_at) {
        (Some(eye), Some(look_at)) => {
            let fov = options.fov.unwrap_or(DEFAULT_FOV_DEGREES);
            if !(fov.is_finite() && fov > 0.0 && fov < 180.0) {
                return Err(PreviewError::Options(format!(
                    "--fov must be between 0 and 180 degrees, got {fov}"
                )));
            }
            let camera =
                Camera::looking_at(eye, look_at, fov.to_radians(), aspect).ok_or_else(|| {
                    PreviewError::Options(
                        "--eye and --look-at must be two different finite points".into(),
                    )
                })?;
            return Ok((camera, CameraChoice::LookAt { eye, look_at }));
        }
        (Some(_), None) | (None, Some(_)) => {
            return Err(PreviewError::Options(
                "--eye and --look-at go together".into(),
            ))
        }
        (None, None) if options.fov.is_some() => {
            return Err(PreviewError::Options(
                "--fov sets the field of view of --eye/--look-at".into(),
            ))
        }
        (None, None) => {}
    }
    if options.view.is_none() {
        if let Some(node) = scene.cameras.first() {
            if let Some(camera) = Camera::from_node(node, aspect) {
                let choice = CameraChoice::Node {
                    name: node.name.clone(),
                };
                return Ok((camera, choice));
            }
        }
    }
    let view = options.view.unwrap_or(DEFAULT_VIEW);
    let bounds = scene.bounds().ok_or_else(|| {
        PreviewError::Options("nothing to draw: the scene has no triangles".into())
    })?;
    let camera = Camera::framing(&bounds, view, aspect).ok_or_else(|| {
        PreviewError::Options(format!(
            "cannot frame the scene looking along {view:?} (a non-zero, finite direction is needed)"
        ))
    })?;
    Ok((camera, CameraChoice::Framing { view }))
}

fn check_size(options: &Options) -> Result<(), PreviewError> {
    for (name, value) in [("width", options.width), ("height", options.height)] {
        if !(1..=MAX_SIZE).contains(&value) {
            return Err(PreviewError::Options(format!(
                "--{name} must be 1…{MAX_SIZE}, got {value}"
            )));
        }
    }
    Ok(())
}

/// Renders a loaded scene with the camera [`choose_camera`] picks.
pub fn render_scene(scene: &Scene, options: &Options) -> Result<Preview, PreviewError> {
    let (camera, choice) = choose_camera(scene, options)?;
    let (frame, stats) = render(
        scene,
        &camera,
        options.width,
        options.height,
        options.background,
    );
    Ok(Preview {
        image: to_rgb8(&frame),
        camera,
        choice,
        triangles: scene.triangles.len(),
        skipped_primitives: scene.skipped_primitives,
        stats,
    })
}

/// Loads and renders a `.gltf`/`.glb` file.
pub fn render_file(path: &Path, options: &Options) -> Result<Preview, PreviewError> {
    let scene = load(path, options.colors)?;
    if scene.triangles.is_empty() {
        return Err(PreviewError::Invalid {
            path: path.to_path_buf(),
            message: "nothing to draw: the scene has no triangles".into(),
        });
    }
    render_scene(&scene, options)
}

/// A frame's linear colours as 8-bit sRGB.
pub fn to_rgb8(frame: &Frame) -> image::RgbImage {
    let mut bytes = Vec::with_capacity(frame.pixels.len() * 3);
    for pixel in &frame.pixels {
        bytes.extend(pixel.map(srgb8));
    }
    image::RgbImage::from_raw(frame.width, frame.height, bytes)
        .unwrap_or_else(|| image::RgbImage::new(frame.width, frame.height))
}

/// Writes `image` as a PNG to `path` through a temporary file in the same directory (a
/// reader never sees a partial file; on error nothing is left behind).
pub fn write_png(path: &Path, image: &image::RgbImage) -> Result<(), PreviewError> {
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(
            image.as_raw(),
            image.width(),
            image.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| PreviewError::Encode {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    let write_error = |source| PreviewError::Write {
        path: path.to_path_buf(),
        source,
    };
    let temporary = temporary_path(path);
    if let Err(error) = std::fs::write(&temporary, &bytes) {
        let _ = std::fs::remove_file(&temporary);
        return Err(write_error(error));
    }
    std::fs::rename(&temporary, path).map_err(|error| {
        let _ = std::fs::remove_file(&temporary);
        write_error(error)
    })
}

/// `<dir>/.<name>.<pid>.<n>.tmp`, unique within this process.
fn temporary_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}.{}.{n}.tmp", std::process::id()))
}

/// The files [`render_file`] reads for `path`: the file itself and every buffer and image it
/// names by a relative URI (resolved beside it, percent-decoded), so that a caller can
/// refuse an output that is one of them before rendering. A file that cannot be parsed
/// gives just itself (rendering it then fails before anything is written).
pub fn input_files(path: &Path) -> Vec<PathBuf> {
    let mut files = vec![path.to_path_buf()];
    let Ok(gltf) = gltf::Gltf::open(path) else {
        return files;
    };
    let base = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    let buffers = gltf.document.buffers().filter_map(|b| match b.source() {
        gltf::buffer::Source::Uri(uri) => Some(uri),
        gltf::buffer::Source::Bin => None,
    });
    let images = gltf.document.images().filter_map(|i| match i.source() {
        gltf::image::Source::Uri { uri, .. } => Some(uri),
        gltf::image::Source::View { .. } => None,
    });
    for uri in buffers.chain(images) {
        if uri.starts_with("data:") || uri.contains(':') {
            continue;
        }
        files.push(base.join(percent_decode(uri)));
    }
    files
}

/// `%XX` escapes decoded (a malformed escape is kept as written).
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut k = 0;
    while k < bytes.len() {
        let hex = bytes
            .get(k + 1..k + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (bytes[k], hex) {
            (b'%', Some(byte)) => {
                out.push(byte);
                k += 3;
            }
            (byte, _) => {
                out.push(byte);
                k += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod input_tests {
    use super::*;

    #[test]
    fn percent_escapes_are_decoded() {
        assert_eq!(percent_decode("my%20tex%2Epng"), "my tex.png");
        assert_eq!(percent_decode("a%2"), "a%2");
        assert_eq!(percent_decode("a%zz.png"), "a%zz.png");
    }
}
