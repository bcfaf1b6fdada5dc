//! Metrics: indexed vs brute force, empty model, matching, coverage, chamfer.

use nalgebra::{Point3, UnitQuaternion, Vector3};
use primfit_core::metrics::*;
use primfit_core::synth::{HallwayParams, axis_rotation, hallway, sample_shape_local};
use primfit_core::{Pose, Primitive, Shape};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_point(rng: &mut ChaCha8Rng, half: f64) -> Point3<f64> {
    Point3::new(
        rng.random_range(-half..half),
        rng.random_range(-half..half),
        rng.random_range(-half..half),
    )
}

fn random_pose(rng: &mut ChaCha8Rng, half: f64) -> Pose {
    let axis =
        nalgebra::Unit::new_normalize(random_point(rng, 1.0).coords + Vector3::new(0.0, 0.0, 1e-3));
    Pose::new(
        UnitQuaternion::from_axis_angle(&axis, rng.random_range(0.0..3.0)),
        random_point(rng, half).coords,
    )
}

/// Five primitives of different types and very different sizes (several radius classes).
fn five_primitives(rng: &mut ChaCha8Rng) -> Vec<Primitive> {
    let shapes = [
        Shape::Square { side: 1.0 },
        Shape::Disk { diameter: 0.3 },
        Shape::Cylinder {
            length: 2.0,
            radius: 0.2,
        },
        Shape::Elbow {
            bend: 0.5,
            radius: 0.1,
        },
        Shape::Sphere { diameter: 4.0 },
    ];
    shapes
        .into_iter()
        .map(|s| Primitive::new(s, random_pose(rng, 2.0)))
        .collect()
}

fn brute_force(points: &[Point3<f64>], model: &[Primitive]) -> Vec<f64> {
    points
        .iter()
        .map(|p| {
            model
                .iter()
                .map(|m| m.distance(p))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

#[test]
fn indexed_point_to_model_equals_brute_force() {
    for seed in 0..5 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let model = five_primitives(&mut rng);
        let points: Vec<_> = (0..2000).map(|_| random_point(&mut rng, 4.0)).collect();
        let fast = point_to_model_distances(&points, &model).unwrap();
        assert_eq!(fast, brute_force(&points, &model), "seed {seed}");
    }
}

#[test]
fn indexed_point_to_model_equals_brute_force_many_mixed_sizes() {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let model: Vec<Primitive> = (0..300)
        .map(|i| {
            let side = if i % 50 == 0 {
                8.0
            } else {
                rng.random_range(0.05..0.6)
            };
            Primitive::new(Shape::Square { side }, random_pose(&mut rng, 5.0))
        })
        .collect();
    let points: Vec<_> = (0..3000).map(|_| random_point(&mut rng, 6.0)).collect();
    let fast = point_to_model_distances(&points, &model).unwrap();
    assert_eq!(fast, brute_force(&points, &model));
}

#[test]
fn empty_model_reports_infinity_and_null() {
    let points = vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0)];
    let m = evaluate(&points, &[], Some(&[]), &MetricsOptions::default()).unwrap();
    assert!(m.point_to_model_mean.is_infinite() && m.point_to_model_max.is_infinite());
    assert!(m.model_to_point_mean.is_infinite() && m.chamfer.is_infinite());
    assert_eq!((m.coverage, m.compactness), (0.0, 0.0));
    let j = m.to_json();
    for key in [
        "point_to_model_mean",
        "point_to_model_p95",
        "point_to_model_max",
        "model_to_point_mean",
        "chamfer",
    ] {
        assert!(j[key].is_null(), "{key} should be null: {}", j[key]);
    }
    assert_eq!(j["scene_accuracy"], 1.0);
    assert!(evaluate(&[], &[], None, &MetricsOptions::default()).is_err());
    let no_truth = evaluate(&points, &[], None, &MetricsOptions::default())
        .unwrap()
        .to_json();
    assert!(no_truth.get("precision").is_none());
}

