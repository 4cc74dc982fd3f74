//! Output paths and atomic writes: every file is written to a temporary in its own directory
//! and renamed into place, so a reader never sees a partial file.

use crate::journal::{absolute, encode, journal_path_for, Step};
use crate::ExportError;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};

/// The container an output path asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum OutputFormat {
    Gltf,
    Glb,
}

impl OutputFormat {
    /// By extension, case-insensitive.
    pub(crate) fn from_path(path: &Path) -> Result<Self, ExportError> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match extension.as_deref() {
            Some("gltf") => Ok(OutputFormat::Gltf),
            Some("glb") => Ok(OutputFormat::Glb),
            _ => Err(ExportError::UnsupportedExtension(path.to_path_buf())),
        }
    }
}

/// `<dir>/<stem>.bin` for `<dir>/<stem>.gltf`.
pub(crate) fn bin_path_for(gltf_path: &Path) -> Result<PathBuf, ExportError> {
    let stem = gltf_path
        .file_stem()
        .ok_or_else(|| ExportError::UnsupportedExtension(gltf_path.to_path_buf()))?;
    let mut name = stem.to_os_string();
    name.push(".bin");
    Ok(gltf_path.with_file_name(name))
}

/// The relative URI of a file beside the glTF: its name, percent-encoded except for the
/// characters RFC 3986 leaves unreserved.
pub(crate) fn uri_for_file_name(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut uri = String::new();
    for byte in name.bytes() {
        if byte.is_ascii_alphanumeric() || b"-._~".contains(&byte) {
            uri.push(char::from(byte));
        } else {
            uri.push_str(&format!("%{byte:02X}"));
        }
    }
    uri
}

/// The file operations an [`OutputSet`] performs, one call each, so that a test can make any
/// one of them fail (EBUSY on a bind-mounted target, EPERM in a sticky folder, EROFS) where
/// permissions cannot (CI runs as root). [`RealFiles`] is the one production implementation:
/// every default method is the plain `std::fs` call.
pub trait FileOps: std::fmt::Debug + Send + Sync {
    /// Creates (truncates) a file to write a temporary into.
    fn create(&self, path: &Path) -> std::io::Result<fs::File> {
        fs::File::create(path)
    }
    /// Renames `from` to `to`, replacing `to`.
    fn rename(&self, from: &Path, to: &Path) -> std::io::Result<()> {
        fs::rename(from, to)
    }
    /// A second name for `from` (a symbolic link itself, not what it points to).
    fn hard_link(&self, from: &Path, to: &Path) -> std::io::Result<()> {
        fs::hard_link(from, to)
    }
    /// Copies `from` to the new file `to` where a hard link is impossible (another mount, a
    /// file system without links); a symbolic link is copied as a link.
    fn copy(&self, from: &Path, to: &Path) -> std::io::Result<()> {
        copy_file_or_link(from, to)
    }
    fn remove_file(&self, path: &Path) -> std::io::Result<()> {
        fs::remove_file(path)
    }
}

/// The temporaries this process's output sets hold now (created, not yet renamed or
/// removed), so that an interrupted bake can remove them ([`abandon_temporaries`]). A
/// temporary is created, and a set committed, with the lock held: an interrupt waits for a
/// commit to end (so it never leaves a set half renamed, and the previous set's backups are
/// never taken for temporaries), and no temporary is created after it removed them.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

pub(crate) fn live() -> MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Takes `path` off the live temporaries.
fn forget(live: &mut Vec<PathBuf>, path: &Path) {
    if let Some(i) = live.iter().position(|p| p == path) {
        live.swap_remove(i);
    }
}

/// Removes a temporary and takes it off the live ones.
fn remove_temporary(files: &dyn FileOps, path: &Path) {
    let mut live = live();
    let _ = files.remove_file(path);
    forget(&mut live, path);
}

/// For an interrupted process (SIGINT, SIGTERM): waits for a commit in progress to end, and
/// removes every temporary this process's output sets hold (never a target, never the
/// previous set's files). While the returned value lives no output set creates a temporary
/// or commits: hold it until the process exits.
pub fn abandon_temporaries() -> Abandoned {
    let mut lock = live();
    let removed = lock
        .drain(..)
        .filter(|t| fs::remove_file(t).is_ok())
        .count();
    Abandoned {
        removed,
        _lock: lock,
    }
}

/// What [`abandon_temporaries`] removed, and the lock that keeps every output set still.
pub struct Abandoned {
    /// How many temporaries were removed.
    pub removed: usize,
    _lock: MutexGuard<'static, Vec<PathBuf>>,
}

