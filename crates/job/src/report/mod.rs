//! The bake report: a JSON record of what was baked (inputs, options, counts, timings,
//! solver diagnostics, warnings) and the per-element results in world space, for tests and
//! for users who want the numbers rather than the picture.
//!
//! Keys appear in struct field order; floats are written so they read back exactly.
//!
//! The bake's own result values are the report's objects, defined once where they are
//! computed: `counts` is [`bake_core::Counts`], `energy` [`bake_core::EnergyBalance`],
//! `effects` [`bake_core::Effects`], `transport` [`bake_core::TransportChoice`], `accuracy`
//! [`bake_core::Accuracy`], `refinement` [`bake_core::refine::Refinement`] and each light's
//! counts [`bake_core::LightStats`]. This module adds what only the report has (the input,
//! the options, timings, the polygon and element lists) and writes and reads the file; the
//! job fills it from a finished bake (`build.rs`).

mod build;
mod failed;

pub(crate) use build::{Baked, Stages};
pub use failed::{read_failed_report, write_failed_report, FailedReport, FailureEntry};

use bake_core::refine::Refinement;
use bake_core::{
    Accuracy, Counts, Effects, EnergyBalance, LightStats, Sky, SkyStats, TransportChoice,
};
use exporter::{ExportError, OutputSet};
use mesher::ElementMesh;
use scene::{Scene, Side};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The version of this report's layout (2: `solver.condition`, `solver.iterations`, the
/// `iterative` method and the `energy` object; 4: `lights`, `energy.delivered`, elements'
/// `direct`; 5: elements' `h`; 6: `elements_included`, `element_summary`, the `accuracy`
/// object and elements' `error`; 7: `sky` and elements' `sky`; 8: `sky.model` `"map"` with
/// `sky.file`, the `"clear"` model with `zenith` and `sun`, `accuracy.error.max_sky`, `sky.delivered` and elements'
/// `sky` per band (a map has colour), and `probes`).
pub const SCHEMA_VERSION: u32 = 8;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// The input file, as given.
    pub input: String,
    /// The options the bake ran with; owned by the CLI.
    pub options: serde_json::Value,
    pub counts: Counts,
    /// Seconds per stage, by stage name.
    pub timings: BTreeMap<String, f64>,
    /// The process's peak resident memory (MiB) at the end of each stage, where the system
    /// says (absent in older reports). Like `timings`, it varies from run to run.
    #[serde(default)]
    pub peak_rss_mib: BTreeMap<String, f64>,
    pub solver: SolverInfo,
    /// Power balance of the solution; `None` until the caller sets it.
    pub energy: Option<EnergyBalance>,
    /// Where the escaping light goes, estimated by rays independently of the transport
    /// (`bake_core::escape`; absent in older reports and in failed bakes').
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub escape: Option<bake_core::escape::Escape>,
    /// The effects the scene called for (absent in older reports).
    #[serde(default)]
    pub effects: Effects,
    /// The light transport used and why (absent in older reports).
    #[serde(default)]
    pub transport: TransportChoice,
    /// The punctual lights the bake used (absent in older reports).
    #[serde(default)]
    pub lights: Vec<LightEntry>,
    /// The sky the bake used (`--sky`), and what it took (absent without one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sky: Option<SkyEntry>,
    /// The target error of `b`, the form-factor tolerance it chose and the bound the solve
    /// leaves (absent in older reports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accuracy: Option<Accuracy>,
    /// What refinement below the element grid did (absent in older reports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refinement: Option<Refinement>,
    /// What `--probes` did: probes placed, valid, moved, the spacing, rays, seconds (absent
    /// without probes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probes: Option<probes::Summary>,
    pub warnings: Vec<String>,
    pub polygons: Vec<PolygonEntry>,
    /// Which per-element data follow (absent in older reports: all).
    #[serde(default)]
    pub elements_included: ElementsIncluded,
    /// Count, area and the range and area-weighted mean of b over all elements (absent in
    /// older reports and with `none`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub element_summary: Option<ElementSummary>,
    /// Every element, when `elements_included` is `all` (else empty).
    pub elements: Vec<ElementEntry>,
}

