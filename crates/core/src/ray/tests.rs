//! Tests of the ray pipeline on the toys of thesis §4.3 and on simulated depth scans.

use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;
use crate::atlas::Shape;
use crate::lattice::CandidateSet;
use crate::progress::Silent;
use crate::synth::{
    SensorParams, SixInARowParams, SixVariant, axis_rotation, depth_sensor, look_at, six_in_a_row,
};
use crate::{PointCloud, Pose, Primitive};

/// The toy's model: range noise 1 cm, σ = 1 cm, one noise return per 20 m of ray.
fn toy_model() -> RayModel {
    RayModel {
        rate: 0.05,
        sigma: 0.01,
        min_cos: 0.2,
    }
}

fn scene_of(mask: u32) -> Vec<bool> {
    (0..6).map(|i| mask & (1 << i) != 0).collect()
}

/// NLL (nats) of all 64 scenes of the six-in-a-row toy, by bit mask.
fn toy_nll(variant: SixVariant) -> (Vec<f64>, Rays, Vec<Primitive>) {
    let toy = six_in_a_row(&SixInARowParams {
        variant,
        ..Default::default()
    })
    .unwrap();
    let rays = Rays::from_cloud(&toy.scene.cloud).unwrap();
    let table = RayTable::build(&rays, &toy.candidates, toy_model()).unwrap();
    let nll = (0..64u32)
        .map(|m| -table.log_likelihood(&scene_of(m)).unwrap())
        .collect();
    (nll, rays, toy.candidates)
}

/// The index of the nearest existing candidate of a scene (6 for the empty scene).
fn nearest(mask: u32) -> u32 {
    if mask == 0 { 6 } else { mask.trailing_zeros() }
}

fn check_six_in_a_row(variant: SixVariant) {
    let (nll, rays, candidates) = toy_nll(variant);
    let best = nll.iter().copied().fold(f64::INFINITY, f64::min);
    for m in 0..64u32 {
        assert!(nll[m as usize].is_finite(), "scene {m:06b}");
        if nearest(m) == 3 {
            // Scenes whose nearest candidate is the 10 m one: the best, all equal (what is
            // behind the points has no effect).
            assert!(
                nll[m as usize] - best < 1e-9,
                "scene {m:06b}: {} vs {best}",
                nll[m as usize]
            );
        } else {
            assert!(
                nll[m as usize] - best > 100.0,
                "scene {m:06b}: {} vs {best}",
                nll[m as usize]
            );
        }
        if nearest(m) > 3 {
            // Only candidates behind the points: exactly the empty scene (all noise).
            assert_eq!(nll[m as usize], nll[0], "scene {m:06b}");
        }
    }
    // The 6×6 matrix of the thesis's heatmap: nearest in front of 10 m is far worse
    // than nearest behind it, which is worse than nearest at 10 m.
    for i in 0..6u32 {
        for k in 0..6u32 {
            let v = nll[((1 << i) | (1 << k)) as usize];
            match i.min(k) {
                0..=2 => assert!(v > nll[0] + 100.0, "({i},{k})"),
                3 => assert!(v < nll[0] - 100.0, "({i},{k})"),
                _ => assert_eq!(v, nll[0]),
            }
        }
    }
    // Algorithm 2 (ray tree + table) agrees with Algorithm 1 (every ray × every candidate).
    for m in [0u32, 0b001000, 0b011000, 0b000001, 0b100101, 0b111111] {
        let naive = -naive_log_likelihood(&rays, &candidates, &scene_of(m), &toy_model()).unwrap();
        let got = nll[m as usize];
        assert!(
            (naive - got).abs() <= 1e-9 * naive.abs(),
            "{m:06b}: {naive} vs {got}"
        );
    }
}

#[test]
fn six_planar_candidates_best_scenes_have_the_10_m_one_nearest() {
    check_six_in_a_row(SixVariant::Squares);
}

#[test]
fn six_cylindrical_candidates_best_scenes_have_the_10_m_one_nearest() {
    check_six_in_a_row(SixVariant::Cylinders);
}

