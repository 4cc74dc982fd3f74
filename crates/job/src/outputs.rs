//! The output set of a bake: which files it writes, the checks before any work (every file
//! writable where it is named, none an input or another output), and staging the two bakes.

use crate::{internal, Failure, Job, Target, DEFAULT_MAX_REFLECTANCE};
use anyhow::{anyhow, Context};
use std::path::{Path, PathBuf};

/// Two paths of the bake are one file: a usage error (exit 2), refused before writing.
fn same_file(error: exporter::SameFile) -> Failure {
    Failure {
        code: 2,
        error: anyhow!(error),
    }
}

/// The lightmap bake's files for `job.target` (`both`: beside OUT; `lightmap`: OUT itself).
fn lightmap_paths(job: &Job) -> anyhow::Result<exporter::LightmapPaths> {
    match job.target {
        Target::Both => exporter::LightmapPaths::beside(&job.output),
        _ => exporter::LightmapPaths::alone(&job.output),
    }
    .with_context(|| format!("cannot write {}", job.output.display()))
}

/// The baked-texture bake's files (`--target baked-texture`: OUT itself).
fn baked_paths(job: &Job) -> anyhow::Result<exporter::BakedTexturePaths> {
    exporter::BakedTexturePaths::new(&job.output)
        .with_context(|| format!("cannot write {}", job.output.display()))
}

/// Every file this bake may write, in the order they are renamed into place (OUT last).
fn output_files(job: &Job) -> anyhow::Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = job.save_links.iter().cloned().collect();
    files.extend(job.report.iter().cloned());
    match job.target {
        Target::Vertex => {}
        Target::BakedTexture => files.extend(baked_paths(job)?.files()?),
        Target::Lightmap | Target::Both => files.extend(lightmap_paths(job)?.files()?),
    }
    if matches!(job.target, Target::Vertex | Target::Both) {
        files.extend(
            exporter::gltf_files(&job.output)
                .with_context(|| format!("cannot write {}", job.output.display()))?,
        );
    }
    Ok(files)
}

/// The files a bake writes and the files it reads.
pub(crate) struct Plan {
    /// In the order they are renamed into place (OUT last).
    pub files: Vec<PathBuf>,
    /// The input and the links file it loads (the scene's own files are checked after import).
    inputs: Vec<PathBuf>,
}

impl Plan {
    /// Fails before the bake, not after it: every file of the set must be writable where it is
    /// named (an existing directory, not itself a directory), and none may be an input.
    pub fn new(job: &Job) -> Result<Plan, Failure> {
        let files = output_files(job).map_err(internal)?;
        // OUT first (it is renamed last), so a missing directory is named by OUT.
        for path in files.iter().rev() {
            let dir = match path.parent() {
                Some(dir) if !dir.as_os_str().is_empty() => dir,
                _ => Path::new("."),
            };
            if !dir.is_dir() {
                return Err(internal(anyhow!(
                    "cannot write {}: {} is not an existing directory",
                    path.display(),
                    dir.display()
                )));
            }
            exporter::check_target(path).map_err(|e| internal(anyhow!(e)))?;
        }
        let mut inputs = vec![job.input.clone()];
        inputs.extend(job.request.load_links.iter().cloned());
        exporter::check_distinct(&files, &inputs).map_err(same_file)?;
        Ok(Plan { files, inputs })
    }

    /// No output may be one of the files the scene was read from (.bin, textures, .mtl).
    pub fn check_scene_inputs(&self, scene: &importer::Scene) -> Result<(), Failure> {
        exporter::check_distinct(&self.files, &scene.input_files).map_err(same_file)
    }

    /// Several atlases add files the check before the bake could not know of: they too must
    /// not be an input or another output.
    pub fn with_atlases(
        mut self,
        job: &Job,
        lightmap: Option<&lightmap::Lightmap>,
        scene: &importer::Scene,
    ) -> Result<Plan, Failure> {
        let Some(built) = lightmap.filter(|b| !b.more.is_empty()) else {
            return Ok(self);
        };
        if job.target == Target::BakedTexture {
            let paths = baked_paths(job).map_err(internal)?;
            let with_png = paths
                .files()
                .map_err(|e| internal(anyhow!(e)))?
                .contains(&paths.png);
            for k in (1..=built.more.len()).filter(|_| with_png) {
                self.files
                    .push(paths.atlas_png(k).map_err(|e| internal(anyhow!(e)))?);
            }
            return self.checked(scene);
        }
        let paths = lightmap_paths(job).map_err(internal)?;
        let with_png = paths
            .files()
            .map_err(|e| internal(anyhow!(e)))?
            .contains(&paths.png);
        for k in 1..=built.more.len() {
            self.files
                .push(paths.atlas_exr(k).map_err(|e| internal(anyhow!(e)))?);
            if with_png {
                self.files
                    .push(paths.atlas_png(k).map_err(|e| internal(anyhow!(e)))?);
            }
        }
        self.checked(scene)
    }

