//! The bake report (`--report`) filled from the bake's result, the job's options, the
//! lightmap and each stage's time and peak memory.

use super::{ElementsIncluded, LightEntry, Report, SkyEntry, SolverInfo, SolverMethod};
use crate::{internal, Events, Exposure, Failure, Job, Target, Warnings, REPORT_ELEMENTS_LIMIT};
use anyhow::Context;
use lightmap::UvMode;
use mesher::Shading;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// Each stage's wall time (s) and the peak memory (MiB) when it ended.
#[derive(Default)]
pub(crate) struct Stages {
    timings: BTreeMap<String, f64>,
    memory: BTreeMap<String, f64>,
}

impl Stages {
    /// The stage `name` that began at `lap` ends now.
    pub fn record(&mut self, name: &str, lap: Instant) {
        self.timings
            .insert(name.to_string(), lap.elapsed().as_secs_f64());
        if let Some(mib) = bake_core::peak_rss_mib_now() {
            self.memory.insert(name.to_string(), mib);
        }
    }

    /// Each finished stage's seconds and peak memory, with `total` up to now.
    pub fn into_maps(mut self, started: Instant) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
        self.timings
            .insert("total".to_string(), started.elapsed().as_secs_f64());
        (self.timings, self.memory)
    }

    /// The stages inside the bake.
    pub fn extend(&mut self, bake: &bake_core::Bake) {
        for (name, seconds) in &bake.timings {
            self.timings.insert(name.to_string(), *seconds);
        }
        for (name, mib) in &bake.peak_rss_mib {
            self.memory.insert(name.to_string(), *mib);
        }
    }
}

/// Everything a report is built from.
pub(crate) struct Baked<'a> {
    pub job: &'a Job,
    pub scene: &'a importer::Scene,
    pub bake: &'a bake_core::Bake,
    pub lightmap: Option<&'a lightmap::Lightmap>,
    pub exposure: f64,
    pub probes: Option<&'a probes::Summary>,
}

impl Baked<'_> {
    /// The report for `path`; a warning about its size goes to `warnings` (which the report
    /// then lists, all of them).
    pub fn report<E: Events>(
        &self,
        path: &Path,
        warnings: &mut Warnings<E>,
        mut stages: Stages,
        started: Instant,
    ) -> Result<Report, Failure> {
        let (scene, bake, mesh) = (self.scene, self.bake, &self.bake.mesh);
        let mut report = Report::new(
            &self.job.input,
            scene,
            mesh,
            &bake.solution.b,
            self.solver(),
        )
        .with_context(|| format!("cannot build the report {}", path.display()))
        .map_err(internal)?;
        report.options = self.options_json();
        if let (Some(built), Some(map)) = (self.lightmap, report.options.as_object_mut()) {
            map.insert("lightmap_layout".into(), lightmap_layout(built));
        }
        // The summary needs only area and b: drop the list before filling in what only the
        // list shows.
        let (which, warning) = report_elements(self.job.report_elements, mesh.elements.len());
        if let Some(line) = warning {
            warnings.push(line);
        }
        report.keep_elements(which);
        for (i, entry) in report.elements.iter_mut().enumerate() {
            // ρ and e as the bake used them (textures averaged over the element).
            entry.rho = bake.rho[i];
            entry.e = bake.emission[i];
            entry.direct = bake.direct[i];
            entry.sky = bake.sky_stats.is_some().then(|| bake.sky[i]);
            entry.h = bake.irradiance.as_ref().map(|h| h[i]);
            entry.error = bake.error.get(i).map(|p| p.total());
        }
        report.lights = light_entries(scene, bake);
        report.sky = sky_entry(bake);
        report.counts = bake.counts;
        report.effects = bake.effects.clone();
        report.transport = bake.plan.transport().clone();
        report.energy = Some(bake.energy.clone());
        report.escape = Some(bake.escape);
        report.accuracy = Some(bake.accuracy);
        report.refinement = Some(bake.refinement.clone());
        report.probes = self.probes.copied();
        report.warnings = warnings.lines.clone();
        stages
            .timings
            .insert("total".to_string(), started.elapsed().as_secs_f64());
        report.timings = stages.timings;
        report.peak_rss_mib = stages.memory;
        Ok(report)
    }

    fn solver(&self) -> SolverInfo {
        let (bake, solution) = (self.bake, &self.bake.solution);
        SolverInfo {
            method: match bake.plan.solve() {
                bake_core::Solve::Direct => SolverMethod::Direct,
                bake_core::Solve::Iterative(_) => SolverMethod::Iterative,
                bake_core::Solve::Bounces(_) => SolverMethod::Bounces,
            },
            bounces: match bake.plan.solve() {
                bake_core::Solve::Bounces(k) => Some(k),
                _ => None,
            },
            residual: solution.residual,
            residual_relative: solution.residual_relative,
            factorizations: solution.factorizations as u32,
            condition: solution.condition,
            iterations: solution.iterations,
        }
    }

    /// The options as resolved for this bake (defaults filled in): the bake's settings plus
    /// the job's output options.
    fn options_json(&self) -> serde_json::Value {
        let job = self.job;
        let mut options = self.bake.plan.options_json();
        let output = serde_json::json!({
            "shading": match job.shading { Shading::Smooth => "smooth", Shading::Flat => "flat" },
            "exposure": self.exposure,
            "exposure_rule": match job.exposure {
                Exposure::Auto => "auto: the 99th percentile (by area) of the elements' brightest band maps to 0.8",
                Exposure::Value(_) => "given",
                Exposure::Ev100(_) => "ev100:N: 1 / (1.2 × 2^N)",
            },
            "keep_lights": job.keep_lights,
            "output": job.output.display().to_string(),
            "target": match job.target {
                Target::Vertex => "vertex",
                Target::Lightmap => "lightmap",
                Target::Both => "both",
                Target::BakedTexture => "baked-texture",
            },
            "lightmap_texel": job
                .lightmap
                .texel
                .unwrap_or_else(|| lightmap::default_texel_size(&self.scene.polygons)),
            "lightmap_max": job.lightmap.max_size,
            "lightmap_uv": match job.lightmap.uv {
                UvMode::Auto => "auto",
                UvMode::Keep => "keep",
                UvMode::Generate => "generate",
            },
        });
        if let (Some(map), serde_json::Value::Object(extra)) = (options.as_object_mut(), output) {
            map.extend(extra);
        }
        options
    }
}

