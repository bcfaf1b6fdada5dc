//! How much the default fit depends on the order of the points: fits a scan as read and
//! permuted by several seeds, and prints each model's primitive count, double cover
//! (`metrics::double_cover_share`) and point→model mean; with `--pairs`, every pair of
//! primitives that covers area twice; with `--list`, every primitive.
//!
//! ```text
//! cargo run --release -p primfit-core --example order_study -- SCAN.ply [PERMUTATIONS] [--pairs] [--list]
//! ```

use std::path::PathBuf;

use primfit_core::fit::{FitOptions, fit};
use primfit_core::io::read_cloud;
use primfit_core::metrics::{MetricsOptions, default_coverage_tau, double_cover_share, evaluate};
use primfit_core::{PointCloud, Silent};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let usage = "usage: order_study SCAN.ply [PERMUTATIONS] [--pairs] [--list]";
    let (mut path, mut permutations, mut pairs, mut list) = (None, 8u64, false, false);
    for a in std::env::args().skip(1) {
        match a.as_str() {
            "--pairs" => pairs = true,
            "--list" => list = true,
            _ if path.is_none() => path = Some(PathBuf::from(a)),
            _ => permutations = a.parse().map_err(|_| usage)?,
        }
    }
    let path = path.ok_or(usage)?;
    let cloud = read_cloud(&path)?;
    let h = default_coverage_tau(&cloud.points);
    for seed in 0..=permutations {
        let mut order: Vec<usize> = (0..cloud.len()).collect();
        if seed > 0 {
            order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        }
        let shuffled = PointCloud::from_points(order.iter().map(|&i| cloud.points[i]).collect());
        let result = fit(&shuffled, &FitOptions::default(), &Silent)?;
        let prims = &result.primitives;
        let double = double_cover_share(prims, h, h / 2.0)?;
        let m = evaluate(&shuffled.points, prims, None, &MetricsOptions::default())?;
        println!(
            "permutation {seed}: {} primitives, double cover {:.2} %, point→model {:.5}",
            prims.len(),
            100.0 * double,
            m.point_to_model_mean
        );
        if list {
            for p in prims {
                let c = p.center();
                println!(
                    "    {} {:.3} m² at {:.2?}: {:?}",
                    p.shape.kind().name(),
                    p.area(),
                    c.coords.as_slice(),
                    p.shape
                );
            }
        }
        if pairs {
            print_pairs(prims, h)?;
        }
    }
    Ok(())
}

/// Every pair of primitives that covers area twice: their kinds, areas, centres, normals,
/// the angle between them and the doubly covered area (scene units²).
fn print_pairs(
    prims: &[primfit_core::Primitive],
    h: f64,
) -> Result<(), Box<dyn std::error::Error>> {
    use primfit_core::na::Vector3;
    let z = |p: &primfit_core::Primitive| p.pose.rotation * Vector3::z();
    for i in 0..prims.len() {
        for j in i + 1..prims.len() {
            let pair = [prims[i].clone(), prims[j].clone()];
            let share = double_cover_share(&pair, h, h / 2.0)?;
            if share > 0.0 {
                let (a, b) = (&prims[i], &prims[j]);
                let angle = z(a).dot(&z(b)).abs().min(1.0).acos().to_degrees();
                let c = |p: &primfit_core::Primitive| {
                    p.pose.to_scene(&primfit_core::na::Point3::origin())
                };
                println!(
                    "  {i} {} {:.4} m² at {:.3?} / {j} {} {:.4} m² at {:.3?}: {:.1}°, offset {:.4}, twice {:.4} m²",
                    a.shape.kind().name(),
                    a.area(),
                    c(a).coords.as_slice(),
                    b.shape.kind().name(),
                    b.area(),
                    c(b).coords.as_slice(),
                    angle,
                    z(a).dot(&(c(b) - c(a))).abs(),
                    share * (a.area() + b.area())
                );
            }
        }
    }
    Ok(())
}
