//! One bounded `plane` primitive for a whole scan: the plane by principal components, its
//! outline traced from the points (`primfit_core::atlas::fit_plane_primitive`), the
//! DESIGN §4 measures, and optionally the result JSON and the mesh.
//!
//! ```text
//! cargo run --release --example plane_outline -- SCAN.ply [--cell-spacings K] [-o result.json] [--mesh plane.ply]
//! ```
//!
//! The occupancy cell is `K` (default 3) times the scan's median point spacing. Meant for
//! scans of one planar surface (e.g. `examples/plane_scan.ply`); on a whole scene it
//! shows what a single plane of every point looks like.

use std::path::PathBuf;

use primfit_core::PointIndex;
use primfit_core::atlas::{Shape, fit_plane_primitive};
use primfit_core::metrics::{MetricsOptions, evaluate};
use primfit_core::{fit, io};
use serde_json::json;

/// Median-spacing probes (points) for the spacing estimate.
const SPACING_PROBES: usize = 10_000;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let (mut scan, mut k, mut out, mut mesh_out) = (None, 3.0, None, None);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--cell-spacings" => k = args.next().ok_or("--cell-spacings needs K")?.parse()?,
            "-o" => out = Some(PathBuf::from(args.next().ok_or("-o needs a path")?)),
            "--mesh" => mesh_out = Some(PathBuf::from(args.next().ok_or("--mesh needs a path")?)),
            _ => scan = Some(PathBuf::from(a)),
        }
    }
    let scan = scan.ok_or(
        "usage: plane_outline SCAN.ply [--cell-spacings K] [-o result.json] [--mesh plane.ply]",
    )?;
    let cloud = io::read_cloud(&scan)?;
    let index = PointIndex::new(&cloud.points);
    let spacing = index
        .median_spacing(&cloud.points, SPACING_PROBES)
        .ok_or("too few points")?;
    let cell = k * spacing;
    let started = std::time::Instant::now();
    let plane = fit_plane_primitive(&cloud.points, None, cell)?;
    let elapsed = started.elapsed();
    let Shape::Plane(shape) = &plane.shape else {
        unreachable!("fit_plane_primitive returns a plane")
    };
    let metrics = evaluate(
        &cloud.points,
        std::slice::from_ref(&plane),
        None,
        &MetricsOptions::default(),
    )?;
    println!(
        "{}: {} points, spacing {spacing:.4}, cell {cell:.4}: plane of area {:.4}, {} outline vertices, {} holes, traced in {elapsed:.2?}",
        scan.display(),
        cloud.len(),
        plane.area(),
        shape.outline().len(),
        shape.holes().len(),
    );
    println!("{}", serde_json::to_string_pretty(&metrics.to_json())?);
    if let Some(path) = out {
        let mut entry = plane.to_json();
        entry["existence"] = json!(1.0);
        io::write_json_atomic(
            &path,
            &json!({ "primfit": primfit_core::VERSION, "primitives": [entry] }),
        )?;
    }
    if let Some(path) = mesh_out {
        let (mesh, owner) = fit::primitives_mesh(std::slice::from_ref(&plane));
        io::write_mesh(&path, &mesh, Some(&owner), io::Encoding::default())?;
    }
    Ok(())
}