/// Which per-element data a report holds (`--report-elements`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ElementsIncluded {
    /// The summary and every element.
    #[default]
    All,
    /// The summary only.
    Summary,
    /// Neither.
    None,
}

/// What a report says about its elements as a whole.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ElementSummary {
    pub count: usize,
    /// Total area.
    pub area: f64,
    /// Per band: the least and largest b, the element with the largest, and the
    /// area-weighted mean.
    pub b_min: [f64; 3],
    pub b_max: [f64; 3],
    pub b_max_element: [u32; 3],
    pub b_mean: [f64; 3],
}

impl ElementSummary {
    /// The summary of `elements` (`None` for no elements).
    pub fn of(elements: &[ElementEntry]) -> Option<ElementSummary> {
        let first = elements.first()?;
        let mut s = ElementSummary {
            count: elements.len(),
            area: 0.0,
            b_min: first.b,
            b_max: first.b,
            b_max_element: [0; 3],
            b_mean: [0.0; 3],
        };
        let mut power = [0.0; 3];
        for (k, el) in elements.iter().enumerate() {
            s.area += el.area;
            for (band, (&b, power)) in el.b.iter().zip(&mut power).enumerate() {
                s.b_min[band] = s.b_min[band].min(b);
                if b > s.b_max[band] {
                    s.b_max[band] = b;
                    s.b_max_element[band] = k as u32;
                }
                *power += el.area * b;
            }
        }
        if s.area > 0.0 {
            s.b_mean = power.map(|p| p / s.area);
        }
        Some(s)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverMethod {
    /// Solved the linear system directly.
    Direct,
    /// A fixed number of light bounces (Jacobi-style gathering).
    Bounces,
    /// Solved the linear system iteratively (GMRES) to a residual tolerance.
    Iterative,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolverInfo {
    pub method: SolverMethod,
    /// The bounce count for [`SolverMethod::Bounces`].
    pub bounces: Option<u32>,
    /// Residual of the solution per band.
    pub residual: [f64; 3],
    /// Whether each band's residual is relative (to the emission) rather than absolute.
    pub residual_relative: [bool; 3],
    /// Matrix factorizations performed.
    pub factorizations: u32,
    /// Per band, the estimate of the condition number `cond_∞(I − ρF)` (how much the system
    /// amplifies relative errors; about `(1 + ρ) / (1 − ρ)` in a closed grey scene); `null`
    /// when the band was not solved as a linear system (bounces, or no emission).
    pub condition: [Option<f64>; 3],
    /// Per band, iterations of the [`SolverMethod::Iterative`] solver (0 otherwise).
    pub iterations: [u32; 3],
}

/// The sky a bake used and what its pass took.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkyEntry {
    /// `model` (`uniform` with `radiance`, `overcast` with `zenith`) and
    /// `ground_reflectance`.
    #[serde(flatten)]
    pub sky: Sky,
    /// The sky's unobstructed horizontal illuminance E_h (lux, for radiance in cd/m²).
    pub horizontal_illuminance: f64,
    /// The ground's radiance below the horizon, `ground_reflectance × E_h / π`.
    pub ground_radiance: f64,
    /// Rays cast, elements that receive sky or ground light, elements given the closed form
    /// (nothing can block them) and elements sampled by rays.
    #[serde(flatten)]
    pub stats: SkyStats,
    /// `Σ A_i E_i / π` per band: what the sky delivered, in the energy unit.
    pub delivered: [f64; 3],
}

/// One punctual light the bake used, in world space, and what its direct light took.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightEntry {
    /// `point`, `spot` or `directional`.
    #[serde(rename = "type")]
    pub kind: String,
    pub name: Option<String>,
    /// Index of the node carrying it.
    pub node: usize,
    pub position: [f64; 3],
    /// Unit direction the light travels (spot axis, sun rays).
    pub direction: [f64; 3],
    /// Candela (point, spot) or lux (directional).
    pub intensity: f64,
    pub color: [f64; 3],
    pub range: Option<f64>,
    /// Spot cone half-angles in radians.
    pub inner_cone_angle: Option<f64>,
    pub outer_cone_angle: Option<f64>,
    /// Elements it lights, elements some polygon may shadow from it, shadow rays cast,
    /// elements whose falloff was integrated over sub-cells, elements clipped exactly (the
    /// direct-light pass's own counts, as keys of this object).
    #[serde(flatten)]
    pub stats: LightStats,
    /// `Σ A_i E_i / π` per band: what it delivered, in the energy unit.
    pub delivered: [f64; 3],
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SideName {
    Front,
    Back,
}

impl From<Side> for SideName {
    fn from(side: Side) -> Self {
        match side {
            Side::Front => SideName::Front,
            Side::Back => SideName::Back,
        }
    }
}

/// Where one scene polygon came from (its [`scene::Origin`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PolygonEntry {
    pub node: usize,
    pub mesh: usize,
    pub primitive: usize,
    pub face: usize,
    pub side: SideName,
}

/// One element's geometry and result, in world space.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ElementEntry {
    /// Index into [`Report::polygons`].
    pub polygon: u32,
    /// Area centroid.
    pub centroid: [f64; 3],
    /// Unit normal.
    pub normal: [f64; 3],
    pub area: f64,
    /// Reflectance of the element's material.
    pub rho: [f64; 3],
    /// Emission of the element's material.
    pub e: [f64; 3],
    /// Radiosity (unclamped, before exposure).
    pub b: [f64; 3],
    /// The part of `b` straight from punctual lights, `ρ E / π` (absent in older reports: 0).
    #[serde(default)]
    pub direct: [f64; 3],
    /// The part of `b` straight from the sky and the ground below it, `ρ E_sky / π`
    /// (absent without `--sky`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sky: Option<[f64; 3]>,
    /// The irradiance H (`b = e + ρ H`, before exposure) when the bake computed it (a
    /// lightmap, or a textured material, whose vertex-bake `COLOR_0` is H).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub h: Option<[f64; 3]>,
    /// The estimated bound on `|b − b̄|` per band, `b̄` the element's area average of the
    /// exact continuous radiosity (absent in older reports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<[f64; 3]>,
}

