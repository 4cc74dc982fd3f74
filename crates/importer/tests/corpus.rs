//! Robustness: every glTF file of the Khronos validator's test suite and every OBJ of
//! tinyobjloader's test models must load or fail with an error, never panic.

use std::path::{Path, PathBuf};

const CORPUS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/corpus");

/// Files under `dir` whose extension (lower-cased) is one of `extensions`, sorted.
fn files(dir: &Path, extensions: &[&str]) -> Vec<PathBuf> {
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

#[test]
fn corpus_files_load_or_fail_without_panicking() {
    let corpus = Path::new(CORPUS);
    if !corpus.is_dir() {
        // Required in CI (`BAKE_REQUIRE_ALL=1`, as `.ci/run` sets); else said on stderr past
        // libtest's capture, so the skip shows.
        let required = ["BAKE_REQUIRE_CORPUS", "BAKE_REQUIRE_ALL"]
            .iter()
            .any(|v| std::env::var(v).is_ok_and(|x| x == "1"));
        assert!(!required, "BAKE_REQUIRE_CORPUS=1 but {CORPUS} is not there");
        use std::io::Write;
        let _ = writeln!(std::io::stderr(), "skipped: corpus not found at {CORPUS}");
        return;
    }
    let mut paths = files(&corpus.join("gltf-validator/test"), &["gltf", "glb"]);
    paths.extend(files(&corpus.join("tinyobjloader"), &["obj"]));
    assert!(!paths.is_empty(), "the corpus has no files");

    let verbose = std::env::var_os("BAKE_CORPUS_VERBOSE").is_some();
    let mut panicked = Vec::new();
    let (mut ok, mut failed) = (0, 0);
    for path in &paths {
        let result = std::panic::catch_unwind(|| bake_importer::load(path));
        if verbose {
            match &result {
                Ok(Ok(scene)) => println!("{}: {} polygons", path.display(), scene.polygons.len()),
                Ok(Err(e)) => println!("{}: {e}", path.display()),
                Err(_) => println!("{}: PANIC", path.display()),
            }
        }
        match result {
            Ok(Ok(_)) => ok += 1,
            Ok(Err(e)) => {
                failed += 1;
                let message = e.to_string();
                assert!(
                    !message.contains('\n'),
                    "{}: multi-line message {message:?}",
                    path.display()
                );
            }
            Err(_) => panicked.push(path.display().to_string()),
        }
    }
    println!(
        "corpus: {} files, {ok} loaded, {failed} refused",
        paths.len()
    );
    assert!(
        panicked.is_empty(),
        "load panicked on:\n{}",
        panicked.join("\n")
    );
}
