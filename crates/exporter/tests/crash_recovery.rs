//! A crash in the middle of a commit's renames is put back at the next start (issue 34): the
//! test binary re-runs itself as a child that commits a set over a previous one and calls
//! `std::process::abort()` (no destructors, no cleanup: as kill -9 or a power loss would stop
//! it) at its k-th file operation, for every k; then the start of the next bake
//! (`recover_interrupted_commits`, then `remove_stale_temporaries`) must leave exactly the
//! previous set, or exactly the new one where the crash came after the commit point (the
//! journal's removal), byte for byte and with no temporary, backup or journal left.
#![cfg(target_os = "linux")]

use bake_exporter::{
    recover_interrupted_commits, remove_stale_temporaries, FileOps, OutputSet, Recovered,
};
use std::collections::BTreeMap;
use std::fs;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// The folder the child commits into (set only in the child).
const CHILD_DIR: &str = "BAKE_CRASH_TEST_DIR";
/// The file operation (counted from 1) at which the child aborts.
const CHILD_CRASH_AT: &str = "BAKE_CRASH_TEST_AT";
const SIGABRT: i32 = 6;

/// The set, in rename order, relative to the test's folder: the report in a folder of its
/// own, the lightmap glTF that the previous bake did not write, OUT's bin, OUT last.
const NAMES: [&str; 4] = [
    "reports/report.json",
    "out/out_lightmap.gltf",
    "out/out.bin",
    "out/out.gltf",
];
const NEW_ONLY: &str = "out/out_lightmap.gltf";

/// Passes every call to the file system, logging it, and aborts the process at call
/// `crash_at` (0: never).
#[derive(Debug)]
struct Crashing {
    crash_at: usize,
    calls: AtomicUsize,
    log: Mutex<Vec<String>>,
}

impl Crashing {
    fn new(crash_at: usize) -> Arc<Crashing> {
        Arc::new(Crashing {
            crash_at,
            calls: AtomicUsize::new(0),
            log: Mutex::new(Vec::new()),
        })
    }

    fn call(&self, what: &str, path: &Path) {
        let n = self.calls.fetch_add(1, Ordering::SeqCst) + 1;
        if n == self.crash_at {
            std::process::abort();
        }
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
        if let Ok(mut log) = self.log.lock() {
            log.push(format!("{what} {}", name.unwrap_or_default()));
        }
    }
}

impl FileOps for Crashing {
    fn create(&self, path: &Path) -> std::io::Result<fs::File> {
        self.call("create", path);
        fs::File::create(path)
    }
    fn rename(&self, from: &Path, to: &Path) -> std::io::Result<()> {
        self.call("rename", to);
        fs::rename(from, to)
    }
    fn hard_link(&self, from: &Path, to: &Path) -> std::io::Result<()> {
        self.call("hard_link", from);
        fs::hard_link(from, to)
    }
    fn copy(&self, from: &Path, to: &Path) -> std::io::Result<()> {
        self.call("copy", from);
        fs::copy(from, to).map(|_| ())
    }
    fn remove_file(&self, path: &Path) -> std::io::Result<()> {
        self.call("remove", path);
        fs::remove_file(path)
    }
}

fn targets(dir: &Path) -> Vec<PathBuf> {
    NAMES.iter().map(|n| dir.join(n)).collect()
}

/// Every file under `dir` (its folders one level down), relative path → bytes.
fn contents(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut all = BTreeMap::new();
    for sub in ["reports", "out"] {
        for entry in fs::read_dir(dir.join(sub)).expect("list").flatten() {
            let name = format!("{sub}/{}", entry.file_name().to_string_lossy());
            all.insert(name, fs::read(entry.path()).expect("read"));
        }
    }
    all
}

/// The folders and the previous set (without [`NEW_ONLY`]).
fn previous_set(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    for sub in ["reports", "out"] {
        fs::create_dir_all(dir.join(sub)).expect("mkdir");
    }
    for name in NAMES.iter().filter(|n| **n != NEW_ONLY) {
        fs::write(dir.join(name), format!("old {name}")).expect("write old");
    }
    contents(dir)
}

