//! Public test corpora of malformed and odd files through the real binary: every `.gltf`
//! and `.glb` of the Khronos glTF validator's test suite and every `.obj` of
//! tinyobjloader's test models must either bake (exit 0, OUT written) or be refused with
//! exactly one `bake: error:` line on stderr (exit 1, nothing written). Never a panic
//! (exit 101), a signal, a run past the time limit or past the memory cap.
//!
//! The corpora live in `shared/corpus` beside the repository; without them the test says
//! `skipped: …` on stderr and passes, or fails with `BAKE_REQUIRE_CORPUS=1` or
//! `BAKE_REQUIRE_ALL=1` (as `.ci/run` sets).

use crate::common;

use bake_testkit::{files_with_extensions, shared_dir, skip};
use common::run_limited;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Wall-clock limit per file; the run is killed past it.
const TIME_LIMIT: Duration = Duration::from_secs(20);
/// Address-space cap per run (`ulimit -v`, KiB): 4 GiB.
const MEMORY_KIB: u64 = 4 * 1024 * 1024;
/// Files baked at once.
const WORKERS: usize = 2;

/// How one run ended.
#[derive(Debug)]
enum Outcome {
    Baked,
    /// Exit 1 with one error line: the line with the path and `bake: error: ` cut off,
    /// for grouping.
    Refused(String),
    /// Anything else, described.
    Failed(String),
}

/// Runs `bake INPUT OUT --quiet --subdiv 1` under the memory cap and time limit.
fn bake(input: &Path, out: &Path) -> Outcome {
    let script = format!("ulimit -v {MEMORY_KIB} && exec \"$0\" \"$@\"");
    let mut command = Command::new("sh");
    command
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_bake"))
        .arg(input)
        .arg(out)
        .args(["--quiet", "--subdiv", "1"]);
    let run = match run_limited(command, TIME_LIMIT) {
        Ok(run) => run,
        Err(e) => return Outcome::Failed(format!("cannot run: {e}")),
    };
    let Some(status) = run.status else {
        return Outcome::Failed(format!("still running after {TIME_LIMIT:?}: killed"));
    };
    judge(status.code(), &run.stderr, out)
}

/// The outcome of a finished run from its exit code, stderr and output.
fn judge(code: Option<i32>, stderr: &str, out: &Path) -> Outcome {
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    match code {
        Some(0) if out.is_file() && lines.is_empty() => Outcome::Baked,
        Some(0) => Outcome::Failed(format!(
            "exit 0 but output written: {}, stderr {stderr:?}",
            out.is_file()
        )),
        Some(1) if out.exists() => Outcome::Failed("exit 1 but OUT was written".into()),
        Some(1) => match lines.as_slice() {
            [line] if line.starts_with("bake: error: ") => Outcome::Refused(error_kind(line)),
            _ => Outcome::Failed(format!("exit 1 without exactly one error line: {stderr:?}")),
        },
        Some(code) => Outcome::Failed(format!("exit {code}: {stderr:?}")),
        None => Outcome::Failed(format!("killed by a signal: {stderr:?}")),
    }
}

/// `bake: error: PATH: malformed glTF: accessors[3]...` → `malformed glTF`: what the
/// summary groups refusals by.
fn error_kind(line: &str) -> String {
    let message = line.trim_start_matches("bake: error: ");
    let mut parts = message.split(": ");
    let first = parts.next().unwrap_or_default();
    // The first part is the input path when the message has more than one part.
    let kind = parts.next().unwrap_or(first);
    kind.split(|c: char| c.is_ascii_digit() || c == '[' || c == '(')
        .next()
        .unwrap_or(kind)
        .trim()
        .to_string()
}

#[test]
fn every_corpus_file_bakes_or_is_refused_in_one_line() {
    let _alone = crate::one_at_a_time();
    let corpus = shared_dir().join("corpus");
    if !corpus.is_dir() {
        skip(
            "BAKE_REQUIRE_CORPUS",
            &format!("the corpus {} is not there", corpus.display()),
        );
        return;
    }
    let mut inputs = files_with_extensions(&corpus.join("gltf-validator"), &["gltf", "glb"]);
    inputs.extend(files_with_extensions(
        &corpus.join("tinyobjloader"),
        &["obj"],
    ));
    assert!(!inputs.is_empty(), "the corpus has no files");
    let dir = tempfile::tempdir().expect("a temporary directory");

    let next = AtomicUsize::new(0);
    let results = Mutex::new(Vec::new());
    let started = Instant::now();
    std::thread::scope(|scope| {
        for _ in 0..WORKERS {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(input) = inputs.get(i) else {
                    break;
                };
                let out = dir.path().join(format!("out-{i}.glb"));
                let outcome = bake(input, &out);
                let _ = std::fs::remove_file(&out);
                if let Ok(mut results) = results.lock() {
                    results.push((input.clone(), outcome));
                }
            });
        }
    });
    let results = results.into_inner().expect("no worker panicked");
    summarise(&results, started.elapsed());

    let failures: Vec<String> = results
        .iter()
        .filter_map(|(input, outcome)| match outcome {
            Outcome::Failed(why) => Some(format!("{}: {why}", input.display())),
            _ => None,
        })
        .collect();
    assert_eq!(results.len(), inputs.len());
    assert!(
        failures.is_empty(),
        "{} of {} files failed:\n{}",
        failures.len(),
        inputs.len(),
        failures.join("\n")
    );
}

/// Prints the counts: baked, refused by kind of error, failed.
fn summarise(results: &[(PathBuf, Outcome)], elapsed: Duration) {
    let mut kinds: BTreeMap<&str, usize> = BTreeMap::new();
    let (mut baked, mut refused, mut failed) = (0, 0, 0);
    for (_, outcome) in results {
        match outcome {
            Outcome::Baked => baked += 1,
            Outcome::Refused(kind) => {
                refused += 1;
                *kinds.entry(kind).or_default() += 1;
            }
            Outcome::Failed(_) => failed += 1,
        }
    }
    println!(
        "corpus: {} files in {:.1} s: {baked} baked, {refused} refused, {failed} failed",
        results.len(),
        elapsed.as_secs_f64()
    );
    let mut kinds: Vec<_> = kinds.into_iter().collect();
    kinds.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
    for (kind, count) in kinds {
        println!("  {count:4} refused: {kind}");
    }
}

#[test]
fn outcomes_are_judged_strictly() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out = dir.path().join("out.glb");
    let refused = "bake: error: in.gltf: malformed glTF: accessors[3]: bad\n";
    assert!(matches!(judge(Some(1), refused, &out), Outcome::Refused(k) if k == "malformed glTF"));
    let two_lines = "bake: error: in.gltf: bad\nmore\n";
    assert!(matches!(
        judge(Some(1), two_lines, &out),
        Outcome::Failed(_)
    ));
    let panic = "thread 'main' panicked at src/x.rs:1:1:\nboom\n";
    assert!(matches!(judge(Some(101), panic, &out), Outcome::Failed(_)));
    assert!(matches!(judge(None, "", &out), Outcome::Failed(_)));
    assert!(
        matches!(judge(Some(0), "", &out), Outcome::Failed(_)),
        "no OUT"
    );
    std::fs::write(&out, b"glTF").expect("write");
    assert!(matches!(judge(Some(0), "", &out), Outcome::Baked));
    assert!(
        matches!(judge(Some(1), refused, &out), Outcome::Failed(_)),
        "OUT left"
    );
}
