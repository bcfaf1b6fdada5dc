//! Shape detection on a PLY scan: segment counts, the largest planes, every cylinder and
//! sphere, and the time taken.
//!
//! ```text
//! cargo run --release -p primfit-core --example detect_scan -- SCAN.ply [--threads N]
//! ```
//!
//! Cylinder axes are reported as their angle to the largest plane's normal (the table
//! top of a table scene).

use std::path::PathBuf;
use std::time::Instant;

use primfit_core::PointIndex;
use primfit_core::detect::{DetectOptions, SurfaceModel, detect};
use primfit_core::io::read_cloud;

/// Planes listed individually.
const LISTED_PLANES: usize = 100;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut path = None;
    let mut threads = None;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--threads" => threads = args.next().map(|t| t.parse::<usize>()).transpose()?,
            _ => path = Some(PathBuf::from(a)),
        }
    }
    let path = path.ok_or("usage: detect_scan SCAN.ply [--threads N]")?;
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()?;
    }
    let cloud = read_cloud(&path)?;
    let start = Instant::now();
    let index = PointIndex::new(&cloud.points);
    let t_index = start.elapsed();
    let detection = detect(&cloud.points, &index, &DetectOptions::default())?;
    let t_all = start.elapsed();
    let n = cloud.points.len();
    let count = |kind: &str| {
        detection
            .segments
            .iter()
            .filter(|s| s.model.name() == kind)
            .count()
    };
    println!(
        "{}: {n} points, {} samples (voxel {:?})",
        path.display(),
        detection.samples,
        detection.voxel
    );
    println!(
        "noise σ = {:.5} (models judged at {:.5}), spacing = {:.5}, growing angle = {:.2}°",
        detection.noise,
        detection.model_noise,
        detection.spacing,
        detection.angle.to_degrees()
    );
    let assigned: usize = detection.segments.iter().map(|s| s.points.len()).sum();
    let clutter: usize = detection.clutter.iter().map(Vec::len).sum();
    println!(
        "segments: {} ({} planes, {} cylinders, {} spheres), clutter {} segments / {clutter} points, {assigned} points explained ({:.1} %), {} unassigned",
        detection.segments.len(),
        count("plane"),
        count("cylinder"),
        count("sphere"),
        detection.clutter.len(),
        100.0 * assigned as f64 / n as f64,
        detection.unassigned.len()
    );
    let reference = detection.segments.iter().find_map(|s| match s.model {
        SurfaceModel::Plane { normal, .. } => Some(normal),
        _ => None,
    });
    for (k, s) in detection.segments.iter().enumerate() {
        match s.model {
            SurfaceModel::Plane { point, normal } if k < LISTED_PLANES => println!(
                "  plane    {:>7} pts  rms {:.4}  normal ({:+.3}, {:+.3}, {:+.3})  at ({:+.3}, {:+.3}, {:+.3})",
                s.points.len(),
                s.rms,
                normal.x,
                normal.y,
                normal.z,
                point.x,
                point.y,
                point.z
            ),
            SurfaceModel::Plane { .. } => {}
            SurfaceModel::Cylinder {
                point,
                axis,
                radius,
                length,
            } => {
                let tilt = reference.map_or(f64::NAN, |n| {
                    axis.dot(&n).abs().min(1.0).acos().to_degrees()
                });
                println!(
                    "  cylinder {:>7} pts  rms {:.4}  radius {radius:.4}  length {length:.3}  axis∠table {tilt:.2}°  at ({:+.3}, {:+.3}, {:+.3})",
                    s.points.len(),
                    s.rms,
                    point.x,
                    point.y,
                    point.z
                );
            }
            SurfaceModel::Sphere { centre, radius } => println!(
                "  sphere   {:>7} pts  rms {:.4}  radius {radius:.4}  at ({:+.3}, {:+.3}, {:+.3})",
                s.points.len(),
                s.rms,
                centre.x,
                centre.y,
                centre.z
            ),
        }
    }
    println!(
        "time: {:.3} s (index {:.3} s, detection {:.3} s) on {} threads",
        t_all.as_secs_f64(),
        t_index.as_secs_f64(),
        (t_all - t_index).as_secs_f64(),
        rayon::current_num_threads()
    );
    Ok(())
}