/// The temporaries live now (for tests of [`abandon_temporaries`]' bookkeeping).
pub fn live_temporaries() -> Vec<PathBuf> {
    live().clone()
}

/// The file system itself.
#[derive(Debug, Default, Clone, Copy)]
pub struct RealFiles;

impl FileOps for RealFiles {}

#[cfg(unix)]
fn copy_file_or_link(from: &Path, to: &Path) -> std::io::Result<()> {
    if fs::symlink_metadata(from)?.file_type().is_symlink() {
        return std::os::unix::fs::symlink(fs::read_link(from)?, to);
    }
    fs::copy(from, to).map(|_| ())
}

#[cfg(not(unix))]
fn copy_file_or_link(from: &Path, to: &Path) -> std::io::Result<()> {
    fs::copy(from, to).map(|_| ())
}

/// The files of one bake, written as one transaction: [`OutputSet::stage`] writes each file
/// to a temporary beside its target (synced to disk), [`OutputSet::commit`] renames them all
/// into place in staging order. Until the first rename nothing the user named has changed;
/// dropping an uncommitted set (any error, or a panic unwinding) removes every temporary.
/// A commit that fails at any step puts every file it had replaced back (the previous file
/// is kept under a temporary's name until the whole set is in place): the set is all
/// previous or all new. A crash in the renames is undone at the next start from the commit's
/// journal ([`recover_interrupted_commits`](crate::recover_interrupted_commits)).
///
/// Temporaries (and those backups) are named `.<name>.tmp-<pid>-<n>` (see
/// [`remove_stale_temporaries`]), the journal `.<name>.journal-<pid>`.
#[derive(Debug)]
pub struct OutputSet {
    /// (temporary, target), in the order they are renamed.
    staged: Vec<(PathBuf, PathBuf)>,
    files: std::sync::Arc<dyn FileOps>,
}

impl Default for OutputSet {
    fn default() -> Self {
        OutputSet::with_files(std::sync::Arc::new(RealFiles))
    }
}

/// A target replaced by a commit: what to put back if a later step fails.
struct Replaced {
    target: PathBuf,
    /// The previous file, under a temporary's name; `None`: there was none.
    backup: Option<PathBuf>,
}

impl OutputSet {
    pub fn new() -> OutputSet {
        OutputSet::default()
    }

    /// A set whose every file operation goes through `files` (tests inject failures).
    pub fn with_files(files: std::sync::Arc<dyn FileOps>) -> OutputSet {
        OutputSet {
            staged: Vec::new(),
            files,
        }
    }

    /// Writes `bytes` to a temporary for `path`; renamed by [`OutputSet::commit`] after every
    /// file staged before it.
    pub(crate) fn stage(&mut self, path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
        self.stage_with(path, |w| w.write_all(bytes))
    }

