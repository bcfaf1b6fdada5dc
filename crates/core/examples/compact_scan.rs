//! The compact model of a scan (`--types auto`'s pipeline) with its measures: counts by
//! type, the largest planes, every cylinder (radius, axis angle to the largest plane's
//! normal), point→model, model→point, coverage, and the time taken.
//!
//! ```text
//! cargo run --release -p primfit-core --example compact_scan -- SCAN.ply [--mesh OUT.ply]
//! ```

use std::path::PathBuf;
use std::time::Instant;

use primfit_core::PointIndex;
use primfit_core::Silent;
use primfit_core::compact::{CompactOptions, compact_model};
use primfit_core::fit::primitives_mesh;
use primfit_core::io::{Encoding, read_cloud, write_mesh};
use primfit_core::metrics::{MetricsOptions, evaluate};
use primfit_core::{Primitive, Shape};

/// Planes listed individually.
const LISTED_PLANES: usize = 8;

fn axis_z(p: &Primitive) -> primfit_core::na::Vector3<f64> {
    p.pose.rotation * primfit_core::na::Vector3::z()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let (mut path, mut mesh) = (None, None);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--mesh" => mesh = args.next().map(PathBuf::from),
            _ => path = Some(PathBuf::from(a)),
        }
    }
    let path = path.ok_or("usage: compact_scan SCAN.ply [--mesh OUT.ply]")?;
    let cloud = read_cloud(&path)?;
    let start = Instant::now();
    let index = PointIndex::new(&cloud.points);
    let model = compact_model(&cloud.points, &index, &CompactOptions::default(), &Silent)?;
    let seconds = start.elapsed().as_secs_f64();
    let prims = &model.primitives;
    let count = |k: &str| prims.iter().filter(|p| p.shape.kind().name() == k).count();
    println!(
        "{}: {} points; {} segments → {} proposed → {} primitives ({} planes, {} cylinders, {} spheres) in {seconds:.2} s (detect {:.2} s, existence {:.2} s)",
        path.display(),
        cloud.points.len(),
        model.detection.segments.len(),
        model.proposed,
        prims.len(),
        count("plane"),
        count("cylinder"),
        count("sphere"),
        model.detect_seconds,
        model.existence_seconds
    );
    println!(
        "σ = {:.5}, spacing = {:.5}, cap = {:.5}",
        model.detection.model_noise, model.detection.spacing, model.cap
    );
    let mut planes: Vec<&Primitive> = prims
        .iter()
        .filter(|p| matches!(p.shape, Shape::Plane(_)))
        .collect();
    planes.sort_by(|a, b| b.area().total_cmp(&a.area()));
    let reference = planes.first().map(|p| axis_z(p));
    for p in planes.iter().take(LISTED_PLANES) {
        let n = axis_z(p);
        if let Shape::Plane(s) = &p.shape {
            println!(
                "  plane area {:.4} m², {} vertices, normal ({:.3}, {:.3}, {:.3})",
                p.area(),
                s.vertex_count(),
                n.x,
                n.y,
                n.z
            );
        }
    }
    for p in prims {
        if let Shape::Cylinder { length, radius } = p.shape {
            // The plane the cylinder stands on: the one nearest to its lower end.
            let a = axis_z(p);
            let ends = [
                p.pose
                    .to_scene(&primfit_core::na::Point3::new(0.0, 0.0, -length / 2.0)),
                p.pose
                    .to_scene(&primfit_core::na::Point3::new(0.0, 0.0, length / 2.0)),
            ];
            let base = planes.iter().min_by(|x, y| {
                let d = |q: &&Primitive| {
                    ends.iter()
                        .map(|e| q.distance(e))
                        .fold(f64::INFINITY, f64::min)
                };
                d(x).total_cmp(&d(y))
            });
            let angle = base.map_or(f64::NAN, |b| {
                axis_z(b).dot(&a).abs().min(1.0).acos().to_degrees()
            });
            let _ = reference;
            println!(
                "  cylinder r = {radius:.4}, length {length:.4}, axis {angle:.1}° from the normal of the plane nearest its ends, at {:?}",
                p.pose.translation.as_slice()
            );
        }
    }
    let m = evaluate(&cloud.points, prims, None, &MetricsOptions::default())?;
    println!(
        "point→model {:.5}, model→point {:.5}, coverage@{:.4} {:.3}",
        m.point_to_model_mean, m.model_to_point_mean, m.coverage_tau, m.coverage
    );
    if let Some(out) = mesh {
        let (mesh, owner) = primitives_mesh(prims);
        write_mesh(&out, &mesh, Some(&owner), Encoding::BinaryLittleEndian)?;
        println!("mesh written to {}", out.display());
    }
    Ok(())
}
