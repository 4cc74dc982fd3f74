//! The commit journal: what [`OutputSet::commit`](crate::OutputSet::commit) is about to do,
//! on disk before its first rename, so that a set a crash left half renamed (kill -9, power
//! loss) is put back at the next start ([`recover_interrupted_commits`]).
//!
//! # Name and place
//!
//! `.<name>.journal-<pid>` beside the set's *last* target (`<name>` its file name, `<pid>` the
//! committing process): in a bake that is OUT, or with `--target lightmap` the last lightmap
//! file beside it, so OUT's folder, the one every rerun of a command writes into (a
//! `--report` may be elsewhere, or dropped the next time).
//! It is written to a temporary (`.<name>.tmp-<pid>-<n>`, a stale temporary like any other if
//! the write is cut short), synced, renamed into place, and the folder is synced, all before
//! the first target is touched. The commit removes it once the last rename succeeded (the
//! commit point: the set is new from then on) or once a rollback finished, and only then
//! removes the backups.
//!
//! # Format
//!
//! Plain text, `\n`-terminated lines. The first is `bake-commit-journal 1`; then one line per
//! step, in rename order, of three tab-separated fields:
//!
//! ```text
//! <target>\t<backup, or none>\t<temporary>
//! ```
//!
//! `target` is the file the step replaces, `backup` the hard link (or copy) that keeps its
//! previous version during the commit (`none`: there was no previous file), `temporary` the
//! staged new file renamed onto `target`. Every path is absolute (made so with the commit's
//! working directory, links not resolved: a target that is a link is replaced as a link), so
//! a set spanning folders (a `--report` elsewhere) is recovered from any working directory.
//! In a path the bytes `%`, tab, CR, LF and the other control bytes are written `%XX` (hex);
//! every other byte as it is (a path need not be UTF-8).
//!
//! # Recovery rolls back
//!
//! Recovery puts the previous set back rather than finishing the new one: the new set may be
//! incomplete in ways a journal cannot repair (a temporary a crash left unsynced), the
//! previous set is complete by construction, and a rollback needs nothing but renames and
//! removals. A step counts as done iff its temporary no longer exists (temporaries' names are
//! unique to one process and one set, and a commit renames each one only after the step's
//! backup exists): a done step's backup is renamed back onto the target (a step without a
//! previous file has its new target removed); an undone step's target was never touched, so
//! only its temporary and a backup made just before the crash are removed.

use crate::files::{live, parent_dir, process_alive, sync_dir};
use crate::ExportError;
use std::ffi::OsString;
use std::fs;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

/// The first line of every journal (the format's version).
const HEADER: &str = "bake-commit-journal 1";
/// What a journal's name adds to its target's: `.` + `.journal-` + the pid.
pub(crate) const JOURNAL_NAME_INFIX: &str = ".journal-";

/// One rename of a commit, as the journal records it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Step {
    pub target: PathBuf,
    /// The previous file's second name during the commit; `None`: there was none.
    pub backup: Option<PathBuf>,
    pub temporary: PathBuf,
}

/// The journal of a commit of this process whose last target is `last_target`.
pub(crate) fn journal_path_for(last_target: &Path) -> PathBuf {
    let name = last_target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let journal = format!(".{name}{JOURNAL_NAME_INFIX}{}", std::process::id());
    last_target.with_file_name(journal)
}