#[test]
fn metrics_of_a_small_problem_by_hand() {
    // One unit square in z = 0; points at heights 0, 0.1, 0.2, 0.3 over its centre.
    let model = vec![Primitive::new(
        Shape::Square { side: 1.0 },
        Pose::identity(),
    )];
    let cloud: Vec<_> = (0..4)
        .map(|k| Point3::new(0.0, 0.0, 0.1 * k as f64))
        .collect();
    let opts = MetricsOptions {
        coverage_tau: Some(0.15),
        sample_spacing: Some(0.5),
        match_tolerance: None,
    };
    let m = evaluate(&cloud, &model, None, &opts).unwrap();
    assert!((m.point_to_model_mean - 0.15).abs() < 1e-12);
    assert!((m.point_to_model_max - 0.3).abs() < 1e-12);
    assert!((m.point_to_model_p95 - 0.3).abs() < 1e-12);
    assert_eq!(m.coverage, 0.5);
    // Model samples at spacing 0.5: the four points (±0.25, ±0.25, 0), each √0.125 from the origin.
    let samples = model_samples(&model, 0.5).unwrap();
    assert_eq!(samples.len(), 4);
    let s2: f64 = samples
        .iter()
        .map(|s| {
            cloud
                .iter()
                .map(|c| (s - c).norm_squared())
                .fold(f64::INFINITY, f64::min)
        })
        .sum();
    assert!((m.chamfer - (0.01 + 0.04 + 0.09 + s2)).abs() < 1e-12);
    assert!((m.model_to_point_mean - 0.125f64.sqrt()).abs() < 1e-12);
    assert!((m.compactness - 8.0 / 12.0).abs() < 1e-12);
    let j = m.to_json();
    for key in [
        "point_to_model_mean",
        "point_to_model_p95",
        "point_to_model_max",
        "model_to_point_mean",
        "coverage",
        "coverage_tau",
        "chamfer",
        "compactness",
    ] {
        assert!(j[key].is_number(), "{key}");
    }
}

#[test]
fn coverage_is_monotone_in_tau() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let model = five_primitives(&mut rng);
    let points: Vec<_> = (0..1000).map(|_| random_point(&mut rng, 3.0)).collect();
    let d = point_to_model_distances(&points, &model).unwrap();
    let mut last = -1.0;
    for k in 0..=40 {
        let c = coverage(&d, 0.05 * k as f64);
        assert!(c >= last && (0.0..=1.0).contains(&c));
        last = c;
    }
    assert_eq!(coverage(&d, f64::MAX), 1.0);
    assert!(coverage(&d, 0.0) < 0.01);
}

#[test]
fn precision_recall_on_known_matches_and_mismatches() {
    let scene = hallway(&HallwayParams::default()).unwrap();
    let truth = scene.truth.clone();
    let n = truth.len();
    let exact = match_primitives(&truth, &truth, 0.05, 0.1).unwrap();
    assert_eq!(
        (exact.precision, exact.recall, exact.scene_accuracy),
        (1.0, 1.0, 1.0)
    );
    assert!(exact.pairs.iter().all(|(i, j)| i == j));

    // Drop two, add one shifted by a lattice step (0.5 m) and one of another size.
    let mut fitted: Vec<Primitive> = truth[2..].to_vec();
    let mut shifted = truth[0].clone();
    shifted.pose.translation += Vector3::new(0.5, 0.0, 0.0) + Vector3::new(0.0, 0.0, 5.0);
    fitted.push(shifted);
    fitted.push(Primitive::new(
        Shape::Square { side: 1.0 + 1e-3 },
        truth[1].pose,
    ));
    let m = match_primitives(&fitted, &truth, 0.05, 0.1).unwrap();
    assert_eq!(m.pairs.len(), n - 2);
    assert!((m.precision - (n - 2) as f64 / n as f64).abs() < 1e-12);
    assert!((m.recall - (n - 2) as f64 / n as f64).abs() < 1e-12);
    assert_eq!(m.scene_accuracy, 0.0);

    // A small in-plane shift (2 cm) still matches; a duplicate does not match twice.
    let mut nudged = truth[0].clone();
    nudged.pose.translation += Vector3::new(0.02, 0.0, 0.0);
    let m = match_primitives(&[nudged.clone(), nudged], &truth[..1], 0.05, 0.05).unwrap();
    assert_eq!(
        (m.pairs.len(), m.precision, m.recall, m.scene_accuracy),
        (1, 0.5, 1.0, 0.0)
    );

    // Relative tolerance through evaluate: the truth itself is a perfect scene.
    let e = evaluate(
        &scene.cloud.points,
        &truth,
        Some(&truth),
        &MetricsOptions::default(),
    )
    .unwrap();
    let t = e.truth.unwrap();
    assert_eq!((t.precision, t.recall, t.scene_accuracy), (1.0, 1.0, 1.0));
}

