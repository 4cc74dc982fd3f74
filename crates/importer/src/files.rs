//! Which files a scene may read and how: only regular files, at most [`MAX_FILE_BYTES`]
//! each, checked before they are opened (so a FIFO never blocks and `/dev/zero` is never
//! read), and — unless [`crate::Options::allow_outside_paths`] — only inside the folder of
//! the scene file. Every file read is recorded for [`crate::Scene::input_files`].

use crate::ImportError;
use std::cell::RefCell;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// The most bytes one input file may have (the scene file, each external buffer, image and
/// material library): 2 GiB. Larger glTF buffers cannot be addressed by a GLB anyway.
pub const MAX_FILE_BYTES: u64 = 1 << 31;

/// A reference refused because it leads outside the scene's folder (carried in an
/// `io::Error` through `tobj`'s material loader, where it is an error, not a warning).
#[derive(Debug)]
pub(crate) struct Refused(pub(crate) String);

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Refused {}

/// Reads the files of one scene.
pub(crate) struct Files {
    /// The scene file's folder: relative references are resolved in it.
    base: PathBuf,
    allow_outside: bool,
    read: RefCell<Vec<PathBuf>>,
}

impl Files {
    pub(crate) fn new(scene: &Path, allow_outside: bool) -> Files {
        let base = match scene.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
            _ => PathBuf::from("."),
        };
        Files {
            base,
            allow_outside,
            read: RefCell::new(Vec::new()),
        }
    }

    /// Reads the scene file itself.
    pub(crate) fn read_scene(&self, path: &Path) -> Result<Vec<u8>, ImportError> {
        let bytes = read_regular_file(path).map_err(|source| ImportError::Io {
            path: path.to_owned(),
            source,
        })?;
        self.read.borrow_mut().push(path.to_owned());
        Ok(bytes)
    }

    /// Where `reference` (a decoded relative URI, or a path from an `mtllib` line) points:
    /// inside the scene's folder, or an error saying why not.
    pub(crate) fn resolve(&self, reference: &Path) -> Result<PathBuf, String> {
        if self.allow_outside {
            return Ok(self.base.join(reference));
        }
        let refuse = |why: &str| {
            Err(format!(
                "{} {why} (outside the scene's folder; --allow-outside-paths reads it)",
                reference.display()
            ))
        };
        let mut depth: usize = 0;
        for component in reference.components() {
            match component {
                Component::Prefix(_) | Component::RootDir => return refuse("is an absolute path"),
                Component::ParentDir => match depth.checked_sub(1) {
                    Some(d) => depth = d,
                    None => return refuse("leaves the scene's folder"),
                },
                Component::Normal(_) => depth += 1,
                Component::CurDir => {}
            }
        }
        let path = self.base.join(reference);
        // A link inside the folder may still lead out of it.
        if let (Ok(target), Ok(base)) = (path.canonicalize(), self.base.canonicalize()) {
            if !target.starts_with(&base) {
                return refuse("leads out of the scene's folder through a link");
            }
        }
        Ok(path)
    }

    /// A `file:` URI: its path when outside paths are allowed.
    pub(crate) fn file_uri(&self, uri: &str) -> Result<PathBuf, String> {
        let rest = uri.strip_prefix("file:").unwrap_or(uri);
        if !self.allow_outside {
            return Err(format!(
                "{uri:?} is a file: URI (outside the scene's folder; --allow-outside-paths reads it)"
            ));
        }
        Ok(PathBuf::from(rest.strip_prefix("//").unwrap_or(rest)))
    }

    /// Reads a file the scene refers to (already resolved).
    pub(crate) fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        let bytes = read_regular_file(path)?;
        self.read.borrow_mut().push(path.to_owned());
        Ok(bytes)
    }

    /// Every file read, in order.
    pub(crate) fn into_read(self) -> Vec<PathBuf> {
        self.read.into_inner()
    }
}

/// Checks `path` before opening it: a regular file (following links) of at most
/// [`MAX_FILE_BYTES`]. Directories, FIFOs, sockets and devices are refused without being
/// opened.
pub(crate) fn check_regular_file(path: &Path) -> std::io::Result<u64> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        let kind = if meta.is_dir() {
            "a directory"
        } else {
            "not a regular file (a device, FIFO or socket)"
        };
        return Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, kind));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "{} bytes, more than the importer's limit of {MAX_FILE_BYTES} (2 GiB)",
                meta.len()
            ),
        ));
    }
    Ok(meta.len())
}