    /// Self, once no output is an input or another output.
    fn checked(self, scene: &importer::Scene) -> Result<Plan, Failure> {
        let mut all_inputs = self.inputs.clone();
        all_inputs.extend(scene.input_files.iter().cloned());
        exporter::check_distinct(&self.files, &all_inputs).map_err(same_file)?;
        Ok(self)
    }
}

/// A probe set as the arrays the exporter writes.
pub(crate) struct ProbeArrays {
    grid: probes::Grid,
    positions: Vec<[f64; 3]>,
    coefficients: Vec<[[f64; 3]; exporter::PROBE_COEFFICIENTS]>,
    valid: Vec<bool>,
}

impl ProbeArrays {
    pub fn of(set: &probes::ProbeSet) -> ProbeArrays {
        ProbeArrays {
            grid: set.grid,
            positions: set.probes.iter().map(|p| p.position.to_array()).collect(),
            coefficients: set.probes.iter().map(|p| p.sh).collect(),
            valid: set.probes.iter().map(|p| p.valid).collect(),
        }
    }

    pub fn grid(&self, exposure: f64) -> exporter::ProbeGrid<'_> {
        exporter::ProbeGrid {
            origin: self.grid.origin,
            spacing: self.grid.spacing,
            counts: self.grid.counts,
            positions: &self.positions,
            coefficients: &self.coefficients,
            valid: &self.valid,
            exposure,
        }
    }
}

/// The vertex bake's and the lightmap (or baked-texture) bake's files, staged (written to
/// temporaries), with the probes (if any) on their scenes.
pub(crate) fn stage_bakes(
    job: &Job,
    scene: &importer::Scene,
    bake: &bake_core::Bake,
    lightmap: Option<&lightmap::Lightmap>,
    exposure: f64,
    probes: Option<&exporter::ProbeGrid>,
) -> Result<(exporter::OutputSet, exporter::OutputSet), Failure> {
    let errors: Vec<[f64; 3]> = bake.error.iter().map(|p| p.total()).collect();
    let vertex_bake = exporter::Bake {
        scene,
        mesh: &bake.mesh,
        radiosity: &bake.solution.b,
        irradiance: bake.irradiance.as_deref(),
        error: Some(&errors),
        shading: job.shading,
        exposure,
        probes,
    };
    let mut vertex_files = exporter::OutputSet::new();
    if matches!(job.target, Target::Vertex | Target::Both) {
        exporter::stage_gltf(&mut vertex_files, &job.output, &vertex_bake)
            .with_context(|| format!("cannot write {}", job.output.display()))
            .map_err(internal)?;
    }
    let mut lightmap_files = exporter::OutputSet::new();
    if let (Some(built), Target::BakedTexture) = (lightmap, job.target) {
        let paths = baked_paths(job).map_err(internal)?;
        let baked = exporter::BakedTextureBake {
            scene,
            lightmap: built,
            exposure,
            ceiling: Some(bake_core::REFLECTS_ALL)
                .zip(
                    job.request
                        .max_reflectance
                        .or(Some(DEFAULT_MAX_REFLECTANCE)),
                )
                .filter(|&(_, to)| to < 1.0),
            probes,
        };
        exporter::stage_baked_texture_gltf(&mut lightmap_files, &paths, &baked)
            .with_context(|| format!("cannot write {}", paths.gltf.display()))
            .map_err(internal)?;
    } else if let Some(built) = lightmap {
        let paths = lightmap_paths(job).map_err(internal)?;
        let lightmap_bake = exporter::LightmapBake {
            scene,
            lightmap: built,
            keep_lights: job.keep_lights,
            exposure,
            probes,
        };
        exporter::stage_lightmap_gltf(&mut lightmap_files, &paths, &lightmap_bake)
            .with_context(|| format!("cannot write {}", paths.gltf.display()))
            .map_err(internal)?;
    }
    Ok((vertex_files, lightmap_files))
}

/// `bake preview IN PNG`: the PNG may be neither a file the preview reads (IN, its buffers,
/// its textures: exit 2, as for a bake) nor something a rename would destroy (a device, a
/// FIFO, a link to one: exit 3, as for a bake's outputs). Checked before rendering.
pub fn check_preview_output(input: &Path, output: &Path) -> Result<(), Failure> {
    exporter::check_target(output).map_err(|e| internal(anyhow!(e)))?;
    let inputs = preview::input_files(input);
    exporter::check_distinct(&[output.to_path_buf()], &inputs).map_err(same_file)
}