fn facing_square(x: f64) -> Primitive {
    Primitive::new(
        Shape::Square { side: 1.0 },
        Pose::new(axis_rotation(0), Vector3::new(x, 0.0, 0.0)),
    )
}

#[test]
fn misaligned_plane_reproduces_table_4_1() {
    // Points on a facing 1 m square at 10 m (not a candidate); candidates 20 cm in front
    // and 20 cm behind it.
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let points: Vec<Point3<f64>> = (0..100)
        .map(|_| {
            let p = Vector3::new(10.0, rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5);
            let noise = 0.005 * (rng.random::<f64>() - 0.5);
            Point3::from(p * (1.0 + noise / p.norm()))
        })
        .collect();
    let mut cloud = PointCloud::from_points(points);
    cloud.sensors = Some(vec![Point3::origin(); cloud.len()]);
    let candidates = [facing_square(9.8), facing_square(10.2)];
    let model = RayModel {
        rate: 0.05,
        sigma: 0.025,
        min_cos: 1.0,
    };
    let rays = Rays::from_cloud(&cloud).unwrap();
    let table = RayTable::build(&rays, &candidates, model).unwrap();
    let ll: Vec<f64> = [[false, false], [true, false], [false, true], [true, true]]
        .iter()
        .map(|s| table.log_likelihood(s).unwrap())
        .collect();
    let max = ll.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let z: f64 = ll.iter().map(|l| (l - max).exp()).sum();
    let prob: Vec<f64> = ll.iter().map(|l| (l - max).exp() / z).collect();
    // Empty, front only, back only, both.
    assert!((prob[0] - 0.5).abs() < 1e-3, "{prob:?}");
    assert!(prob[1] < 1e-100, "{prob:?}");
    assert!((prob[2] - 0.5).abs() < 1e-3, "{prob:?}");
    assert!(prob[3] < 1e-100, "{prob:?}");
    assert!(ll[1] - ll[0] < -300.0, "{ll:?}");
}

/// A small room scanned from a few poses, and a lattice of 1 m squares around it.
pub(crate) fn room() -> (PointCloud, Vec<Primitive>, Vec<Primitive>) {
    let sq = |axis: usize, side: f64, at: [f64; 3]| {
        Primitive::new(
            Shape::Square { side },
            Pose::new(axis_rotation(axis), Vector3::from(at)),
        )
    };
    let truth = vec![
        sq(2, 3.0, [1.5, 0.0, 0.0]), // floor x ∈ [0, 3], y ∈ [−1.5, 1.5]
        sq(0, 3.0, [3.0, 0.0, 1.5]), // wall x = 3
        sq(1, 2.0, [2.0, 1.5, 1.0]), // side wall y = 1.5
    ];
    let poses = (0..4)
        .map(|k| {
            let eye = Point3::new(0.2 + 0.2 * k as f64, -0.8 + 0.3 * k as f64, 1.2);
            look_at(eye, Point3::new(3.0, 0.3 * k as f64 - 0.3, 0.6)).unwrap()
        })
        .collect();
    let cloud = depth_sensor(
        &truth,
        &SensorParams {
            poses,
            columns: 40,
            rows: 30,
            labels: Some(vec![1, 2, 2]),
            max_range: 10.0,
            range_noise: 0.005,
            ..Default::default()
        },
    )
    .unwrap();
    let set = CandidateSet::unit_squares(&cloud);
    let candidates = (0..set.len()).map(|i| set.primitive(i)).collect();
    (cloud, truth, candidates)
}

