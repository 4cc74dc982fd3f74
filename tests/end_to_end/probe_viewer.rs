//! The probe viewer (`tools/probe-viewer.html`, driven by `tools/probe-viewer-check` in
//! headless Chromium): a sphere lit only by the probes of a bake of the two rooms (a light
//! panel in room A's ceiling, room B lit through the doorway), drawn by three.js. The
//! probes the page uses, their weights, and the 8-bit pixel at the sphere's centre are
//! compared with what this file computes from the extension alone: trilinear weights over the
//! grid cell, invalid probes and probes behind the partition (the fixture's stated geometry,
//! not a ray cast) left out and the rest renormalised, the blended coefficients' irradiance
//! `Σ Â_l c_k Y_k(n)` at the normal facing the camera, × ρ × exposure, 8-bit sRGB.

use crate::common::bake;
use crate::probes::{probes_of, reconstruct};
use bake_testkit::fixture;
use serde_json::Value;
use std::path::Path;

/// The two rooms' partition (x 3.9–4.1) and its doorway (y < 2, z 1.5–2.5), as
/// `tools/fixtures` builds them.
const PARTITION: [f64; 2] = [3.9, 4.1];
const DOOR_TOP: f64 = 2.0;
const DOOR_Z: [f64; 2] = [1.5, 2.5];

/// Whether the segment from `a` to `b` (both inside the rooms) crosses the partition's solid
/// part: where it meets the slab's two faces, both points must be in the doorway (the doorway
/// is a box, so the part between is in it too).
fn through_partition(a: [f64; 3], b: [f64; 3]) -> bool {
    let lo = a[0].min(b[0]);
    let hi = a[0].max(b[0]);
    if hi <= PARTITION[0] || lo >= PARTITION[1] {
        return false;
    }
    let at = |x: f64| {
        let t = if b[0] == a[0] {
            0.0
        } else {
            ((x - a[0]) / (b[0] - a[0])).clamp(0.0, 1.0)
        };
        [0, 1, 2].map(|k| a[k] + t * (b[k] - a[k]))
    };
    let in_door = |p: [f64; 3]| p[1] <= DOOR_TOP && (DOOR_Z[0]..=DOOR_Z[1]).contains(&p[2]);
    !(in_door(at(PARTITION[0])) && in_door(at(PARTITION[1])))
}

/// The probes a point is lit by and their weights, the ones dropped as invalid or behind the
/// partition (unless `through_walls`), and the blended coefficients (unscaled).
struct Blend {
    used: Vec<(usize, f64)>,
    invalid: Vec<usize>,
    blocked: Vec<usize>,
    sh: [[f64; 3]; 9],
}

fn blend(
    ext: &Value,
    positions: &[f64],
    coefficients: &[f64],
    valid: &[f64],
    at: [f64; 3],
    through_walls: bool,
) -> Blend {
    let number = |v: &Value| v.as_f64().expect("a number");
    let spacing = number(&ext["grid"]["spacing"]);
    let origin = [0, 1, 2].map(|a| number(&ext["grid"]["origin"][a]));
    let counts = [0, 1, 2].map(|a| ext["grid"]["counts"][a].as_u64().expect("a count") as usize);
    let mut corner = [0usize; 3];
    let mut fraction = [0.0; 3];
    for a in 0..3 {
        let t = (at[a] - origin[a]) / spacing;
        let i = (t.floor().max(0.0) as usize).min(counts[a].saturating_sub(2));
        corner[a] = i;
        fraction[a] = (t - i as f64).clamp(0.0, 1.0);
    }
    let mut out = Blend {
        used: Vec::new(),
        invalid: Vec::new(),
        blocked: Vec::new(),
        sh: [[0.0; 3]; 9],
    };
    for c in 0..8 {
        let o = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
        let weight: f64 = (0..3)
            .map(|a| match o[a] {
                1 => fraction[a],
                _ => 1.0 - fraction[a],
            })
            .product();
        let index =
            corner[0] + o[0] + counts[0] * (corner[1] + o[1] + counts[1] * (corner[2] + o[2]));
        let p = [0, 1, 2].map(|k| positions[3 * index + k]);
        if weight == 0.0 {
            continue;
        } else if valid[index] == 0.0 {
            out.invalid.push(index);
        } else if !through_walls && through_partition(at, p) {
            out.blocked.push(index);
        } else {
            out.used.push((index, weight));
        }
    }
    let total: f64 = out.used.iter().map(|u| u.1).sum();
    for (index, weight) in &mut out.used {
        *weight /= total;
        for k in 0..9 {
            for band in 0..3 {
                out.sh[k][band] += *weight * coefficients[27 * *index + 3 * k + band];
            }
        }
    }
    out
}

