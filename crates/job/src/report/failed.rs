//! The report of a bake that failed (`--report` given): the error line, the stage it failed
//! in, the exit code, and what was measured up to there, so that a build log can say why.

use super::{ReadReportError, SCHEMA_VERSION};
use bake_core::Counts;
use exporter::{ExportError, OutputSet};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

/// A failed bake's report. Told from a finished bake's [`super::Report`] by its `failure`
/// object (a finished bake's report has none).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FailedReport {
    /// [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// The input file, as given.
    pub input: String,
    pub failure: FailureEntry,
    /// The scene's counts once the import finished (`null` when it did not): polygons and
    /// what the importer read, merged and dropped. `elements` and the work counts are 0: the
    /// bake did not finish (a refusal's error line says the element count it refused).
    pub counts: Option<Counts>,
    /// Seconds per stage that finished, by stage name, and `total` up to the failure.
    pub timings: BTreeMap<String, f64>,
    /// Peak resident memory (MiB) at the end of each stage that finished.
    pub peak_rss_mib: BTreeMap<String, f64>,
    /// The warnings shown before the failure.
    pub warnings: Vec<String>,
}

/// What failed.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FailureEntry {
    /// The error line the binary prints (without `bake: error: `).
    pub error: String,
    /// The stage it failed in: `import`, `bake` (or `bake: <step>`, the last step the bake
    /// began, as its progress names it: `form factors`, `solve`, …) or `lightmap` (a failure
    /// while the outputs are written leaves the previous set, report included, as it was).
    pub stage: String,
    /// The exit code of the bake (1 bad input, 3 output or internal, 4 too large).
    pub exit_code: u8,
}

impl FailedReport {
    pub fn new(input: &Path, failure: FailureEntry) -> FailedReport {
        FailedReport {
            schema_version: SCHEMA_VERSION,
            input: input.to_string_lossy().into_owned(),
            failure,
            counts: None,
            timings: BTreeMap::new(),
            peak_rss_mib: BTreeMap::new(),
            warnings: Vec::new(),
        }
    }
}

/// Writes `report` to `path` atomically. A failed bake may have failed before it knew the
/// scene's files (a malformed glTF names its buffers only once parsed), so the report replaces
/// only nothing or a previous bake report (a file beginning `{` with `"schema_version"` in its
/// first line or two); anything else at `path` is kept and the write refused.
pub fn write_failed_report(path: &Path, report: &FailedReport) -> Result<(), ExportError> {
    if !replaceable(path)? {
        return Err(ExportError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                "exists and is not a bake report: the failed bake's report does not replace it",
            ),
        });
    }
    let mut json = serde_json::to_vec_pretty(report).map_err(|e| ExportError::Encode {
        what: "the failed bake's report",
        message: e.to_string(),
    })?;
    json.push(b'\n');
    let mut set = OutputSet::new();
    set.stage_with(path, |w| w.write_all(&json))?;
    set.commit().map(drop)
}

/// Whether `path` is free, or holds a previous bake report.
fn replaceable(path: &Path) -> Result<bool, ExportError> {
    let io = |source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = match std::fs::File::open(path) {
        Ok(file) => file,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(true),
        Err(e) => return Err(io(e)),
    };
    let mut head = Vec::with_capacity(64);
    file.take(64).read_to_end(&mut head).map_err(io)?;
    let head = String::from_utf8_lossy(&head);
    Ok(head.trim_start().starts_with('{') && head.contains("\"schema_version\""))
}

/// Reads a report written by [`write_failed_report`].
pub fn read_failed_report(path: &Path) -> Result<FailedReport, ReadReportError> {
    super::read_json(path)
}