impl Report {
    /// A report with the scene's counts, warnings, polygons and elements filled in.
    /// `options` is `{}`, `timings` is empty, `energy` is `None` and `counts` holds only the
    /// scene's and the mesh's sizes: the caller sets them from the bake.
    pub fn new(
        input: &Path,
        scene: &Scene,
        mesh: &ElementMesh,
        radiosity: &[[f64; 3]],
        solver: SolverInfo,
    ) -> Result<Report, ExportError> {
        Ok(Report {
            schema_version: SCHEMA_VERSION,
            input: input.to_string_lossy().into_owned(),
            options: serde_json::Value::Object(serde_json::Map::new()),
            counts: Counts::default().with_scene(scene, mesh),
            timings: BTreeMap::new(),
            peak_rss_mib: BTreeMap::new(),
            solver,
            energy: None,
            escape: None,
            effects: Effects::default(),
            transport: TransportChoice::default(),
            lights: Vec::new(),
            sky: None,
            accuracy: None,
            refinement: None,
            probes: None,
            warnings: scene.warnings.clone(),
            polygons: Report::polygons_from(scene),
            elements_included: ElementsIncluded::All,
            element_summary: None,
            elements: Report::elements_from(scene, mesh, radiosity)?,
        })
    }

    /// Keeps `which` of the per-element data: fills in the summary (unless `None`) and drops
    /// the element list (unless `All`). Call once the elements are complete.
    pub fn keep_elements(&mut self, which: ElementsIncluded) {
        self.elements_included = which;
        self.element_summary = match which {
            ElementsIncluded::None => None,
            _ => ElementSummary::of(&self.elements),
        };
        if which != ElementsIncluded::All {
            self.elements = Vec::new();
        }
    }

