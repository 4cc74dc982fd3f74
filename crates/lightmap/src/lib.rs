//! Lightmaps for a radiosity bake: charts (one per polygon; unfolded across smooth, connected
//! surfaces where any polygons group; or the input's own `TEXCOORD_1` kept,
//! [`UvMode`]: the whole scene's as it is, or with `Auto` each usable primitive's in a region
//! of its own beside generated charts) packed into one atlas — or, when they do not fit one at the texel size, into
//! several ([`Options::max_atlases`], whole primitives per atlas, [`Lightmap::atlases`]) —
//! and per-texel irradiance reconstructed from the element solution, ready to be written as
//! a linear EXR and an 8-bit PNG per atlas. Not here: conformal unwrapping of doubly curved
//! charts (grouped charts are unfolded, so a sphere is cut where its unfolding would overlap
//! or leave a gap), splitting one primitive across atlases (a primitive too large for
//! one atlas makes the texels coarser), alpha cut-outs.
//!
//! Public API: [`build`] / [`build_with`] with [`Options`] → [`Lightmap`] (its atlases:
//! [`Lightmap::atlases`], each chart's [`Chart::atlas`]); [`encode_exr`], [`encode_png`]
//! (the first atlas), [`encode_exr_atlas`], [`encode_png_atlas`] (any).
//!
//! What a texel holds: the **irradiance** H, the light arriving at the surface, in the bake's
//! intensity units (those of emission e and radiosity b), so that `b = e + ρ H`. Engines
//! multiply a lightmap by their own albedo; a lightmap of b would apply ρ twice.
//!
//! How ([`Shading::Smooth`], the default): per-element H is smoothed to the element grid's
//! vertices (`ElementMesh::smooth`, the vertex bake's smoothing); vertices on edges shared with
//! coplanar polygons of the same material are welded (averaged) so those charts agree along
//! the edge; each texel whose centre maps to a surface point through the chart gets the grid's
//! interpolant there (bilinear on a quad's elements, linear on a triangle's). With
//! [`Shading::Flat`] (`--shading flat`) each such texel holds the H of the element its centre
//! maps into instead, so bilinear sampling at an element's centre reads exactly that element's
//! H once elements span at least 2 texels each way (steps at element edges, as the flat vertex
//! bake shows). Texels around a chart copy their nearest chart texel, far enough that bilinear
//! filtering at full resolution and at the first mip level reads only the chart's own values.
//!
//! Layout rules ([`chart`]): a quad becomes a rectangle with its true aspect, a triangle a right
//! triangle of its area so two share a rectangle; every chart has [`PADDING`] texels of its own
//! around it and regions start on even texels. Packing uses `etagere` (a maintained shelf
//! allocator: ~10k rectangles in milliseconds, ~85% occupancy sorted by height). That is the
//! layout of a scene of separate polygons (the cube, the Cornell box). Where polygons share
//! edges, charts are grouped (`group`: same node and material, grown by unfolding each
//! polygon about the edge it shares with the chart, across edges whose normals are within
//! [`CREASE_DEGREES`], normals within [`CHART_CONE_DEGREES`] of the chart's first polygon's,
//! no overlap, no part of the chart nearer in it than on the surface), so every polygon keeps
//! its shape and texel density is the same everywhere; each chart is turned to its smallest
//! bounding rectangle and packed by its shape (`mask`: the 2×2 blocks within reach of a
//! bilinear read at full resolution or the first mip level; `pack::pack_masks`, a profile
//! skyline, fits ragged charts into each other's corners), and owns those blocks: its gutter
//! is filled from its own charts only. Their texels, like a kept layout's, are made over the
//! whole atlas (`raster::atlas_texels`).
//!
//! Deterministic: the same input gives the same texels whatever the thread count.

mod authored;
mod chart;
mod encode;
mod field;
mod group;
mod mask;
mod pack;
mod raster;
mod seams;

pub use authored::{AuthoredUv, UvDecision, UvMode, MIN_PADDING, OWN_ATLAS, OWN_REGION};
pub use chart::{PADDING, PAIR_GAP};
pub use encode::{
    encode_exr, encode_exr_atlas, encode_png, encode_png_atlas, encode_srgb_png,
    encode_srgb_png_alpha, linear_to_srgb, png_scale, srgb_to_linear, PngLightmap, EXR_COMMENT,
    PNG_HEADROOM, PNG_PERCENTILE,
};
pub use group::{CHART_CONE_DEGREES, CREASE_DEGREES, GROUPED_ABOVE};
pub use raster::DILATION_RADIUS;

use field::Field;
use glam::{DVec2, DVec3};
use mesher::ElementMesh;
use rayon::prelude::*;
use scene::Polygon;
pub use seams::{Seams, FOOTPRINT, POINTS_PER_EDGE};

/// Default `--lightmap-max`: the largest atlas side, in texels.
pub const DEFAULT_MAX_SIZE: u32 = 4096;
/// The default texel size is the scene's bounding-box diagonal divided by this (the unit cube:
/// 148 texels per wall; 16 texels per default element).
pub const DEFAULT_TEXELS_PER_DIAGONAL: f64 = 256.0;

/// The default texel size (world units per texel) for `polygons`: diagonal / 256.
pub fn default_texel_size(polygons: &[Polygon]) -> f64 {
    let (lo, hi) = scene::bounds(polygons);
    (hi - lo).length() / DEFAULT_TEXELS_PER_DIAGONAL
}

/// How to build a lightmap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// World units per texel wanted; made coarser when the atlas would not fit in `max_size`.
    pub texel_size: f64,
    /// Largest atlas side, in texels (≥ 16).
    pub max_size: u32,
    /// How texels are made from the per-element values (`--shading`).
    pub shading: Shading,
    /// Most atlases (≥ 1): when the charts at the requested texel size do not fit one
    /// `max_size` atlas, whole primitives are packed into several (`--lightmap-atlases`)
    /// before the texel size is made coarser.
    pub max_atlases: u32,
}

/// Default `--lightmap-atlases`.
pub const DEFAULT_MAX_ATLASES: u32 = 16;

/// How texels are reconstructed from the per-element values (`--shading`, as for the
/// vertex bake).
pub use mesher::Shading;

/// Per-element values and each polygon's first element, for [`Shading::Flat`].
#[derive(Clone, Debug, PartialEq)]
struct Flat {
    elements: Vec<[f64; 3]>,
    first: Vec<u32>,
}

fn source<'a>(flat: &'a Option<Flat>, vertex_values: &'a [[f64; 3]]) -> raster::Source<'a> {
    match flat {
        Some(f) => raster::Source::Flat {
            elements: &f.elements,
            first: &f.first,
        },
        None => raster::Source::Smooth(vertex_values),
    }
}

