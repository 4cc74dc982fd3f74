//! Where the workspace keeps test inputs and tools, and directory listings.

use std::path::{Path, PathBuf};

/// The workspace root (two levels above this crate, without `..` in the path).
pub fn workspace_dir() -> PathBuf {
    let kit = Path::new(env!("CARGO_MANIFEST_DIR"));
    kit.ancestors()
        .nth(2)
        .expect("crates/testkit sits two levels below the workspace root")
        .to_path_buf()
}

/// The workspace's `fixtures/` directory.
pub fn fixtures_dir() -> PathBuf {
    workspace_dir().join("fixtures")
}

/// `fixtures/<name>` in the workspace.
pub fn fixture(name: &str) -> PathBuf {
    fixtures_dir().join(name)
}

/// `../shared` next to the workspace, where the optional corpora live
/// (`../shared/corpus/…`); tests that need it [`crate::skip`] without it.
pub fn shared_dir() -> PathBuf {
    workspace_dir().join("../shared")
}

/// The workspace's `tools/` directory.
pub fn tools_dir() -> PathBuf {
    workspace_dir().join("tools")
}

/// The names of everything in `dir` (hidden files included), sorted.
pub fn file_names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("list the directory")
        .map(|entry| {
            entry
                .expect("a directory entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    names.sort();
    names
}

/// Files under `dir` (recursively) whose extension, lower-cased, is one of `extensions`,
/// sorted. A directory that cannot be read is passed over.
pub fn files_with_extensions(dir: &Path, extensions: &[&str]) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for path in entries.flatten().map(|e| e.path()) {
            if path.is_dir() {
                stack.push(path);
            } else if path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| extensions.contains(&e.to_ascii_lowercase().as_str()))
            {
                found.push(path);
            }
        }
    }
    found.sort();
    found
}
