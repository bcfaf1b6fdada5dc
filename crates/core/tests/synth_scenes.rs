//! Synthetic scenes: points near the truth, counts, seeds, lattice, pipe topology.

use nalgebra::{Point3, Vector3};
use primfit_core::metrics::{MetricsOptions, evaluate, point_to_model_distances};
use primfit_core::synth::*;
use primfit_core::{Primitive, Shape};

/// Checks that all points are within `k·σ` of the truth and the mean distance is about
/// right for surface noise `σ` (3-D isotropic noise ⇒ |N(0, σ)| off a smooth surface).
fn assert_near_truth(scene: &Scene, sigma: f64) {
    let d = point_to_model_distances(&scene.cloud.points, &scene.truth).unwrap();
    let max = d.iter().copied().fold(0.0, f64::max);
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    assert!(
        max < 6.0 * sigma,
        "max distance {max} ≥ 6σ = {}",
        6.0 * sigma
    );
    let expected = sigma * (2.0 / std::f64::consts::PI).sqrt();
    assert!(
        (mean - expected).abs() < 0.25 * expected,
        "mean distance {mean}, expected ≈ {expected}"
    );
}

fn assert_on_lattice(scene: &Scene) {
    for (i, p) in scene.aligned_truth().iter().enumerate() {
        assert!(
            scene.lattice.contains(p, 1e-9),
            "truth {i} off the lattice: {:?}",
            p.pose
        );
    }
}

fn same_clouds(a: &Scene, b: &Scene) -> bool {
    a.cloud.points == b.cloud.points
}

#[test]
fn hallway_default_counts_lattice_and_noise() {
    let p = HallwayParams::default();
    let s = hallway(&p).unwrap();
    // Floor 10×2 m → 10×2 tiles; each wall 10×2.5 m → 10×3 tiles (one overlapping row).
    assert_eq!(s.truth.len(), 20 + 2 * 30);
    let area = 10.0 * 2.0 + 2.0 * 10.0 * 2.5;
    assert_eq!(s.cloud.len(), (100.0 * area) as usize);
    assert_eq!(s.lattice.spacing, 0.5);
    assert_on_lattice(&s);
    assert_near_truth(&s, p.noise.jitter);
}

#[test]
fn hallway_ceiling_odd_length_and_noise_free_points_on_tiles() {
    let p = HallwayParams {
        length: 10.3,
        ceiling: true,
        noise: Noise::default(),
        ..Default::default()
    };
    let s = hallway(&p).unwrap();
    // 11 tiles along x (the last overhangs by 0.2 m), 2 across, 3 up.
    assert_eq!(s.truth.len(), 2 * 11 * 2 + 2 * 11 * 3);
    assert_on_lattice(&s);
    let d = point_to_model_distances(&s.cloud.points, &s.truth).unwrap();
    assert!(
        d.iter().all(|&d| d < 1e-9),
        "a noise-free point is off every tile"
    );
    let (lo, hi) = s.cloud.bounds().unwrap();
    assert!(lo.coords.min() > -1e-9 && (hi - Point3::new(10.3, 2.0, 2.5)).max() < 1e-9);
}

#[test]
fn hallway_misalignment_moves_cloud_and_truth_together() {
    let p = HallwayParams {
        misalignment: Misalignment {
            offset: 0.5,
            angle: 0.1,
        },
        noise: Noise::default(),
        ..Default::default()
    };
    let s = hallway(&p).unwrap();
    let angle = s.misalignment.rotation.angle();
    assert!(
        angle > 0.0 && angle <= 0.1 + 1e-12,
        "rotation angle {angle}"
    );
    assert!(
        s.truth.iter().any(|t| !s.lattice.contains(t, 1e-6)),
        "misaligned truth should be off the lattice"
    );
    assert_on_lattice(&s);
    let d = point_to_model_distances(&s.cloud.points, &s.truth).unwrap();
    assert!(d.iter().all(|&d| d < 1e-9));
}

#[test]
fn hallway_rejects_bad_params() {
    for p in [
        HallwayParams {
            width: 2.3,
            ..Default::default()
        },
        HallwayParams {
            length: -1.0,
            ..Default::default()
        },
        HallwayParams {
            side: f64::NAN,
            ..Default::default()
        },
        HallwayParams {
            noise: Noise {
                jitter: -0.1,
                drift: 0.0,
            },
            ..Default::default()
        },
        HallwayParams {
            density: Density::PerArea(-5.0),
            ..Default::default()
        },
        HallwayParams {
            misalignment: Misalignment {
                offset: f64::INFINITY,
                angle: 0.0,
            },
            ..Default::default()
        },
    ] {
        assert!(hallway(&p).is_err(), "{p:?} should be rejected");
    }
}