/// What one texel of the atlas is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Texel {
    /// Outside every chart and gutter: never read by filtering (value 0).
    Unused,
    /// Read by bilinear filtering for some point of this polygon's chart.
    Chart(u32),
    /// Copy of the nearest chart texel of this polygon.
    Gutter(u32),
}

/// A rectangle of texels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

/// One polygon's place in the atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct Chart {
    /// Index into the polygons given to [`build`].
    pub polygon: usize,
    /// Texel-space position (x right, y down; texel (i, j) covers [i, i+1] × [j, j+1]) of each
    /// polygon vertex, in the polygon's vertex order. `TEXCOORD_1 = uv / (width, height)`.
    pub uv: Vec<[f64; 2]>,
    /// The region the packer placed: the chart, its gutter and, for two triangles sharing a
    /// rectangle, the other one. Regions never overlap. For a kept authored layout: the
    /// chart's bounding box in whole texels (neighbours in one island share edges).
    pub region: Rect,
    /// The atlas it is in (0: the [`Lightmap`]'s own texels; k ≥ 1: `more[k − 1]`).
    pub atlas: u32,
}

/// A second or later atlas of a [`Lightmap`] (the first is the lightmap's own fields).
#[derive(Clone, Debug, PartialEq)]
pub struct Atlas {
    pub width: u32,
    pub height: u32,
    /// Linear irradiance H per texel, row-major from the top-left.
    pub texels: Vec<[f32; 3]>,
    pub coverage: Vec<Texel>,
}

/// One atlas of a [`Lightmap`], borrowed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasRef<'a> {
    pub width: u32,
    pub height: u32,
    pub texels: &'a [[f32; 3]],
    pub coverage: &'a [Texel],
}

/// Numbers about a built lightmap.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    /// Texels read by filtering at full resolution for some chart point ([`Texel::Chart`]).
    pub chart_texels: u64,
    /// Chart texels whose centre lies inside their polygon.
    pub interior_texels: u64,
    pub gutter_texels: u64,
    /// `chart_texels / (width × height)`.
    pub occupancy: f64,
    /// Grid vertices averaged with a coplanar neighbour of the same material.
    pub welded_vertices: usize,
    /// Times the texel size was made coarser to fit `max_size`.
    pub reductions: u32,
    /// Charts made: one per polygon, or per group above [`GROUPED_ABOVE`] polygons (when
    /// any polygons group); 0 for a kept authored layout.
    pub charts: usize,
    /// Atlases (1 unless the charts did not fit one at the texel size).
    pub atlases: usize,
}

/// A built lightmap: the atlas of irradiance and where every polygon is in it.
#[derive(Clone, Debug, PartialEq)]
pub struct Lightmap {
    /// The first atlas (see [`Lightmap::atlases`] for all).
    pub width: u32,
    pub height: u32,
    /// World units per texel used (≥ the requested one).
    pub texel_size: f64,
    pub requested_texel_size: f64,
    /// Linear irradiance H per texel, row-major from the top-left.
    pub texels: Vec<[f32; 3]>,
    pub coverage: Vec<Texel>,
    /// The second and later atlases, when the charts needed several.
    pub more: Vec<Atlas>,
    /// One per polygon, in polygon order.
    pub charts: Vec<Chart>,
    /// The smoothed, welded H per mesh vertex the texels were reconstructed from.
    pub vertex_values: Vec<[f64; 3]>,
    pub stats: Stats,
    /// Per primitive instance, in (node, mesh, primitive) order: whether its `TEXCOORD_1`
    /// was kept as the layout, and if not why.
    pub uv_decisions: Vec<UvDecision>,
    /// Things the user should know (authored padding under [`MIN_PADDING`] texels).
    pub warnings: Vec<String>,
    /// How the texels were made.
    pub shading: Shading,
    fields: Vec<Field>,
    flat: Option<Flat>,
}

#[derive(Debug, thiserror::Error)]
pub enum LightmapError {
    #[error("invalid lightmap options: {0}")]
    InvalidOptions(String),
    /// The polygons, mesh and values do not fit together (a bug upstream).
    #[error("invalid lightmap data: {0}")]
    InvalidData(String),
    #[error("the charts do not fit in a {max}×{max} atlas at any texel size (too many polygons)")]
    TooLarge { max: u32 },
    /// `--lightmap-uv keep` with a `TEXCOORD_1` that is not a usable layout.
    #[error("cannot keep the input's TEXCOORD_1 as the lightmap layout: {0}")]
    AuthoredUv(String),
    #[error("cannot encode the {what} lightmap: {message}")]
    Encode { what: &'static str, message: String },
}

impl LightmapError {
    /// Whether the input is what cannot be mapped (too many charts for the atlas limits, an
    /// unusable authored layout), rather than a bug or an encoder failing.
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            LightmapError::TooLarge { .. } | LightmapError::AuthoredUv(_)
        )
    }
}

/// Builds the lightmap of `polygons` (the importer's polygons, world space) from their element
/// mesh and per-element irradiance H (3 bands, same units as e and b), with generated charts.
pub fn build(
    polygons: &[Polygon],
    mesh: &ElementMesh,
    element_irradiance: &[[f64; 3]],
    options: &Options,
) -> Result<Lightmap, LightmapError> {
    let none = AuthoredUv::none(polygons.len());
    build_with(
        polygons,
        mesh,
        element_irradiance,
        options,
        &none,
        UvMode::Generate,
    )
}

/// Whether each primitive's `TEXCOORD_1` would be kept, without building anything: for
/// `UvMode::Keep`, an error naming the first primitive whose layout is not usable.
pub fn plan_uv(
    polygons: &[Polygon],
    authored: &AuthoredUv,
    mode: UvMode,
    options: &Options,
) -> Result<Vec<UvDecision>, LightmapError> {
    let plan = authored::plan(
        polygons,
        authored,
        mode,
        options.texel_size,
        options.max_size,
    )?;
    if plan.exact {
        too_many_exact(plan.own.len(), options)?;
    }
    Ok(plan.decisions)
}

/// `keep` with an atlas per primitive: refused past `Options::max_atlases`.
fn too_many_exact(primitives: usize, options: &Options) -> Result<(), LightmapError> {
    if primitives > options.max_atlases as usize {
        return Err(LightmapError::AuthoredUv(format!(
            "{primitives} primitives' TEXCOORD_1 overlap each other: keeping each needs an atlas of its own, more than --lightmap-atlases {}",
            options.max_atlases
        )));
    }
    Ok(())
}

