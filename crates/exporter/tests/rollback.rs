//! An output set is all previous or all new after any failed step (issue 34, item 1): every
//! file operation of staging and commit is made to fail in turn, with each of EBUSY
//! (a bind-mounted target), EPERM (a sticky shared folder) and EROFS, through the
//! fault-injecting [`FileOps`] layer (CI runs as root, where permissions cannot fail).

use bake_exporter::{FileOps, OutputSet};
use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

const EBUSY: i32 = 16;
const EPERM: i32 = 1;
const EROFS: i32 = 30;

/// Passes every call to the file system except the `fail_at`-th (counted from 1), which
/// fails with `errno`; logs each call.
#[derive(Debug)]
struct Faulty {
    fail_at: usize,
    errno: i32,
    calls: AtomicUsize,
    log: Mutex<Vec<String>>,
}

impl Faulty {
    fn new(fail_at: usize, errno: i32) -> Arc<Faulty> {
        Arc::new(Faulty {
            fail_at,
            errno,
            calls: AtomicUsize::new(0),
            log: Mutex::new(Vec::new()),
        })
    }

    fn call(&self, what: &str, path: &Path) -> std::io::Result<()> {
        let n = self.calls.fetch_add(1, Ordering::SeqCst) + 1;
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
        if let Ok(mut log) = self.log.lock() {
            log.push(format!("{n} {what} {}", name.unwrap_or_default()));
        }
        if n == self.fail_at {
            return Err(std::io::Error::from_raw_os_error(self.errno));
        }
        Ok(())
    }

    fn calls(&self) -> usize {
        self.calls.load(Ordering::SeqCst)
    }
}

impl FileOps for Faulty {
    fn create(&self, path: &Path) -> std::io::Result<fs::File> {
        self.call("create", path)?;
        fs::File::create(path)
    }
    fn rename(&self, from: &Path, to: &Path) -> std::io::Result<()> {
        self.call("rename", to)?;
        fs::rename(from, to)
    }
    fn hard_link(&self, from: &Path, to: &Path) -> std::io::Result<()> {
        self.call("hard_link", from)?;
        fs::hard_link(from, to)
    }
    fn copy(&self, from: &Path, to: &Path) -> std::io::Result<()> {
        self.call("copy", from)?;
        fs::copy(from, to).map(|_| ())
    }
    fn remove_file(&self, path: &Path) -> std::io::Result<()> {
        self.call("remove", path)?;
        fs::remove_file(path)
    }
}

/// The set in rename order, as the job stages it: report, lightmap glTF + bin + EXR,
/// OUT's bin, OUT last.
const NAMES: [&str; 6] = [
    "report.json",
    "out_lightmap.gltf",
    "out_lightmap.bin",
    "out_lightmap.exr",
    "out.bin",
    "out.gltf",
];

/// Every file of `dir`, name → bytes.
fn contents(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fs::read_dir(dir)
        .expect("list")
        .flatten()
        .map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            (name, fs::read(e.path()).expect("read"))
        })
        .collect()
}

