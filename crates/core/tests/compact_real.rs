//! Issue 14's targets for the default fit (the compact model, no options) on the bundled
//! real scan `examples/table_mug.ply` (PCL's stereo table-and-mug scan, 209 280 points):
//!
//! - the mug is one cylinder of radius 0.040 ± 0.003 m whose axis is within 5° of the
//!   table's normal;
//! - the table top is at most 3 primitives;
//! - at most 40 primitives in all;
//! - under 1 % of the model's area covered twice (another primitive within h along the
//!   normal, `metrics::double_cover_share`), also with the points in another order.

use std::path::Path;

use primfit_core::fit::{FitOptions, fit};
use primfit_core::io::read_cloud;
use primfit_core::metrics::{default_coverage_tau, double_cover_share, overlap_share};
use primfit_core::na::{Point3, Vector3};
use primfit_core::{PointCloud, Silent};
use primfit_core::{Primitive, Shape};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

/// The mug's radius (m), measured by hand on the scan: its rim spans 0.080 m.
const MUG_RADIUS: f64 = 0.040;
const MUG_RADIUS_TOLERANCE: f64 = 0.003;
const MUG_AXIS_DEG: f64 = 5.0;
const MAX_TABLE_PRIMITIVES: usize = 3;
const MAX_PRIMITIVES: usize = 40;
/// A primitive lies on the table top when its normal is within this angle (degrees) of
/// the table's and its centre within [`ON_TABLE_DISTANCE`] of the table's plane.
const ON_TABLE_DEG: f64 = 5.0;
const ON_TABLE_DISTANCE: f64 = 0.01;
/// Largest share of model area covered twice.
const MAX_DOUBLE_COVER: f64 = 0.01;
/// The seed of the other order of the points (`examples/order_study.rs`, permutation 6).
const PERMUTATION_SEED: u64 = 6;
/// The table top is nearer than this to the camera (m).
const TABLE_RANGE: f64 = 1.5;

fn normal(p: &Primitive) -> Vector3<f64> {
    p.pose.rotation * Vector3::z()
}

fn degrees(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.normalize()
        .dot(&b.normalize())
        .abs()
        .min(1.0)
        .acos()
        .to_degrees()
}

fn centre(p: &Primitive) -> Point3<f64> {
    p.pose.to_scene(&Point3::origin())
}

fn table_scan() -> PointCloud {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/table_mug.ply");
    read_cloud(&path).unwrap()
}

/// The share of the model's area covered twice, at h = 2 point spacings of `cloud`.
fn double_cover(cloud: &PointCloud, prims: &[Primitive]) -> f64 {
    let h = default_coverage_tau(&cloud.points);
    let double = double_cover_share(prims, h, h / 2.0).unwrap();
    let literal = overlap_share(prims, h, h / 2.0).unwrap();
    eprintln!("double cover {double:.4}, literal overlap {literal:.4} (h = {h:.4})");
    double
}

#[test]
fn the_table_scan_is_a_table_top_a_mug_and_a_few_more() {
    let cloud = table_scan();
    let result = fit(&cloud, &FitOptions::default(), &Silent).unwrap();
    let prims = &result.primitives;
    let area = |p: &Primitive| p.area();
    let planes: Vec<&Primitive> = prims
        .iter()
        .filter(|p| matches!(p.shape, Shape::Plane(_)))
        .collect();
    // The table top: the largest plane nearer than the far wall (the scan is in the
    // camera's frame; the table is 0.7–1.2 m away, the wall 2.1 m).
    let table = *planes
        .iter()
        .filter(|p| centre(p).coords.norm() < TABLE_RANGE)
        .max_by(|a, b| area(a).total_cmp(&area(b)))
        .expect("a plane");
    let (n, c) = (normal(table), centre(table));
    let on_table = prims
        .iter()
        .filter(|p| {
            matches!(p.shape, Shape::Plane(_))
                && degrees(&normal(p), &n) < ON_TABLE_DEG
                && n.dot(&(centre(p) - c)).abs() < ON_TABLE_DISTANCE
        })
        .count();
    let mug: Vec<(f64, f64)> = prims
        .iter()
        .filter_map(|p| match p.shape {
            Shape::Cylinder { radius, .. } => Some((radius, degrees(&normal(p), &n))),
            _ => None,
        })
        .filter(|(r, _)| (r - MUG_RADIUS).abs() <= MUG_RADIUS_TOLERANCE)
        .collect();
    eprintln!(
        "{} primitives ({} planes), {on_table} on the table top, mug candidates (radius, axis°) {mug:?}",
        prims.len(),
        planes.len()
    );
    assert!(prims.len() <= MAX_PRIMITIVES, "{} primitives", prims.len());
    assert!((1..=MAX_TABLE_PRIMITIVES).contains(&on_table), "{on_table}");
    assert_eq!(mug.len(), 1, "{mug:?}");
    assert!(mug[0].1 <= MUG_AXIS_DEG, "{mug:?}");
    // No surface covered twice: under 1 % of the model's area has another primitive
    // within h = 2 point spacings along its normal (the stereo depth layers of the far
    // wall once came out as interleaved planes covering it three times).
    let double = double_cover(&cloud, prims);
    assert!(double < MAX_DOUBLE_COVER, "{double}");
}

/// The same points in another order. Which of the far wall's depth layers and tilted
/// patches become planes depends on how ties between equidistant neighbours fall; this
/// order once covered 2.9 % of the model twice (two patches tilted 8–11° crossing the
/// wall's plane), until planes gave up what a larger primitive covers
/// (`compact/trim.rs`).
#[test]
fn the_table_scan_in_another_order_covers_no_surface_twice() {
    let cloud = table_scan();
    let mut order: Vec<usize> = (0..cloud.len()).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(PERMUTATION_SEED));
    let shuffled = PointCloud::from_points(order.iter().map(|&i| cloud.points[i]).collect());
    let result = fit(&shuffled, &FitOptions::default(), &Silent).unwrap();
    let prims = &result.primitives;
    eprintln!("{} primitives", prims.len());
    assert!(prims.len() <= MAX_PRIMITIVES, "{} primitives", prims.len());
    let double = double_cover(&shuffled, prims);
    assert!(double < MAX_DOUBLE_COVER, "{double}");
}
