//! Sky maps (`--sky map:FILE`): the same texels written as `.hdr` (RGBE: 8-bit mantissas) and
//! `.exr` (32-bit floats) come back in place, row 0 at the top and column 0 at the left; a
//! missing file and a file of another format are refused naming the file.

use std::path::Path;

#[test]
fn hdr_and_exr_files_load_in_place() {
    let (w, h) = (8usize, 4usize);
    let value = |c: usize, r: usize| [1.0 + c as f32, 0.5 + r as f32, 0.25];
    let dir = tempfile::tempdir().expect("a temporary directory");
    let exr_path = dir.path().join("sky.exr");
    exr::prelude::write_rgb_file(&exr_path, w, h, |c, r| {
        let [a, b, d] = value(c, r);
        (a, b, d)
    })
    .expect("write the EXR");
    let hdr_path = dir.path().join("sky.hdr");
    let pixels: Vec<image::Rgb<f32>> = (0..w * h)
        .map(|k| image::Rgb(value(k % w, k / w)))
        .collect();
    let file = std::fs::File::create(&hdr_path).expect("create the HDR");
    image::codecs::hdr::HdrEncoder::new(file)
        .encode(&pixels, w, h)
        .expect("write the HDR");
    for (path, tolerance) in [(&exr_path, 0.0), (&hdr_path, 1.0 / 128.0)] {
        let map = bake_importer::load_sky_map(path).expect("load the map");
        assert_eq!((map.width, map.height), (w, h));
        for r in 0..h {
            for c in 0..w {
                let got = map.texels[r * w + c];
                for (b, expected) in value(c, r).into_iter().enumerate() {
                    assert!(
                        (got[b] - expected).abs() <= tolerance * expected,
                        "{}: ({c}, {r}) band {b}: {} against {expected}",
                        path.display(),
                        got[b]
                    );
                }
            }
        }
    }
}

#[test]
fn unreadable_maps_are_refused_naming_the_file() {
    let missing = bake_importer::load_sky_map(Path::new("/nonexistent/sky.exr"));
    let message = missing.expect_err("no file").to_string();
    assert!(message.contains("/nonexistent/sky.exr"), "{message}");
    let format = bake_importer::load_sky_map(Path::new("sky.png")).expect_err("not a map");
    assert!(format.to_string().contains("sky.png"), "{format}");
}
