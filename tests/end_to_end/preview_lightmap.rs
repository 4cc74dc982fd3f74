//! `bake preview` of a lightmap bake (issue 32): drawn through its `MOZ_lightmap` as a lit
//! viewer shows it, it must look like the vertex bake's preview of the same scene, which is
//! computed from the same element values by another path (the vertex smoothing and `COLOR_0`,
//! not the atlas); and `--eye`/`--look-at` put the camera inside a room.

use crate::common;

use bake_testkit::fixture;
use common::bake;
use preview::image::{self, RgbImage};
use std::ffi::OsStr;
use std::path::Path;

fn read_png(path: &Path) -> RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
}

fn preview(input: &Path, png: &Path, args: &[&str]) {
    let mut all: Vec<&OsStr> = vec!["preview".as_ref(), input.as_os_str(), png.as_os_str()];
    all.extend(args.iter().map(OsStr::new));
    bake(all).success();
}

/// Of the pixels either image covers (not the background in both), the share whose channels
/// all differ by at most `tolerance` (of 255), and the largest difference.
fn agreement(a: &RgbImage, b: &RgbImage, tolerance: u8) -> (f64, u8, usize) {
    assert_eq!(a.dimensions(), b.dimensions());
    let background = *a.get_pixel(0, 0);
    let (mut covered, mut within, mut worst) = (0usize, 0usize, 0u8);
    for (p, q) in a.pixels().zip(b.pixels()) {
        if *p == background && *q == background {
            continue;
        }
        covered += 1;
        let d = (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0);
        worst = worst.max(d);
        within += usize::from(d <= tolerance);
    }
    (within as f64 / covered.max(1) as f64, worst, covered)
}

/// Bakes `input` to a vertex and a lightmap bake in `dir`: (vertex glTF, lightmap glTF).
fn both(dir: &Path, input: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let out = dir.join("out.gltf");
    bake([
        input.as_os_str(),
        out.as_os_str(),
        "--target".as_ref(),
        "both".as_ref(),
        "--quality".as_ref(),
        "draft".as_ref(),
        "-q".as_ref(),
    ])
    .success();
    (out, dir.join("out.lightmap.gltf"))
}

#[test]
fn a_lightmap_bake_previews_like_its_vertex_bake() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (vertex, lightmap) = both(dir.path(), &fixture("cornell.gltf"));
    let (v, l) = (dir.path().join("v.png"), dir.path().join("l.png"));
    preview(&vertex, &v, &[]);
    preview(&lightmap, &l, &[]);
    let (share, worst, covered) = agreement(&read_png(&v), &read_png(&l), 3);
    assert!(covered > 100_000, "{covered} pixels covered");
    assert!(
        share >= 0.99,
        "{:.2}% of {covered} covered pixels within 3/255 (worst {worst})",
        100.0 * share
    );

    // Inside the box (just past its open side), looking at the back wall: both bakes, the
    // same picture.
    let view = [
        "--eye",
        "278,274,50",
        "--look-at",
        "278,274,559",
        "--fov",
        "60",
    ];
    preview(&vertex, &v, &view);
    preview(&lightmap, &l, &view);
    let (inside_v, inside_l) = (read_png(&v), read_png(&l));
    let (share, worst, covered) = agreement(&inside_v, &inside_l, 3);
    assert!(
        share >= 0.99,
        "inside: {:.2}% of {covered} within 3/255 (worst {worst})",
        100.0 * share
    );
    // From inside, the walls fill the frame: no background left.
    let background = preview::srgb8(preview::BACKGROUND[0]);
    let empty = inside_v.pixels().filter(|p| p.0 == [background; 3]).count();
    assert_eq!(empty, 0, "{empty} background pixels seen from inside");

    // --exposure re-exposes the lightmap bake: 0 is black (the emitter too).
    preview(&lightmap, &l, &["--exposure", "0"]);
    let dark = read_png(&l);
    assert!(
        dark.pixels()
            .all(|p| p.0 == [0; 3] || p.0 == [background; 3]),
        "exposure 0 leaves only black and the background"
    );
}

#[test]
fn eye_and_look_at_go_together() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let png = dir.path().join("p.png");
    let cube = fixture("cube.gltf");
    for args in [
        &["--eye", "0,0,0"][..],
        &["--look-at", "0,0,-1"][..],
        &["--fov", "50"][..],
    ] {
        let mut all: Vec<&OsStr> = vec!["preview".as_ref(), cube.as_os_str(), png.as_os_str()];
        all.extend(args.iter().map(OsStr::new));
        let run = bake(all);
        assert_eq!(run.code, Some(2), "{args:?}: {run:#?}");
        assert!(!png.exists());
    }
    let run = bake([
        "preview".as_ref(),
        cube.as_os_str(),
        png.as_os_str(),
        "--eye".as_ref(),
        "1,1,1".as_ref(),
        "--look-at".as_ref(),
        "1,1,1".as_ref(),
    ]);
    assert_eq!(run.code, Some(1), "{run:#?}");
    assert!(run.stderr.contains("--eye and --look-at"), "{}", run.stderr);
}