/// The pid in a journal's file name `.<name>.journal-<pid>`.
fn journal_pid(file_name: &str) -> Option<u32> {
    let (name, pid) = file_name
        .strip_prefix('.')?
        .rsplit_once(JOURNAL_NAME_INFIX)?;
    if name.is_empty() || pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// `path` made absolute with the working directory (nothing resolved).
pub(crate) fn absolute(path: &Path) -> Result<PathBuf, ExportError> {
    std::path::absolute(path).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The journal's bytes for `steps` (paths already absolute).
pub(crate) fn encode(steps: &[Step]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(HEADER.as_bytes());
    out.push(b'\n');
    for step in steps {
        escape_into(&mut out, &step.target);
        out.push(b'\t');
        match &step.backup {
            Some(backup) => escape_into(&mut out, backup),
            None => out.extend_from_slice(b"none"),
        }
        out.push(b'\t');
        escape_into(&mut out, &step.temporary);
        out.push(b'\n');
    }
    out
}

fn escape_into(out: &mut Vec<u8>, path: &Path) {
    for &byte in path.as_os_str().as_encoded_bytes() {
        if byte == b'%' || byte < 0x20 || byte == 0x7f {
            out.extend_from_slice(format!("%{byte:02X}").as_bytes());
        } else {
            out.push(byte);
        }
    }
}

/// The steps of a journal's bytes; `Err` says what is wrong with them.
pub(crate) fn decode(bytes: &[u8]) -> Result<Vec<Step>, String> {
    let mut lines = bytes.split(|&b| b == b'\n');
    if lines.next() != Some(HEADER.as_bytes()) {
        return Err(format!("its first line is not `{HEADER}`"));
    }
    let mut steps = Vec::new();
    for (n, line) in lines.enumerate() {
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&[u8]> = line.split(|&b| b == b'\t').collect();
        let bad = |why: &str| format!("step {}: {why}", n + 1);
        let [target, backup, temporary] = fields[..] else {
            return Err(bad("not three tab-separated fields"));
        };
        let path = |field: &[u8]| -> Result<PathBuf, String> {
            let path = unescape(field).ok_or_else(|| bad("a malformed path"))?;
            if !path.is_absolute() {
                return Err(bad("a path that is not absolute"));
            }
            Ok(path)
        };
        steps.push(Step {
            target: path(target)?,
            backup: match backup {
                b"none" => None,
                other => Some(path(other)?),
            },
            temporary: path(temporary)?,
        });
    }
    Ok(steps)
}

fn unescape(field: &[u8]) -> Option<PathBuf> {
    let mut bytes = Vec::with_capacity(field.len());
    let mut rest = field;
    while let Some((&byte, tail)) = rest.split_first() {
        if byte == b'%' {
            let hex = tail.get(..2)?;
            let hex = std::str::from_utf8(hex).ok()?;
            bytes.push(u8::from_str_radix(hex, 16).ok()?);
            rest = &tail[2..];
        } else {
            bytes.push(byte);
            rest = tail;
        }
    }
    os_string_from_bytes(bytes).map(PathBuf::from)
}

#[cfg(unix)]
fn os_string_from_bytes(bytes: Vec<u8>) -> Option<OsString> {
    use std::os::unix::ffi::OsStringExt;
    Some(OsString::from_vec(bytes))
}

#[cfg(not(unix))]
fn os_string_from_bytes(bytes: Vec<u8>) -> Option<OsString> {
    String::from_utf8(bytes).ok().map(OsString::from)
}

/// What [`recover_interrupted_commits`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Recovered {
    /// Journals of dead processes found and rolled back (each one removed).
    pub journals: usize,
    /// Targets put back from their backup.
    pub restored: usize,
    /// New targets removed (files the interrupted commit created where there was none).
    pub removed: usize,
}

/// Puts back the output sets whose commit a crash (kill -9, power loss) cut short in the
/// renames: finds, in the folders of `targets`, every commit journal (`.<name>.journal-<pid>`,
/// any `<name>`: a previous bake may have had other outputs) whose process `<pid>` no longer
/// runs, and rolls its set back to the previous files (see the module's documentation for the
/// journal's format and the rules), then removes the set's leftover temporaries and backups
/// and the journal. A journal of another running process (another bake committing now) is
/// left alone, as is everything where liveness cannot be told (no `/proc`). A journal named
/// with this process's own id is a dead process's too (one that had the same id before a
/// reboot): this process's own commits hold the lock this function takes from before they
/// write their journal until they removed it. Call it at the start of a bake, before [`remove_stale_temporaries`](crate::remove_stale_temporaries), which would
/// otherwise remove the backups the rollback needs.
///
/// An error lists every step that could not be put back (its journal is kept, so a later
/// call retries): the previous file is then still under the backup name the message gives.
pub fn recover_interrupted_commits(targets: &[PathBuf]) -> Result<Recovered, ExportError> {
    let own = std::process::id();
    // No commit of this process is between its journal's writing and its removal meanwhile.
    let _commits = live();
    let mut recovered = Recovered::default();
    let mut problems = Vec::new();
    let mut dirs: Vec<PathBuf> = Vec::new();
    for target in targets {
        let dir = parent_dir(target).to_path_buf();
        if !dirs.contains(&dir) {
            dirs.push(dir);
        }
    }
    for dir in dirs {
        let Ok(entries) = fs::read_dir(&dir) else {
            continue;
        };
        let mut journals: Vec<PathBuf> = entries
            .flatten()
            .filter(|entry| {
                let pid = entry.file_name().to_str().and_then(journal_pid);
                let dead = pid.is_some_and(|p| p == own || process_alive(p) == Some(false));
                dead && entry.file_type().is_ok_and(|t| t.is_file())
            })
            .map(|entry| entry.path())
            .collect();
        journals.sort();
        for journal in journals {
            match roll_back_journal(&journal, &mut recovered) {
                Ok(()) => recovered.journals += 1,
                Err(mut failed) => problems.append(&mut failed),
            }
        }
    }
    if problems.is_empty() {
        Ok(recovered)
    } else {
        Err(ExportError::Recovery(problems.join("; ")))
    }
}

/// Rolls back the set of one journal and removes it; `Err` lists what could not be done (the
/// journal is then kept).
fn roll_back_journal(journal: &Path, recovered: &mut Recovered) -> Result<(), Vec<String>> {
    let shown = journal.display();
    let bytes =
        fs::read(journal).map_err(|e| vec![format!("cannot read the journal {shown}: {e}")])?;
    let steps = decode(&bytes).map_err(|why| {
        vec![format!(
            "{shown} is not a commit journal this version reads ({why}); \
             check the outputs beside it and remove it"
        )]
    })?;
    let mut problems = Vec::new();
    let mut dirs: Vec<PathBuf> = Vec::new();
    for step in steps.iter().rev() {
        if let Err(problem) = roll_back_step(step, recovered) {
            problems.push(problem);
        }
        let dir = parent_dir(&step.target).to_path_buf();
        if !dirs.contains(&dir) {
            dirs.push(dir);
        }
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    // The rollback is on disk before the journal that asked for it goes.
    dirs.iter().for_each(|dir| sync_dir(dir));
    fs::remove_file(journal)
        .map_err(|e| vec![format!("cannot remove the journal {shown}: {e}")])?;
    sync_dir(parent_dir(journal));
    Ok(())
}

/// Whether `path` exists (a link counts, whatever it points to).
fn exists(path: &Path) -> Result<bool, String> {
    match fs::symlink_metadata(path) {
        Ok(_) => Ok(true),
        Err(e) if e.kind() == ErrorKind::NotFound => Ok(false),
        Err(e) => Err(format!(
            "cannot tell whether {} exists: {e}",
            path.display()
        )),
    }
}

/// Removes `path` if it is there.
fn remove_if_there(path: &Path) -> Result<(), String> {
    match fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == ErrorKind::NotFound => Ok(()),
        Err(e) => Err(format!("cannot remove {}: {e}", path.display())),
    }
}

/// Puts one step's target back as it was before the commit (see the module's rules).
fn roll_back_step(step: &Step, recovered: &mut Recovered) -> Result<(), String> {
    let done = !exists(&step.temporary)?;
    match (&step.backup, done) {
        (Some(backup), true) => {
            // Absent: a rollback already put it back before the crash.
            if exists(backup)? {
                fs::rename(backup, &step.target).map_err(|e| {
                    format!(
                        "{} could not be put back ({e}; the previous file is {})",
                        step.target.display(),
                        backup.display()
                    )
                })?;
                recovered.restored += 1;
                // A rename onto another name of the same file does nothing.
                remove_if_there(backup)?;
            }
        }
        (None, true) => {
            if exists(&step.target)? {
                remove_if_there(&step.target)?;
                recovered.removed += 1;
            }
        }
        (Some(backup), false) => {
            // The target was not replaced: the backup (maybe a partial copy) is not needed.
            remove_if_there(backup)?;
            remove_if_there(&step.temporary)?;
        }
        (None, false) => remove_if_there(&step.temporary)?,
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn journals_read_back_what_was_written() {
        let steps = vec![
            Step {
                target: PathBuf::from("/a b/r%.json"),
                backup: Some(PathBuf::from("/a b/.r%.json.tmp-1-2")),
                temporary: PathBuf::from("/a b/.r%.json.tmp-1-0"),
            },
            Step {
                target: PathBuf::from("/o/new\tline\n.gltf"),
                backup: None,
                temporary: PathBuf::from("/o/.x.tmp-1-1"),
            },
        ];
        let bytes = encode(&steps);
        assert_eq!(bytes.iter().filter(|&&b| b == b'\n').count(), 3);
        assert_eq!(decode(&bytes), Ok(steps));
    }

    #[test]
    fn malformed_journals_are_refused() {
        assert!(decode(b"something else\n").is_err());
        assert!(decode(b"bake-commit-journal 1\n/a\tnone\n").is_err());
        assert!(decode(b"bake-commit-journal 1\nrel\tnone\t/t\n").is_err());
        assert!(decode(b"bake-commit-journal 1\n/a%4\tnone\t/t\n").is_err());
        assert_eq!(decode(b"bake-commit-journal 1\n"), Ok(Vec::new()));
    }

    #[test]
    fn journal_names_parse_back_to_their_pid() {
        assert_eq!(journal_pid(".o.gltf.journal-123"), Some(123));
        assert_eq!(journal_pid(".o.journal-x.journal-7"), Some(7));
        assert_eq!(journal_pid(".o.gltf.journal-"), None);
        assert_eq!(journal_pid("o.gltf.journal-123"), None);
        assert_eq!(journal_pid("..journal-123"), None);
        assert_eq!(journal_pid(".o.gltf.journal-12a"), None);
        let name = journal_path_for(Path::new("d/o.gltf"));
        let name = name
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        assert_eq!(journal_pid(name), Some(std::process::id()));
    }
}
