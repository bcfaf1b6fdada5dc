//! Tests of the free-space cost: the closed form against brute-force ray marching, and
//! its independence from the thread count.

use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{FreeSpace, Rays, marched_free_space};
use crate::lattice::CandidateSet;
use crate::synth::{axis_rotation, ray_scene};
use crate::{Pose, Primitive, Shape};

/// The box-before-a-wall scene at a few pixels per frame, and candidates: the lattice
/// squares near its points (every third), a square floating in the open, a cylinder.
fn small_scene() -> (Rays, Vec<Primitive>) {
    let scene = ray_scene("object", 12, 9, 5).unwrap();
    let set = CandidateSet::unit_squares(&scene.cloud);
    let mut candidates: Vec<Primitive> = (0..set.len())
        .step_by(3)
        .map(|i| set.primitive(i))
        .collect();
    candidates.push(Primitive::new(
        Shape::Square { side: 1.0 },
        Pose::new(axis_rotation(0), Vector3::new(1.0, 0.0, 1.0)),
    ));
    candidates.push(Primitive::new(
        Shape::Cylinder {
            length: 1.0,
            radius: 0.2,
        },
        Pose::new(axis_rotation(2), Vector3::new(1.2, -0.8, 0.5)),
    ));
    candidates.extend(scene.truth.iter().cloned());
    (Rays::from_cloud(&scene.cloud).unwrap(), candidates)
}

#[test]
fn closed_form_equals_brute_force_ray_marching() {
    let (rays, candidates) = small_scene();
    let d_cap = 0.25;
    let free = FreeSpace::build(&rays, &candidates, d_cap).unwrap();
    assert_eq!(free.scale, 1.0);
    assert!(
        free.crossings.iter().sum::<usize>() > 100,
        "{:?}",
        free.crossings
    );
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for trial in 0..4 {
        let exists: Vec<bool> = (0..candidates.len())
            .map(|i| trial == 0 || i % (trial + 1) == 0 || rng.random::<f64>() < 0.3)
            .collect();
        let closed = free.binary_value(&exists).unwrap();
        let marched = marched_free_space(&rays, &candidates, &exists, d_cap, 1e-10).unwrap();
        // A ray that meets a candidate's edge to within ~1e-7 counts on either side (one
        // ray of this scene crosses the floor on the edge shared by two squares), so the
        // two agree to a few 1e-7 of the total, not to rounding.
        assert!(
            (closed - marched).abs() <= 1e-6 * marched.max(1.0),
            "trial {trial}: {closed} vs {marched}"
        );
        assert!(marched > 0.0);
    }
}

#[test]
fn a_floating_square_pays_for_every_ray_through_it_and_the_truth_almost_nothing() {
    let scene = ray_scene("object", 16, 12, 1).unwrap();
    let rays = Rays::from_cloud(&scene.cloud).unwrap();
    let floating = Primitive::new(
        Shape::Square { side: 1.0 },
        Pose::new(axis_rotation(0), Vector3::new(1.0, 0.0, 1.0)),
    );
    let mut candidates = scene.truth.clone();
    candidates.push(floating);
    let d_cap = 0.25;
    let free = FreeSpace::build(&rays, &candidates, d_cap).unwrap();
    let last = candidates.len() - 1;
    // Every point behind the square is more than 0.5 m from it: each ray pays d_cap.
    assert!(free.crossings[last] > 20);
    assert!((free.cost[last] - d_cap * free.crossings[last] as f64).abs() < 1e-9);
    // The true surfaces are crossed only by rays whose noisy points lie just behind them.
    for i in 0..last {
        let per_crossing = free.cost[i] / free.crossings[i].max(1) as f64;
        assert!(per_crossing < 1e-3, "truth {i}: {per_crossing}");
    }
}

#[test]
fn costs_do_not_depend_on_the_thread_count() {
    let (rays, candidates) = small_scene();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| FreeSpace::build(&rays, &candidates, 0.25).unwrap())
    };
    let one = run(1);
    assert_eq!(one, run(3));
}

#[test]
fn costs_add_up_over_rays() {
    let (mut rays, candidates) = small_scene();
    let full = FreeSpace::build(&rays, &candidates, 0.25).unwrap();
    // Every ray three times: three times the cost.
    let n = rays.len();
    for _ in 0..2 {
        for j in 0..n {
            rays.frame.push(rays.frame[j]);
            rays.dirs.push(rays.dirs[j]);
            rays.ranges.push(rays.ranges[j]);
            rays.point.push(rays.point[j]);
        }
    }
    let tripled = FreeSpace::build(&rays, &candidates, 0.25).unwrap();
    for (a, b) in full.cost.iter().zip(&tripled.cost) {
        assert!((3.0 * a - b).abs() <= 1e-9 * b.max(1.0));
    }
}

#[test]
fn bad_input_is_an_error() {
    let (rays, candidates) = small_scene();
    assert!(FreeSpace::build(&rays, &candidates, -1.0).is_err());
    let free = FreeSpace::build(&rays, &candidates, 0.25).unwrap();
    assert!(free.value(&[0.5]).is_err());
    assert!(marched_free_space(&rays, &candidates, &[true], 0.25, 1e-7).is_err());
}