#[test]
fn same_type_and_size_respects_types_and_scale() {
    let sq = Primitive::new(Shape::Square { side: 1.0 }, Pose::identity());
    let disk = Primitive::new(Shape::Disk { diameter: 1.0 }, Pose::identity());
    let big = Primitive::new(
        Shape::Square { side: 0.5 },
        Pose {
            scale: 2.0,
            ..Pose::identity()
        },
    );
    let off = Primitive::new(Shape::Square { side: 1.0 + 1e-5 }, Pose::identity());
    assert!(!same_type_and_size(&sq, &disk));
    assert!(same_type_and_size(&sq, &big));
    assert!(!same_type_and_size(&sq, &off));
    let rot = Primitive::new(
        Shape::Square { side: 1.0 },
        Pose::new(axis_rotation(0), Vector3::zeros()),
    );
    assert!(surface_distance(&sq, &sq, 0.05) < 1e-12);
    assert!(surface_distance(&sq, &rot, 0.05) > 0.1);
}

#[test]
fn truth_model_fits_its_own_scene() {
    let scene = hallway(&HallwayParams::default()).unwrap();
    let m = evaluate(
        &scene.cloud.points,
        &scene.truth,
        None,
        &MetricsOptions::default(),
    )
    .unwrap();
    assert!(
        m.point_to_model_mean < 0.012 && m.point_to_model_max < 0.06,
        "{m:?}"
    );
    assert!(m.model_to_point_mean < 0.1, "{m:?}");
    // Default τ = twice the median nearest-neighbour distance: ~0.1 m at 100 points/m²,
    // well above the 1 cm jitter, so (almost) everything is covered.
    assert!(
        m.coverage_tau > 0.03 && m.coverage_tau < 0.2,
        "τ = {}",
        m.coverage_tau
    );
    assert!(m.coverage > 0.999, "coverage {}", m.coverage);
}

#[test]
fn elbow_random_samples_are_area_uniform() {
    // Share of points on the outer half (cos ψ > 0) is (πB + 2r) / (2πB).
    let (b, r) = (0.5, 0.1);
    let shape = Shape::Elbow { bend: b, radius: r };
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n = 40_000;
    let outer = (0..n)
        .filter(|_| {
            let p = sample_shape_local(&shape, &mut rng);
            (p.x * p.x + p.y * p.y).sqrt() > b
        })
        .count() as f64
        / n as f64;
    let expected = (std::f64::consts::PI * b + 2.0 * r) / (2.0 * std::f64::consts::PI * b);
    assert!(
        (outer - expected).abs() < 0.01,
        "outer share {outer}, expected {expected}"
    );
    for s in [
        shape,
        Shape::Cylinder {
            length: 1.0,
            radius: 0.3,
        },
        Shape::Disk { diameter: 1.0 },
        Shape::Sphere { diameter: 2.0 },
    ] {
        let prim = Primitive::new(s, Pose::identity());
        assert!((0..500).all(|_| prim.distance(&sample_shape_local(&prim.shape, &mut rng)) < 1e-9));
    }
}

#[test]
fn percentile_nearest_rank() {
    let v: Vec<f64> = (1..=100).map(f64::from).collect();
    assert_eq!(percentile(&v, 0.95), 95.0);
    assert_eq!(percentile(&v, 1.0), 100.0);
    assert_eq!(percentile(&v, 0.0), 1.0);
    assert!(percentile(&[], 0.5).is_nan());
}