/// [`build`] with the input's authored `TEXCOORD_1` (`AuthoredUv::from_scene`) as the
/// layout where `mode` says so (see [`UvMode`]).
pub fn build_with(
    polygons: &[Polygon],
    mesh: &ElementMesh,
    element_irradiance: &[[f64; 3]],
    options: &Options,
    authored: &AuthoredUv,
    mode: UvMode,
) -> Result<Lightmap, LightmapError> {
    if !(options.texel_size.is_finite() && options.texel_size > 0.0) {
        return Err(LightmapError::InvalidOptions(format!(
            "the texel size must be a positive number, got {}",
            options.texel_size
        )));
    }
    if polygons.is_empty() {
        return Err(LightmapError::InvalidData("no polygons to lay out".into()));
    }
    if options.max_size < 16 {
        return Err(LightmapError::InvalidOptions(format!(
            "the atlas must be at least 16 texels wide, got {}",
            options.max_size
        )));
    }
    if element_irradiance.len() != mesh.elements.len() || mesh.patches.len() != polygons.len() {
        return Err(LightmapError::InvalidData(format!(
            "{} values for {} elements, {} patches for {} polygons",
            element_irradiance.len(),
            mesh.elements.len(),
            mesh.patches.len(),
            polygons.len()
        )));
    }
    if let Some(i) = element_irradiance
        .iter()
        .position(|v| !v.iter().all(|x| x.is_finite()))
    {
        return Err(LightmapError::InvalidData(format!(
            "irradiance of element {i} is not finite"
        )));
    }
    let fields = fields(polygons, mesh)?;
    let (vertex_values, welded_vertices) =
        smooth_and_weld(polygons, mesh, &fields, element_irradiance);
    let flat = (options.shading == Shading::Flat).then(|| Flat {
        elements: element_irradiance.to_vec(),
        first: mesh.patches.iter().map(|p| p.elements.start).collect(),
    });

    let plan = authored::plan(
        polygons,
        authored,
        mode,
        options.texel_size,
        options.max_size,
    )?;
    if let Some(kept) = plan.kept {
        return Ok(kept_lightmap(
            kept,
            options,
            fields,
            flat,
            vertex_values,
            welded_vertices,
            plan.decisions,
        ));
    }
    let layout = if plan.exact {
        Some(exact_layout(polygons, &plan.own, options)?)
    } else if !plan.own.is_empty() {
        Some(mixed_layout(polygons, &plan.own, options)?)
    } else {
        // Grouped charts where any polygons group (those alone in their group keep the
        // per-polygon layout beside them), or more polygons than one etagere atlas takes
        // as regions.
        let groups = (polygons.len() > GROUPED_ABOVE)
            .then(|| {
                group::groups(
                    polygons,
                    group::largest(options),
                    FOOTPRINT * options.texel_size,
                )
            })
            .filter(|g| g.len() < polygons.len() || polygons.len() > pack::MAX_REGIONS);
        match groups {
            Some(groups) => {
                let all: Vec<usize> = (0..polygons.len()).collect();
                Some(packed_layout(polygons, &[], &all, Some(groups), options)?)
            }
            None => None,
        }
    };
    // One chart per polygon: one atlas, or when that needs coarser texels several.
    let fitted = match layout {
        Some(_) => None,
        None => Some(fit(polygons, options)?),
    };
    let layout = match (layout, &fitted) {
        (Some(layout), _) => Some(layout),
        (None, Some(f)) if f.3 > 0 && options.max_atlases > 1 => {
            let all: Vec<usize> = (0..polygons.len()).collect();
            Some(packed_layout(polygons, &[], &all, None, options)?)
        }
        _ => None,
    };
    if let Some(layout) = layout {
        return Ok(assemble(
            layout,
            options,
            fields,
            flat,
            vertex_values,
            welded_vertices,
            plan.decisions,
        ));
    }
    let (texel_size, regions, packing, reductions) =
        fitted.ok_or_else(|| LightmapError::InvalidData("no layout".into()))?;
    let width = packing.width as usize;
    let mut texels = vec![[0.0f32; 3]; width * packing.height as usize];
    let mut coverage = vec![Texel::Unused; texels.len()];
    let mut charts: Vec<Option<Chart>> = vec![None; polygons.len()];
    let filled: Vec<raster::RegionTexels> = regions
        .par_iter()
        .map(|region| raster::region_texels(region, &fields, source(&flat, &vertex_values)))
        .collect();
    for ((region, &(rx, ry)), block) in regions.iter().zip(&packing.positions).zip(&filled) {
        let rect = Rect {
            x: rx,
            y: ry,
            width: region.width,
            height: region.height,
        };
        for y in 0..region.height as usize {
            let row = (ry as usize + y) * width + rx as usize;
            let from = y * region.width as usize;
            let n = region.width as usize;
            texels[row..row + n].copy_from_slice(&block.values[from..from + n]);
            coverage[row..row + n].copy_from_slice(&block.coverage[from..from + n]);
        }
        for (polygon, uv) in &region.charts {
            let offset = DVec2::new(f64::from(rx), f64::from(ry));
            charts[*polygon] = Some(Chart {
                polygon: *polygon,
                uv: uv.iter().map(|p| (*p + offset).to_array()).collect(),
                region: rect,
                atlas: 0,
            });
        }
    }
    let charts = charts
        .into_iter()
        .enumerate()
        .map(|(k, c)| {
            c.ok_or_else(|| LightmapError::InvalidData(format!("polygon {k} has no chart")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut stats = Stats {
        welded_vertices,
        reductions,
        charts: polygons.len(),
        atlases: 1,
        ..Stats::default()
    };
    for (k, t) in coverage.iter().enumerate() {
        match t {
            Texel::Chart(p) => {
                stats.chart_texels += 1;
                let c = DVec2::new((k % width) as f64 + 0.5, (k / width) as f64 + 0.5);
                let uv: Vec<DVec2> = charts[*p as usize]
                    .uv
                    .iter()
                    .map(|&q| DVec2::from_array(q))
                    .collect();
                stats.interior_texels += u64::from(raster::inside(c, &uv));
            }
            Texel::Gutter(_) => stats.gutter_texels += 1,
            Texel::Unused => {}
        }
    }
    stats.occupancy = stats.chart_texels as f64 / texels.len() as f64;
    Ok(Lightmap {
        width: packing.width,
        height: packing.height,
        texel_size,
        requested_texel_size: options.texel_size,
        texels,
        coverage,
        more: Vec::new(),
        charts,
        vertex_values,
        stats,
        uv_decisions: plan.decisions,
        warnings: Vec::new(),
        shading: options.shading,
        fields,
        flat,
    })
}

/// The lightmap of an authored layout: one square atlas, every chart where its TEXCOORD_1
/// puts it (regions: each chart's bounding box in whole texels).
fn kept_lightmap(
    kept: authored::Kept,
    options: &Options,
    fields: Vec<Field>,
    flat: Option<Flat>,
    vertex_values: Vec<[f64; 3]>,
    welded_vertices: usize,
    uv_decisions: Vec<UvDecision>,
) -> Lightmap {
    let side = kept.side;
    let regions = kept.charts.iter().map(|uv| texel_box(uv, side)).collect();
    let warnings = kept
        .padding
        .map(|gap| {
            format!(
                "the input's TEXCOORD_1 islands are {gap:.2} texels apart at {side}×{side} (under {MIN_PADDING}): filtering mixes their light"
            )
        })
        .into_iter()
        .collect();
    let atlas = vec![0; kept.charts.len()];
    assemble(
        Assembly {
            pages: vec![(side, side)],
            atlas,
            texel_size: kept.texel_size,
            reductions: kept.reductions,
            charts: kept.charts,
            regions,
            chart_count: 0,
            warnings,
            owners: None,
        },
        options,
        fields,
        flat,
        vertex_values,
        welded_vertices,
        uv_decisions,
    )
}

/// The bounding box in whole texels of a texel-space chart, inside a `side` atlas.
fn texel_box(uv: &[DVec2], side: u32) -> Rect {
    let (lo, hi) = uv.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), q| (lo.min(*q), hi.max(*q)),
    );
    let x = (lo.x.floor().max(0.0) as u32).min(side);
    let y = (lo.y.floor().max(0.0) as u32).min(side);
    let right = (hi.x.ceil().max(0.0) as u32).clamp(x, side);
    let bottom = (hi.y.ceil().max(0.0) as u32).clamp(y, side);
    Rect {
        x,
        y,
        width: right - x,
        height: bottom - y,
    }
}

/// `--lightmap-uv keep` when primitives' TEXCOORD_1 overlap each other but each one's is
/// usable: an atlas per primitive, square, its side from the texel size over the
/// primitive's UV area (as for a whole kept layout), TEXCOORD_1 unchanged. The lightmap's
/// texel size is the coarsest atlas's.
fn exact_layout(
    polygons: &[Polygon],
    own: &[authored::Own],
    options: &Options,
) -> Result<Assembly, LightmapError> {
    too_many_exact(own.len(), options)?;
    let max = options.max_size;
    let n = polygons.len();
    let mut charts = vec![Vec::new(); n];
    let mut regions = vec![texel_box(&[], 0); n];
    let mut atlas = vec![0; n];
    let (mut pages, mut warnings) = (Vec::new(), Vec::new());
    let (mut texel, mut reductions) = (0.0f64, 0);
    for (k, o) in own.iter().enumerate() {
        let (side, used, reduced) =
            authored::square_side(o.world_per_uv.sqrt(), options.texel_size, max);
        reductions += u32::from(reduced);
        texel = texel.max(used);
        let s = f64::from(side);
        for (&p, t) in o.polygons.iter().zip(&o.uv) {
            charts[p] = t.iter().map(|q| *q * s).collect();
            regions[p] = texel_box(&charts[p], side);
            atlas[p] = k as u32;
        }
        let uv: Vec<&[DVec2]> = o.uv.iter().map(Vec::as_slice).collect();
        if let Some(gap) = authored::check_layout(&uv, Some(s)).padding {
            warnings.push(format!(
                "{}: its TEXCOORD_1 islands are {gap:.2} texels apart at {side}×{side} (under {MIN_PADDING}): filtering mixes their light",
                o.label
            ));
        }
        pages.push((side, side));
    }
    if let Some(p) = charts.iter().position(Vec::is_empty) {
        return Err(LightmapError::InvalidData(format!(
            "polygon {p} is in no kept primitive"
        )));
    }
    Ok(Assembly {
        pages,
        atlas,
        texel_size: texel,
        reductions,
        charts,
        regions,
        chart_count: 0,
        warnings,
        owners: None,
    })
}

/// An atlas laid out by per-polygon texel-space charts, before its texels are made.
struct Assembly {
    /// Each atlas's size.
    pages: Vec<(u32, u32)>,
    /// Per polygon, its atlas.
    atlas: Vec<u32>,
    texel_size: f64,
    reductions: u32,
    charts: Vec<Vec<DVec2>>,
    regions: Vec<Rect>,
    chart_count: usize,
    warnings: Vec<String>,
    /// For mask-packed layouts: per atlas, the region owning each 2×2 block (`u32::MAX`:
    /// none), and per polygon its region; gutters are then filled from the owner's charts.
    owners: Option<(Vec<Vec<u32>>, Vec<u32>)>,
}

fn assemble(
    a: Assembly,
    options: &Options,
    fields: Vec<Field>,
    flat: Option<Flat>,
    vertex_values: Vec<[f64; 3]>,
    welded_vertices: usize,
    uv_decisions: Vec<UvDecision>,
) -> Lightmap {
    let mut stats = Stats {
        welded_vertices,
        reductions: a.reductions,
        charts: a.chart_count,
        atlases: a.pages.len(),
        ..Stats::default()
    };
    let mut total = 0u64;
    let mut atlases = Vec::with_capacity(a.pages.len());
    for (page, &(width, height)) in a.pages.iter().enumerate() {
        // This atlas's charts; the others' are empty (skipped).
        let charts: Vec<Vec<DVec2>> = a
            .charts
            .iter()
            .zip(&a.atlas)
            .map(|(c, &k)| {
                if k as usize == page {
                    c.clone()
                } else {
                    Vec::new()
                }
            })
            .collect();
        let ownership = a
            .owners
            .as_ref()
            .map(|(pages, item_of)| (pages[page].as_slice(), item_of.as_slice()));
        let block = raster::atlas_texels(
            width,
            height,
            &charts,
            &fields,
            source(&flat, &vertex_values),
            ownership,
        );
        let n = width as usize;
        for (k, t) in block.coverage.iter().enumerate() {
            match t {
                Texel::Chart(p) => {
                    stats.chart_texels += 1;
                    let c = DVec2::new((k % n) as f64 + 0.5, (k / n) as f64 + 0.5);
                    stats.interior_texels += u64::from(raster::inside(c, &charts[*p as usize]));
                }
                Texel::Gutter(_) => stats.gutter_texels += 1,
                Texel::Unused => {}
            }
        }
        total += block.coverage.len() as u64;
        atlases.push(Atlas {
            width,
            height,
            texels: block.values,
            coverage: block.coverage,
        });
    }
    stats.occupancy = stats.chart_texels as f64 / total.max(1) as f64;
    let charts = a
        .charts
        .iter()
        .zip(&a.regions)
        .zip(&a.atlas)
        .enumerate()
        .map(|(polygon, ((uv, region), &atlas))| Chart {
            polygon,
            uv: uv.iter().map(|p| p.to_array()).collect(),
            region: *region,
            atlas,
        })
        .collect();
    let mut pages = atlases.into_iter();
    let first = pages.next().unwrap_or(Atlas {
        width: 0,
        height: 0,
        texels: Vec::new(),
        coverage: Vec::new(),
    });
    Lightmap {
        width: first.width,
        height: first.height,
        texel_size: a.texel_size,
        requested_texel_size: options.texel_size,
        texels: first.texels,
        coverage: first.coverage,
        more: pages.collect(),
        charts,
        vertex_values,
        stats,
        uv_decisions,
        warnings: a.warnings,
        shading: options.shading,
        fields,
        flat,
    }
}

/// One rectangle for the packer: its charts (polygon, texel coordinates inside it).
struct Item {
    width: u32,
    height: u32,
    charts: Vec<(usize, Vec<DVec2>)>,
}

/// A primitive's own TEXCOORD_1 at `texels_per_unit` (world): scaled by
/// sqrt(world area / UV area) × texels per unit, moved so its UV bounding box starts
/// [`PADDING`] texels inside the rectangle; `None` when it does not fit in u32. Also the
/// scale (texels per UV unit).
fn own_item(own: &authored::Own, texels_per_unit: f64) -> Option<(Item, f64)> {
    let s = own.world_per_uv.sqrt() * texels_per_unit;
    let (lo, hi) = own.uv.iter().flatten().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), q| (lo.min(*q), hi.max(*q)),
    );
    let size = ((hi - lo) * s).ceil().max(DVec2::ONE);
    let limit = f64::from(u32::MAX / 4);
    if !(size.x.is_finite() && size.y.is_finite() && size.x <= limit && size.y <= limit) {
        return None;
    }
    let even = |n: u32| n + n % 2;
    let p = DVec2::splat(f64::from(PADDING));
    let charts = own
        .polygons
        .iter()
        .zip(&own.uv)
        .map(|(&k, t)| (k, t.iter().map(|q| (*q - lo) * s + p).collect()))
        .collect();
    Some((
        Item {
            width: even(size.x as u32 + 2 * PADDING),
            height: even(size.y as u32 + 2 * PADDING),
            charts,
        },
        s,
    ))
}