fn new_set() -> BTreeMap<String, Vec<u8>> {
    NAMES
        .iter()
        .map(|n| (n.to_string(), format!("new {n}, longer").into_bytes()))
        .collect()
}

/// Stages the new set over the previous one and commits it through `files`.
fn commit_new_set(dir: &Path, files: Arc<dyn FileOps>) {
    let mut set = OutputSet::with_files(files);
    for (name, target) in NAMES.iter().zip(targets(dir)) {
        set.stage_with(&target, |w| write!(w, "new {name}, longer"))
            .expect("stage");
    }
    set.commit().expect("commit");
}

/// The child's part of the crash test: commits into `$BAKE_CRASH_TEST_DIR`, aborting at
/// call `$BAKE_CRASH_TEST_AT`.
fn child(dir: &Path) {
    let crash_at = std::env::var(CHILD_CRASH_AT)
        .ok()
        .and_then(|k| k.parse().ok())
        .expect("the call to crash at");
    commit_new_set(dir, Crashing::new(crash_at));
}

/// Runs this test in a child that crashes at call `crash_at` of committing into `dir`.
fn crash_child(dir: &Path, crash_at: usize) -> std::process::ExitStatus {
    let exe = std::env::current_exe().expect("the test binary");
    // No core file (abort would write one where core dumps are on).
    Command::new("sh")
        .arg("-c")
        .arg("ulimit -c 0; exec \"$0\" \"$@\"")
        .arg(exe)
        .args([
            "--exact",
            "a_crash_at_any_file_operation_of_a_commit_is_undone_at_the_next_start",
            "--test-threads=1",
            "--nocapture",
        ])
        .env(CHILD_DIR, dir)
        .env(CHILD_CRASH_AT, crash_at.to_string())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .expect("run the child")
}

#[test]
fn a_crash_at_any_file_operation_of_a_commit_is_undone_at_the_next_start() {
    if let Some(dir) = std::env::var_os(CHILD_DIR) {
        child(Path::new(&dir));
        return;
    }
    // Every call of staging and commit, in order, from a run to completion.
    let clean = tempfile::tempdir().expect("temp dir");
    previous_set(clean.path());
    let counter = Crashing::new(0);
    commit_new_set(clean.path(), counter.clone());
    let calls = counter.log.lock().map(|l| l.clone()).unwrap_or_default();
    assert_eq!(contents(clean.path()), new_set());
    // The commit point: the journal's removal (the set is new from the call after it on).
    let journal_removal = calls
        .iter()
        .position(|c| c.starts_with("remove .out.gltf.journal-"))
        .map(|i| i + 1)
        .expect("the commit removes its journal");
    let renames = calls.iter().filter(|c| c.starts_with("rename ")).count();
    // The journal's, then one per file.
    assert_eq!(renames, 1 + NAMES.len(), "{calls:?}");
    let (old, new) = {
        let dir = tempfile::tempdir().expect("temp dir");
        (previous_set(dir.path()), new_set())
    };
    let mut mixed = Vec::new();
    for crash_at in 1..=calls.len() {
        let dir = tempfile::tempdir().expect("temp dir");
        let d = dir.path();
        assert_eq!(previous_set(d), old);
        let status = crash_child(d, crash_at);
        let call = &calls[crash_at - 1];
        assert_eq!(
            status.signal(),
            Some(SIGABRT),
            "the child did not crash at call {crash_at} ({call}): {status}"
        );
        let outputs: BTreeMap<String, Vec<u8>> = contents(d)
            .into_iter()
            .filter(|(name, _)| !name.contains("/."))
            .collect();
        if outputs != old && outputs != new {
            mixed.push(crash_at);
        }
        // The start of the next bake.
        let recovered = recover_interrupted_commits(&targets(d));
        assert!(
            recovered.is_ok(),
            "crash at {crash_at} ({call}): {recovered:?}"
        );
        remove_stale_temporaries(&targets(d));
        let expected = if crash_at > journal_removal {
            &new
        } else {
            &old
        };
        assert_eq!(
            &contents(d),
            expected,
            "crash at call {crash_at} ({call}) of {calls:?}"
        );
    }
    // Without the recovery these would be left mixed: the test covers the renames.
    assert!(mixed.len() >= NAMES.len() - 1, "mixed after {mixed:?}");
}

