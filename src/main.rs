//! `bake`: the command line. It parses options and wires the pipeline stages together
//! (importer → the `bake` library's one bake → lightmap → exporter); all the work is in the
//! crates.

mod bars;
mod preview_cli;

use bake_job::{
    ContourOptions, ElementsIncluded, EstimatorKind, Exposure, Job, LightmapOptions, Probes,
    Quality, Request, Shading, Sky, SkyModel, SolverKind, Subdivision, Target, TransportKind,
    UvMode, DEFAULT_GROUND_REFLECTANCE, MAX_SKY_SAMPLES,
};
use clap::builder::TypedValueParser;
use clap::{CommandFactory, Parser, ValueEnum};
use std::path::PathBuf;
use std::process::ExitCode;
use std::str::FromStr;

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
/// solution, iterative solver not converged); 2 usage error; 3 internal or output error (OUT
/// could not be written); 4 too large for this machine (needs more memory than is available:
/// it may bake on a larger machine or with coarser options); 130 or 143 interrupted (SIGINT,
/// SIGTERM: the bake's temporary files are removed, the previous outputs kept).
///
/// To look at a bake with no viewer installed: `bake preview OUT.gltf OUT.png` renders it
/// (see `bake preview --help`).
#[derive(Parser, Debug)]
#[command(name = "bake", version, about, long_about, max_term_width = 100)]
pub struct Cli {
    /// Input scene: .gltf, .glb or .obj (materials from the .mtl it names).
    pub input: PathBuf,
    /// Output scene: .gltf (writes OUT's stem + .bin beside it) or .glb. Written atomically.
    pub output: PathBuf,