    /// Writes a file through `write` (buffered) to a temporary for `path`, for files too
    /// large to hold twice in memory; renamed like [`OutputSet::stage`]'s.
    pub fn stage_with(
        &mut self,
        path: &Path,
        write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<(), ExportError> {
        let temporary = write_temporary_with(&*self.files, path, write)?;
        self.staged.push((temporary, path.to_path_buf()));
        Ok(())
    }

    /// Moves `other`'s staged files to the end of this set (renamed after this set's).
    pub fn append(&mut self, mut other: OutputSet) {
        self.staged.append(&mut other.staged);
    }

    /// The targets staged so far, in rename order.
    pub fn targets(&self) -> Vec<PathBuf> {
        self.staged.iter().map(|(_, t)| t.clone()).collect()
    }

    /// Renames every temporary into place, in staging order, and returns the targets. Checks
    /// first that no target is a directory or a special file (a rename onto one would fail
    /// half-way through the set, or replace a device). Each existing target is first given a
    /// second name (a hard link, or a copy where links cannot be made), so that if a later
    /// rename fails every replaced target is put back and every new one removed: the error
    /// comes with the previous set intact.
    ///
    /// Before the first rename a commit journal listing every step is on disk
    /// (`.<name>.journal-<pid>` beside the last target; its format is in `journal.rs`). It is
    /// removed after the last rename (the commit point: a failure to remove it rolls the set
    /// back too) or after a rollback, and the backups only after it. A crash (kill -9, power
    /// loss) in the renames still leaves a set that mixes new and previous files, but only
    /// until the next start: [`recover_interrupted_commits`](crate::recover_interrupted_commits)
    /// finds the dead process's journal and puts the previous set back.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, ExportError> {
        if self.staged.is_empty() {
            return Ok(Vec::new());
        }
        for (_, target) in &self.staged {
            check_target(target)?;
        }
        // Held through the journal, the renames and any rollback: an interrupt waits for the
        // set to be all new or all previous. (An error before the renames returns with the
        // lock released first, then drop removes the temporaries.)
        let mut live = live();
        let steps = self.plan()?;
        let journal = self.write_journal(&steps)?;
        let staged = std::mem::take(&mut self.staged);
        for (temporary, _) in &staged {
            // Renamed or removed below, either way no longer a temporary to remove.
            forget(&mut live, temporary);
        }
        let mut replaced: Vec<Replaced> = Vec::with_capacity(staged.len());
        let mut rest = staged.into_iter().zip(steps);
        while let Some(((temporary, target), step)) = rest.next() {
            match self.replace(&temporary, &target, step.backup.as_deref()) {
                Ok(()) => replaced.push(Replaced {
                    target,
                    backup: step.backup,
                }),
                Err(error) => {
                    let _ = self.files.remove_file(&temporary);
                    rest.for_each(|((t, _), _)| {
                        let _ = self.files.remove_file(&t);
                    });
                    let error = self.roll_back(replaced, error);
                    // Best effort: a journal left behind finds nothing left to put back.
                    let _ = self.files.remove_file(&journal);
                    return Err(error);
                }
            }
        }
        // The renames are on disk before the journal that would undo them goes.
        let mut dirs: Vec<&Path> = Vec::new();
        for done in &replaced {
            let dir = parent_dir(&done.target);
            if !dirs.contains(&dir) {
                dirs.push(dir);
            }
        }
        dirs.iter().for_each(|dir| sync_dir(dir));
        if let Err(source) = self.files.remove_file(&journal) {
            // Left in place, the journal would have the next start undo this commit.
            let error = ExportError::Io {
                path: journal.clone(),
                source,
            };
            let error = self.roll_back(replaced, error);
            let _ = self.files.remove_file(&journal);
            return Err(error);
        }
        sync_dir(parent_dir(&journal));
        for done in &replaced {
            if let Some(backup) = &done.backup {
                // Best effort: a backup left behind is a stale temporary for the next bake.
                let _ = self.files.remove_file(backup);
            }
        }
        drop(live);
        Ok(replaced.into_iter().map(|r| r.target).collect())
    }

    /// The steps of the commit, paths absolute: a backup name for each target that exists now.
    fn plan(&self) -> Result<Vec<Step>, ExportError> {
        let mut steps = Vec::with_capacity(self.staged.len());
        for (temporary, target) in &self.staged {
            let backup = match fs::symlink_metadata(target) {
                Ok(_) => Some(absolute(&temporary_path_for(target))?),
                Err(error) if error.kind() == std::io::ErrorKind::NotFound => None,
                Err(source) => {
                    return Err(ExportError::Io {
                        path: target.clone(),
                        source,
                    })
                }
            };
            steps.push(Step {
                target: absolute(target)?,
                backup,
                temporary: absolute(temporary)?,
            });
        }
        Ok(steps)
    }

    /// Writes the journal of `steps` beside the last target (temporary, synced, renamed, the
    /// folder synced) and returns its path. Nothing of the set has changed yet if it fails.
    fn write_journal(&self, steps: &[Step]) -> Result<PathBuf, ExportError> {
        let Some(last) = steps.last() else {
            return Err(ExportError::InvalidData(
                "a commit of no file has no journal".to_string(),
            ));
        };
        let journal = journal_path_for(&last.target);
        let io = |source| ExportError::Io {
            path: journal.clone(),
            source,
        };
        let temporary = temporary_path_for(&last.target);
        let written = self.files.create(&temporary).and_then(|mut file| {
            file.write_all(&encode(steps))?;
            file.sync_all()
        });
        let renamed = written.and_then(|()| self.files.rename(&temporary, &journal));
        if let Err(error) = renamed {
            let _ = self.files.remove_file(&temporary);
            return Err(io(error));
        }
        sync_dir(parent_dir(&journal));
        Ok(journal)
    }