/// Reads a regular file of at most [`MAX_FILE_BYTES`] (checked before opening, and the read
/// is capped, should the file change between the check and the read).
pub(crate) fn read_regular_file(path: &Path) -> std::io::Result<Vec<u8>> {
    let len = check_regular_file(path)?;
    let file = std::fs::File::open(path)?;
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0).saturating_add(1));
    file.take(MAX_FILE_BYTES + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "grew past the importer's limit of 2 GiB while being read",
        ));
    }
    Ok(bytes)
}

/// Counts the lines of an OBJ file whose keyword is `f` without reading it into memory
/// (64 KiB at a time), so a file with far too many faces is refused before it is parsed.
pub(crate) fn count_obj_faces(path: &Path) -> std::io::Result<u64> {
    check_regular_file(path)?;
    let mut file = std::fs::File::open(path)?;
    let mut buffer = vec![0u8; 1 << 16];
    // 0: at a line's start (blanks skipped), 1: just read `f`, 2: inside a line.
    let mut state = 0u8;
    let mut faces = 0u64;
    loop {
        let n = file.read(&mut buffer)?;
        if n == 0 {
            break;
        }
        for &byte in &buffer[..n] {
            state = match (state, byte) {
                (_, b'\n') => 0,
                (0, b' ' | b'\t' | b'\r') => 0,
                (0, b'f') => 1,
                (1, b' ' | b'\t') => {
                    faces += 1;
                    2
                }
                _ => 2,
            };
        }
    }
    Ok(faces)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn references_stay_inside_the_folder_unless_allowed() {
        let files = Files::new(Path::new("scenes/a.gltf"), false);
        assert_eq!(
            files.resolve(Path::new("sub/../a.bin")),
            Ok(PathBuf::from("scenes/sub/../a.bin"))
        );
        for outside in ["../a.bin", "sub/../../a.bin", "/etc/passwd"] {
            let error = files.resolve(Path::new(outside)).expect_err(outside);
            assert!(error.contains("--allow-outside-paths"), "{error}");
        }
        assert!(files.file_uri("file:///etc/passwd").is_err());
        let open = Files::new(Path::new("scenes/a.gltf"), true);
        assert_eq!(
            open.resolve(Path::new("../a.bin")),
            Ok(PathBuf::from("scenes/../a.bin"))
        );
        assert_eq!(
            open.file_uri("file:///etc/passwd"),
            Ok(PathBuf::from("/etc/passwd"))
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_link_inside_the_folder_that_leads_out_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let scenes = dir.path().join("scenes");
        std::fs::create_dir(&scenes).expect("mkdir");
        std::fs::write(dir.path().join("secret.bin"), b"x").expect("write");
        std::fs::write(scenes.join("real.bin"), b"x").expect("write");
        std::os::unix::fs::symlink(dir.path().join("secret.bin"), scenes.join("out.bin"))
            .expect("symlink");
        std::os::unix::fs::symlink(scenes.join("real.bin"), scenes.join("in.bin"))
            .expect("symlink");
        let files = Files::new(&scenes.join("s.gltf"), false);
        let error = files.resolve(Path::new("out.bin")).expect_err("leads out");
        assert!(error.contains("through a link"), "{error}");
        assert_eq!(
            files.resolve(Path::new("in.bin")),
            Ok(scenes.join("in.bin"))
        );
        let open = Files::new(&scenes.join("s.gltf"), true);
        assert_eq!(
            open.resolve(Path::new("out.bin")),
            Ok(scenes.join("out.bin"))
        );
    }

    #[test]
    fn faces_are_counted_by_their_keyword() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("a.obj");
        std::fs::write(
            &path,
            "v 0 0 0\nf 1 2 3\n  f\t1 2 3\nfo 1\n# f 1\nvt 0 0\nf 1 2 3",
        )
        .expect("write");
        assert_eq!(count_obj_faces(&path).ok(), Some(3));
    }

    #[cfg(unix)]
    #[test]
    fn devices_and_directories_are_refused_before_opening() {
        let dir = tempfile::tempdir().expect("temp dir");
        assert!(read_regular_file(dir.path()).is_err());
        let link = dir.path().join("z.gltf");
        std::os::unix::fs::symlink("/dev/zero", &link).expect("symlink");
        let error = read_regular_file(&link).expect_err("/dev/zero");
        assert!(error.to_string().contains("not a regular file"), "{error}");
    }
}
