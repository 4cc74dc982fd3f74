//! The PNG companion's scale (issue 32): one hot texel must not black out the rest. The
//! scale is the brightest covered texel unless that is more than `PNG_HEADROOM` times the
//! `PNG_PERCENTILE` of the covered texels' brightest bands; then it is that many times the
//! percentile and the texels above it clip (counted). The EXR keeps the exact values.
//! References are computed here from the atlas's texels: a sort, not the crate's selection.

mod common;

use bake_lightmap as lightmap;
use common::polygon;
use glam::DVec3;
use importer::Polygon;
use lightmap::{Options, Shading, Texel};

fn quad(o: DVec3, size: f64, material: usize) -> Polygon {
    let corner = |x: f64, y: f64| o + DVec3::new(x, y, 0.0) * size;
    polygon(
        vec![
            corner(0.0, 0.0),
            corner(1.0, 0.0),
            corner(1.0, 1.0),
            corner(0.0, 1.0),
        ],
        material,
    )
}

/// A 1 × 1 floor lit by a gentle ramp and, apart from it, a 5 mm square at `hot` (in its
/// own material, so nothing averages it with the floor).
fn lightmap_with(hot: f64) -> lightmap::Lightmap {
    let polygons = vec![
        quad(DVec3::ZERO, 1.0, 0),
        quad(DVec3::new(2.0, 0.0, 0.0), 0.005, 1),
    ];
    let mesh = mesher::mesh(&polygons, mesher::Subdivision::Count(8)).expect("mesh");
    let values: Vec<[f64; 3]> = mesh
        .elements
        .iter()
        .map(|e| {
            if e.polygon == 1 {
                [hot, hot / 2.0, hot / 4.0]
            } else {
                let x = e.centroid.x;
                [0.5 + 0.5 * x, 0.4 + 0.3 * x, 0.3]
            }
        })
        .collect();
    let options = Options {
        texel_size: 0.004,
        max_size: 4096,
        shading: Shading::Smooth,
        max_atlases: 1,
    };
    lightmap::build(&polygons, &mesh, &values, &options).expect("build")
}

/// Covered texels' brightest bands, sorted.
fn brightest(l: &lightmap::Lightmap) -> Vec<f32> {
    let mut b: Vec<f32> = l
        .texels
        .iter()
        .zip(&l.coverage)
        .filter(|(_, c)| matches!(c, Texel::Chart(_)))
        .map(|(t, _)| t[0].max(t[1]).max(t[2]))
        .collect();
    b.sort_by(f32::total_cmp);
    b
}

fn decode(png: &lightmap::PngLightmap) -> Vec<[u8; 3]> {
    let image = image::load_from_memory(&png.bytes)
        .expect("decode")
        .to_rgb8();
    image.pixels().map(|p| p.0).collect()
}

#[test]
fn one_hot_texel_does_not_black_out_the_png() {
    let l = lightmap_with(1000.0);
    let sorted = brightest(&l);
    let n = sorted.len();
    let max = f64::from(sorted[n - 1]);
    // The nearest-rank percentile.
    let rank = ((lightmap::PNG_PERCENTILE * n as f64).ceil() as usize).clamp(1, n);
    let percentile = f64::from(sorted[rank - 1]);
    assert!(max > 100.0 * percentile, "the scene has a hot spot");
    let png = lightmap::encode_png(&l).expect("encode");
    let want = lightmap::PNG_HEADROOM * percentile;
    assert!(
        (png.scale - want).abs() <= 1e-12 * want,
        "scale {} want {want}",
        png.scale
    );
    let clipped = sorted.iter().filter(|&&b| f64::from(b) > png.scale).count();
    assert_eq!(png.clipped as usize, clipped);
    assert_eq!(png.covered as usize, n);
    assert!(clipped > 0 && clipped * 1000 <= n, "{clipped} of {n} clip");
    // Unclipped texels are within half an 8-bit step of H; no covered floor texel is black.
    let pixels = decode(&png);
    let mut worst = 0.0f64;
    let mut black = 0;
    for ((t, cover), p) in l.texels.iter().zip(&l.coverage).zip(&pixels) {
        if !matches!(cover, Texel::Chart(_)) {
            continue;
        }
        if t.iter().all(|&h| f64::from(h) <= png.scale) {
            for c in 0..3 {
                let decoded = lightmap::srgb_to_linear(f64::from(p[c]) / 255.0) * png.scale;
                worst = worst.max((decoded - f64::from(t[c])).abs() / png.scale);
            }
        }
        black += usize::from(*p == [0, 0, 0]);
    }
    // Before: the scale was the brightest texel (1000), which put the floor at ≤ 1e-3 of
    // full scale: a few 8-bit levels.
    let old_floor_level =
        lightmap::linear_to_srgb(f64::from(sorted[n - clipped - 1]) / max) * 255.0;
    println!(
        "{n} covered texels, {clipped} clipped; scale {:.4} (brightest {max:.1}); unclipped \
         error ≤ {worst:.2e} of the scale; brightest floor texel at level {:.0} before, 255 now",
        png.scale, old_floor_level
    );
    assert_eq!(black, 0);
    assert!(worst <= 2.4 * 0.5 / 255.0, "{worst}");
}

#[test]
fn without_an_outlier_the_scale_is_the_brightest_texel() {
    // The hot square is as bright as the floor: no outlier, nothing clips.
    let l = lightmap_with(1.0);
    let sorted = brightest(&l);
    let png = lightmap::encode_png(&l).expect("encode");
    assert_eq!(png.scale, f64::from(sorted[sorted.len() - 1]));
    assert_eq!(png.clipped, 0);
}