#[test]
fn seeds_reproduce_and_differ() {
    let h = |seed| {
        hallway(&HallwayParams {
            seed,
            ..Default::default()
        })
        .unwrap()
    };
    assert!(same_clouds(&h(1), &h(1)) && !same_clouds(&h(1), &h(2)));
    let pp = |seed| {
        pipe(&PipeParams {
            seed,
            ..Default::default()
        })
        .unwrap()
    };
    assert!(same_clouds(&pp(3), &pp(3)) && !same_clouds(&pp(3), &pp(4)));
    let n = |seed| {
        nine_cylinders(&NineCylinderParams {
            seed,
            offset: 0.5,
            ..Default::default()
        })
        .unwrap()
    };
    assert!(same_clouds(&n(5), &n(5)) && !same_clouds(&n(5), &n(6)));
    let six = |seed| {
        six_in_a_row(&SixInARowParams {
            seed,
            ..Default::default()
        })
        .unwrap()
        .scene
    };
    assert!(same_clouds(&six(7), &six(7)) && !same_clouds(&six(7), &six(8)));
    let obj = asymmetric_object();
    let r = |seed| {
        registration(
            &obj,
            &RegistrationParams {
                seed,
                ..Default::default()
            },
        )
        .unwrap()
    };
    assert!(same_clouds(&r(9), &r(9)) && !same_clouds(&r(9), &r(10)));
}

/// Centre-line end points of a pipe part (scene frame).
fn ends(p: &Primitive) -> [Point3<f64>; 2] {
    match p.shape {
        Shape::Cylinder { length, .. } => [
            p.pose.to_scene(&Point3::new(0.0, 0.0, -length / 2.0)),
            p.pose.to_scene(&Point3::new(0.0, 0.0, length / 2.0)),
        ],
        Shape::Elbow { bend, .. } => [
            p.pose.to_scene(&Point3::new(bend, 0.0, 0.0)),
            p.pose.to_scene(&Point3::new(0.0, bend, 0.0)),
        ],
        _ => panic!("unexpected pipe part {:?}", p.shape),
    }
}

#[test]
fn pipe_parts_join_on_the_lattice_without_overlap() {
    for seed in 0..6 {
        let p = PipeParams {
            segments: 6,
            seed,
            ..Default::default()
        };
        let s = pipe(&p).unwrap();
        assert_on_lattice(&s);
        let elbows = s
            .truth
            .iter()
            .filter(|t| matches!(t.shape, Shape::Elbow { .. }))
            .count();
        assert_eq!(elbows, 5, "seed {seed}: segments − 1 elbows");
        // Consecutive parts share a centre-line end point; every part end except the
        // chain's two ends is shared.
        for w in s.truth.windows(2) {
            let (a, b) = (ends(&w[0]), ends(&w[1]));
            let joined = a.iter().any(|x| b.iter().any(|y| (x - y).norm() < 1e-9));
            assert!(
                joined,
                "seed {seed}: consecutive parts do not meet: {a:?} {b:?}"
            );
        }
        // Parts that are not neighbours in the chain stay apart.
        let samples: Vec<Vec<Point3<f64>>> =
            s.truth.iter().map(|t| t.sample_surface(0.02)).collect();
        for (i, samples_i) in samples.iter().enumerate() {
            for j in i + 2..s.truth.len() {
                let d = samples_i
                    .iter()
                    .map(|x| s.truth[j].distance(x))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    d > 0.01,
                    "seed {seed}: parts {i} and {j} overlap (distance {d})"
                );
            }
        }
        assert_near_truth(&s, p.noise.jitter);
    }
}

#[test]
fn pipe_density_and_sizes_honoured() {
    let p = PipeParams {
        density: Density::Total(1234),
        bend: Some(1.0),
        radius: Some(0.2),
        ..Default::default()
    };
    let s = pipe(&p).unwrap();
    assert_eq!(s.cloud.len(), 1234);
    assert!(s.truth.iter().all(|t| match t.shape {
        Shape::Cylinder { length, radius } => length == 1.0 && radius == 0.2,
        Shape::Elbow { bend, radius } => bend == 1.0 && radius == 0.2,
        _ => false,
    }));
    assert_on_lattice(&s);
    for bad in [
        PipeParams {
            bend: Some(0.7),
            ..Default::default()
        },
        PipeParams {
            radius: Some(0.5),
            ..Default::default()
        },
        PipeParams {
            segments: 0,
            ..Default::default()
        },
        PipeParams {
            segment_length: 0.0,
            ..Default::default()
        },
    ] {
        assert!(pipe(&bad).is_err(), "{bad:?} should be rejected");
    }
}