/// 8-bit sRGB of a linear value in [0, 1], not rounded.
fn level(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    255.0
        * if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        }
}

/// The linear value of 8-bit sRGB level `l` (clamped to 0–255).
fn linear(l: f64) -> f64 {
    let s = l.clamp(0.0, 255.0) / 255.0;
    if s <= 0.040_45 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}

/// Runs the viewer on `out` with a sphere of reflectance `rho` and radius `radius` at `at`,
/// seen from `from`; the page's JSON.
fn view(out: &Path, at: [f64; 3], from: [f64; 3], rho: f64, radius: f64) -> Value {
    let list = |v: [f64; 3]| format!("{},{},{}", v[0], v[1], v[2]);
    let run = std::process::Command::new(bake_testkit::tools_dir().join("probe-viewer-check"))
        .arg(out)
        .args(["--at", &list(at), "--from", &list(from)])
        .args(["--rho", &list([rho; 3]), "--radius", &radius.to_string()])
        .output()
        .expect("run tools/probe-viewer-check");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    stdout
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("PROBE_VIEWER "))
        .and_then(|l| serde_json::from_str(l).ok())
        .expect("a PROBE_VIEWER line")
}

/// What one sphere showed: per band the expected level (unrounded), the pixel, and the
/// irradiance E(n) the probes give.
struct Shown {
    normal: [f64; 3],
    expected: [f64; 3],
    pixel: [f64; 3],
    irradiance: [f64; 3],
}

/// Views a sphere at `at` and checks the page against [`blend`]: the same probes, weights
/// within 1e-12, the same dropped ones, the LightProbe's coefficients = blend × exposure × π,
/// and the centre pixel within 1 level of `ρ E(n) × exposure` in 8-bit sRGB.
fn check_sphere(
    out: &Path,
    probes: &(Value, Vec<f64>, Vec<f64>, Vec<f64>),
    at: [f64; 3],
    from: [f64; 3],
    rho: f64,
) -> (Shown, Blend) {
    let (ext, positions, coefficients, valid) = probes;
    let want = blend(ext, positions, coefficients, valid, at, false);
    let got = view(out, at, from, rho, 0.08);
    let indices = |v: &Value| -> Vec<usize> {
        v.as_array()
            .expect("an array")
            .iter()
            .map(|i| i.as_u64().expect("an index") as usize)
            .collect()
    };
    assert_eq!(indices(&got["dropped"]["invalid"]), want.invalid, "{got}");
    assert_eq!(indices(&got["dropped"]["blocked"]), want.blocked, "{got}");
    let used = got["used"].as_array().expect("used");
    assert_eq!(used.len(), want.used.len(), "{got}");
    for (u, (index, weight)) in used.iter().zip(&want.used) {
        assert_eq!(u["index"].as_u64(), Some(*index as u64), "{got}");
        let w = u["weight"].as_f64().expect("a weight");
        assert!((w - weight).abs() < 1e-12, "{w} vs {weight}");
    }
    let exposure = ext["exposure"].as_f64().expect("exposure");
    let scale = exposure * std::f64::consts::PI;
    for k in 0..9 {
        for band in 0..3 {
            let page = got["sh"][k][band].as_f64().expect("a coefficient");
            let here = scale * want.sh[k][band];
            assert!(
                (page - here).abs() <= 1e-9 * (1.0 + scale * want.sh[0][band].abs()),
                "c{k} band {band}: {page} vs {here}"
            );
        }
    }
    // The sphere's normal at the centre pixel faces the camera.
    let d = [0, 1, 2].map(|k| from[k] - at[k]);
    let length = d.iter().map(|x| x * x).sum::<f64>().sqrt();
    let normal = d.map(|x| x / length);
    let irradiance = reconstruct(&want.sh, normal);
    let expected = irradiance.map(|e| level(rho * e * exposure));
    let pixel = [0, 1, 2].map(|b| got["centre_pixel"][b].as_f64().expect("a level"));
    eprintln!(
        "sphere at {at:?}: probes {:?}, dropped {:?} (invalid) {:?} (behind the partition); \
         E(n) {irradiance:.4?}, expected levels {expected:.2?}, pixel {pixel:?}",
        want.used, want.invalid, want.blocked
    );
    for band in 0..3 {
        assert!(
            expected[band] > 2.0 && expected[band] < 253.0,
            "band {band}: {expected:?} (choose ρ to stay off 0 and 255)"
        );
        assert!(
            (pixel[band] - expected[band]).abs() <= 1.0,
            "band {band}: pixel {pixel:?}, expected {expected:?}"
        );
    }
    let shown = Shown {
        normal,
        expected,
        pixel,
        irradiance,
    };
    (shown, want)
}

