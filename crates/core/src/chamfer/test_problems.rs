//! Small scenes (cloud and candidate sample sets) shared by the tests of the loss and of
//! its solvers.

use nalgebra::Point3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::SampleSets;

/// Two clusters of points; candidates: one on each cluster, one duplicate of the
/// first, one far away. The solution keeps exactly one per cluster.
pub(crate) fn clusters() -> (Vec<Point3<f64>>, SampleSets) {
    let cloud: Vec<Point3<f64>> = (0..20)
        .map(|k| {
            let c = if k < 10 { 0.0 } else { 5.0 };
            Point3::new(c + 0.01 * (k % 10) as f64, 0.0, 0.0)
        })
        .collect();
    let samples = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(0.09, 0.0, 0.0),
        Point3::new(5.0, 0.0, 0.0),
        Point3::new(5.09, 0.0, 0.0),
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(0.09, 0.0, 0.0),
        Point3::new(2.5, 3.0, 0.0),
    ];
    let owner = vec![0, 0, 1, 1, 2, 2, 3];
    (cloud.clone(), SampleSets::new(&samples, &owner, 4).unwrap())
}

/// A random planar problem: points on a few true segments, candidate segments on a grid.
pub(crate) fn segments(seed: u64) -> (Vec<Point3<f64>>, SampleSets) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut samples = Vec::new();
    let mut owner = Vec::new();
    let mut cloud = Vec::new();
    for i in 0..30 {
        let (x0, y0) = ((i % 6) as f64 * 0.5, (i / 6) as f64 * 0.5);
        for k in 0..10 {
            let p = Point3::new(x0 + 0.1 * k as f64, y0, 0.0);
            samples.push(p);
            owner.push(i);
            if i % 4 == 1 {
                for _ in 0..8 {
                    let jitter = rng.random_range(-0.05..0.05);
                    cloud.push(Point3::new(p.x + jitter, p.y + 0.2 * jitter, 0.0));
                }
            }
        }
    }
    (cloud, SampleSets::new(&samples, &owner, 30).unwrap())
}
