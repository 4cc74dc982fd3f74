//! `walkthrough bench`: per floor size, generate the floor, run `bake` on it as a child, and
//! report elements, links, rays, the report's stage times, wall time and the child's peak RSS.

use anyhow::{bail, Context, Result};
use bake_walkthrough::{gltf, office};
use office::Rooms;
use serde_json::Value;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// The bake binary [default: target/release/bake of this workspace, else `bake` beside
    /// this executable].
    #[arg(long)]
    bake: Option<PathBuf>,
    /// Floor sizes to bench, in order (comma-separated or repeated).
    #[arg(long, value_delimiter = ',', default_value = "2x2,8x8")]
    rooms: Vec<Rooms>,
    /// Clear width and depth of every room (m).
    #[arg(long, default_value_t = 4.0)]
    room_size: f64,
    /// Floor-to-ceiling height (m).
    #[arg(long, default_value_t = 3.0)]
    height: f64,
    /// No walls between the rooms (see `walkthrough office --open-plan`).
    #[arg(long)]
    open_plan: bool,
    /// Passed to bake as --max-element-size.
    #[arg(long, default_value_t = 0.25)]
    max_element_size: f64,
    /// Where the floors, bakes, reports, bake stderr and bench.csv go [default: a new
    /// directory under the system temp dir, kept].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Extra arguments for every bake (after `--`).
    #[arg(last = true)]
    extra: Vec<String>,
}

/// One bake's measurements.
struct Row {
    rooms: Rooms,
    polygons: String,
    elements: String,
    predicted: u64,
    links: String,
    rays: String,
    /// The report's `timings`, in its order (seconds).
    timings: Vec<(String, f64)>,
    /// The report's `peak_rss_mib`: the bake's peak RSS at the end of each stage (MiB).
    memory: Vec<(String, f64)>,
    wall_s: f64,
    peak_rss_mib: f64,
}

pub fn run(args: Args) -> Result<()> {
    if !(args.max_element_size.is_finite() && args.max_element_size > 0.0) {
        bail!(
            "--max-element-size must be a positive number, got {}",
            args.max_element_size
        );
    }
    let bake = match args.bake {
        Some(b) => b,
        None => default_bake()?,
    };
    let dir = match args.out {
        Some(d) => d,
        None => std::env::temp_dir().join(format!("walkthrough-bench-{}", std::process::id())),
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    eprintln!("bench: bake {}, files in {}", bake.display(), dir.display());

    let mut rows = Vec::new();
    for &rooms in &args.rooms {
        let floor = office::office_with(rooms, args.room_size, args.height, args.open_plan)
            .map_err(anyhow::Error::msg)?;
        let input = dir.join(format!("office-{rooms}.gltf"));
        gltf::write(&floor, &input)?;
        let output = dir.join(format!("office-{rooms}-baked.gltf"));
        let report = dir.join(format!("office-{rooms}-report.json"));
        let stderr_path = dir.join(format!("office-{rooms}-bake.stderr"));
        let predicted = floor.elements(args.max_element_size);
        eprintln!(
            "bench: {rooms}: {} quads, {predicted} elements predicted, baking…",
            floor.quad_count()
        );

        let stderr = File::create(&stderr_path)
            .with_context(|| format!("creating {}", stderr_path.display()))?;
        let mut command = Command::new(&bake);
        command
            .arg(&input)
            .arg(&output)
            .arg("--max-element-size")
            .arg(args.max_element_size.to_string())
            .args(["--target", "vertex", "--report"])
            .arg(&report)
            .arg("--quiet")
            .args(&args.extra)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(stderr);
        let start = Instant::now();
        let child = command
            .spawn()
            .with_context(|| format!("starting {}", bake.display()))?;
        let (status, max_rss_kib) = wait_with_rusage(child.id())?;
        let wall_s = start.elapsed().as_secs_f64();
        if status != 0 {
            let err = std::fs::read_to_string(&stderr_path).unwrap_or_default();
            eprint!("{err}");
            if !rows.is_empty() {
                write_csv(&dir, &rows)?;
            }
            bail!("bake failed on {} ({status})", input.display());
        }
        let text = std::fs::read_to_string(&report)
            .with_context(|| format!("reading {}", report.display()))?;
        let report_json: Value =
            serde_json::from_str(&text).with_context(|| format!("parsing {}", report.display()))?;
        let row = row(rooms, predicted, &report_json, wall_s, max_rss_kib);
        eprintln!(
            "bench: {rooms}: {} elements, {:.2} s, {:.0} MiB",
            row.elements, row.wall_s, row.peak_rss_mib
        );
        rows.push(row);
    }
    print_table(&rows);
    let csv = write_csv(&dir, &rows)?;
    eprintln!("bench: wrote {}", csv.display());
    Ok(())
}

/// `target/release/bake` of the workspace this crate was built in, else `bake` beside the
/// running executable (both are in `target/release` after `cargo build --release`).
fn default_bake() -> Result<PathBuf> {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let root = manifest.ancestors().nth(2).unwrap_or(manifest);
    let mut candidates = vec![root.join("target/release/bake")];
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        candidates.push(dir.join("bake"));
    }
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .with_context(|| {
            format!(
                "no bake binary at {}: build it with `cargo build --release --bin bake` or pass --bake",
                candidates
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(" or ")
            )
        })
}