#[test]
fn incremental_evaluation_equals_full_after_long_random_flip_sequences() {
    let (cloud, _, candidates) = room();
    let rays = Rays::from_cloud(&cloud).unwrap();
    let model = RayModel {
        rate: 0.2,
        sigma: 0.03,
        min_cos: 0.2,
    };
    let table = RayTable::build(&rays, &candidates, model).unwrap();
    let n = table.candidates() as u32;
    assert!(n > 100 && table.frames() == 4, "{n} candidates");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let start: Vec<bool> = (0..n).map(|_| rng.random::<f64>() < 0.2).collect();
    let mut state = SceneState::new(&table, start).unwrap();
    let mut flips = Vec::new();
    for step in 1..=5000 {
        flips.clear();
        for _ in 0..rng.random_range(1..=4) {
            let i = rng.random_range(0..n);
            if !flips.contains(&i) {
                flips.push(i);
            }
        }
        let delta = state.propose(&flips).unwrap();
        assert!(delta.is_finite());
        if rng.random::<f64>() < 0.5 {
            state.accept();
        } else {
            state.reject();
        }
        if step % 1000 == 0 {
            let full = table.log_likelihood(state.exists()).unwrap();
            let inc = state.log_likelihood();
            assert!(
                (full - inc).abs() <= 1e-9 * full.abs().max(1.0),
                "step {step}: {inc} vs {full}"
            );
            let per_ray = table.ray_log_likelihoods(state.exists()).unwrap();
            assert_eq!(per_ray, state.ray_log_likelihoods());
        }
    }
    // And Algorithm 1 on the final scene.
    let naive = naive_log_likelihood(&rays, &candidates, state.exists(), &model).unwrap();
    let inc = state.log_likelihood();
    assert!(
        (naive - inc).abs() <= 1e-9 * naive.abs(),
        "{naive} vs {inc}"
    );
    // A pending proposal blocks the next one; bad ids are errors.
    state.propose(&[0]).unwrap();
    assert!(state.propose(&[1]).is_err());
    state.reject();
    assert!(state.propose(&[n]).is_err());
}

#[test]
fn ray_tree_ball_search_finds_every_crossing_ray_even_behind_and_at_the_poles() {
    // Rays in every direction from one sensor (a 360° scan), points far away.
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let o = Point3::new(0.3, -0.2, 0.1);
    let mut dirs: Vec<Vector3<f64>> = (0..4000)
        .map(|_| {
            let v = Vector3::new(
                rng.random::<f64>() - 0.5,
                rng.random::<f64>() - 0.5,
                rng.random::<f64>() - 0.5,
            );
            v.normalize()
        })
        .collect();
    // Mostly forward (+x), so the seam is behind, plus exact poles and the seam itself.
    dirs.extend((0..4000).map(|k| {
        Vector3::new(
            3.0,
            (k % 63) as f64 * 0.05 - 1.5,
            (k / 63) as f64 * 0.05 - 1.5,
        )
        .normalize()
    }));
    dirs.extend([Vector3::z(), -Vector3::z(), -Vector3::x()]);
    let mut cloud = PointCloud::from_points(dirs.iter().map(|d| o + d * 50.0).collect());
    cloud.sensors = Some(vec![o; cloud.len()]);
    let rays = Rays::from_cloud(&cloud).unwrap();
    let candidates: Vec<Primitive> = vec![
        facing_square(5.0),
        facing_square(-5.0), // straight behind: across the seam
        Primitive::new(
            Shape::Sphere { diameter: 2.0 },
            Pose::new(Default::default(), Vector3::new(0.0, 0.0, 6.0)),
        ), // the pole
        Primitive::new(
            Shape::Cylinder {
                length: 3.0,
                radius: 0.5,
            },
            Pose::new(axis_rotation(1), Vector3::new(-2.0, 0.0, -3.0)),
        ),
        Primitive::new(
            Shape::Elbow {
                bend: 1.0,
                radius: 0.3,
            },
            Pose::new(axis_rotation(0), Vector3::new(1.0, 3.0, 2.0)),
        ),
        Primitive::new(
            Shape::Sphere { diameter: 3.0 },
            Pose::new(Default::default(), Vector3::new(0.5, 0.0, 0.0)),
        ), // contains the sensor
    ];
    let table = RayTable::build(&rays, &candidates, RayModel::default()).unwrap();
    for (i, c) in candidates.iter().enumerate() {
        let brute: Vec<u32> = (0..rays.len() as u32)
            .filter(|&j| c.first_hit(&o, &rays.dirs[j as usize]).is_some())
            .collect();
        assert!(!brute.is_empty(), "candidate {i}");
        assert_eq!(table.candidate_rays(i), &brute[..], "candidate {i}");
    }
}