    /// Keeps the previous `target` under the name `backup` (`None`: there is none), then
    /// renames `temporary` onto it.
    fn replace(
        &self,
        temporary: &Path,
        target: &Path,
        backup: Option<&Path>,
    ) -> Result<(), ExportError> {
        let io = |source| ExportError::Io {
            path: target.to_path_buf(),
            source,
        };
        if let Some(backup) = backup {
            if self.files.hard_link(target, backup).is_err() {
                if let Err(error) = self.files.copy(target, backup) {
                    let _ = self.files.remove_file(backup);
                    return Err(io(error));
                }
            }
        }
        if let Err(error) = self.files.rename(temporary, target) {
            if let Some(backup) = backup {
                let _ = self.files.remove_file(backup);
            }
            return Err(io(error));
        }
        Ok(())
    }

    /// Puts back every target `replaced` changed, last first, and returns `error` (saying
    /// that the previous files are in place, or which could not be put back and where it is).
    fn roll_back(&self, replaced: Vec<Replaced>, error: ExportError) -> ExportError {
        let mut failures = Vec::new();
        for done in replaced.into_iter().rev() {
            let restored = match &done.backup {
                Some(backup) => self.files.rename(backup, &done.target),
                None => self.files.remove_file(&done.target),
            };
            if let Err(e) = restored {
                failures.push(match &done.backup {
                    Some(backup) => format!(
                        "{} could not be put back ({e}; the previous file is {})",
                        done.target.display(),
                        backup.display()
                    ),
                    None => format!(
                        "the new {} could not be removed ({e})",
                        done.target.display()
                    ),
                });
            }
        }
        let ExportError::Io { path, source } = error else {
            return error;
        };
        let outcome = if failures.is_empty() {
            "every output was left as it was".to_string()
        } else {
            failures.join("; ")
        };
        ExportError::Io {
            path,
            source: std::io::Error::new(source.kind(), format!("{source}; {outcome}")),
        }
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for (temporary, _) in &self.staged {
            remove_temporary(&*self.files, temporary);
        }
    }
}

/// A target may be a file (replaced) or not exist yet, or be a link to a file (the link is
/// replaced). A directory, a device, a FIFO or a socket, or a link to one (`/dev/stdout`),
/// cannot be replaced by a rename without destroying it: refused. Outputs are never streamed.
pub fn check_target(path: &Path) -> Result<(), ExportError> {
    let refuse = |why: &str| {
        Err(ExportError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::other(why.to_string()),
        })
    };
    let name_bytes = path.file_name().map_or(0, |n| n.as_encoded_bytes().len());
    let extra = temporary_name_extra();
    if name_bytes + extra > NAME_MAX {
        return Err(ExportError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::other(format!(
                "its file name is {name_bytes} bytes long: its temporary \
                 `.NAME.tmp-PID-N` needs up to {extra} more, past the {NAME_MAX}-byte \
                 limit of a file name (at most {} bytes)",
                NAME_MAX - extra
            )),
        });
    }
    let Ok(meta) = fs::symlink_metadata(path) else {
        return Ok(());
    };
    if meta.is_file() {
        return Ok(());
    }
    if !meta.file_type().is_symlink() {
        return refuse("it exists and is not a regular file");
    }
    match fs::metadata(path) {
        // A dangling link is replaced like a missing file.
        Err(_) => Ok(()),
        Ok(target) if target.is_file() => Ok(()),
        Ok(_) => refuse(
            "it is a link to something that is not a regular file (a device, a FIFO, a \
             directory); outputs replace their target by a rename and are never streamed: \
             name a regular file",
        ),
    }
}

/// The longest file name most file systems take (Linux's `NAME_MAX`).
const NAME_MAX: usize = 255;
/// What a temporary's name adds to its target's: `.`, `.tmp-`, a pid (as many digits as
/// the system's largest, `/proc/sys/kernel/pid_max`; 10 where that cannot be read), `-` and
/// a counter (4 digits: a bake stages and backs up far fewer files; a longer one fails
/// when its temporary is created, before anything is replaced).
fn temporary_name_extra() -> usize {
    let pid_digits = fs::read_to_string("/proc/sys/kernel/pid_max")
        .ok()
        .and_then(|max| max.trim().parse::<u64>().ok())
        .map_or(10, |max| max.saturating_sub(1).max(1).to_string().len());
    1 + 5 + pid_digits + 1 + 4
}

/// `.<name>.tmp-<pid>-<n>` beside `path`; `n` keeps threads of one process apart.
fn temporary_path_for(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let temporary_name = format!(".{name}.tmp-{}-{n}", std::process::id());
    path.with_file_name(temporary_name)
}

