//! Unit tests of the lattice.

use super::*;
use crate::atlas::ShapeKind;

fn spec() -> LatticeSpec {
    LatticeSpec {
        shapes: vec![Shape::Square { side: 1.0 }],
        spacing: 0.5,
        origin: Point3::origin(),
        frame: UnitQuaternion::identity(),
        sample_spacing: 0.1,
    }
}

#[test]
fn orientation_counts() {
    assert_eq!(orientations(ShapeKind::Square).len(), 3);
    assert_eq!(orientations(ShapeKind::Elbow).len(), 12);
    assert_eq!(orientations(ShapeKind::Sphere).len(), 1);
    // Square normals cover the three axes.
    let normals: Vec<Vector3<f64>> = orientations(ShapeKind::Square)
        .iter()
        .map(|r| r * Vector3::z())
        .collect();
    for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
        assert!(normals.iter().any(|n| (n - axis).norm() < 1e-12));
    }
}

#[test]
fn elbow_orientations_are_distinct() {
    let elbow = Shape::Elbow {
        bend: 0.5,
        radius: 0.1,
    };
    let probe = [Point3::new(0.5, 0.0, 0.1), Point3::new(0.3, 0.4, 0.0)];
    let images: Vec<Vec<Point3<f64>>> = orientations(elbow.kind())
        .iter()
        .map(|r| probe.iter().map(|p| r * p).collect())
        .collect();
    for a in 0..images.len() {
        for b in a + 1..images.len() {
            let same = images[a]
                .iter()
                .zip(&images[b])
                .all(|(p, q)| (p - q).norm() < 1e-9);
            assert!(!same, "orientations {a} and {b} coincide");
        }
    }
}

#[test]
fn occupancy_keeps_only_candidates_near_points() {
    let cloud = PointCloud::from_points(vec![Point3::new(0.1, 0.1, 0.0)]);
    let set = CandidateSet::build(&spec(), &cloud).unwrap();
    assert!(!set.is_empty());
    let reach = set.templates[0].radius + 0.5 * 0.5 * 3f64.sqrt();
    for p in &set.poses {
        // Node of the point is the origin; every kept centre is within reach of it.
        assert!(p.translation.norm() <= reach + 1e-9);
        // Translations lie on the grid.
        for c in p.translation.iter() {
            assert!(((c / 0.5).round() * 0.5 - c).abs() < 1e-12);
        }
    }
    // A far-away node is never a candidate.
    assert!(set.poses.iter().all(|p| p.translation.norm() < 2.0));
}

/// The point term's β candidates per point equal a brute-force ranking of every
/// candidate, with surface or sample distances, for squares, cylinders and elbows
/// (whose surfaces reach beyond their samples' bounding radius).
#[test]
fn beta_rows_match_a_brute_force_ranking() {
    use crate::chamfer::{ChamferOptions, Coefficients};
    use crate::progress::Silent;
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let points: Vec<Point3<f64>> = (0..300)
        .map(|_| {
            Point3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-0.3..0.3),
            )
        })
        .collect();
    let cloud = PointCloud::from_points(points.clone());
    let shapes = vec![
        Shape::Square { side: 1.0 },
        Shape::Cylinder {
            length: 1.0,
            radius: 0.1,
        },
        Shape::Elbow {
            bend: 0.5,
            radius: 0.1,
        },
    ];
    let set = CandidateSet::build(&LatticeSpec { shapes, ..spec() }, &cloud).unwrap();
    for surface_distance in [true, false] {
        for beta in [1, 7, 40] {
            let o = ChamferOptions {
                beta: Some(beta),
                cap: 0.01,
                surface_distance,
                ..Default::default()
            };
            let c = Coefficients::build(&points, &set, &o, &Silent).unwrap();
            for (j, y) in points.iter().enumerate() {
                let mut all: Vec<(f64, u32)> = (0..set.len())
                    .map(|i| {
                        let d = if surface_distance {
                            set.surface_distance(i, y)
                        } else {
                            set.nearest_sample(i, y).1
                        };
                        (d, i as u32)
                    })
                    .collect();
                all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                all.truncate(beta);
                let r = c.row(j);
                let got: Vec<(f64, u32)> = c.dist[r.clone()]
                    .iter()
                    .copied()
                    .zip(c.cand[r].iter().copied())
                    .collect();
                assert_eq!(
                    got, all,
                    "point {j}, β = {beta}, surface {surface_distance}"
                );
            }
        }
    }
}

