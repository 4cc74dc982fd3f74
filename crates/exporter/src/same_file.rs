//! Refusing a bake whose outputs would overwrite one another or one of its inputs.

use std::path::{Path, PathBuf};

/// Two paths of one bake name the same file.
#[derive(Debug, thiserror::Error)]
#[error("{first} and {second} are the same file{why}", first = .first.display(), second = .second.display())]
pub struct SameFile {
    pub first: PathBuf,
    pub second: PathBuf,
    /// Why that is refused (` (output would overwrite input)` and the like).
    pub why: String,
}

/// What identifies a file: its canonical path (the existing parent canonicalized, plus the
/// name, for a file that does not exist yet) and, for an existing file on unix, its device
/// and inode (so hard links and bind mounts are caught too).
#[derive(Debug, PartialEq, Eq)]
struct Identity {
    path: Option<PathBuf>,
    inode: Option<(u64, u64)>,
}

impl Identity {
    fn of(path: &Path) -> Identity {
        let canonical = path.canonicalize().ok().or_else(|| {
            let name = path.file_name()?;
            let parent = match path.parent() {
                Some(p) if !p.as_os_str().is_empty() => p,
                _ => Path::new("."),
            };
            Some(parent.canonicalize().ok()?.join(name))
        });
        Identity {
            path: canonical,
            inode: inode(path),
        }
    }

    fn same(&self, other: &Identity) -> bool {
        let by_path = self.path.is_some() && self.path == other.path;
        let by_inode = self.inode.is_some() && self.inode == other.inode;
        by_path || by_inode
    }
}

#[cfg(unix)]
fn inode(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    let meta = std::fs::metadata(path).ok()?;
    Some((meta.dev(), meta.ino()))
}

#[cfg(not(unix))]
fn inode(_: &Path) -> Option<(u64, u64)> {
    None
}

/// Refuses when two `outputs` are one file, or an output is one of the `inputs` (the scene
/// and every file it read: buffers, images, material libraries). Paths are compared by
/// their canonical form and, for files that exist, by device and inode.
pub fn check_distinct(outputs: &[PathBuf], inputs: &[PathBuf]) -> Result<(), SameFile> {
    let outs: Vec<Identity> = outputs.iter().map(|p| Identity::of(p)).collect();
    let ins: Vec<Identity> = inputs.iter().map(|p| Identity::of(p)).collect();
    for (k, out) in outs.iter().enumerate() {
        if let Some(i) = ins.iter().position(|input| out.same(input)) {
            return Err(SameFile {
                first: outputs[k].clone(),
                second: inputs[i].clone(),
                why: ": an output would overwrite an input".into(),
            });
        }
        if let Some(j) = outs[..k].iter().position(|earlier| out.same(earlier)) {
            return Err(SameFile {
                first: outputs[j].clone(),
                second: outputs[k].clone(),
                why: ": two outputs would overwrite each other".into(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_file_by_another_name_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let input = dir.path().join("in.gltf");
        std::fs::write(&input, b"{}").expect("write");
        let other_name = dir.path().join(".").join("in.gltf");
        assert!(check_distinct(
            std::slice::from_ref(&other_name),
            std::slice::from_ref(&input)
        )
        .is_err());
        #[cfg(unix)]
        {
            let link = dir.path().join("hard.gltf");
            std::fs::hard_link(&input, &link).expect("hard link");
            assert!(
                check_distinct(std::slice::from_ref(&link), std::slice::from_ref(&input)).is_err()
            );
        }
        let new = dir.path().join("out.gltf");
        let report = dir.path().join("sub").join("..").join("out.gltf");
        assert!(check_distinct(std::slice::from_ref(&new), std::slice::from_ref(&input)).is_ok());
        // Not existing yet: the same canonical parent and name.
        std::fs::create_dir(dir.path().join("sub")).expect("mkdir");
        let error = check_distinct(&[new, report], &[input]).expect_err("same output twice");
        assert!(error.to_string().contains("two outputs"), "{error}");
    }
}