    // ---- Accuracy ----
    /// The accuracy–time trade in one knob.
    ///
    /// Sets the element size, target error (--max-error), form-factor estimator, and shadow
    /// rays, as measured in docs/accuracy.md. `draft`: elements of diagonal/8, --max-error 3e-2,
    /// 49 rays; `normal`: diagonal/16, 1e-2, 121 rays; `high`: diagonal/32, 3e-3, 961 rays.
    /// Options given explicitly override the preset.
    #[arg(long, value_enum, default_value_t = Quality::Normal, help_heading = "Accuracy")]
    pub quality: Quality,
    /// Target relative error of the radiosity b, in (0, 1).
    ///
    /// The dense transport's per-pair form-factor tolerance is derived from it and the scene's
    /// largest reflectance ρ, through the bound cond∞ ≤ (1 + ρ(1 + τ))/(1 − ρ(1 + τ)) (bright
    /// rooms get tighter form factors, e.g. 5e-7 per pair for ρ = 0.999 at 1e-3). The
    /// hierarchical transport's link tolerance is derived from it and the amplification its
    /// coarse solves measure (ε = E × mean b / (mean b / mean emission)), and its GMRES
    /// tolerance is E / 100 (at most 1e-6). It bounds what the transport can add, not the element size's
    /// discretisation error (see the report's `error`). [default: from --quality: 3e-2 draft,
    /// 1e-2 normal, 3e-3 high]
    #[arg(long, value_name = "E", value_parser = parse_tolerance, help_heading = "Accuracy")]
    pub max_error: Option<f64>,
    /// No element edge longer than L (world units).
    ///
    /// Default when neither this nor --subdiv is given: the scene's bounding-box diagonal / 16
    /// with --quality normal (the unit cube gets 10×10 elements per wall), / 8 draft, / 32 high.
    #[arg(
        long,
        value_name = "L",
        allow_negative_numbers = true,
        help_heading = "Accuracy"
    )]
    pub max_element_size: Option<f64>,
    /// Subdivide every quad into N×N elements and every triangle into N² elements.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024),
          conflicts_with = "max_element_size", help_heading = "Accuracy")]
    pub subdiv: Option<u32>,
    /// Refine where the light changes (default: on, dense transport).
    ///
    /// After a solve, split elements whose discretisation estimate exceeds --max-error
    /// (relative to the mean radiosity) or that a light's shadow edge crosses, and solve again,
    /// until the estimate meets it, --max-elements is reached (a warning says where) or nothing
    /// changes; vertex values are not smoothed across shadow edges. On by default on the dense
    /// transport; on the hierarchical transport (each solve links the scene again, at most 3
    /// solves) only when asked (`on`, or --max-elements); `off` keeps the uniform mesh.
    #[arg(long, value_enum, value_name = "on|off", help_heading = "Accuracy")]
    pub refine: Option<OnOff>,
    /// The element budget of refinement.
    ///
    /// [default: 2000, the dense crossover; on a scene of up to 4000 elements that `auto` gives
    /// the hierarchical transport, twice the grid's elements and at least 4000; else on the
    /// hierarchical transport the grid's elements plus a quarter where that is more]
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..),
          help_heading = "Accuracy")]
    pub max_elements: Option<u64>,
    /// Shadow rays per element pair that something may come between.
    ///
    /// Hidden surfaces: shadow rays per element pair that some polygon may come between
    /// (rounded to a square of strata, 1…1024). Pairs nothing can come between (every pair of
    /// a convex enclosure such as the paper's cube) keep the exact form factor and cast no
    /// ray. Measured on the Cornell box: 49 / 121 / 289 / 961 rays give an rms error of the
    /// visible fraction of 0.030 / 0.016 / 0.009 / 0.005. [default: from --quality: 49,
    /// 121, 961]
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..=1024),
          help_heading = "Accuracy")]
    pub visibility_samples: Option<u32>,
    /// Hierarchical transport: largest error of one link, relative to the mean radiosity.
    ///
    /// The largest estimated error of one link's contribution to the radiosity of its
    /// receiver, relative to the scene's mean radiosity [default: derived from --max-error:
    /// E over the amplification the linking passes' coarse solves measure].
    #[arg(long, value_name = "T", value_parser = parse_positive, help_heading = "Accuracy")]
    pub link_tolerance: Option<f64>,

    // ---- Lights ----
    /// Shadow rays per element that a point or spot light may be shadowed on.
    ///
    /// Punctual lights (KHR_lights_punctual point and spot lights): shadow rays per element
    /// that some polygon may shadow from the light (rounded to a square of strata, 1…1024).
    /// Elements nothing can shadow get the exact closed form and no ray; directional lights'
    /// shadows are clipped exactly and cast none. [default: from --quality: 4, 16, 64]
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..=1024),
          help_heading = "Lights")]
    pub light_samples: Option<u32>,
    /// A sky over the scene as a light source: uniform:L, overcast:Lz, clear:Lz or map:FILE.
    ///
    /// uniform:L is the same radiance L in every direction above the horizon; overcast:Lz the
    /// CIE standard overcast sky, L(γ) = Lz (1 + 2 sin γ) / 3 at elevation γ (the horizon a
    /// third of the zenith); clear:Lz the CIE standard clear sky (type 12) of zenith
    /// luminance Lz around the sun of the scene's directional light (or --sun-direction),
    /// the sun's own light being that light's; map:FILE an equirectangular .hdr or .exr map over the whole
    /// sphere (row 0 at the zenith, the middle column along +X, three quarters along +Z; its
    /// lower half is the ground). Radiance is in the bake's units (cd/m² when the lights are in
    /// candela and lux). +Y is up. The sky is what a ray reaches when it meets no surface at
    /// all: any polygon, front or back face, blocks it; below the horizon a ray that meets
    /// nothing sees the ground (--ground-reflectance). See docs/lights.md, "Sky".
    #[arg(long, value_name = "MODEL:L", value_parser = parse_sky, help_heading = "Lights")]
    pub sky: Option<SkyModel>,
    /// The direction toward the sun for --sky clear (x,y,z, +Y up; need not be unit).
    ///
    /// Without it the clear sky's sun is opposite the scene's first directional light.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_direction, help_heading = "Lights")]
    pub sun_direction: Option<[f64; 3]>,
    /// Reflectance of the ground below the sky's horizon, in [0, 1].
    ///
    /// The ground has radiance R × E_h / π, E_h the sky's unobstructed horizontal
    /// illuminance (uniform: π L; overcast: 7π Lz / 9).
    #[arg(long, value_name = "R", default_value_t = DEFAULT_GROUND_REFLECTANCE,
          value_parser = parse_reflectance, help_heading = "Lights")]
    pub ground_reflectance: f64,
    /// Rays per element that some polygon may block from the sky.
    ///
    /// Rounded to a square of strata (stratified cosine-weighted directions from stratified
    /// points of the element). Elements with no polygon in front of their plane get the
    /// exact closed form and cast no ray. Measured on an open courtyard at 0.5 m elements:
    /// 256 / 1024 / 4096 / 16384 rays give 2.6% / 1.1% / 0.44% / 0.20% RMS error.
    /// [default: from --quality: 256, 1024, 4096]
    #[arg(long, value_name = "K",
          value_parser = clap::value_parser!(u32).range(1..=MAX_SKY_SAMPLES as i64),
          help_heading = "Lights")]
    pub sky_samples: Option<u32>,
    /// Lightmap bake: keep the input's punctual lights on their nodes.
    ///
    /// Their light is already in the lightmap, so a lit viewer shows it twice; for engines that
    /// use them for specular highlights only.
    #[arg(long, help_heading = "Lights")]
    pub keep_lights: bool,
    /// Light probes: off, auto (a grid at the scene's diagonal / 16) or grid:SPACING.
    ///
    /// Probes on a grid over the scene's bounds, moved out of geometry (or flagged invalid),
    /// each with the incident radiance from the baked surfaces as spherical harmonics up to
    /// L2, written as the BAKE_irradiance_probes extension on every output scene. Punctual
    /// lights and the sky are not in them: the renderer draws those. Nodes marked
    /// `"bake_probe": true` in their glTF extras are added after the grid. See docs/probes.md.
    #[arg(long, value_name = "auto|off|grid:SPACING", default_value = "off",
          value_parser = parse_probes, help_heading = "Lights")]
    pub probes: Probes,

    // ---- Lightmap ----
    /// Lightmap texel size in world units (default: the scene's bounding-box diagonal / 256).
    ///
    /// Made coarser automatically when the atlases would be larger than --lightmap-max (after
    /// --lightmap-atlases atlases).
    #[arg(
        long,
        value_name = "L",
        allow_negative_numbers = true,
        help_heading = "Lightmap"
    )]
    pub lightmap_texel: Option<f64>,
    /// Largest lightmap atlas side, in texels.
    #[arg(long, value_name = "N", default_value_t = bake_job::DEFAULT_MAX_SIZE,
          value_parser = clap::value_parser!(u32).range(16..=16384), help_heading = "Lightmap")]
    pub lightmap_max: u32,
    /// Most lightmap atlases before the texel size is made coarser.
    ///
    /// When the charts at the texel size do not fit one --lightmap-max atlas, whole primitives
    /// are packed into several (each its own PNG and EXR) before the texel size is made
    /// coarser; 1 keeps one atlas.
    #[arg(long, value_name = "N", default_value_t = bake_job::DEFAULT_MAX_ATLASES,
          value_parser = clap::value_parser!(u32).range(1..=256), help_heading = "Lightmap")]
    pub lightmap_atlases: u32,
    /// Where the lightmap's charts come from.
    ///
    /// `keep`: the input's TEXCOORD_1 as authored (refused when it leaves [0, 1], overlaps
    /// within a primitive — or a double-sided face's sides would share texels — or a material
    /// samples it as a texture set; primitives that overlap each other get an atlas each);
    /// `generate`: one chart per polygon, packed; `auto`: `keep` when the whole scene's
    /// TEXCOORD_1 is usable, else per primitive: one whose own TEXCOORD_1 is usable keeps it
    /// in an atlas region of its own (scaled and moved), the others are generated (the
    /// report's options.lightmap_layout says which and why, per primitive).
    #[arg(long, value_enum, default_value_t = UvMode::Auto, help_heading = "Lightmap")]
    pub lightmap_uv: UvMode,

    // ---- Output ----
    /// What to write: the vertex bake, the lightmap bake, both, or the baked-texture bake.
    ///
    /// `vertex`: OUT holds the element mesh with the radiosity in COLOR_0 (unlit). `lightmap`:
    /// OUT holds the input's polygons (not subdivided) with lit materials, TEXCOORD_1 and a
    /// MOZ_lightmap PNG (OUT's stem + .lightmap.png), plus OUT's stem + .lightmap.exr (linear
    /// float irradiance). `both`: OUT holds the vertex bake and OUT's stem + .lightmap.gltf (or
    /// .glb) the lightmap bake, the images beside it. `baked-texture`: OUT holds the input's
    /// polygons with KHR_materials_unlit materials whose base-colour texture on TEXCOORD_1
    /// (OUT's stem + .baked.png, sRGB) is what the surface shows, (ρ × H + e) × exposure, the
    /// base-colour texture multiplied in per texel: any glTF viewer shows the bake as it is
    /// (the --lightmap-* options set its texels).
    #[arg(long, value_enum, default_value_t = Target::Both, help_heading = "Output")]
    pub target: Target,
    /// Vertex values and lightmap texels: smoothed, or constant per element.
    ///
    /// `smooth` averages neighbouring elements (area-weighted, the paper's linear smoothing,
    /// Figure 8); `flat` exports every element with its own constant value (Figure 6), and
    /// every lightmap texel with its element's H.
    #[arg(long, value_enum, default_value_t = Shading::Smooth, help_heading = "Output")]
    pub shading: Shading,
    /// Multiply radiosity by X before clamping it into COLOR_0.
    ///
    /// Multiply radiosity by X before clamping to [0, 1] for COLOR_0 (the unclamped value is
    /// kept in the _RADIOSITY attribute and the report). `auto`: the exposure that maps the
    /// 99th percentile, by area, of the elements' brightest band to 0.8 (punctual lights give
    /// b in the hundreds or thousands of nits); `ev100:N`: a camera's exposure value at ISO
    /// 100, exposure = 1 / (1.2 × 2^N), so 1.2 × 2^N cd/m² maps to 1 (overcast daylight
    /// N ≈ 12, an office N ≈ 7); the summary line and the report say which exposure was used.
    #[arg(
        long,
        value_name = "X|auto|ev100:N",
        default_value = "1",
        allow_negative_numbers = true,
        value_parser = Exposure::from_str,
        help_heading = "Output"
    )]
    pub exposure: Exposure,
    /// Write a JSON bake report.
    ///
    /// Options, counts, timings, residuals, every element's centroid, normal, area, ρ, e and b
    /// in world space.
    #[arg(long, value_name = "FILE.json", help_heading = "Output")]
    pub report: Option<PathBuf>,
    /// What the report says per element.
    ///
    /// `all` (a summary and every element), `summary` (count, area, range and mean of b) or
    /// `none` [default: all up to 100 000 elements, summary above, with a warning].
    #[arg(long, value_enum, value_name = "WHICH", help_heading = "Output")]
    pub report_elements: Option<ElementsIncluded>,
    /// Print nothing but errors (no warnings, progress or summary).
    #[arg(long, short, help_heading = "Output")]
    pub quiet: bool,

    // ---- Expert ----
    /// How light moves between elements.
    ///
    /// `dense`: every element pair's form factor in an n × n matrix (exact; time and memory
    /// grow with n²). `hierarchical`: hierarchical radiosity (Hanrahan, Salzman & Aupperle
    /// 1991): each polygon is a tree over its elements and light moves along links between the
    /// coarsest node pairs whose estimated error is below the link tolerance --max-error
    /// derives (or --link-tolerance; links grow about
    /// linearly with n). `auto`: the cheaper by a cost model measured on this project's scenes
    /// (pairs and shadow rays against links, each at the elements its refinement would reach;
    /// dense also where it costs under 0.1 s: it is exact), dense for bright scenes up to 8000
    /// elements; scenes up to 4000 elements on the hierarchy are refined by default, to twice
    /// their grid and at least 4000 elements. The report's `transport.reason` gives both
    /// estimates.
    #[arg(long, value_enum, default_value_t = TransportKind::Auto, help_heading = "Expert")]
    pub transport: TransportKind,
    /// How to solve (I − ρF) b = e exactly: LU or GMRES.
    ///
    /// `direct`: LU factorisation, O(n³) time and an n×n matrix per distinct reflectance band;
    /// always finishes. `iterative`: GMRES, O(n²) per iteration and little extra memory; stops
    /// when the relative residual ‖(I − ρF) b − e‖ / ‖e‖ of every band is at most --tolerance,
    /// and fails (exit 1, naming the band, iterations and residual) rather than return an
    /// unconverged answer when --max-iterations runs out. Both refuse systems without a
    /// meaningful finite solution (e.g. a closed scene with ρ = 1 and an emitter) and report
    /// the condition number cond∞(I − ρF) per band, about (1 + ρ)/(1 − ρ) in a closed grey
    /// scene. [default: direct for the dense transport; the hierarchical transport is always
    /// solved by GMRES]
    #[arg(long, value_enum, help_heading = "Expert")]
    pub solver: Option<SolverKind>,
    /// Iterative solver: the relative residual to reach, in (0, 1).
    ///
    /// [default: 1e-12 dense, 1e-6 hierarchical]; implies --solver iterative. The error of b is
    /// at most about cond∞ × T. Rounding alone leaves a residual of about 1e-16 × cond∞ × √n,
    /// so very bright closed scenes (ρ ≥ 0.9999) may need T ≥ 1e-11.
    #[arg(long, value_name = "T", value_parser = parse_tolerance, help_heading = "Expert")]
    pub tolerance: Option<f64>,
    /// Iterative solver: GMRES iterations allowed per band.
    ///
    /// Each one multiplies by the form-factor matrix once [default: 1000]; implies --solver
    /// iterative.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..),
          help_heading = "Expert")]
    pub max_iterations: Option<u32>,
    /// Truncate after exactly K interreflections instead of solving exactly.
    ///
    /// Truncate the light transport after exactly K interreflections instead of solving the
    /// system exactly (K = 0: direct light from emitters only; the paper's Figure 7). At most
    /// 10000 (each bounce multiplies by the transport once). Not with --solver.
    #[arg(long, value_name = "K", conflicts_with = "solver",
          value_parser = clap::value_parser!(u32).range(0..=i64::from(bake_job::MAX_BOUNCES)),
          help_heading = "Expert")]
    pub bounces: Option<u32>,
    /// How to compute each element pair's form factor.
    ///
    /// `contour`: the contour integral (eq. 13), exact to ~1e-15 with the default options.
    /// `point-polygon`: the closed form from points of the smaller element (--ff-points per
    /// triangle) to the other element. `point-point`: cosθi cosθj Aj / (π r²) at the
    /// centroids. `auto` (the presets' choice): per pair, the cheapest of those whose measured
    /// error bound meets --ff-tolerance.
    #[arg(long, value_enum, value_name = "E", help_heading = "Expert")]
    pub ff_estimator: Option<EstimatorKind>,
    /// `auto` estimator: largest relative error per element pair, in (0, 1).
    ///
    /// Implies --ff-estimator auto, and overrides the one --max-error derives. Below 1e-8 every
    /// pair gets the contour integral.
    #[arg(long, value_name = "T", value_parser = parse_tolerance, help_heading = "Expert")]
    pub ff_tolerance: Option<f64>,
    /// `point-polygon` estimator: quadrature points on the smaller element of each pair.
    ///
    /// 1 (its centroid), or 3 (degree 2) or 7 (degree 5) per triangle of its fan (a quad is two
    /// triangles).
    #[arg(long, value_name = "N", default_value_t = 3,
          value_parser = clap::builder::PossibleValuesParser::new(["1", "3", "7"])
              .map(|s| s.parse::<u32>().unwrap_or(3)),
          help_heading = "Expert")]
    pub ff_points: u32,
    /// Contour integral: cut each element edge into this many equal segments.
    #[arg(long, value_name = "N", default_value_t = 1,
          value_parser = clap::value_parser!(u32).range(1..=64), help_heading = "Expert")]
    pub ff_segments: u32,
    /// Contour integral: least Gauss–Legendre points per segment.
    ///
    /// For well-separated segment pairs (3 is the paper's nine-point rule). Pairs closer than
    /// 64 segment lengths get order 4 or 5 automatically unless --ff-fixed-order is given; near
    /// and touching segments are always integrated semi-analytically to machine precision.
    #[arg(long, value_name = "N", default_value_t = 3,
          value_parser = clap::value_parser!(u32).range(1..=8), help_heading = "Expert")]
    pub ff_order: u32,
    /// Contour integral: use --ff-order for every well-separated pair, as the paper does.
    ///
    /// Cheaper, ~1e-10 row-sum error instead of ~1e-15.
    #[arg(long, help_heading = "Expert")]
    pub ff_fixed_order: bool,
    /// Contour integral: segment pairs closer than R × their length get the semi-analytic rule.
    ///
    /// They get the closed-form inner integral and an adaptive outer rule (exact near
    /// contact); 0 gives every non-collinear segment pair the product Gauss rule, as the paper
    /// does (faster, far less accurate near shared edges).
    #[arg(long, value_name = "R", default_value_t = 8.0, value_parser = parse_near_ratio,
          help_heading = "Expert")]
    pub ff_near_ratio: f64,
    /// Reflectances at or above 1 are lowered to R.
    ///
    /// Reflectances at or above 1 (glTF's default material, a white texture on a white base
    /// colour) reflect all light, which no real surface does and which leaves a closed scene
    /// with an emitter no finite answer: they are lowered to R (one warning names the
    /// materials). Values below 1 stay as authored; 1 keeps them.
    #[arg(long, value_name = "R", default_value_t = bake_job::DEFAULT_MAX_REFLECTANCE,
          help_heading = "Expert")]
    pub max_reflectance: f64,
    /// Save the hierarchical transport's links to FILE, for re-bakes.
    ///
    /// The links hold form factors and visible fractions; for re-bakes that change only
    /// emission or colours (`--load-links`).
    #[arg(long, value_name = "FILE", help_heading = "Expert")]
    pub save_links: Option<PathBuf>,
    /// Solve with the links saved by `--save-links` instead of linking again.
    ///
    /// Refused unless the geometry, mesh and link options are the same.
    #[arg(long, value_name = "FILE", help_heading = "Expert")]
    pub load_links: Option<PathBuf>,
    /// Worker threads (default: all cores). Output bytes do not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024),
          help_heading = "Expert")]
    pub threads: Option<u32>,
    /// Let the scene read files outside its own folder.
    ///
    /// Buffer, image and `mtllib` URIs that are absolute, `file:` URIs, or relative paths that
    /// leave the folder (`..`, or a link inside it that points out). Refused by default, so
    /// that a scene only reads where the user points (docs/input-handling.md, "Files a scene
    /// reads").
    #[arg(long, help_heading = "Expert")]
    pub allow_outside_paths: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

