//! `accuracy-report`: for now only writes demo plots, to show what the report's plots look
//! like; the report itself comes later.
//!
//! Usage: `accuracy-report OUT_DIR` writes `OUT_DIR/error_vs_time.png` and
//! `OUT_DIR/scanline.png` from synthetic data.

mod plot;

use std::path::PathBuf;

use anyhow::Context;
use plot::{Curve, Point};

fn main() -> anyhow::Result<()> {
    let dir = PathBuf::from(
        std::env::args_os()
            .nth(1)
            .context("usage: accuracy-report OUT_DIR")?,
    );
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;

    // Three solvers, each run at a few accuracy settings: error falls as a power of time.
    let mut points = Vec::new();
    for (group, t0, e0, slope) in [
        ("jacobi", 0.02, 0.3, 1.0),
        ("gauss-seidel", 0.015, 0.2, 1.6),
        ("progressive", 0.005, 0.5, 1.2),
    ] {
        for k in 0..6 {
            let time_s: f64 = t0 * 2f64.powi(k);
            let error = e0 * (time_s / t0).powf(-slope) * (1.0 + 0.15 * (k as f64).sin());
            points.push(Point {
                label: format!("{group} n={}", 1 << k),
                group: group.to_string(),
                time_s,
                error,
            });
        }
    }
    let front = plot::pareto_front(&points);
    println!(
        "Pareto front: {:?}",
        front.iter().map(|&i| &points[i].label).collect::<Vec<_>>()
    );
    let path = dir.join("error_vs_time.png");
    plot::error_vs_time(
        &path,
        "Error versus time (demo data)",
        "time (s)",
        "RMS error",
        &points,
    )
    .with_context(|| format!("writing {}", path.display()))?;

    // A scanline over three walls: the reference is smooth, one estimate is piecewise constant
    // (one value per patch), one is smooth but biased.
    let x: Vec<f64> = (0..=300).map(|i| f64::from(i) / 100.0).collect();
    let smooth = |x: f64| {
        [
            0.6 + 0.25 * (2.0 * x).sin(),
            0.4 + 0.2 * x.cos(),
            0.3 + 0.1 * x,
        ]
    };
    let curves = vec![
        Curve {
            label: "reference".into(),
            x: x.clone(),
            rgb: x.iter().map(|&x| smooth(x)).collect(),
        },
        Curve {
            label: "constant patches".into(),
            x: x.clone(),
            rgb: x
                .iter()
                .map(|&x| smooth((x * 5.0).floor().min(14.0) / 5.0 + 0.1))
                .collect(),
        },
        Curve {
            label: "smooth, biased".into(),
            x: x.clone(),
            rgb: x
                .iter()
                .map(|&x| smooth(x).map(|v| 0.9 * v + 0.02))
                .collect(),
        },
    ];
    let path = dir.join("scanline.png");
    plot::scanline(
        &path,
        "Scanline intensity (demo data)",
        "position along the scanline",
        &curves,
        &[1.0, 2.0],
        &["left | back", "back | right"],
    )
    .with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", dir.display());
    Ok(())
}