/// The process id in a temporary's name `.<name>.tmp-<pid>-<n>` of target `name`.
fn temporary_pid(file_name: &str, name: &str) -> Option<u32> {
    let rest = file_name
        .strip_prefix('.')?
        .strip_prefix(name)?
        .strip_prefix(".tmp-")?;
    let (pid, n) = rest.split_once('-')?;
    if n.is_empty() || !n.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// Whether process `pid` is alive (Linux: `/proc/<pid>` exists). `None` where that cannot
/// be told (no `/proc`): such temporaries (and journals) are kept.
pub(crate) fn process_alive(pid: u32) -> Option<bool> {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return None;
    }
    Some(proc.join(pid.to_string()).exists())
}

/// The folder `path` is in (`.` for a bare file name).
pub(crate) fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    }
}

/// Syncs a folder, so that the renames and removals in it are on disk (best effort: a
/// file system that cannot sync a folder still orders them in most cases).
pub(crate) fn sync_dir(dir: &Path) {
    if let Ok(dir) = fs::File::open(dir) {
        let _ = dir.sync_all();
    }
}

/// Removes the temporaries a killed bake left beside `targets`: files named
/// `.<name>.tmp-<pid>-<n>`, `<name>` one of the targets' file names, whose process `<pid>`
/// is no longer running (another bake's live temporaries are kept). Returns how many were
/// removed. Only on systems with `/proc` (elsewhere nothing is removed).
pub fn remove_stale_temporaries(targets: &[PathBuf]) -> usize {
    let own = std::process::id();
    let mut removed = 0;
    let mut dirs: Vec<(PathBuf, Vec<String>)> = Vec::new();
    for target in targets {
        let Some(name) = target.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        let dir = parent_dir(target).to_path_buf();
        match dirs.iter_mut().find(|(d, _)| *d == dir) {
            Some((_, names)) => names.push(name.to_owned()),
            None => dirs.push((dir, vec![name.to_owned()])),
        }
    }
    for (dir, names) in dirs {
        let Ok(entries) = fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let file_name = entry.file_name();
            let Some(file_name) = file_name.to_str() else {
                continue;
            };
            let pid = names.iter().find_map(|n| temporary_pid(file_name, n));
            let stale = pid.is_some_and(|p| p != own && process_alive(p) == Some(false));
            let is_file = entry.file_type().is_ok_and(|t| t.is_file());
            if stale && is_file && fs::remove_file(entry.path()).is_ok() {
                removed += 1;
            }
        }
    }
    removed
}