/// `--lightmap-uv auto` when only some primitives' TEXCOORD_1 is usable: each of those
/// primitives is one rectangle of its own layout ([`own_item`]), the other polygons get
/// generated charts (grouped as in [`build_with`], or one per polygon).
fn mixed_layout(
    polygons: &[Polygon],
    own: &[authored::Own],
    options: &Options,
) -> Result<Assembly, LightmapError> {
    let mut owned = vec![false; polygons.len()];
    for o in own {
        for &k in &o.polygons {
            owned[k] = true;
        }
    }
    let rest: Vec<usize> = (0..polygons.len()).filter(|&k| !owned[k]).collect();
    let groups = if rest.len() > GROUPED_ABOVE {
        let sub: Vec<Polygon> = rest.iter().map(|&k| polygons[k].clone()).collect();
        Some(group::groups(
            &sub,
            group::largest(options),
            FOOTPRINT * options.texel_size,
        ))
        .filter(|g| g.len() < sub.len() || sub.len() > pack::MAX_REGIONS)
    } else {
        None
    };
    packed_layout(polygons, own, &rest, groups, options)
}

/// Regions mask-packed ([`pack::pack_masks`]) into one atlas at the requested texel size,
/// or several, or coarser until they fit: each `own` primitive's ([`own_item`]), and for
/// the polygons `rest` the unfolded charts `groups` (indices into `rest`; a polygon alone
/// is a chart of one, in its own shape, so texel density is the same everywhere), or
/// without groups one chart per polygon (`chart::layout`).
fn packed_layout(
    polygons: &[Polygon],
    own: &[authored::Own],
    rest: &[usize],
    groups: Option<Vec<group::Group>>,
    options: &Options,
) -> Result<Assembly, LightmapError> {
    let chart_count = groups.as_ref().map_or(rest.len(), Vec::len);
    let singles: Vec<usize> = match groups {
        None => (0..rest.len()).collect(),
        Some(_) => Vec::new(),
    };
    // Indices into `rest` of the polygons laid out one per chart.
    let rest_singles: Vec<usize> = singles.iter().map(|&k| rest[k]).collect();
    let sub: Vec<Polygon> = rest_singles.iter().map(|&k| polygons[k].clone()).collect();
    let max = options.max_size;
    let area: f64 = polygons.iter().map(polygon_area).sum();
    // No packing beats the polygons' own area over every atlas allowed.
    let room = f64::from(max) * f64::from(max) * f64::from(options.max_atlases.max(1));
    let floor = (area / room).sqrt();
    let mut texel = options.texel_size.max(floor);
    let mut reductions = u32::from(texel > options.texel_size);
    for _ in 0..64 {
        let per_unit = 1.0 / texel;
        let mut items = Vec::new();
        let mut scales = Vec::new();
        let mut fits = true;
        for o in own {
            match own_item(o, per_unit) {
                Some((item, s)) => {
                    items.push(item);
                    scales.push(s);
                }
                None => fits = false,
            }
        }
        for g in groups.iter().flatten() {
            match group::region(g, per_unit) {
                Some((width, height, uv)) => items.push(Item {
                    width,
                    height,
                    charts: g.polygons.iter().map(|&p| rest[p]).zip(uv).collect(),
                }),
                None => fits = false,
            }
        }
        if !sub.is_empty() {
            match chart::layout(&sub, per_unit) {
                Some(regions) => items.extend(regions.into_iter().map(|r| {
                    Item {
                        width: r.width,
                        height: r.height,
                        charts: r
                            .charts
                            .into_iter()
                            .map(|(p, uv)| (rest_singles[p], uv))
                            .collect(),
                    }
                })),
                None => fits = false,
            }
        }
        if !fits {
            texel *= 2.0;
            reductions += 1;
            continue;
        }
        let sizes: Vec<(u32, u32)> = items.iter().map(|r| (r.width, r.height)).collect();
        let masks: Vec<mask::Mask> = items
            .par_iter()
            .map(|r| mask::mask(r.width, r.height, &r.charts))
            .collect();
        let all: Vec<&mask::Mask> = masks.iter().collect();
        let pages = match pack::pack_masks(&all, max) {
            Some(packing) => Ok(vec![(packing, (0..items.len()).collect())]),
            None if options.max_atlases > 1 => {
                atlases(&items, &masks, polygons, max, options.max_atlases as usize)
            }
            None => Err(coarser(&sizes, max)),
        };
        if let Ok(pages) = &pages {
            let mut charts = vec![Vec::new(); polygons.len()];
            let mut atlas = vec![0; polygons.len()];
            let mut regions = vec![
                Rect {
                    x: 0,
                    y: 0,
                    width: 0,
                    height: 0
                };
                polygons.len()
            ];
            let mut item_of = vec![u32::MAX; polygons.len()];
            let mut owners = Vec::with_capacity(pages.len());
            for (page, (packing, members)) in pages.iter().enumerate() {
                let columns = packing.width as usize / 2;
                let mut owner = vec![u32::MAX; columns * (packing.height as usize / 2)];
                for (&i, &(x, y)) in members.iter().zip(&packing.positions) {
                    let item = &items[i];
                    let m = &masks[i];
                    for (c, &(a, b)) in m.columns.iter().enumerate() {
                        for r in a..b {
                            let (bx, by) = (x as usize / 2 + c, y as usize / 2 + r as usize);
                            owner[by * columns + bx] = i as u32;
                        }
                    }
                    let offset = DVec2::new(f64::from(x), f64::from(y));
                    for (p, uv) in &item.charts {
                        charts[*p] = uv.iter().map(|q| *q + offset).collect();
                        atlas[*p] = page as u32;
                        item_of[*p] = i as u32;
                        regions[*p] = Rect {
                            x,
                            y,
                            width: 2 * m.width,
                            height: 2 * m.height,
                        };
                    }
                }
                owners.push(owner);
            }
            let warnings = own
                .iter()
                .zip(&scales)
                .filter_map(|(o, &s)| {
                    let uv: Vec<&[DVec2]> = o.uv.iter().map(Vec::as_slice).collect();
                    authored::check_layout(&uv, Some(s)).padding.map(|gap| {
                        format!(
                            "{}: its TEXCOORD_1 islands are {gap:.2} texels apart in its atlas region (under {MIN_PADDING}): filtering mixes their light",
                            o.label
                        )
                    })
                })
                .collect();
            return Ok(Assembly {
                pages: pages.iter().map(|(p, _)| (p.width, p.height)).collect(),
                atlas,
                texel_size: texel,
                reductions,
                charts,
                regions,
                chart_count,
                warnings,
                owners: Some((owners, item_of)),
            });
        }
        texel *= pages.err().unwrap_or(1.05);
        reductions += 1;
        let room = u64::from(max) * u64::from(max) * u64::from(options.max_atlases.max(1));
        if sizes.len() as u64 * 64 > room {
            return Err(LightmapError::TooLarge { max });
        }
    }
    Err(LightmapError::TooLarge { max })
}