impl Cli {
    /// The job: what to read and write, and the bake's options as the library takes them
    /// (`None`: from the preset or default).
    pub fn job(&self) -> Job {
        let subdivision = match (self.subdiv, self.max_element_size) {
            (Some(n), _) => Some(Subdivision::Count(n)),
            (None, Some(l)) => Some(Subdivision::MaxSize(l)),
            (None, None) => None,
        };
        let iterative_given = self.tolerance.is_some() || self.max_iterations.is_some();
        let request = Request {
            quality: self.quality,
            subdivision,
            contour: ContourOptions {
                segments: self.ff_segments,
                order: self.ff_order,
                auto_order: !self.ff_fixed_order,
                near_ratio: self.ff_near_ratio,
            },
            ff_estimator: self.ff_estimator,
            ff_tolerance: self.ff_tolerance,
            max_error: self.max_error,
            ff_points: self.ff_points,
            visibility_samples: self.visibility_samples,
            solver: match (self.solver, iterative_given) {
                (Some(kind), _) => Some(kind),
                (None, true) => Some(SolverKind::Iterative),
                (None, false) => None,
            },
            bounces: self.bounces,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            transport: self.transport,
            link_tolerance: self.link_tolerance,
            light_samples: self.light_samples,
            sky: self.sky.clone().map(|model| Sky {
                model: match model {
                    SkyModel::Clear { zenith, map, .. } => SkyModel::Clear {
                        zenith,
                        sun: self.sun_direction,
                        map,
                    },
                    other => other,
                },
                ground_reflectance: self.ground_reflectance,
            }),
            sky_samples: self.sky_samples,
            // Set by the job from the target and the scene.
            irradiance: false,
            save_links: false,
            load_links: self.load_links.clone(),
            refine: self.refine.map(|r| r == OnOff::On),
            max_elements: self.max_elements,
            max_reflectance: Some(self.max_reflectance),
            refine_levels: None,
        };
        Job {
            input: self.input.clone(),
            output: self.output.clone(),
            request,
            target: self.target,
            shading: self.shading,
            exposure: self.exposure,
            lightmap: LightmapOptions {
                texel: self.lightmap_texel,
                max_size: self.lightmap_max,
                atlases: self.lightmap_atlases,
                uv: self.lightmap_uv,
            },
            keep_lights: self.keep_lights,
            report: self.report.clone(),
            report_elements: self.report_elements,
            save_links: self.save_links.clone(),
            allow_outside_paths: self.allow_outside_paths,
            probes: self.probes,
        }
    }
}