/// A sphere under room A's light panel and one in room B's corner against the partition:
/// each shows what its probes say within 1 level (rounding to 8 bits is 0.5 of it; three.js'
/// SH constants have 6 digits, the shader computes in f32: under 0.01 level here); the
/// corner's cell has four probes in room A, which the page drops (their segments cross the
/// partition), and with them kept the pixel would differ by more than 3 levels. The panel's
/// sphere is brighter than the corner's by the ratio of their E(n) (ρ divided out), within
/// the bounds one level either way on both pixels allows.
#[test]
fn the_probe_viewer_lights_a_sphere_as_the_probes_say() {
    if !bake_testkit::chromium_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out = dir.path().join("rooms.gltf");
    bake([
        fixture("two-rooms.gltf").as_os_str(),
        out.as_os_str(),
        "--subdiv".as_ref(),
        "2".as_ref(),
        "--probes".as_ref(),
        "grid:0.5".as_ref(),
        "--target".as_ref(),
        "vertex".as_ref(),
        "--quiet".as_ref(),
    ])
    .success();
    let probes = probes_of(&out);

    let (rho_lit, rho_dark) = (0.1, 0.5);
    let (lit, lit_blend) = check_sphere(&out, &probes, [2.0, 1.9, 2.0], [2.0, 2.3, 2.6], rho_lit);
    assert!(lit_blend.blocked.is_empty() && lit_blend.used.len() == 8);
    let corner = [4.2, 0.3, 0.3];
    let (dark, dark_blend) = check_sphere(&out, &probes, corner, [4.6, 0.5, 0.9], rho_dark);
    assert_eq!(dark_blend.blocked.len(), 4, "the cell's room-A probes");

    // The leak the rule prevents: the same cell with its room-A probes kept.
    let (ext, positions, coefficients, valid) = &probes;
    let leaky = blend(ext, positions, coefficients, valid, corner, true);
    assert_eq!(leaky.used.len(), 8);
    let exposure = ext["exposure"].as_f64().expect("exposure");
    let e_leaky = reconstruct(&leaky.sh, dark.normal);
    for (band, (e, pixel)) in e_leaky.iter().zip(dark.pixel).enumerate() {
        let l = level(rho_dark * e * exposure);
        eprintln!("corner band {band}: {pixel} levels, {l:.2} with the room-A probes kept");
        assert!((l - pixel).abs() > 3.0, "the partition leaks");
    }

    for band in 0..3 {
        let ratio = lit.irradiance[band] / dark.irradiance[band];
        let shown = |a: f64, b: f64| (linear(a) / rho_lit) / (linear(b) / rho_dark);
        let (lo, hi) = (
            shown(lit.pixel[band] - 1.0, dark.pixel[band] + 1.0),
            shown(lit.pixel[band] + 1.0, dark.pixel[band] - 1.0),
        );
        eprintln!(
            "band {band}: E ratio {ratio:.3}, pixels {:.3} (bounds {lo:.3}–{hi:.3}; expected levels {:.2}, {:.2})",
            shown(lit.pixel[band], dark.pixel[band]),
            lit.expected[band],
            dark.expected[band]
        );
        assert!(ratio > 5.0, "the panel's sphere is the brighter: {ratio}");
        assert!((lo..=hi).contains(&ratio), "{ratio} not in {lo}–{hi}");
    }
}
