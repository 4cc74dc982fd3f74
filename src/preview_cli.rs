//! `bake preview FILE PNG`: its own small command line, dispatched from `main` when the first
//! argument is `preview`. The rendering is in the `bake-preview` crate.

use clap::Parser;
use std::ffi::OsString;
use std::path::PathBuf;
use std::process::ExitCode;

/// Renders a baked glTF/GLB to a PNG with a small software rasterizer, so a bake can be
/// checked with no viewer installed.
///
/// Every vertex shows COLOR_0 (what an unlit viewer shows; with --exposure, _RADIOSITY × X
/// instead), interpolated across triangles: a `--shading flat` bake shows one constant colour
/// per element, a smooth one the interpolated vertex values. Single-sided triangles are culled
/// from behind (glTF's rule), so the camera looks into a closed room through its near wall.
///
/// A lightmap bake (`MOZ_lightmap` on TEXCOORD_1) is drawn through its lightmap as a lit viewer
/// shows it: clamp((e + ρ H) × exposure, 0, 1), the exposure the bake recorded (or --exposure).
///
/// Camera: --eye looking at --look-at (--fov, default 60°); else the file's first perspective
/// camera node, if any; otherwise (or with --view) a 45° camera looking along the view
/// direction (default 0,0,-1: from the +Z side), backed off until the scene's bounding box
/// fills the image. Output: 8-bit sRGB PNG, written atomically;
/// the same file and options give the same bytes.
///
/// Exit codes: 0 ok; 1 bad input (unreadable file, nothing to draw, invalid option values);
/// 2 usage error; 3 output error (PNG could not be written).
#[derive(Parser, Debug)]
#[command(
    name = "bake preview",
    bin_name = "bake preview",
    version,
    about,
    long_about,
    max_term_width = 100
)]
struct PreviewCli {
    /// Baked scene: .gltf or .glb.
    input: PathBuf,
    /// Image to write (.png).
    output: PathBuf,
    /// Image width in pixels.
    #[arg(long, value_name = "PX", default_value_t = 512,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(bake_job::preview::MAX_SIZE)))]
    width: u32,
    /// Image height in pixels.
    #[arg(long, value_name = "PX", default_value_t = 512,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(bake_job::preview::MAX_SIZE)))]
    height: u32,
    /// Show clamp(_RADIOSITY × X, 0, 1) instead of COLOR_0.
    ///
    /// Re-exposes without re-baking; COLOR_0 × X where a primitive has no _RADIOSITY.
    #[arg(long, value_name = "X", allow_negative_numbers = true)]
    exposure: Option<f64>,
    /// Look along this direction, framing the whole scene.
    ///
    /// Overrides a camera node; e.g. `--view 0,-1,-1` to look down at 45°.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_view, allow_hyphen_values = true)]
    view: Option<[f64; 3]>,
    /// Stand here (with --look-at), e.g. inside a room.
    ///
    /// Overrides --view and a camera node; single-sided walls are seen from their front.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_view, allow_hyphen_values = true,
          requires = "look_at")]
    eye: Option<[f64; 3]>,
    /// Look at this point from --eye.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_view, allow_hyphen_values = true,
          requires = "eye")]
    look_at: Option<[f64; 3]>,
    /// Vertical field of view of --eye/--look-at, in degrees [default: 60].
    #[arg(long, value_name = "DEG", requires = "eye")]
    fov: Option<f64>,
    /// Print nothing but errors.
    #[arg(long, short)]
    quiet: bool,
}

/// Runs `bake preview` with `args` (the first one being `preview`).
pub fn main(args: impl IntoIterator<Item = OsString>) -> ExitCode {
    let cli = match PreviewCli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => return crate::usage_error(&e, "bake preview"),
    };
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err((code, message)) => {
            eprintln!("bake: error: {message}");
            ExitCode::from(code)
        }
    }
}

/// `X,Y,Z` → three finite numbers.
fn parse_view(text: &str) -> Result<[f64; 3], String> {
    let numbers: Vec<f64> = text
        .split(',')
        .map(|part| part.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("expected three numbers X,Y,Z: {e}"))?;
    match numbers[..] {
        [x, y, z] if [x, y, z].iter().all(|v| v.is_finite()) => Ok([x, y, z]),
        _ => Err("expected three finite numbers X,Y,Z".to_string()),
    }
}

fn run(cli: &PreviewCli) -> Result<(), (u8, String)> {
    let is_png = cli
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        return Err((
            3,
            format!(
                "unsupported output extension for {} (expected .png)",
                cli.output.display()
            ),
        ));
    }
    let colors = match cli.exposure {
        None => bake_job::preview::ColorSource::Color0,
        Some(x) if x.is_finite() && x >= 0.0 => {
            bake_job::preview::ColorSource::Radiosity { exposure: x }
        }
        Some(x) => {
            return Err((
                1,
                format!("--exposure must be a finite number ≥ 0, got {x}"),
            ))
        }
    };
    let options = bake_job::preview::Options {
        width: cli.width,
        height: cli.height,
        colors,
        view: cli.view,
        eye: cli.eye,
        look_at: cli.look_at,
        fov: cli.fov,
        ..bake_job::preview::Options::default()
    };
    bake_job::check_preview_output(&cli.input, &cli.output)
        .map_err(|failure| (failure.code, failure.line()))?;
    let code = |e: &bake_job::preview::PreviewError| if e.is_input_error() { 1 } else { 3 };
    let rendered = bake_job::preview::render_file(&cli.input, &options)
        .map_err(|e| (code(&e), e.to_string()))?;
    bake_job::preview::write_png(&cli.output, &rendered.image)
        .map_err(|e| (code(&e), e.to_string()))?;
    if !cli.quiet {
        if rendered.skipped_primitives > 0 {
            eprintln!(
                "bake: warning: {} point or line primitives not drawn",
                rendered.skipped_primitives
            );
        }
        eprintln!(
            "bake: preview {} → {}: {}×{}, {} triangles ({} drawn, {} back faces culled), {}",
            cli.input.display(),
            cli.output.display(),
            cli.width,
            cli.height,
            rendered.triangles,
            rendered.stats.rasterized,
            rendered.stats.culled,
            rendered.choice,
        );
    }
    Ok(())
}