/// `items` split into at most `most` atlases of at most `max` texels a side, whole primitives
/// per atlas (items that hold polygons of one primitive instance stay together: the output
/// draws a primitive with one lightmap): largest first into the first atlas with room
/// (70% of its area), then each atlas packed, halved while it does not fit. Per atlas its
/// packing and its items (in the order packed); when a primitive alone does not fit or more
/// atlases would be needed, how much coarser the texels should get ([`coarser`] of the
/// primitive that did not fit, or of the whole area over `most` atlases).
fn atlases(
    items: &[Item],
    masks: &[mask::Mask],
    polygons: &[Polygon],
    max: u32,
    most: usize,
) -> Result<Vec<(pack::Packing, Vec<usize>)>, f64> {
    use std::collections::{BTreeMap, VecDeque};
    // Items joined through the primitives they hold.
    let mut parent: Vec<usize> = (0..items.len()).collect();
    fn root(parent: &mut [usize], mut k: usize) -> usize {
        while parent[k] != k {
            parent[k] = parent[parent[k]];
            k = parent[k];
        }
        k
    }
    let mut first: BTreeMap<(usize, usize, usize), usize> = BTreeMap::new();
    for (i, item) in items.iter().enumerate() {
        for (p, _) in &item.charts {
            let o = polygons[*p].origin;
            let other = *first.entry((o.node, o.mesh, o.primitive)).or_insert(i);
            let (a, b) = (root(&mut parent, i), root(&mut parent, other));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut units: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for i in 0..items.len() {
        units.entry(root(&mut parent, i)).or_default().push(i);
    }
    let area = |i: &usize| f64::from(items[*i].width) * f64::from(items[*i].height);
    let mut units: Vec<(f64, Vec<usize>)> = units
        .into_values()
        .map(|u| (u.iter().map(area).sum(), u))
        .collect();
    units.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1[0].cmp(&b.1[0])));
    let budget = 0.7 * f64::from(max) * f64::from(max);
    let mut bins: Vec<(f64, Vec<usize>)> = Vec::new();
    for (a, members) in units {
        match bins.iter_mut().find(|b| b.0 + a <= budget) {
            Some(bin) => {
                bin.0 += a;
                bin.1.extend(members);
            }
            None => bins.push((a, members)),
        }
        if bins.len() > most {
            return Err(too_many(items, max, most));
        }
    }
    // Pack each atlas; one that does not fit is split in two (whole units: the items of a
    // unit are contiguous in its list).
    let mut queue: VecDeque<Vec<usize>> = bins.into_iter().map(|b| b.1).collect();
    let mut done = Vec::new();
    while let Some(members) = queue.pop_front() {
        let sizes: Vec<(u32, u32)> = members
            .iter()
            .map(|&i| (items[i].width, items[i].height))
            .collect();
        let these: Vec<&mask::Mask> = members.iter().map(|&i| &masks[i]).collect();
        if let Some(packing) = pack::pack_masks(&these, max) {
            done.push((packing, members));
            continue;
        }
        // Split between units, near the middle.
        let roots: Vec<usize> = members.iter().map(|&i| root(&mut parent, i)).collect();
        let middle = members.len() / 2;
        let Some(cut) = (1..members.len())
            .filter(|&k| roots[k] != roots[k - 1])
            .min_by_key(|&k| k.abs_diff(middle))
        else {
            return Err(coarser(&sizes, max)); // one primitive alone
        };
        queue.push_back(members[..cut].to_vec());
        queue.push_back(members[cut..].to_vec());
        if done.len() + queue.len() > most {
            return Err(too_many(items, max, most));
        }
    }
    Ok(done)
}

