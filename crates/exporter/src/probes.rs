//! The `BAKE_irradiance_probes` vendor extension on every scene of a baked glTF: the probe
//! grid, and accessors of the probes' positions, SH L2 coefficients and validity
//! (docs/probes.md, docs/BAKE_irradiance_probes.schema.json). The exporter gets the probes
//! as arrays; it knows nothing of how they were placed or gathered.

use crate::document::{accessor, DocumentWriter};
use crate::ExportError;
use gltf::json::accessor::{ComponentType, Type};
use serde_json::json;

/// The extension's name (listed in `extensionsUsed`, never in `extensionsRequired`).
pub const PROBES_EXTENSION: &str = "BAKE_irradiance_probes";

/// Coefficients per probe and band.
pub const PROBE_COEFFICIENTS: usize = 9;

/// A bake's probes as plain arrays.
#[derive(Clone, Copy, Debug)]
pub struct ProbeGrid<'a> {
    /// Point (i, j, k) of the grid is at `origin + spacing (i, j, k)`; the first
    /// `counts[0] × counts[1] × counts[2]` probes are its points, x fastest (a moved probe's
    /// position differs from its point's); any after them were added by the scene.
    pub origin: [f64; 3],
    pub spacing: f64,
    pub counts: [u32; 3],
    pub positions: &'a [[f64; 3]],
    /// Per probe, nine RGB coefficients of the incident radiance (three.js
    /// `SphericalHarmonics3` order and basis), in the unit of the bake's b over π.
    pub coefficients: &'a [[[f64; 3]; PROBE_COEFFICIENTS]],
    pub valid: &'a [bool],
    /// The exposure the file's `COLOR_0` used, for viewers that want probes as bright.
    pub exposure: f64,
}

/// Adds the probes' accessors and the extension on every scene of `writer`.
pub(crate) fn add(writer: &mut DocumentWriter, probes: &ProbeGrid) -> Result<(), ExportError> {
    let n = probes.positions.len();
    if probes.coefficients.len() != n || probes.valid.len() != n {
        return Err(ExportError::InvalidData(format!(
            "{n} probe positions, {} coefficient sets, {} validity flags",
            probes.coefficients.len(),
            probes.valid.len()
        )));
    }
    let finite32 = |what: &str, v: f64| {
        let x = v as f32;
        if x.is_finite() {
            Ok(x)
        } else {
            Err(ExportError::InvalidData(format!(
                "probe {what} {v} is not a finite f32"
            )))
        }
    };
    let mut positions = Vec::with_capacity(n);
    for p in probes.positions {
        positions.push([
            finite32("position", p[0])?,
            finite32("position", p[1])?,
            finite32("position", p[2])?,
        ]);
    }
    let mut coefficients = Vec::with_capacity(n * PROBE_COEFFICIENTS);
    for sh in probes.coefficients {
        for c in sh {
            coefficients.push([
                finite32("coefficient", c[0])?,
                finite32("coefficient", c[1])?,
                finite32("coefficient", c[2])?,
            ]);
        }
    }
    let valid: Vec<u8> = probes.valid.iter().map(|&v| u8::from(v)).collect();
    let positions = if n > 0 {
        Some(writer.add_vec3_on(&positions, true, None))
    } else {
        None
    };
    let coefficient_accessor = if n > 0 {
        Some(writer.add_vec3_on(&coefficients, false, None))
    } else {
        None
    };
    let valid_accessor = if n > 0 {
        let view = writer.push_view(&valid, None);
        Some(writer.root.push(accessor(
            view,
            n,
            ComponentType::U8,
            Type::Scalar,
            None,
            None,
        )))
    } else {
        None
    };
    let mut extension = json!({
        "grid": {
            "origin": probes.origin,
            "spacing": probes.spacing,
            "counts": probes.counts,
        },
        "count": n,
        "exposure": probes.exposure,
        "convention": "three.js SphericalHarmonics3 coefficients of the incident radiance b/pi; \
                       irradiance(n) = sum_l A_l c_lm Y_lm(n) (three.js shGetIrradianceAt) is \
                       in the unit of the bake's H, b = e + rho H",
    });
    if let (Some(p), Some(c), Some(v)) = (positions, coefficient_accessor, valid_accessor) {
        extension["positions"] = json!(p.value());
        extension["coefficients"] = json!(c.value());
        extension["valid"] = json!(v.value());
    }
    if writer.root.scenes.is_empty() {
        return Ok(());
    }
    for scene in &mut writer.root.scenes {
        let mut ext = scene.extensions.take().unwrap_or_default();
        ext.others
            .insert(PROBES_EXTENSION.to_string(), extension.clone());
        scene.extensions = Some(ext);
    }
    writer.use_extension(PROBES_EXTENSION);
    Ok(())
}