/// Writes a temporary for `path` through `write` (buffered), synced; removed on failure.
fn write_temporary_with(
    files: &dyn FileOps,
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<PathBuf, ExportError> {
    let temporary = temporary_path_for(path);
    let created = {
        let mut live = live();
        let created = files.create(&temporary);
        if created.is_ok() {
            live.push(temporary.clone());
        }
        created
    };
    let result = created.and_then(|file| {
        let mut buffered = std::io::BufWriter::with_capacity(1 << 20, file);
        write(&mut buffered)?;
        let file = buffered.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()
    });
    match result {
        Ok(()) => Ok(temporary),
        Err(source) => {
            remove_temporary(files, &temporary);
            Err(ExportError::Io {
                path: path.to_path_buf(),
                source,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn format_by_extension_ignores_case() {
        assert_eq!(
            OutputFormat::from_path(Path::new("a/b.GLTF")).ok(),
            Some(OutputFormat::Gltf)
        );
        assert_eq!(
            OutputFormat::from_path(Path::new("b.Glb")).ok(),
            Some(OutputFormat::Glb)
        );
        assert!(OutputFormat::from_path(Path::new("b.obj")).is_err());
        assert!(OutputFormat::from_path(Path::new("gltf")).is_err());
    }

    #[test]
    fn temporary_names_parse_back_to_their_pid() {
        assert_eq!(temporary_pid(".o.gltf.tmp-123-4", "o.gltf"), Some(123));
        assert_eq!(temporary_pid(".o.gltf.tmp-123-", "o.gltf"), None);
        assert_eq!(temporary_pid(".o.gltf.tmp-x-1", "o.gltf"), None);
        assert_eq!(temporary_pid(".o.bin.tmp-123-4", "o.gltf"), None);
        assert_eq!(temporary_pid("o.gltf.tmp-123-4", "o.gltf"), None);
    }

    #[test]
    fn stale_temporaries_of_dead_processes_are_removed_live_ones_kept() {
        let dir = tempfile::tempdir().expect("temp dir");
        let target = dir.path().join("o.gltf");
        // No process has an id above pid_max (at most 2^22 on Linux); our own is alive.
        let dead = dir.path().join(".o.gltf.tmp-4294967294-0");
        let live = dir
            .path()
            .join(format!(".o.gltf.tmp-{}-7", std::process::id()));
        let other = dir.path().join(".x.gltf.tmp-4294967294-0");
        for path in [&dead, &live, &other] {
            fs::write(path, b"partial").expect("write");
        }
        let removed = remove_stale_temporaries(std::slice::from_ref(&target));
        if Path::new("/proc/self").exists() {
            assert_eq!(removed, 1);
            assert!(!dead.exists());
        }
        assert!(live.exists() && other.exists());
    }

    #[test]
    fn a_dropped_set_leaves_no_temporary_and_no_target() {
        let dir = tempfile::tempdir().expect("temp dir");
        let a = dir.path().join("a.bin");
        let b = dir.path().join("b.gltf");
        let mut set = OutputSet::new();
        set.stage(&a, b"1").expect("stage");
        set.stage(&b, b"2").expect("stage");
        drop(set);
        assert_eq!(fs::read_dir(dir.path()).expect("list").count(), 0);
    }

    /// The temporaries an interrupt would remove are exactly those staged and not yet
    /// renamed or removed: live from staging until commit or drop, never a target.
    #[test]
    fn staged_temporaries_are_live_until_committed_or_dropped() {
        let dir = tempfile::tempdir().expect("temp dir");
        // Sorted: other tests' sets come and go in parallel, and taking one off the list
        // (swap_remove) reorders the rest.
        let in_dir = |paths: Vec<PathBuf>| -> Vec<PathBuf> {
            let mut mine: Vec<PathBuf> = paths
                .into_iter()
                .filter(|p| p.starts_with(dir.path()))
                .collect();
            mine.sort();
            mine
        };
        let (a, b) = (dir.path().join("a.bin"), dir.path().join("b.gltf"));
        let mut set = OutputSet::new();
        set.stage(&a, b"1").expect("stage");
        set.stage(&b, b"2").expect("stage");
        let live = in_dir(live_temporaries());
        assert_eq!(
            live,
            in_dir(set.staged.iter().map(|(t, _)| t.clone()).collect())
        );
        assert_eq!(live.len(), 2);
        set.commit().expect("commit");
        assert_eq!(in_dir(live_temporaries()), Vec::<PathBuf>::new());
        let mut set = OutputSet::new();
        set.stage(&a, b"3").expect("stage");
        assert_eq!(in_dir(live_temporaries()).len(), 1);
        drop(set);
        assert_eq!(in_dir(live_temporaries()), Vec::<PathBuf>::new());
        assert_eq!(fs::read(&a).expect("committed"), b"1");
    }

    #[test]
    fn a_directory_target_fails_the_commit_before_any_rename() {
        let dir = tempfile::tempdir().expect("temp dir");
        let a = dir.path().join("a.bin");
        let b = dir.path().join("b.json");
        fs::create_dir(&b).expect("mkdir");
        let mut set = OutputSet::new();
        set.stage(&a, b"1").expect("stage");
        set.stage(&b, b"2").expect("stage");
        assert!(set.commit().is_err());
        let names: Vec<_> = fs::read_dir(dir.path())
            .expect("list")
            .flatten()
            .map(|e| e.file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("b.json")]);
    }

    #[test]
    fn names_whose_temporary_would_be_too_long_are_refused() {
        let extra = temporary_name_extra();
        assert!((13..=21).contains(&extra), "{extra}");
        let fits = format!("{}.gltf", "a".repeat(NAME_MAX - extra - 5));
        assert!(check_target(Path::new(&fits)).is_ok());
        // The longest name that passes has room for its temporary.
        let dir = tempfile::tempdir().expect("temp dir");
        let mut set = OutputSet::new();
        set.stage(&dir.path().join(&fits), b"x")
            .expect("its temporary fits");
        set.commit().expect("renamed");
        let long = format!("a{fits}");
        let error = check_target(Path::new(&long)).expect_err("too long");
        let says = format!("{} bytes long", NAME_MAX - extra + 1);
        assert!(error.to_string().contains(&says), "{error}");
    }

    #[test]
    fn bin_beside_gltf_with_encoded_uri() {
        let bin = bin_path_for(Path::new("out/my scene.gltf")).ok();
        assert_eq!(bin, Some(PathBuf::from("out/my scene.bin")));
        assert_eq!(
            uri_for_file_name(Path::new("out/my scene#1.bin")),
            "my%20scene%231.bin"
        );
    }
}
