//! Robustness: every glTF file of the Khronos validator's test suite and every OBJ of
//! tinyobjloader's test models must load or fail with an error, never panic.

use bake_testkit::{files_with_extensions, shared_dir, skip};

#[test]
fn corpus_files_load_or_fail_without_panicking() {
    let corpus = shared_dir().join("corpus");
    if !corpus.is_dir() {
        // Required in CI (`BAKE_REQUIRE_ALL=1`, as `.ci/run` sets).
        skip(
            "BAKE_REQUIRE_CORPUS",
            &format!("corpus not found at {}", corpus.display()),
        );
        return;
    }
    let mut paths = files_with_extensions(&corpus.join("gltf-validator/test"), &["gltf", "glb"]);
    paths.extend(files_with_extensions(
        &corpus.join("tinyobjloader"),
        &["obj"],
    ));
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