/// How much coarser texels must get for `items` to fill at most `most` atlases of `max`
/// texels a side at 70%: by area, at least 5%, at most 4×.
fn too_many(items: &[Item], max: u32, most: usize) -> f64 {
    let area: f64 = items
        .iter()
        .map(|r| f64::from(r.width) * f64::from(r.height))
        .sum();
    let room = 0.7 * f64::from(max) * f64::from(max) * most as f64;
    (area / room).sqrt().clamp(1.05, 4.0)
}

fn fields(polygons: &[Polygon], mesh: &ElementMesh) -> Result<Vec<Field>, LightmapError> {
    if mesh.patches.len() != polygons.len() {
        return Err(LightmapError::InvalidData(format!(
            "{} polygons, {} patches",
            polygons.len(),
            mesh.patches.len()
        )));
    }
    polygons
        .iter()
        .zip(&mesh.patches)
        .enumerate()
        .map(|(k, (p, patch))| Field::new(p, patch, mesh, k))
        .collect()
}

fn smooth_and_weld(
    polygons: &[Polygon],
    mesh: &ElementMesh,
    fields: &[Field],
    element_values: &[[f64; 3]],
) -> (Vec<[f64; 3]>, usize) {
    let smoothed = mesh.smooth(element_values);
    let (lo, hi) = scene::bounds(polygons);
    let tolerance = 1e-6 * (hi - lo).length();
    field::weld(polygons, fields, &smoothed, tolerance)
}