/// A journal as the format documents it, of one done step whose previous file is in its
/// backup; returns (target, backup).
fn one_step_journal(dir: &Path, journal_name: &str) -> (PathBuf, PathBuf) {
    let target = dir.join("out.gltf");
    let backup = dir.join(".out.gltf.tmp-4294967294-1");
    let temporary = dir.join(".out.gltf.tmp-4294967294-0");
    fs::write(&target, "new").expect("write");
    fs::write(&backup, "old").expect("write");
    let journal = format!(
        "bake-commit-journal 1\n{}\t{}\t{}\n",
        target.display(),
        backup.display(),
        temporary.display()
    );
    fs::write(dir.join(journal_name), journal).expect("write");
    (target, backup)
}

/// Another process that runs now (the one that started this test) may be committing: its
/// journal is not touched.
#[test]
fn the_journal_of_a_running_process_is_left_alone() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let running = std::os::unix::process::parent_id();
    assert!(Path::new(&format!("/proc/{running}")).exists());
    let live = format!(".out.gltf.journal-{running}");
    let (target, backup) = one_step_journal(d, &live);
    let recovered = recover_interrupted_commits(std::slice::from_ref(&target));
    assert_eq!(recovered.ok(), Some(Recovered::default()));
    assert_eq!(fs::read(&target).expect("read"), b"new");
    assert!(backup.exists() && d.join(&live).exists());
    // The same journal of a process that no longer runs (no pid exceeds pid_max) is
    // rolled back and removed.
    let dead = d.join(".out.gltf.journal-4294967294");
    fs::rename(d.join(&live), &dead).expect("rename");
    let recovered = recover_interrupted_commits(std::slice::from_ref(&target));
    let expected = Recovered {
        journals: 1,
        restored: 1,
        removed: 0,
    };
    assert_eq!(recovered.ok(), Some(expected));
    assert_eq!(fs::read(&target).expect("read"), b"old");
    assert!(!backup.exists() && !dead.exists());
}

/// A journal named with this process's own id is a previous process's (the same id after a
/// reboot): this process's commits hold the lock recovery takes, so none is in progress.
#[test]
fn a_journal_with_this_process_id_is_a_previous_process_and_rolled_back() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let own = d.join(format!(".out.gltf.journal-{}", std::process::id()));
    let name = own.file_name().and_then(|n| n.to_str()).expect("a name");
    let (target, backup) = one_step_journal(d, name);
    let recovered = recover_interrupted_commits(std::slice::from_ref(&target));
    assert_eq!(recovered.ok().map(|r| r.restored), Some(1));
    assert_eq!(fs::read(&target).expect("read"), b"old");
    assert!(!backup.exists() && !own.exists());
}

/// A journal that cannot be read is reported and kept, with everything it names.
#[test]
fn a_malformed_journal_is_reported_and_kept() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let (target, backup) = one_step_journal(d, ".out.gltf.journal-4294967294");
    let journal = d.join(".out.gltf.journal-4294967294");
    fs::write(&journal, "bake-commit-journal 99\n").expect("write");
    let error = recover_interrupted_commits(std::slice::from_ref(&target))
        .expect_err("an unreadable journal");
    assert!(error.to_string().contains("journal-4294967294"), "{error}");
    assert!(journal.exists() && backup.exists());
    assert_eq!(fs::read(&target).expect("read"), b"new");
}