#[test]
fn nine_cylinders_all_512_subsets() {
    let base = NineCylinderParams {
        density: Density::PerArea(5.0),
        ..Default::default()
    };
    let candidates = nine_cylinders_candidates(&base).unwrap();
    assert_eq!(candidates.len(), 9);
    for mask in 0..512u16 {
        let s = nine_cylinders(&NineCylinderParams {
            mask,
            seed: mask as u64,
            ..base.clone()
        })
        .unwrap();
        assert_eq!(s.truth.len(), mask.count_ones() as usize, "mask {mask:#b}");
        for t in &s.truth {
            assert!(
                candidates
                    .iter()
                    .any(|c| (c.center() - t.center()).norm() < 1e-12)
            );
        }
        assert_on_lattice(&s);
    }
    assert!(
        nine_cylinders(&NineCylinderParams {
            mask: 512,
            ..Default::default()
        })
        .is_err()
    );
    assert!(
        nine_cylinders(&NineCylinderParams {
            pitch: 0.3,
            ..Default::default()
        })
        .is_err()
    );
}

#[test]
fn nine_cylinders_noise_and_offset() {
    let p = NineCylinderParams {
        noise: Noise {
            jitter: 0.01,
            drift: 0.0,
        },
        ..Default::default()
    };
    assert_near_truth(&nine_cylinders(&p).unwrap(), 0.01);
    let mut shifts = Vec::new();
    for seed in 0..20 {
        let s = nine_cylinders(&NineCylinderParams {
            offset: 1.0,
            seed,
            ..p.clone()
        })
        .unwrap();
        let t = s.misalignment.translation;
        assert!(
            t.norm() <= 1.0 + 1e-12 && t.z == 0.0 && (t.x == 0.0 || t.y == 0.0),
            "shift {t:?}"
        );
        assert_near_truth(&s, 0.01);
        assert_on_lattice(&s);
        shifts.push(t.norm());
    }
    assert!(shifts.iter().any(|&x| x > 0.5) && shifts.iter().any(|&x| x < 0.5));
    // Drift moves whole cylinders: the point→truth mean grows well beyond the jitter's.
    let drifted = nine_cylinders(&NineCylinderParams {
        noise: Noise {
            jitter: 0.0,
            drift: 0.05,
        },
        ..p
    })
    .unwrap();
    let m = evaluate(
        &drifted.cloud.points,
        &drifted.truth,
        None,
        &MetricsOptions::default(),
    )
    .unwrap();
    assert!(
        m.point_to_model_mean > 0.01,
        "drift had no effect: {}",
        m.point_to_model_mean
    );
}

#[test]
fn six_in_a_row_squares_and_cylinders() {
    for variant in [SixVariant::Squares, SixVariant::Cylinders] {
        let p = SixInARowParams {
            variant,
            ..Default::default()
        };
        let t = six_in_a_row(&p).unwrap();
        assert_eq!(t.candidates.len(), 6);
        assert_eq!(t.scene.cloud.len(), p.points);
        assert_eq!(t.scene.cloud.sensors.as_ref().map(Vec::len), Some(p.points));
        assert_eq!(t.true_index, 3);
        assert!((t.candidates[3].center().x - 10.0).abs() < 1e-12);
        for (i, c) in t.candidates.iter().enumerate() {
            assert!(
                t.scene.lattice.contains(c, 1e-12),
                "candidate {i} off the lattice"
            );
            let d =
                point_to_model_distances(&t.scene.cloud.points, std::slice::from_ref(c)).unwrap();
            let max = d.iter().copied().fold(0.0, f64::max);
            if i == 3 {
                assert!(
                    max < 6.0 * p.jitter,
                    "{variant:?}: points off the true candidate ({max})"
                );
            } else {
                assert!(
                    d.iter().all(|&d| d > 0.25),
                    "{variant:?}: a point lies on candidate {i}"
                );
            }
        }
        if variant == SixVariant::Cylinders {
            // Only the side facing the sensor is seen: x ≤ 10 − r²/10 (tangent rays).
            let clean = six_in_a_row(&SixInARowParams {
                jitter: 0.0,
                ..p.clone()
            })
            .unwrap();
            let r = p.size / 4.0;
            assert!(
                clean
                    .scene
                    .cloud
                    .points
                    .iter()
                    .all(|q| q.x <= 10.0 - r * r / 10.0 + 1e-9)
            );
        }
    }
}