/// `--tolerance`: a finite number in (0, 1).
fn parse_tolerance(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(t) if t > 0.0 && t < 1.0 => Ok(t),
        Ok(t) => Err(format!("must be a number in (0, 1), got {t}")),
        Err(e) => Err(e.to_string()),
    }
}

/// `--link-tolerance`: a finite number > 0.
fn parse_positive(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(t) if t.is_finite() && t > 0.0 => Ok(t),
        Ok(t) => Err(format!("must be a finite number > 0, got {t}")),
        Err(e) => Err(e.to_string()),
    }
}

/// `--sky`: `uniform:L` or `overcast:Lz`.
fn parse_probes(text: &str) -> Result<Probes, String> {
    text.parse::<Probes>().map_err(|e| e.to_string())
}

fn parse_sky(text: &str) -> Result<SkyModel, String> {
    text.parse::<SkyModel>().map_err(|e| e.to_string())
}

/// `--sun-direction`: three finite numbers, not all 0.
fn parse_direction(text: &str) -> Result<[f64; 3], String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|e| e.to_string()))
        .collect::<Result<_, _>>()?;
    match values[..] {
        [x, y, z] if [x, y, z].iter().all(|v| v.is_finite()) && (x, y, z) != (0.0, 0.0, 0.0) => {
            Ok([x, y, z])
        }
        _ => Err(format!(
            "expected x,y,z: three finite numbers, not all 0; got {text:?}"
        )),
    }
}

