//! Output paths and atomic writes: every file is written to a temporary in its own directory
//! and renamed into place, so a reader never sees a partial file.

use crate::ExportError;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

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

/// Writes `bytes` to `path` through a temporary file in the same directory.
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    let temporary = write_temporary(path, bytes)?;
    rename_into_place(&temporary, path)
}

/// Writes two files that belong together (the `.bin` and its `.gltf`): both temporaries
/// first, then `first` is renamed into place before `second`, so `second` never refers to
/// data that is not there yet.
pub(crate) fn write_pair_atomically(
    first: &Path,
    first_bytes: &[u8],
    second: &Path,
    second_bytes: &[u8],
) -> Result<(), ExportError> {
    let first_temporary = write_temporary(first, first_bytes)?;
    let second_temporary = match write_temporary(second, second_bytes) {
        Ok(temporary) => temporary,
        Err(error) => {
            remove_quietly(&first_temporary);
            return Err(error);
        }
    };
    if let Err(error) = rename_into_place(&first_temporary, first) {
        remove_quietly(&second_temporary);
        return Err(error);
    }
    rename_into_place(&second_temporary, second)
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

/// Writes the temporary for `path` and returns its path; removes it again on error.
pub(crate) fn write_temporary(path: &Path, bytes: &[u8]) -> Result<PathBuf, ExportError> {
    let temporary = temporary_path_for(path);
    let result = fs::File::create(&temporary).and_then(|mut file| {
        file.write_all(bytes)?;
        file.sync_all()
    });
    match result {
        Ok(()) => Ok(temporary),
        Err(source) => {
            remove_quietly(&temporary);
            Err(ExportError::Io {
                path: path.to_path_buf(),
                source,
            })
        }
    }
}

pub(crate) fn rename_into_place(temporary: &Path, path: &Path) -> Result<(), ExportError> {
    fs::rename(temporary, path).map_err(|source| {
        remove_quietly(temporary);
        ExportError::Io {
            path: path.to_path_buf(),
            source,
        }
    })
}

/// Best-effort clean-up of a temporary; the error being reported matters more.
pub(crate) fn remove_quietly(path: &Path) {
    let _ = fs::remove_file(path);
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
    fn bin_beside_gltf_with_encoded_uri() {
        let bin = bin_path_for(Path::new("out/my scene.gltf")).ok();
        assert_eq!(bin, Some(PathBuf::from("out/my scene.bin")));
        assert_eq!(
            uri_for_file_name(Path::new("out/my scene#1.bin")),
            "my%20scene%231.bin"
        );
    }
}