/// Waits for the child `pid` and returns its exit status (the code, or 128 + signal) and its
/// own peak RSS in KiB. `wait4` gives the rusage of that one child, unlike
/// `getrusage(RUSAGE_CHILDREN)`, which is the maximum over every child waited for so far.
fn wait_with_rusage(pid: u32) -> Result<(i32, i64)> {
    let pid = libc::pid_t::try_from(pid).context("child pid out of range")?;
    let mut status: libc::c_int = 0;
    // SAFETY: rusage is plain old data; wait4 fills it for a child of this process.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    loop {
        // SAFETY: valid pointers to local variables; pid is our own child, not yet reaped
        // (std's Child never waits unless asked).
        let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
        if r == pid {
            break;
        }
        let err = std::io::Error::last_os_error();
        if err.kind() != std::io::ErrorKind::Interrupted {
            return Err(err).context("waiting for bake");
        }
    }
    let code = if libc::WIFEXITED(status) {
        libc::WEXITSTATUS(status)
    } else if libc::WIFSIGNALED(status) {
        128 + libc::WTERMSIG(status)
    } else {
        -1
    };
    // Linux reports ru_maxrss in KiB.
    Ok((code, usage.ru_maxrss))
}

fn row(rooms: Rooms, predicted: u64, report: &Value, wall_s: f64, max_rss_kib: i64) -> Row {
    let count = |key: &str| match &report["counts"][key] {
        Value::Null => "-".to_string(),
        v => v.to_string(),
    };
    let numbers = |key: &str| -> Vec<(String, f64)> {
        report[key]
            .as_object()
            .map(|t| {
                t.iter()
                    .filter_map(|(k, v)| v.as_f64().map(|v| (k.clone(), v)))
                    .collect()
            })
            .unwrap_or_default()
    };
    let timings = numbers("timings");
    let memory = numbers("peak_rss_mib");
    Row {
        rooms,
        polygons: count("polygons"),
        elements: count("elements"),
        predicted,
        links: count("links"),
        rays: count("rays_cast"),
        timings,
        memory,
        wall_s,
        peak_rss_mib: max_rss_kib as f64 / 1024.0,
    }
}

/// Every key of `field` over all rows, in first-seen order.
fn keys_of(rows: &[Row], field: fn(&Row) -> &Vec<(String, f64)>) -> Vec<String> {
    let mut keys: Vec<String> = Vec::new();
    for (k, _) in rows.iter().flat_map(field) {
        if !keys.contains(k) {
            keys.push(k.clone());
        }
    }
    keys
}

fn cells(rows: &[Row]) -> (Vec<String>, Vec<Vec<String>>) {
    let keys = keys_of(rows, |r| &r.timings);
    let memory_keys = keys_of(rows, |r| &r.memory);
    let mut header: Vec<String> = [
        "rooms",
        "polygons",
        "elements",
        "predicted",
        "links",
        "rays",
    ]
    .map(String::from)
    .to_vec();
    header.extend(keys.iter().map(|k| format!("{k}_s")));
    header.extend(memory_keys.iter().map(|k| format!("{k}_peak_mib")));
    header.extend(["wall_s".into(), "peak_rss_mib".into()]);
    let body = rows
        .iter()
        .map(|r| {
            let mut c = vec![
                r.rooms.to_string(),
                r.polygons.clone(),
                r.elements.clone(),
                r.predicted.to_string(),
                r.links.clone(),
                r.rays.clone(),
            ];
            let find = |values: &[(String, f64)], k: &str, digits: usize| {
                values
                    .iter()
                    .find(|(key, _)| key == k)
                    .map_or("-".into(), |(_, v)| format!("{v:.digits$}"))
            };
            for k in &keys {
                c.push(find(&r.timings, k, 4));
            }
            for k in &memory_keys {
                c.push(find(&r.memory, k, 1));
            }
            c.push(format!("{:.3}", r.wall_s));
            c.push(format!("{:.1}", r.peak_rss_mib));
            c
        })
        .collect();
    (header, body)
}

fn print_table(rows: &[Row]) {
    let (header, body) = cells(rows);
    let width: Vec<usize> = (0..header.len())
        .map(|i| {
            body.iter()
                .map(|r| r[i].len())
                .chain([header[i].len()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    for line in std::iter::once(&header).chain(&body) {
        let text: Vec<String> = line
            .iter()
            .zip(&width)
            .map(|(c, w)| format!("{c:>w$}"))
            .collect();
        println!("{}", text.join("  "));
    }
}

fn write_csv(dir: &Path, rows: &[Row]) -> Result<PathBuf> {
    let (header, body) = cells(rows);
    let mut text = header.join(",") + "\n";
    for r in body {
        text += &(r.join(",") + "\n");
    }
    let path = dir.join("bench.csv");
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}