/// The vertex values a lightmap is reconstructed from, for any per-element quantity (H, or b
/// for a vertex bake that should match the lightmap): `mesh.smooth(element_values)`, then
/// every grid vertex on an edge shared with a coplanar polygon of the same material (same
/// facing, within 1e-6 × the scene's diagonal) gets the mean of the fields of all such
/// polygons there. Linear in the values, so for b = e + ρH on one material the welded b is
/// e + ρ × the welded H.
pub fn welded_vertex_values(
    polygons: &[Polygon],
    mesh: &ElementMesh,
    element_values: &[[f64; 3]],
) -> Result<Vec<[f64; 3]>, LightmapError> {
    if element_values.len() != mesh.elements.len() {
        return Err(LightmapError::InvalidData(format!(
            "{} values for {} elements",
            element_values.len(),
            mesh.elements.len()
        )));
    }
    let fields = fields(polygons, mesh)?;
    Ok(smooth_and_weld(polygons, mesh, &fields, element_values).0)
}

type Fitted = (f64, Vec<chart::Region>, pack::Packing, u32);

/// Lays out and packs the charts at the requested texel size, or coarser until they fit.
fn fit(polygons: &[Polygon], options: &Options) -> Result<Fitted, LightmapError> {
    let max = options.max_size;
    let too_large = LightmapError::TooLarge { max };
    // No packing beats the polygons' own area: start there if the request is finer.
    let area: f64 = polygons.iter().map(polygon_area).sum();
    let floor = (area / (f64::from(max) * f64::from(max))).sqrt();
    let mut texel = options.texel_size.max(floor);
    let mut reductions = u32::from(texel > options.texel_size);
    for _ in 0..64 {
        let Some(regions) = chart::layout(polygons, 1.0 / texel) else {
            texel *= 2.0;
            reductions += 1;
            continue;
        };
        let sizes: Vec<(u32, u32)> = regions.iter().map(|r| (r.width, r.height)).collect();
        if let Some(packing) = pack::pack(&sizes, max) {
            return Ok((texel, regions, packing, reductions));
        }
        texel *= coarser(&sizes, max);
        reductions += 1;
        if sizes.len() as u64 * 64 > u64::from(max) * u64::from(max) {
            // Every region is at least 8×8 texels: no texel size helps.
            return Err(too_large);
        }
    }
    Err(too_large)
}

/// How much coarser texels must get for regions of `sizes` (texels) to fit a `max` atlas:
/// in proportion to the overflow, at least 5%, at most 4×.
fn coarser(sizes: &[(u32, u32)], max: u32) -> f64 {
    let needed: f64 = sizes
        .iter()
        .map(|&(w, h)| f64::from(w) * f64::from(h))
        .sum::<f64>()
        / 0.8;
    let widest = sizes.iter().map(|s| s.0.max(s.1)).max().unwrap_or(0);
    let by_area = (needed / (f64::from(max) * f64::from(max))).sqrt();
    let by_width = f64::from(widest) / f64::from(max);
    by_area.max(by_width).clamp(1.05, 4.0)
}

pub(crate) fn polygon_area(p: &Polygon) -> f64 {
    let v = &p.vertices;
    (1..v.len() - 1)
        .map(|k| (v[k] - v[0]).cross(v[k + 1] - v[0]).length() / 2.0)
        .sum()
}

impl Lightmap {
    /// `TEXCOORD_1` of vertex `vertex` of polygon `polygon` (u right, v down, in [0, 1]).
    pub fn texcoord(&self, polygon: usize, vertex: usize) -> [f32; 2] {
        let chart = &self.charts[polygon];
        let p = chart.uv[vertex];
        let atlas = self.atlas(chart.atlas as usize);
        [
            (p[0] / f64::from(atlas.width)) as f32,
            (p[1] / f64::from(atlas.height)) as f32,
        ]
    }

    /// Atlas `k` (0: the lightmap's own texels; then [`Lightmap::more`]). Panics past the
    /// last: `k` comes from a [`Chart::atlas`].
    pub fn atlas(&self, k: usize) -> AtlasRef<'_> {
        match k.checked_sub(1) {
            None => AtlasRef {
                width: self.width,
                height: self.height,
                texels: &self.texels,
                coverage: &self.coverage,
            },
            Some(m) => {
                let a = &self.more[m];
                AtlasRef {
                    width: a.width,
                    height: a.height,
                    texels: &a.texels,
                    coverage: &a.coverage,
                }
            }
        }
    }

    /// Every atlas, the first one first.
    pub fn atlases(&self) -> Vec<AtlasRef<'_>> {
        (0..=self.more.len()).map(|k| self.atlas(k)).collect()
    }

    /// The surface point texel `index` (row-major) of atlas `k` shows: its polygon and the
    /// weights of that polygon's corners (in vertex order; a triangle's fourth is 0) at the
    /// chart point nearest the texel's centre — the point its H was reconstructed at for a
    /// chart texel, and near the chart texel a gutter texel copies. `None` for unused texels.
    /// Lets a caller colour texels by what else varies over the surface (textures).
    pub fn texel_point(&self, k: usize, index: usize) -> Option<(usize, [f64; 4])> {
        let atlas = self.atlas(k);
        let polygon = match atlas.coverage.get(index)? {
            Texel::Unused => return None,
            Texel::Chart(p) | Texel::Gutter(p) => *p as usize,
        };
        let chart = self.charts.get(polygon)?;
        let uv: Vec<DVec2> = chart.uv.iter().map(|p| DVec2::new(p[0], p[1])).collect();
        if uv.len() < 3 {
            return None;
        }
        let width = atlas.width as usize;
        let c = DVec2::new((index % width) as f64 + 0.5, (index / width) as f64 + 0.5);
        Some((polygon, raster::chart_weights(c, &uv)))
    }

    /// Bilinear sample at texture coordinate `uv` (texel centres at (i + ½)/width, clamped to
    /// the edge), as a GPU samples level 0.
    pub fn sample(&self, uv: [f64; 2]) -> [f64; 3] {
        sample_bilinear(&self.texels, self.width, self.height, uv)
    }

    /// The irradiance at world point `point` of polygon `polygon` that the texels were
    /// reconstructed from: the smoothed, welded field, or for [`Shading::Flat`] the H of the
    /// element there.
    pub fn irradiance_at(&self, polygon: usize, point: DVec3) -> [f64; 3] {
        let field = &self.fields[polygon];
        source(&self.flat, &self.vertex_values).at(polygon, field, field.to_plane(point))
    }
}