/// `--ground-reflectance`: a number in [0, 1].
fn parse_reflectance(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(r) if (0.0..=1.0).contains(&r) => Ok(r),
        Ok(r) => Err(format!("must be a reflectance in [0, 1], got {r}")),
        Err(e) => Err(e.to_string()),
    }
}

/// `--ff-near-ratio`: a finite number ≥ 0.
fn parse_near_ratio(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(r) if r.is_finite() && r >= 0.0 => Ok(r),
        Ok(r) => Err(format!("must be a finite number ≥ 0, got {r}")),
        Err(e) => Err(e.to_string()),
    }
}

fn main() -> ExitCode {
    if std::env::args_os().nth(1).is_some_and(|a| a == "preview") {
        return preview_cli::main(std::env::args_os().skip(1));
    }
    let cli = match Cli::try_parse().and_then(check_solver_options) {
        Ok(cli) => cli,
        Err(e) => return usage_error(&e, "bake"),
    };
    if let Some(threads) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(threads as usize)
            .build_global()
        {
            eprintln!("bake: error: cannot start {threads} worker threads: {e}");
            return ExitCode::from(3);
        }
    }
    if let Err(e) = bake_job::exit_cleanly_on_interrupt(|line| eprintln!("\nbake: error: {line}")) {
        eprintln!("bake: error: cannot install the interrupt handler: {e}");
        return ExitCode::from(3);
    }
    let bars = bars::Bars::new(cli.quiet);
    let done = bake_job::run(&cli.job(), &bars);
    // A bar still open when the bake stops early is cleared, so the error line stands alone.
    drop(bars);
    match done {
        Ok(done) => {
            if !cli.quiet {
                eprintln!("bake: {}", done.summary);
            }
            ExitCode::SUCCESS
        }
        Err(failure) => {
            eprintln!("bake: error: {}", failure.line());
            ExitCode::from(failure.code)
        }
    }
}