#[test]
fn sampler_finds_the_true_toy_candidate_deterministically() {
    let toy = six_in_a_row(&SixInARowParams::default()).unwrap();
    let rays = Rays::from_cloud(&toy.scene.cloud).unwrap();
    let table = RayTable::build(&rays, &toy.candidates, toy_model()).unwrap();
    let prior = vec![0.1; 6];
    let options = McmcOptions {
        steps: 400,
        burn_in: 100,
        decay: 1.0,
        seed: 5,
        ..Default::default()
    };
    let rates = flip_rates(&table, &prior, &options).unwrap();
    assert!(rates.iter().all(|r| (r - 1.0 / 6.0).abs() < 1e-12));
    let run = sample(&table, &prior, &rates, &options, &Silent).unwrap();
    // With the prior, the extra candidates behind the points cost ln 9 each.
    assert_eq!(run.best, scene_of(1 << 3));
    assert!(run.frequency[3] > 0.9, "{:?}", run.frequency);
    assert!(
        run.frequency[..3].iter().all(|f| *f == 0.0),
        "{:?}",
        run.frequency
    );
    assert!(run.frequency.iter().all(|f| (0.0..=1.0).contains(f)));
    let again = sample(&table, &prior, &rates, &options, &Silent).unwrap();
    assert_eq!(
        (run.best, run.trace, run.accepted),
        (again.best, again.trace, again.accepted)
    );
}

#[test]
fn flip_rates_decay_with_age_and_sum_to_the_expected_flips() {
    let (cloud, _, candidates) = room();
    let rays = Rays::from_cloud(&cloud).unwrap();
    let table = RayTable::build(&rays, &candidates, RayModel::default()).unwrap();
    let prior = vec![0.1; table.candidates()];
    let options = McmcOptions {
        flips_per_step: 2.0,
        decay: 0.5,
        ..Default::default()
    };
    let rates = flip_rates(&table, &prior, &options).unwrap();
    assert!((rates.iter().sum::<f64>() - 2.0).abs() < 1e-9);
    let newest = (table.frames() - 1) as u32;
    for i in 0..table.candidates() {
        for k in 0..table.candidates() {
            let (a, b) = (table.last_seen(i), table.last_seen(k));
            if a.map_or(0, |f| f + 1) > b.map_or(0, |f| f + 1) {
                assert!(rates[i] > rates[k]);
            }
        }
        if table.last_seen(i) == Some(newest) {
            assert!(rates[i] > 0.0);
        }
    }
    assert!(
        rates
            .iter()
            .any(|r| *r < rates.iter().copied().fold(0.0, f64::max))
    );
}

#[test]
fn rays_skip_points_at_their_sensor_and_reject_bad_input() {
    let mut cloud = PointCloud::from_points(vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0)]);
    cloud.sensors = Some(vec![Point3::origin(); 2]);
    let rays = Rays::from_cloud(&cloud).unwrap();
    assert_eq!((rays.len(), rays.skipped, rays.point[0]), (1, 1, 1));
    cloud.sensors = Some(vec![Point3::origin()]);
    assert!(Rays::from_cloud(&cloud).is_err());
    cloud.sensors = Some(vec![Point3::new(f64::NAN, 0.0, 0.0); 2]);
    assert!(Rays::from_cloud(&cloud).is_err());
    let table = RayTable::build(&rays, &[facing_square(5.0)], RayModel::default()).unwrap();
    assert!(table.log_likelihood(&[true, false]).is_err());
    let bad = RayModel {
        rate: -1.0,
        ..Default::default()
    };
    assert!(RayTable::build(&rays, &[], bad).is_err());
}