/// Writes the previous set (`missing` left out: a file the previous bake did not write).
fn previous_set(dir: &Path, missing: &[&str]) -> BTreeMap<String, Vec<u8>> {
    for name in NAMES.iter().filter(|n| !missing.contains(n)) {
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

/// Stages the new set and commits it through `files`: Ok(()) when both succeeded.
fn bake_into(dir: &Path, files: Arc<dyn FileOps>) -> Result<(), String> {
    let mut set = OutputSet::with_files(files);
    for name in NAMES {
        let target: PathBuf = dir.join(name);
        set.stage_with(&target, |w| write!(w, "new {name}, longer"))
            .map_err(|e| e.to_string())?;
    }
    set.commit().map(|_| ()).map_err(|e| e.to_string())
}

/// Fails each call in turn; after a failure the folder holds exactly the previous set, byte
/// for byte, and no temporary; after a success exactly the new set (a backup whose removal
/// failed is the only thing that may be left, under a temporary's name).
fn every_failure_position(missing: &[&str]) {
    let clean = tempfile::tempdir().expect("temp dir");
    previous_set(clean.path(), missing);
    let counter = Faulty::new(0, EBUSY);
    bake_into(clean.path(), counter.clone()).expect("a bake with no fault");
    let total = counter.calls();
    let stages = NAMES.len();
    // create per file, then per target (hard link if it exists) + rename, then removals.
    assert!(total >= 2 * stages, "{total} calls");
    let mut failed = 0;
    for errno in [EBUSY, EPERM, EROFS] {
        for fail_at in 1..=total {
            let dir = tempfile::tempdir().expect("temp dir");
            let before = previous_set(dir.path(), missing);
            let faulty = Faulty::new(fail_at, errno);
            let result = bake_into(dir.path(), faulty.clone());
            let after = contents(dir.path());
            let log = faulty.log.lock().map(|l| l.join(", ")).unwrap_or_default();
            match result {
                Err(message) => {
                    failed += 1;
                    assert_eq!(
                        after, before,
                        "errno {errno}, call {fail_at} failed ({message}); calls: {log}"
                    );
                    assert!(
                        message.contains(&std::io::Error::from_raw_os_error(errno).to_string()),
                        "{message}"
                    );
                }
                Ok(()) => {
                    let new = new_set();
                    let extra: Vec<&String> =
                        after.keys().filter(|k| !new.contains_key(*k)).collect();
                    assert!(
                        extra
                            .iter()
                            .all(|k| k.starts_with('.') && k.contains(".tmp-")),
                        "errno {errno}, call {fail_at}: {extra:?}; calls: {log}"
                    );
                    assert!(extra.len() <= 1, "{extra:?}");
                    let kept: BTreeMap<String, Vec<u8>> = after
                        .into_iter()
                        .filter(|(k, _)| new.contains_key(k))
                        .collect();
                    assert_eq!(kept, new, "errno {errno}, call {fail_at}; calls: {log}");
                }
            }
        }
    }
    // Every create and rename of the set can fail the bake (the removals of backups cannot).
    assert!(failed >= 3 * 2 * stages, "{failed} failures");
}

#[test]
fn any_failed_step_leaves_the_previous_set_byte_for_byte() {
    every_failure_position(&[]);
}

#[test]
fn files_the_previous_bake_did_not_write_are_removed_again() {
    every_failure_position(&["out_lightmap.exr", "report.json"]);
}

#[test]
fn a_first_bake_that_fails_leaves_an_empty_folder() {
    every_failure_position(&NAMES);
}

/// Where no hard link can be made (another mount, a file system without links), the
/// previous file is copied aside and still put back.
#[test]
fn without_hard_links_the_previous_file_is_copied_aside_and_restored() {
    #[derive(Debug)]
    struct NoLinks {
        fail_rename_of: &'static str,
    }
    impl FileOps for NoLinks {
        fn hard_link(&self, _: &Path, _: &Path) -> std::io::Result<()> {
            Err(std::io::Error::from_raw_os_error(18)) // EXDEV
        }
        fn rename(&self, from: &Path, to: &Path) -> std::io::Result<()> {
            if to.file_name().is_some_and(|n| n == self.fail_rename_of) {
                return Err(std::io::Error::from_raw_os_error(EBUSY));
            }
            fs::rename(from, to)
        }
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let before = previous_set(dir.path(), &[]);
    let error = bake_into(
        dir.path(),
        Arc::new(NoLinks {
            fail_rename_of: "out.gltf",
        }),
    )
    .expect_err("OUT cannot be replaced");
    assert!(error.contains("out.gltf"), "{error}");
    assert!(error.contains("every output was left as it was"), "{error}");
    assert_eq!(contents(dir.path()), before);
}