/// A clap error as one line on stderr, exit 2 (`--help` and `--version`, which clap reports
/// as errors too, are printed as they are, exit 0). clap's block (the error, a tip, the usage
/// line, "for more information") becomes `error: <error> (<tip>; usage: <usage>; see
/// `<command> --help`)`.
pub(crate) fn usage_error(e: &clap::Error, command: &str) -> ExitCode {
    if !e.use_stderr() {
        let _ = e.print();
        return ExitCode::SUCCESS;
    }
    eprintln!("{}", usage_line(&e.render().to_string(), command));
    ExitCode::from(2)
}

/// See [`usage_error`].
fn usage_line(block: &str, command: &str) -> String {
    let mut lines = block.lines().map(str::trim).filter(|l| !l.is_empty());
    let first = lines.next().unwrap_or("error: invalid usage");
    let first = first.strip_prefix("error: ").unwrap_or(first);
    let mut notes: Vec<String> = Vec::new();
    for line in lines {
        if let Some(usage) = line.strip_prefix("Usage: ") {
            notes.push(format!("usage: {usage}"));
        } else if line.starts_with("For more information") {
            continue;
        } else {
            notes.push(line.to_string());
        }
    }
    notes.push(format!("see `{command} --help`"));
    format!("error: {first} ({})", notes.join("; "))
}