/// The report's `options.lightmap_layout`: per primitive instance, whether the input's
/// TEXCOORD_1 was kept as the lightmap layout, and if not why.
fn lightmap_layout(built: &lightmap::Lightmap) -> serde_json::Value {
    let entries: Vec<serde_json::Value> = built
        .uv_decisions
        .iter()
        .map(|d| {
            serde_json::json!({
                "node": d.node,
                "mesh": d.mesh,
                "primitive": d.primitive,
                "polygons": d.polygons,
                "uv": if d.kept { "kept" } else { "generated" },
                "reason": d.reason,
                "own_region": d.own_region,
            })
        })
        .collect();
    serde_json::Value::Array(entries)
}

/// The report's `lights`: each light the bake used, where it is, and what it took.
fn light_entries(scene: &importer::Scene, bake: &bake_core::Bake) -> Vec<LightEntry> {
    scene
        .lights
        .iter()
        .enumerate()
        .map(|(l, light)| {
            let stats = bake.light_stats.get(l).copied().unwrap_or_default();
            let (inner, outer) = match light.kind {
                importer::LightKind::Spot { inner, outer } => (Some(inner), Some(outer)),
                _ => (None, None),
            };
            LightEntry {
                kind: light.kind.name().to_string(),
                name: light.name.clone(),
                node: light.node,
                position: light.position.to_array(),
                direction: light.direction.to_array(),
                intensity: light.intensity,
                color: light.color,
                range: light.range,
                inner_cone_angle: inner,
                outer_cone_angle: outer,
                stats,
                delivered: light
                    .band_intensity()
                    .map(|i| i * stats.flux / std::f64::consts::PI),
            }
        })
        .collect()
}

/// The report's `sky`: the sky the bake used and what its pass took.
fn sky_entry(bake: &bake_core::Bake) -> Option<SkyEntry> {
    let (sky, stats) = (bake.plan.settings().sky()?, bake.sky_stats?);
    Some(SkyEntry {
        horizontal_illuminance: sky.model.horizontal_illuminance(),
        ground_radiance: sky.ground_radiance(),
        sky,
        stats,
        delivered: stats.flux.map(|f| f / std::f64::consts::PI),
    })
}

/// What a report keeps per element: the user's choice, else all up to
/// [`REPORT_ELEMENTS_LIMIT`] elements and the summary above (with a warning).
fn report_elements(
    choice: Option<ElementsIncluded>,
    elements: usize,
) -> (ElementsIncluded, Option<String>) {
    match choice {
        Some(which) => (which, None),
        None if elements > REPORT_ELEMENTS_LIMIT => (
            ElementsIncluded::Summary,
            Some(format!(
                "the report lists no elements, only their summary: {elements} elements, more \
                 than {REPORT_ELEMENTS_LIMIT} (--report-elements all lists them)"
            )),
        ),
        None => (ElementsIncluded::All, None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_reports_keep_the_summary_unless_asked() {
        assert_eq!(
            report_elements(None, 100_000),
            (ElementsIncluded::All, None)
        );
        let (which, warning) = report_elements(None, 100_001);
        assert_eq!(which, ElementsIncluded::Summary);
        assert!(warning.is_some_and(|w| w.contains("100001 elements")));
        for which in [
            ElementsIncluded::All,
            ElementsIncluded::Summary,
            ElementsIncluded::None,
        ] {
            assert_eq!(report_elements(Some(which), 5_000_000), (which, None));
            assert_eq!(report_elements(Some(which), 1), (which, None));
        }
    }
}