    /// One entry per scene polygon, in polygon order.
    pub fn polygons_from(scene: &Scene) -> Vec<PolygonEntry> {
        scene
            .polygons
            .iter()
            .map(|polygon| PolygonEntry {
                node: polygon.origin.node,
                mesh: polygon.origin.mesh,
                primitive: polygon.origin.primitive,
                face: polygon.origin.face,
                side: polygon.origin.side.into(),
            })
            .collect()
    }

    /// One entry per element, in element order, with ρ and e from the polygon's material and
    /// b from `radiosity` (one value per element).
    pub fn elements_from(
        scene: &Scene,
        mesh: &ElementMesh,
        radiosity: &[[f64; 3]],
    ) -> Result<Vec<ElementEntry>, ExportError> {
        if radiosity.len() != mesh.elements.len() {
            return Err(ExportError::InvalidData(format!(
                "{} radiosity values for {} elements",
                radiosity.len(),
                mesh.elements.len()
            )));
        }
        mesh.elements
            .iter()
            .zip(radiosity)
            .enumerate()
            .map(|(i, (element, b))| {
                let material = scene
                    .polygons
                    .get(element.polygon as usize)
                    .and_then(|polygon| scene.materials.get(polygon.material))
                    .ok_or_else(|| {
                        ExportError::InvalidData(format!(
                            "element {i}: polygon {} or its material is missing",
                            element.polygon
                        ))
                    })?;
                Ok(ElementEntry {
                    polygon: element.polygon,
                    centroid: element.centroid.to_array(),
                    normal: element.normal.to_array(),
                    area: element.area,
                    rho: material.rho,
                    e: material.emission,
                    b: *b,
                    direct: [0.0; 3],
                    sky: None,
                    h: None,
                    error: None,
                })
            })
            .collect()
    }
}

/// Writes `report` as pretty JSON to `path`, atomically (temporary file, then rename).
///
/// JSON has no NaN or infinity (`serde_json` would write `null`): every number is checked
/// first (elements, timings, solver residual and condition, energy), and a non-finite one
/// is an [`ExportError::NonFinite`] naming the element (and its polygon's origin) or the
/// field; nothing is written then. (A `null` condition means "not solved as a linear
/// system", not a NaN.)
pub fn write_report(path: &Path, report: &Report) -> Result<(), ExportError> {
    let mut set = OutputSet::new();
    stage_report(&mut set, path, report)?;
    set.commit().map(drop)
}

/// [`write_report`] as part of a larger set (renamed into place when `set` is committed).
pub fn stage_report(set: &mut OutputSet, path: &Path, report: &Report) -> Result<(), ExportError> {
    check_finite(report)?;
    let mut json = serde_json::to_vec_pretty(report).map_err(|e| ExportError::Encode {
        what: "the bake report",
        message: e.to_string(),
    })?;
    json.push(b'\n');
    set.stage_with(path, |w| w.write_all(&json))
}