/// Bilinear sample of a row-major RGB image at texture coordinate `uv`, clamp-to-edge.
pub fn sample_bilinear(texels: &[[f32; 3]], width: u32, height: u32, uv: [f64; 2]) -> [f64; 3] {
    let (w, h) = (i64::from(width), i64::from(height));
    let x = uv[0] * w as f64 - 0.5;
    let y = uv[1] * h as f64 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |i: i64, j: i64| {
        let (i, j) = (i.clamp(0, w - 1), j.clamp(0, h - 1));
        texels[(j * w + i) as usize].map(f64::from)
    };
    let (i, j) = (x0 as i64, y0 as i64);
    let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
    std::array::from_fn(|k| {
        (1.0 - fy) * ((1.0 - fx) * a[k] + fx * b[k]) + fy * ((1.0 - fx) * c[k] + fx * d[k])
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::{Origin, Side};

    fn polygon(vertices: Vec<DVec3>, material: usize) -> Polygon {
        let normal = (vertices[1] - vertices[0])
            .cross(vertices[2] - vertices[0])
            .normalize();
        Polygon {
            vertices,
            normal,
            material,
            origin: Origin {
                node: 0,
                mesh: 0,
                primitive: 0,
                face: 0,
                side: Side::Front,
            },
        }
    }

    /// A linear function of position, per band.
    fn linear(p: DVec3) -> [f64; 3] {
        [
            1.0 + 0.3 * p.x + 0.2 * p.y,
            2.0 - 0.1 * p.x,
            0.5 + 0.05 * p.y,
        ]
    }

    #[test]
    fn fields_interpolate_linear_vertex_values_exactly() {
        let polygons = vec![
            // A parallelogram and a triangle.
            polygon(
                vec![
                    DVec3::new(0.0, 0.0, 0.0),
                    DVec3::new(2.0, 0.0, 0.0),
                    DVec3::new(2.5, 1.0, 0.0),
                    DVec3::new(0.5, 1.0, 0.0),
                ],
                0,
            ),
            polygon(
                vec![
                    DVec3::new(0.0, 0.0, 1.0),
                    DVec3::new(3.0, 0.0, 1.0),
                    DVec3::new(1.0, 2.0, 1.0),
                ],
                0,
            ),
        ];
        let mesh = mesher::mesh(&polygons, mesher::Subdivision::Count(3)).expect("mesh");
        let values: Vec<[f64; 3]> = mesh.vertices.iter().map(|p| linear(*p)).collect();
        for (k, p) in polygons.iter().enumerate() {
            let field = Field::new(p, &mesh.patches[k], &mesh, k).expect("grid");
            for (a, b) in [(0.1, 0.2), (0.5, 0.3), (0.33, 0.33), (0.9, 0.05)] {
                let v = &p.vertices;
                let point = v[0] + (v[1] - v[0]) * a + (v[v.len() - 1] - v[0]) * b;
                let got = field.value_at(field.to_plane(point), &values);
                let want = linear(point);
                for c in 0..3 {
                    assert!((got[c] - want[c]).abs() < 1e-12, "{k} {a} {b}: {got:?}");
                }
            }
        }
    }

    #[test]
    fn coplanar_neighbours_of_one_material_are_welded_along_their_edge() {
        let square = |x: f64, material: usize| {
            polygon(
                vec![
                    DVec3::new(x, 0.0, 0.0),
                    DVec3::new(x + 1.0, 0.0, 0.0),
                    DVec3::new(x + 1.0, 1.0, 0.0),
                    DVec3::new(x, 1.0, 0.0),
                ],
                material,
            )
        };
        for (material, welded) in [(0, true), (1, false)] {
            let polygons = vec![square(0.0, 0), square(1.0, material)];
            let mesh = mesher::mesh(&polygons, mesher::Subdivision::Count(2)).expect("mesh");
            // Element values differ per polygon: the one-sided smoothing disagrees at x = 1.
            let values: Vec<[f64; 3]> = mesh
                .elements
                .iter()
                .map(|e| [1.0 + e.polygon as f64 + e.centroid.y, 1.0, 1.0])
                .collect();
            let vertex = welded_vertex_values(&polygons, &mesh, &values).expect("weld");
            let on_edge = |k: usize| (mesh.vertices[k].x - 1.0).abs() < 1e-12;
            let left: Vec<usize> = (0..9).filter(|&k| on_edge(k)).collect();
            let right: Vec<usize> = (9..18).filter(|&k| on_edge(k)).collect();
            assert_eq!((left.len(), right.len()), (3, 3));
            for (&a, &b) in left.iter().zip(&right) {
                assert_eq!(mesh.vertices[a], mesh.vertices[b]);
                assert_eq!(vertex[a] == vertex[b], welded, "material {material}");
            }
            let smoothed = mesh.smooth(&values);
            for k in (0..18).filter(|&k| !on_edge(k)) {
                assert_eq!(vertex[k], smoothed[k], "only shared-edge vertices move");
            }
        }
    }

    #[test]
    fn similar_triangles_share_a_rectangle_with_a_gap() {
        let polygons = vec![
            polygon(
                vec![
                    DVec3::new(0.0, 0.0, 0.0),
                    DVec3::new(1.0, 0.0, 0.0),
                    DVec3::new(0.3, 0.8, 0.0),
                ],
                0,
            ),
            polygon(
                vec![
                    DVec3::new(0.0, 0.0, 1.0),
                    DVec3::new(1.0, 0.0, 1.0),
                    DVec3::new(0.6, 0.7, 1.0),
                ],
                0,
            ),
        ];
        let mesh = mesher::mesh(&polygons, mesher::Subdivision::Count(2)).expect("mesh");
        let values = vec![[1.0; 3]; mesh.elements.len()];
        let options = Options {
            texel_size: 0.02,
            max_size: 1024,
            shading: Shading::Smooth,
            max_atlases: 1,
        };
        let lightmap = build(&polygons, &mesh, &values, &options).expect("build");
        assert_eq!(lightmap.charts[0].region, lightmap.charts[1].region);
        // The two footprints never touch and every written texel is 1.
        for (k, t) in lightmap.coverage.iter().enumerate() {
            if !matches!(t, Texel::Unused) {
                assert_eq!(lightmap.texels[k], [1.0; 3]);
            }
        }
        let owner = |x: usize, y: usize| lightmap.coverage[y * lightmap.width as usize + x];
        for y in 0..lightmap.height as usize {
            for x in 1..lightmap.width as usize {
                if let (Texel::Chart(a), Texel::Chart(b)) = (owner(x - 1, y), owner(x, y)) {
                    assert_eq!(a, b, "footprints of the pair meet at ({x}, {y})");
                }
            }
        }
    }
}
