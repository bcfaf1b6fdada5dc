//! Unit tests of the translation votes.

use super::*;
use crate::atlas::Shape;
use crate::register::particle_filter::random_rotation;
use crate::synth::{RegistrationParams, asymmetric_object, registration};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// With the true rotation, the best peak of a vote over the whole scene box is
/// within 4 % of the model size of the true translation (half a vote cell), 2 % on
/// average, for 100 object points among 1900 uniform outliers (the grid and samples
/// of the filter's defaults); and the
/// votes rank rotations: the true one's peak beats that of 3 in 4 random rotations.
#[test]
fn the_vote_peak_recovers_a_known_translation_at_95_percent_outliers() {
    let mesh = asymmetric_object();
    let (lo, hi) = crate::cloud::bounds_of(&mesh.mesh.vertices).unwrap();
    let size = (hi - lo).norm();
    let d = crate::register::RegisterOptions::default();
    let samples = Shape::Mesh(mesh.clone()).sample_surface(d.vote_spacing * size);
    let rotate = |r: &nalgebra::UnitQuaternion<f64>| -> Vec<Vector3<f64>> {
        samples.iter().map(|m| r * m.coords).collect()
    };
    let mut total = 0.0;
    for seed in 0..6 {
        let scene = registration(
            &mesh,
            &RegistrationParams {
                inliers: 100,
                outliers: 1900,
                translation: 0.25 * size,
                seed,
                ..Default::default()
            },
        )
        .unwrap();
        let truth = scene.truth[0].pose;
        let index = VoteIndex::new(&scene.cloud.points, d.vote_bin * size);
        // Domain: every translation that keeps the model's origin in the scene box.
        let (slo, shi) = crate::cloud::bounds_of(&scene.cloud.points).unwrap();
        let peaks = vote_translation(&index, &rotate(&truth.rotation), &slo, &shi, 2, 2);
        assert_eq!(peaks.len(), 2);
        let err = (peaks[0].translation - truth.translation).norm() / size;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let beaten = (0..40)
            .filter(|_| {
                let wrong = random_rotation(&mut rng);
                let bad = vote_translation(&index, &rotate(&wrong), &slo, &shi, 1, 0);
                bad[0].votes < peaks[0].votes
            })
            .count();
        println!(
            "seed {seed}: error {:.2} %, votes {:?}, beats {beaten}/40 random rotations",
            100.0 * err,
            peaks.iter().map(|p| p.votes).collect::<Vec<_>>()
        );
        assert!(
            err < 0.04,
            "seed {seed}: error {:.2} % of the size",
            100.0 * err
        );
        total += err;
        assert!(beaten >= 30, "seed {seed}: beats only {beaten}/40");
    }
    assert!(
        total / 6.0 < 0.02,
        "mean error {:.2} %",
        100.0 * total / 6.0
    );
}

#[test]
fn bad_input_gives_no_peaks() {
    let points = vec![Point3::new(0.0, 0.0, 0.0), Point3::new(f64::NAN, 0.0, 0.0)];
    let index = VoteIndex::new(&points, 0.1);
    assert_eq!(index.len(), 1);
    let o = [Vector3::zeros()];
    let (lo, hi) = (Point3::new(-1.0, -1.0, -1.0), Point3::new(1.0, 1.0, 1.0));
    let p = vote_translation(&index, &o, &lo, &hi, 2, 1);
    assert_eq!(p.len(), 1);
    assert!(p[0].translation.norm() < 1e-9, "{p:?}");
    assert!(vote_translation(&index, &o, &hi, &lo, 2, 1).is_empty());
    assert!(vote_translation(&index, &[], &lo, &hi, 2, 1).is_empty());
    let nan = [Vector3::repeat(f64::NAN)];
    assert!(vote_translation(&index, &nan, &lo, &hi, 2, 1).is_empty());
    let inf = Point3::new(f64::INFINITY, 0.0, 0.0);
    assert!(vote_translation(&index, &o, &lo, &inf, 2, 1).is_empty());
    assert!(vote_translation(&index, &o, &lo, &hi, 0, 1).is_empty());
    let empty = VoteIndex::new(&[], 0.1);
    assert!(empty.is_empty());
    assert!(vote_translation(&empty, &o, &lo, &hi, 2, 1).is_empty());
    for cell in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let index = VoteIndex::new(&points, cell);
        assert_eq!(vote_translation(&index, &o, &lo, &hi, 1, 1).len(), 1);
    }
    // A huge domain is clipped to the translations the points can vote for.
    let (big_lo, big_hi) = (
        Point3::new(-1e300, -1e6, -1e6),
        Point3::new(1e300, 1e6, 1e6),
    );
    let p = vote_translation(&index, &o, &big_lo, &big_hi, 1, 1);
    assert_eq!(p.len(), 1);
    assert!(p[0].translation.norm() < 1e-9);
    assert_eq!(
        mean_shift(&index, &o, Vector3::zeros(), f64::NAN, 3).votes,
        0.0
    );
}

#[test]
fn window_sums_are_the_brute_force_three_by_three_by_three_sums() {
    let bins = HistogramBins {
        ulo: [0, 0, 0],
        dims: [5, 4, 3],
    };
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let hist: Vec<f32> = (0..60)
        .map(|_| (rng.random::<f64>() * 10.0).floor() as f32)
        .collect();
    let window = bins.window_sums(&hist);
    let at = |x: i64, y: i64, z: i64| {
        let inside = (0..5).contains(&x) && (0..4).contains(&y) && (0..3).contains(&z);
        if inside {
            hist[(x + 5 * (y + 4 * z)) as usize]
        } else {
            0.0
        }
    };
    for z in 0..3i64 {
        for y in 0..4i64 {
            for x in 0..5i64 {
                let mut expected = 0.0;
                for d in 0..27i64 {
                    expected += at(x + d % 3 - 1, y + (d / 3) % 3 - 1, z + d / 9 - 1);
                }
                assert_eq!(
                    window[(x + 5 * (y + 4 * z)) as usize],
                    expected,
                    "bin {x} {y} {z}"
                );
            }
        }
    }
}

#[test]
fn forward_window_sums_are_the_brute_force_sums() {
    let n = 6;
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let count: Vec<u32> = (0..n * n * n)
        .map(|_| (rng.random::<f64>() * 5.0) as u32)
        .collect();
    let sums = forward_window_sums(&count, n);
    for z in 0..n - 2 {
        for y in 0..n - 2 {
            for x in 0..n - 2 {
                let expected: u32 = (0..27)
                    .map(|d| count[(x + d % 3) + n * ((y + (d / 3) % 3) + n * (z + d / 9))])
                    .sum();
                assert_eq!(sums[x + n * (y + n * z)], expected, "window at {x} {y} {z}");
            }
        }
    }
}

#[test]
fn floor_without_a_call_is_floor() {
    for v in [
        -2.5, -2.0, -1e-12, 0.0, 1e-12, 0.999_999, 1.0, 3.7, -1e15, 1e15,
    ] {
        assert_eq!(floor_to_i64(v), v.floor() as i64, "{v}");
    }
}