#[test]
fn registration_counts_and_inliers_on_mesh() {
    let obj = asymmetric_object();
    let p = RegistrationParams {
        translation: 2.0,
        scale: Some((0.5, 2.0)),
        ..Default::default()
    };
    let s = registration(&obj, &p).unwrap();
    assert_eq!(s.cloud.len(), 2000);
    assert_eq!(s.truth.len(), 1);
    let d = point_to_model_distances(&s.cloud.points, &s.truth).unwrap();
    assert!(
        d[..100].iter().all(|&d| d < 1e-9),
        "inliers must lie on the posed mesh"
    );
    let outliers_off = d[100..].iter().filter(|&&d| d > 1e-3).count();
    assert!(
        outliers_off > 1800,
        "outliers should mostly be off the surface ({outliers_off})"
    );
    let t = &s.truth[0].pose;
    assert!(t.translation.amax() <= 2.0 && (0.5..=2.0).contains(&t.scale));
    let rot_only = registration(&obj, &RegistrationParams::default()).unwrap();
    assert_eq!(rot_only.truth[0].pose.translation, Vector3::zeros());
    assert!(
        registration(
            &obj,
            &RegistrationParams {
                scale: Some((2.0, 1.0)),
                ..Default::default()
            }
        )
        .is_err()
    );
}

#[test]
fn asymmetric_object_is_closed_oriented_and_asymmetric() {
    let obj = asymmetric_object();
    let m = &obj.mesh;
    assert_eq!(m.faces.len(), 320);
    // Closed and consistently oriented: every directed edge once, its reverse once.
    let mut edges = std::collections::HashSet::new();
    for f in &m.faces {
        for k in 0..3 {
            assert!(
                edges.insert((f[k], f[(k + 1) % 3])),
                "directed edge repeated"
            );
        }
    }
    assert!(
        edges.iter().all(|&(a, b)| edges.contains(&(b, a))),
        "open edge"
    );
    // Outward: positive signed volume.
    let vol: f64 = m
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| m.vertices[i as usize].coords);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum();
    assert!(vol > 0.0);
    // No half-turn about any axis through the centroid maps the vertices onto themselves
    // (try the coordinate axes and diagonals) — and no quarter-turn either.
    let c = m.vertices.iter().map(|v| v.coords).sum::<Vector3<f64>>() / m.vertices.len() as f64;
    let axes = [
        Vector3::x(),
        Vector3::y(),
        Vector3::z(),
        Vector3::new(1.0, 1.0, 0.0),
        Vector3::new(1.0, 0.0, 1.0),
    ];
    for axis in axes {
        for angle in [std::f64::consts::PI, std::f64::consts::FRAC_PI_2] {
            let r =
                nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
            let mismatch = m
                .vertices
                .iter()
                .map(|v| {
                    let w = r * (v.coords - c) + c;
                    m.vertices
                        .iter()
                        .map(|u| (u.coords - w).norm())
                        .fold(f64::INFINITY, f64::min)
                })
                .fold(0.0, f64::max);
            assert!(mismatch > 0.05, "looks symmetric about {axis:?} by {angle}");
        }
    }
}

#[test]
fn lattice_rotations_are_axis_permutations() {
    for axis in 0..3 {
        let r = axis_rotation(axis);
        assert!((r * Vector3::z() - Vector3::ith(axis, 1.0)).norm() < 1e-12);
    }
    // The elbow arc runs from the entry to entry + B(d_in + d_out) with the right tangents.
    let (d_in, d_out) = (Vector3::y(), -Vector3::z());
    let rot = elbow_rotation(&d_in, &d_out).unwrap();
    let b = 0.5;
    let entry = Point3::new(1.0, 2.0, 3.0);
    let elbow = Primitive::new(
        Shape::Elbow {
            bend: b,
            radius: 0.1,
        },
        primfit_core::Pose::new(rot, (entry + d_out * b).coords),
    );
    let ends = ends(&elbow);
    let exit = entry + (d_in + d_out) * b;
    assert!(
        ends.iter().any(|e| (e - entry).norm() < 1e-12)
            && ends.iter().any(|e| (e - exit).norm() < 1e-12)
    );
    assert!(
        (rot * Vector3::z()).iter().all(|&v| v > -1e-12),
        "canonical normal is a positive axis"
    );
    assert!(elbow_rotation(&Vector3::x(), &Vector3::x()).is_err());
}
