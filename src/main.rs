//! `bake`: the command line. It parses options and wires the pipeline stages together
//! (importer → mesher → form-factor → solver → exporter); all the work is in the crates.

mod pipeline;

use clap::{Parser, ValueEnum};
use std::path::PathBuf;
use std::process::ExitCode;

/// Bakes diffuse global illumination (radiosity) into a glTF scene.
///
/// Reads IN (.gltf, .glb, or .obj with its .mtl), subdivides every polygon into elements,
/// computes element-to-element form factors by the contour integral, solves
/// (I − ρF) b = e per colour band, and writes OUT (.gltf + .bin, or .glb) with the
/// radiosity baked into vertex colours (COLOR_0) on the element mesh, shown by an unlit
/// material. Emission and radiosity share one unit (the paper's intensity): a surface
/// with e = 1 and nothing else lit shows 1.
///
/// Exit codes: 0 ok; 1 bad input (unreadable or malformed scene, invalid values, no finite
/// solution); 2 usage error; 3 internal or output error (OUT could not be written).
#[derive(Parser, Debug)]
#[command(name = "bake", version, about, long_about, max_term_width = 100)]
pub struct Cli {
    /// Input scene: .gltf, .glb or .obj (materials from the .mtl it names).
    pub input: PathBuf,
    /// Output scene: .gltf (writes OUT's stem + .bin beside it) or .glb. Written atomically.
    pub output: PathBuf,

    /// Subdivide every quad into N×N elements and every triangle into N² elements.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024),
          conflicts_with = "max_element_size")]
    pub subdiv: Option<u32>,
    /// Subdivide so that no element edge is longer than L (world units). Default when neither
    /// this nor --subdiv is given: the scene's bounding-box diagonal / 16 (the unit cube gets
    /// 10×10 elements per wall).
    #[arg(long, value_name = "L", allow_negative_numbers = true)]
    pub max_element_size: Option<f64>,

    /// Truncate the light transport after exactly K interreflections instead of solving the
    /// system exactly (K = 0: direct light from emitters only; the paper's Figure 7).
    #[arg(long, value_name = "K")]
    pub bounces: Option<u32>,

    /// Vertex values: `smooth` averages neighbouring elements (area-weighted, the paper's
    /// linear smoothing, Figure 8); `flat` exports every element with its own constant value
    /// (Figure 6).
    #[arg(long, value_enum, default_value_t = Shading::Smooth)]
    pub shading: Shading,
    /// Multiply radiosity by this before clamping to [0, 1] for COLOR_0 (the unclamped value
    /// is kept in the _RADIOSITY attribute and the report).
    #[arg(
        long,
        value_name = "X",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    pub exposure: f64,

    /// Contour integral: cut each element edge into this many equal segments.
    #[arg(long, value_name = "N", default_value_t = 1,
          value_parser = clap::value_parser!(u32).range(1..=64))]
    pub ff_segments: u32,
    /// Contour integral: Gauss–Legendre points per segment for well-separated segment pairs
    /// (3 is the paper's nine-point rule). Near and touching segments are always integrated
    /// semi-analytically to machine precision.
    #[arg(long, value_name = "N", default_value_t = 3,
          value_parser = clap::value_parser!(u32).range(1..=8))]
    pub ff_order: u32,

    /// What to write. `vertex`: OUT holds the element mesh with the radiosity in COLOR_0
    /// (unlit). `lightmap`: OUT holds the input's polygons (not subdivided) with lit materials,
    /// TEXCOORD_1 and a MOZ_lightmap PNG (OUT's stem + .lightmap.png), plus OUT's stem +
    /// .lightmap.exr (linear float irradiance). `both`: OUT holds the vertex bake and OUT's stem
    /// + .lightmap.gltf (or .glb) the lightmap bake, the images beside it.
    #[arg(long, value_enum, default_value_t = Target::Both)]
    pub target: Target,
    /// Lightmap texel size in world units (default: the scene's bounding-box diagonal / 256).
    /// Made coarser automatically when the atlas would be larger than --lightmap-max.
    #[arg(long, value_name = "L", allow_negative_numbers = true)]
    pub lightmap_texel: Option<f64>,
    /// Largest lightmap atlas side, in texels.
    #[arg(long, value_name = "N", default_value_t = lightmap::DEFAULT_MAX_SIZE,
          value_parser = clap::value_parser!(u32).range(16..=16384))]
    pub lightmap_max: u32,

    /// Write a JSON bake report (options, counts, timings, residuals, every element's
    /// centroid, normal, area, ρ, e and b in world space).
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// Worker threads (default: all cores). Output bytes do not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// Print nothing but errors (no warnings, progress or summary).
    #[arg(long, short)]
    pub quiet: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Target {
    Vertex,
    Lightmap,
    Both,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Shading {
    Smooth,
    Flat,
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    match pipeline::run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            eprintln!("bake: error: {}", one_line(&failure.error));
            ExitCode::from(failure.code)
        }
    }
}

/// The error and its causes on one line, `: `-separated. A cause whose text the line already
/// holds is left out: the crates' messages often embed their source (`cannot read X: {io}`).
fn one_line(error: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        let text = text.split_whitespace().collect::<Vec<_>>().join(" ");
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}