/// Every float of the report must be finite.
fn check_finite(report: &Report) -> Result<(), ExportError> {
    let not_finite = |what: String| Err(ExportError::NonFinite { what });
    for (i, element) in report.elements.iter().enumerate() {
        let fields: [(&str, &[f64]); 7] = [
            ("centroid", &element.centroid),
            ("normal", &element.normal),
            ("area", std::slice::from_ref(&element.area)),
            ("rho", &element.rho),
            ("e", &element.e),
            ("b", &element.b),
            ("direct", &element.direct),
        ];
        if let Some((name, values)) = fields.iter().find(|(_, v)| !all_finite(v)) {
            return not_finite(format!(
                "report {}: {name} {values:?}",
                element_name(report, i)
            ));
        }
        if let Some(sky) = element.sky.filter(|e| !all_finite(e)) {
            return not_finite(format!("report {}: sky {sky:?}", element_name(report, i)));
        }
        if let Some(error) = element.error.filter(|e| !all_finite(e)) {
            return not_finite(format!(
                "report {}: error {error:?}",
                element_name(report, i)
            ));
        }
    }
    for light in &report.lights {
        let values = light
            .position
            .iter()
            .chain(&light.direction)
            .chain(&light.color)
            .chain(&light.delivered)
            .chain(std::iter::once(&light.intensity));
        if !values.copied().all(f64::is_finite) {
            return not_finite(format!("report light on node {}", light.node));
        }
    }
    if let Some(sky) = &report.sky {
        let values = sky
            .delivered
            .iter()
            .chain([&sky.horizontal_illuminance, &sky.ground_radiance]);
        if !values.copied().all(f64::is_finite) {
            return not_finite("report sky".to_string());
        }
    }
    if let Some((stage, seconds)) = report.timings.iter().find(|(_, s)| !s.is_finite()) {
        return not_finite(format!("report timing {stage:?}: {seconds}"));
    }
    let solver = &report.solver;
    if !all_finite(&solver.residual) {
        return not_finite(format!("report solver residual {:?}", solver.residual));
    }
    if solver.condition.iter().flatten().any(|c| !c.is_finite()) {
        return not_finite(format!("report solver condition {:?}", solver.condition));
    }
    if let Some(energy) = &report.energy {
        let fields = [
            ("delivered", &energy.delivered),
            ("emitted", &energy.emitted),
            ("absorbed", &energy.absorbed),
            ("escaped", &energy.escaped),
            ("imbalance", &energy.imbalance),
        ];
        if let Some((name, values)) = fields.iter().find(|(_, v)| !all_finite(&v[..])) {
            return not_finite(format!("report energy {name} {values:?}"));
        }
    }
    if let Some(escape) = &report.escape {
        if !all_finite(&escape.openings) || !all_finite(&escape.back_faces) {
            return not_finite(format!("report escape {escape:?}"));
        }
    }
    if let Some(a) = &report.accuracy {
        let values = [a.max_error, a.rho_max, a.row_sum_accuracy]
            .into_iter()
            .chain(a.ff_tolerance)
            .chain(a.condition_bound)
            .chain(a.error_bound.iter().flatten().copied())
            .chain(a.error.iter().flat_map(|e| {
                [
                    e.max,
                    e.rms,
                    e.max_discretisation,
                    e.max_form_factors,
                    e.max_visibility,
                    e.max_solver,
                    e.max_links,
                    e.max_sky,
                ]
                .into_iter()
                .flatten()
            }));
        if !values.into_iter().all(f64::is_finite) {
            return not_finite(format!("report accuracy {a:?}"));
        }
    }
    Ok(())
}

fn all_finite(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

/// `element 3 (polygon 1: node 0, mesh 0, primitive 0, face 2, front)`.
fn element_name(report: &Report, index: usize) -> String {
    let polygon = report.elements[index].polygon;
    match report.polygons.get(polygon as usize) {
        Some(p) => format!(
            "element {index} (polygon {polygon}: node {}, mesh {}, primitive {}, face {}, {})",
            p.node,
            p.mesh,
            p.primitive,
            p.face,
            match p.side {
                SideName::Front => "front",
                SideName::Back => "back",
            }
        ),
        None => format!("element {index} (polygon {polygon})"),
    }
}

/// Reads a report written by [`write_report`].
pub fn read_report(path: &Path) -> Result<Report, ReadReportError> {
    read_json(path)
}

/// Reads the JSON file `path` as a `T`.
fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, ReadReportError> {
    let bytes = std::fs::read(path).map_err(|source| ReadReportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    serde_json::from_slice(&bytes).map_err(|source| ReadReportError::Json {
        path: path.to_path_buf(),
        source,
    })
}

#[derive(Debug, thiserror::Error)]
pub enum ReadReportError {
    #[error("cannot read {path}: {source}")]
    Io {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path} is not a bake report: {source}")]
    Json {
        path: std::path::PathBuf,
        #[source]
        source: serde_json::Error,
    },
}