#[test]
fn nearest_sample_matches_scene_brute_force() {
    let cloud =
        PointCloud::from_points(vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.3, 0.2)]);
    let set = CandidateSet::build(&spec(), &cloud).unwrap();
    let y = Point3::new(0.37, -0.21, 0.13);
    let mut buf = Vec::new();
    for i in 0..set.len() {
        set.scene_samples(i, &mut buf);
        let brute = buf
            .iter()
            .map(|x| (x - y).norm_squared())
            .fold(f64::INFINITY, f64::min);
        let (_, d) = set.nearest_sample(i, &y);
        assert!((d - brute).abs() < 1e-12);
        let mut all = Vec::new();
        set.nearest_samples(i, &y, None, &mut all);
        assert!((all[0].1 - brute).abs() < 1e-12);
        assert_eq!(all.len(), buf.len());
    }
}

#[test]
fn surface_distances_remove_the_reward_for_redundant_copies() {
    use crate::chamfer::{ChamferOptions, Coefficients, Evaluator};
    use crate::progress::Silent;
    // A dense patch on z = 0 and two candidates covering it: the square at the origin
    // and a copy shifted by less than the sample spacing.
    let pts: Vec<Point3<f64>> = (0..20)
        .flat_map(|i| {
            (0..20).map(move |j| Point3::new(i as f64 * 0.05 - 0.475, j as f64 * 0.05 - 0.475, 0.0))
        })
        .collect();
    let cloud = PointCloud::from_points(pts);
    let template = Template::new(Shape::Square { side: 1.0 }, 0.1);
    let poses = vec![
        Pose::identity(),
        Pose::new(UnitQuaternion::identity(), Vector3::new(0.025, 0.025, 0.0)),
    ];
    let set = CandidateSet::from_parts(vec![template], vec![0, 0], poses).unwrap();
    let loss = |surface_distance: bool, exists: &[bool]| {
        let o = ChamferOptions {
            cap: 0.01,
            surface_distance,
            ..Default::default()
        };
        let c = Coefficients::build(&cloud.points, &set, &o, &Silent).unwrap();
        Evaluator::new(&c).binary_value(exists).point
    };
    // With sample distances the copy lowers the point term (its samples interleave)…
    assert!(loss(false, &[true, true]) < loss(false, &[true, false]) - 1e-6);
    // …with surface distances it explains nothing new.
    assert!((loss(true, &[true, true]) - loss(true, &[true, false])).abs() < 1e-12);
    // And the surface distance is the exact one.
    let y = Point3::new(0.7, 0.2, 0.3);
    let exact = set.primitive(1).distance(&y);
    assert!((set.surface_distance(1, &y) - exact * exact).abs() < 1e-12);
}

#[test]
fn near_data_keeps_every_candidate_within_the_distance() {
    let cloud =
        PointCloud::from_points(vec![Point3::new(0.1, 0.1, 0.0), Point3::new(3.0, 0.2, 0.0)]);
    let set = CandidateSet::build(&spec(), &cloud).unwrap();
    let distance = 0.3;
    let keep = set.near_data(&cloud.points, distance);
    let mut buf = Vec::new();
    for (i, k) in keep.iter().enumerate() {
        set.scene_samples(i, &mut buf);
        let nearest = buf
            .iter()
            .flat_map(|x| cloud.points.iter().map(move |y| (x - y).norm()))
            .fold(f64::INFINITY, f64::min);
        if nearest <= distance {
            assert!(*k, "candidate {i} at {nearest} dropped");
        }
        if nearest > 2.0 * 3f64.sqrt() * distance {
            assert!(!*k, "candidate {i} at {nearest} kept");
        }
    }
    assert!(keep.iter().any(|k| !k), "nothing was far enough to drop");
}

#[test]
fn bad_specs_are_errors() {
    let cloud = PointCloud::from_points(vec![Point3::origin()]);
    let mut s = spec();
    s.spacing = 0.0;
    let e = CandidateSet::build(&s, &cloud).expect_err("zero spacing");
    assert!(
        matches!(&e, Error::OutOfRange { name, .. } if name == "spacing"),
        "{e}"
    );
    let mut s = spec();
    s.shapes = vec![Shape::Square { side: -1.0 }];
    assert!(CandidateSet::build(&s, &cloud).is_err());
    let e = CandidateSet::build(&spec(), &PointCloud::default()).expect_err("empty");
    assert!(matches!(e, Error::EmptyCloud), "{e}");
}
