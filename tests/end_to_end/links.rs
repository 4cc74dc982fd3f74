//! `--save-links` / `--load-links`: a re-bake with other emission reuses the links and agrees
//! with a fresh bake of that emission; the file is the same bytes whatever the thread count;
//! other geometry or link options, a damaged file, the dense transport and a links file that
//! is also an output are refused with one line.

use crate::common;

use bake_testkit::fixture;
use common::{bake, report_without_timings};
use std::path::{Path, PathBuf};

/// The two-room fixture (OBJ + MTL) copied into `dir`, its lamp's `Ke` replaced by `ke`.
fn two_rooms(dir: &Path, name: &str, ke: &str) -> PathBuf {
    let obj = std::fs::read_to_string(fixture("two-rooms.obj")).expect("read the fixture");
    let mtl = std::fs::read_to_string(fixture("two-rooms.mtl")).expect("read its materials");
    assert!(mtl.contains("Ke 16 16 16"), "the fixture's lamp");
    let obj = obj.replace("mtllib two-rooms.mtl", &format!("mtllib {name}.mtl"));
    std::fs::write(dir.join(format!("{name}.obj")), obj).expect("write the scene");
    std::fs::write(
        dir.join(format!("{name}.mtl")),
        mtl.replace("Ke 16 16 16", &format!("Ke {ke}")),
    )
    .expect("write its materials");
    dir.join(format!("{name}.obj"))
}

fn run(args: &[&std::ffi::OsStr]) -> common::Run {
    bake(args.iter().copied())
}

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

#[test]
fn a_rebake_from_saved_links_matches_a_fresh_bake_of_the_new_emission() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let white = two_rooms(d, "white", "16 16 16");
    let warm = two_rooms(d, "warm", "30 20 9");
    let links = d.join("rooms.links");
    let common = ["--target", "vertex", "--max-element-size", "0.2"];
    let first = run(&[
        white.as_os_str(),
        d.join("white.gltf").as_os_str(),
        os("--save-links"),
        links.as_os_str(),
        os(common[0]),
        os(common[1]),
        os(common[2]),
        os(common[3]),
    ]);
    assert_eq!(first.code, Some(0), "{}", first.stderr);
    assert!(links.is_file());
    let warm_out = d.join("warm.gltf");
    let bake_warm = |extra: &[&std::ffi::OsStr], json: &Path| {
        let mut args = vec![
            warm.as_os_str(),
            warm_out.as_os_str(),
            os("--report"),
            json.as_os_str(),
        ];
        args.extend(common.iter().map(|s| os(s)));
        args.extend_from_slice(extra);
        let r = run(&args);
        assert_eq!(r.code, Some(0), "{}", r.stderr);
        report_without_timings(json)
    };
    let reused = bake_warm(
        &[os("--load-links"), links.as_os_str()],
        &d.join("reused.json"),
    );
    // Auto would pick the dense transport for these ~3 600 elements; compare like with like.
    let fresh = bake_warm(
        &[os("--transport"), os("hierarchical")],
        &d.join("fresh.json"),
    );
    assert_eq!(reused.transport.kind.name(), "hierarchical");
    assert!(reused.transport.reason.contains("links loaded from"));
    assert_eq!(reused.counts.rays_cast, 0, "nothing linked, no rays");
    assert!(reused.counts.links > 0);
    let (mut num, mut den) = (0.0, 0.0);
    for (a, b) in reused.elements.iter().zip(&fresh.elements) {
        for k in 0..3 {
            num += (a.b[k] - b.b[k]).powi(2);
            den += b.b[k].powi(2);
        }
    }
    let rms = (num / den).sqrt();
    assert!(rms < 0.01, "RMS {rms} between reused and fresh links");
    // The energy balance holds on the reused operator as on any other.
    let energy = reused.energy.expect("an energy balance");
    for band in 0..3 {
        assert!(
            energy.imbalance[band].abs() <= 1e-6 * energy.emitted[band],
            "{energy:?}"
        );
    }
}

#[test]
fn saved_links_are_the_same_bytes_with_one_and_two_threads() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let scene = two_rooms(d, "rooms", "16 16 16");
    let mut files = Vec::new();
    for threads in ["1", "2"] {
        let links = d.join(format!("t{threads}.links"));
        let r = run(&[
            scene.as_os_str(),
            d.join(format!("t{threads}.gltf")).as_os_str(),
            os("--target"),
            os("vertex"),
            os("--threads"),
            os(threads),
            os("--save-links"),
            links.as_os_str(),
        ]);
        assert_eq!(r.code, Some(0), "{}", r.stderr);
        files.push(std::fs::read(&links).expect("read the links"));
    }
    assert!(files[0] == files[1], "links differ between thread counts");
}

#[test]
fn links_for_other_geometry_options_or_damaged_files_are_refused() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let scene = two_rooms(d, "rooms", "16 16 16");
    let links = d.join("rooms.links");
    let out = d.join("out.gltf");
    let base = |extra: &[&std::ffi::OsStr]| {
        let mut args = vec![
            scene.as_os_str(),
            out.as_os_str(),
            os("--target"),
            os("vertex"),
        ];
        args.extend_from_slice(extra);
        run(&args)
    };
    let saved = base(&[os("--save-links"), links.as_os_str()]);
    assert_eq!(saved.code, Some(0), "{}", saved.stderr);
    let error_line = |r: &common::Run| {
        r.error_lines()
            .into_iter()
            .map(str::to_string)
            .collect::<Vec<_>>()
    };
    // Another mesh: the key differs.
    let finer = base(&[
        os("--load-links"),
        links.as_os_str(),
        os("--max-element-size"),
        os("0.15"),
    ]);
    assert_eq!(finer.code, Some(1), "{}", finer.stderr);
    let lines = error_line(&finer);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains("rooms.links"), "{lines:?}");
    assert!(
        lines[0].contains("other geometry or link options"),
        "{lines:?}"
    );
    // Another link tolerance: refused too.
    let looser = base(&[
        os("--load-links"),
        links.as_os_str(),
        os("--link-tolerance"),
        os("0.05"),
    ]);
    assert_eq!(looser.code, Some(1), "{}", looser.stderr);
    // A truncated file.
    let bytes = std::fs::read(&links).expect("read the links");
    let cut = d.join("cut.links");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).expect("write a truncated copy");
    let truncated = base(&[os("--load-links"), cut.as_os_str()]);
    assert_eq!(truncated.code, Some(1), "{}", truncated.stderr);
    assert_eq!(error_line(&truncated).len(), 1, "{}", truncated.stderr);
    // The dense transport has no links.
    let dense = base(&[
        os("--load-links"),
        links.as_os_str(),
        os("--transport"),
        os("dense"),
    ]);
    assert_eq!(dense.code, Some(1), "{}", dense.stderr);
    assert!(dense.stderr.contains("need the hierarchical transport"));
    // Saving over the links being loaded, or over the input: refused before anything runs.
    let same = base(&[
        os("--load-links"),
        links.as_os_str(),
        os("--save-links"),
        links.as_os_str(),
    ]);
    assert_eq!(same.code, Some(2), "{}", same.stderr);
    let over_input = base(&[os("--save-links"), scene.as_os_str()]);
    assert_eq!(over_input.code, Some(2), "{}", over_input.stderr);
    assert_eq!(
        std::fs::read(&links).expect("still there"),
        bytes,
        "refusals leave the links file alone"
    );
}
