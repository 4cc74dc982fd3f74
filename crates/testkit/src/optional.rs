//! Tests that need something this machine may lack (the Khronos validator, Blender,
//! pyrender, gltfpack, the `../shared` corpora): they say they were skipped and pass, unless
//! a `BAKE_REQUIRE_*` variable turns the missing piece into a failure.

use crate::paths::tools_dir;
use std::path::PathBuf;
use std::process::{Command, Output};

/// Whether the environment variable `name` is exactly `1`.
fn set(name: &str) -> bool {
    std::env::var(name).is_ok_and(|v| v == "1")
}

/// Whether the test that needs what `variable` names must run: `variable=1`, or
/// `BAKE_REQUIRE_ALL=1` (as `.ci/run` sets).
pub fn required(variable: &str) -> bool {
    set(variable) || set("BAKE_REQUIRE_ALL")
}

/// A test that cannot run here because `why` (e.g. "the validator is not installed"): fails
/// when [`required`]`(variable)`, else says `skipped: …` on stderr. Written straight to the
/// process's stderr, past libtest's capture of `print!`/`eprint!`, so `cargo test` shows it
/// even when the test passes.
pub fn skip(variable: &str, why: &str) {
    assert!(
        !required(variable),
        "{variable}=1 (or BAKE_REQUIRE_ALL=1) but {why}"
    );
    say_skipped(variable, why);
}

/// [`skip`] for a check that only `variable=1` makes fail, `BAKE_REQUIRE_ALL` not: what a
/// machine may lack by policy rather than by a missing install (the mount namespaces of
/// `tests/end_to_end/reliability3.rs`). Everything `.ci/run` installs uses [`skip`].
pub fn skip_unless_set(variable: &str, why: &str) {
    assert!(!set(variable), "{variable}=1 but {why}");
    say_skipped(variable, why);
}

fn say_skipped(variable: &str, why: &str) {
    use std::io::Write;
    let _ = writeln!(
        std::io::stderr(),
        "skipped: {} ({why}; {variable}=1 makes it fail)",
        std::thread::current().name().unwrap_or("a test")
    );
}

/// Whether `node` runs and `tools/install-validator` has installed the Khronos validator.
pub fn validator_available() -> bool {
    let installed = tools_dir()
        .join(".validator/node_modules/gltf-validator/package.json")
        .is_file();
    let node_runs = Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|output| output.status.success());
    installed && node_runs
}

/// Whether the validator is installed; when it is not, [`skip`]s for
/// `BAKE_REQUIRE_VALIDATOR` (so `BAKE_REQUIRE_ALL=1` makes it fail too).
pub fn validator_or_skip() -> bool {
    here_or_skip(
        validator_available(),
        "BAKE_REQUIRE_VALIDATOR",
        "the validator is not installed (run tools/install-validator)",
    )
}

/// Runs the Khronos validator (`node tools/validate.mjs`) on `files`: one summary line per
/// file (`PATH: N errors, N warnings, N infos`), each followed by its messages indented.
pub fn validator_output(files: &[PathBuf]) -> Output {
    Command::new("node")
        .arg(tools_dir().join("validate.mjs"))
        .args(files)
        .output()
        .expect("run node tools/validate.mjs")
}

/// Runs the validator on `files` and returns its output, asserting that every file has
/// 0 errors and 0 warnings. `None` (with a message) when the validator is not installed,
/// unless `BAKE_REQUIRE_VALIDATOR=1` or `BAKE_REQUIRE_ALL=1`.
pub fn validate_clean(files: &[PathBuf]) -> Option<String> {
    if !validator_available() {
        skip(
            "BAKE_REQUIRE_VALIDATOR",
            "the validator is not installed (run tools/install-validator)",
        );
        return None;
    }
    let output = validator_output(files);
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    let summaries: Vec<&str> = stdout.lines().filter(|l| !l.starts_with(' ')).collect();
    assert_eq!(summaries.len(), files.len(), "{stdout}");
    for line in &summaries {
        assert!(line.contains(": 0 errors, 0 warnings, "), "{stdout}");
    }
    assert!(output.status.success(), "{stdout}");
    Some(stdout)
}

/// Whether `blender` runs.
pub fn blender_installed() -> bool {
    Command::new("blender")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Whether `blender` runs; when it does not, [`skip`]s for `BAKE_REQUIRE_BLENDER` (so
/// `BAKE_REQUIRE_ALL=1` makes it fail too).
pub fn blender_or_skip() -> bool {
    here_or_skip(
        blender_installed(),
        "BAKE_REQUIRE_BLENDER",
        "blender is not installed (tools/ci-clients --blender installs it)",
    )
}

/// Whether `chromium` runs (for the three.js checks in headless Chromium); when it does not,
/// [`skip`]s for `BAKE_REQUIRE_THREEJS` (so `BAKE_REQUIRE_ALL=1` makes it fail too).
pub fn chromium_or_skip() -> bool {
    let runs = Command::new("chromium")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    here_or_skip(
        runs,
        "BAKE_REQUIRE_THREEJS",
        "chromium is not installed (tools/ci-clients --chromium installs it)",
    )
}

/// `here`; when false, [`skip`]s first.
fn here_or_skip(here: bool, variable: &str, why: &str) -> bool {
    if !here {
        skip(variable, why);
    }
    here
}
