//! `walkthrough`: scale scenes and a scale benchmark for the baker (issue 11, "Walkthrough
//! scale").
//!
//! - `walkthrough office --rooms NxM OUT.gltf` writes an office floor (a grid of rooms joined by
//!   doors, two ceiling light panels, a desk and a cabinet per room; see `office.rs`) as
//!   glTF 2.0 and prints its quad and element counts at `--element-size`. Deterministic: the
//!   same options give the same bytes.
//! - `walkthrough atrium OUT.gltf` writes an open atrium (a courtyard ringed by colonnaded
//!   galleries, open to the sky, one sun; `atrium.rs`), about 164 000 polygons by default.
//! - `walkthrough bench` generates floors, runs the `bake` binary on each (one child at a time)
//!   and tabulates elements, links, rays, the report's per-stage times, wall time and the
//!   child's own peak RSS (`wait4`), also as `DIR/bench.csv`.
//!
//! It is not a test of the bake's results (it checks only that the bake succeeds), not a
//! profiler (stage times are the bake report's), and not portable beyond Unix (`wait4`).

mod bench;

use anyhow::{Context, Result};
use bake_walkthrough::{atrium, gltf, office};
use clap::{Parser, Subcommand};
use office::Rooms;
use std::path::PathBuf;

#[derive(Parser)]
#[command(version, about = "Office-floor scenes and a scale benchmark for bake")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write an office floor of N×M rooms as glTF (.gltf + .bin, or .glb).
    Office {
        /// Rooms along x × along z, e.g. 2x2 or 8x8.
        #[arg(long, default_value = "2x2")]
        rooms: Rooms,
        /// Clear width and depth of every room (m).
        #[arg(long, default_value_t = 4.0)]
        room_size: f64,
        /// Floor-to-ceiling height (m).
        #[arg(long, default_value_t = 3.0)]
        height: f64,
        /// Element size for the printed element count (the bake's --max-element-size).
        #[arg(long, default_value_t = 0.25)]
        element_size: f64,
        /// No walls between the rooms (outer walls only): every part of the floor sees every
        /// other.
        #[arg(long)]
        open_plan: bool,
        /// Output file: .gltf (writes its stem + .bin beside it) or .glb.
        out: PathBuf,
    },
    /// Write an open atrium (a courtyard ringed by colonnaded galleries, open to the sky,
    /// one sun) as glTF (.gltf + .bin, or .glb). The defaults make about 164 000 polygons.
    Atrium {
        /// Courtyard width (m).
        #[arg(long, default_value_t = 24.0)]
        courtyard: f64,
        /// Gallery depth (m).
        #[arg(long, default_value_t = 4.0)]
        gallery: f64,
        #[arg(long, default_value_t = 4)]
        storeys: usize,
        /// Storey height (m).
        #[arg(long, default_value_t = 4.0)]
        storey: f64,
        /// Column spacing along each side (m).
        #[arg(long, default_value_t = 3.0)]
        pitch: f64,
        /// Sides of each column.
        #[arg(long, default_value_t = 32)]
        facets: usize,
        /// Bands of each column.
        #[arg(long, default_value_t = 40)]
        segments: usize,
        /// Element size for the printed element count (the bake's --max-element-size).
        #[arg(long, default_value_t = 0.5)]
        element_size: f64,
        /// Output file: .gltf (writes its stem + .bin beside it) or .glb.
        out: PathBuf,
    },
    /// Generate floors and time `bake` on each.
    Bench(bench::Args),
}

fn main() -> std::process::ExitCode {
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("walkthrough: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Office {
            rooms,
            room_size,
            height,
            element_size,
            open_plan,
            out,
        } => {
            check_element_size(element_size)?;
            let floor = office::office_with(rooms, room_size, height, open_plan)
                .map_err(anyhow::Error::msg)?;
            create_parent(&out)?;
            let written = gltf::write(&floor, &out)?;
            println!(
                "{}: {rooms} rooms, {} quads, {} elements at {element_size} m ({})",
                out.display(),
                floor.quad_count(),
                floor.elements(element_size),
                written
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            Ok(())
        }
        Command::Atrium {
            courtyard,
            gallery,
            storeys,
            storey,
            pitch,
            facets,
            segments,
            element_size,
            out,
        } => {
            check_element_size(element_size)?;
            let scene = atrium::atrium(&atrium::Atrium {
                courtyard,
                gallery,
                storeys,
                storey,
                pitch,
                facets,
                segments,
            })
            .map_err(anyhow::Error::msg)?;
            create_parent(&out)?;
            gltf::write(&scene, &out)?;
            println!(
                "{}: atrium, {} quads, {} elements at {element_size} m",
                out.display(),
                scene.quad_count(),
                scene.elements(element_size)
            );
            Ok(())
        }
        Command::Bench(args) => bench::run(args),
    }
}

/// `--element-size` must be a positive number.
fn check_element_size(element_size: f64) -> Result<()> {
    if !(element_size.is_finite() && element_size > 0.0) {
        anyhow::bail!("--element-size must be a positive number, got {element_size}");
    }
    Ok(())
}

/// Creates the folder `out` is written into.
fn create_parent(out: &std::path::Path) -> Result<()> {
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    Ok(())
}