/// `--tolerance` and `--max-iterations` tune the iterative solver only: a usage error otherwise
/// (rather than silently ignoring them).
fn check_solver_options(cli: Cli) -> Result<Cli, clap::Error> {
    if cli.ff_tolerance.is_some() && cli.ff_estimator.is_some_and(|e| e != EstimatorKind::Auto) {
        return Err(Cli::command().error(
            clap::error::ErrorKind::ArgumentConflict,
            "--ff-tolerance applies only to --ff-estimator auto",
        ));
    }
    if cli.solver == Some(SolverKind::Direct) || cli.bounces.is_some() {
        for (given, flag) in [
            (cli.tolerance.is_some(), "--tolerance"),
            (cli.max_iterations.is_some(), "--max-iterations"),
        ] {
            if given {
                return Err(Cli::command().error(
                    clap::error::ErrorKind::ArgumentConflict,
                    format!(
                        "{flag} applies only to the iterative solver (--solver iterative, or the \
                         hierarchical transport)"
                    ),
                ));
            }
        }
    }
    Ok(cli)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clap_blocks_become_one_line() {
        let block = "error: unexpected argument '--foo' found\n\n  tip: to pass '--foo' as a \
                     value, use '-- --foo'\n\nUsage: bake [OPTIONS] <INPUT> <OUTPUT>\n\nFor more \
                     information, try '--help'.\n";
        assert_eq!(
            usage_line(block, "bake"),
            "error: unexpected argument '--foo' found (tip: to pass '--foo' as a value, use \
             '-- --foo'; usage: bake [OPTIONS] <INPUT> <OUTPUT>; see `bake --help`)"
        );
    }
}
