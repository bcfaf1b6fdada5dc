//! Tests of `elbows.rs` and `elbow_loss.rs`: an L-shaped pipe made here.

use super::*;
use crate::spatial::PointIndex;

/// Tube radius, bend radius, noise σ and point spacing of the test pipe.
const R: f64 = 0.1;
const BEND: f64 = 0.5;
const SIGMA: f64 = 0.005;
const SPACING: f64 = 0.02;

/// A cylinder along `axis` between axis points `from` and `to`.
fn tube(from: Point3<f64>, to: Point3<f64>) -> Primitive {
    let axis = (to - from).normalize();
    let rotation = UnitQuaternion::rotation_between(&Vector3::z(), &axis)
        .unwrap_or_else(UnitQuaternion::identity);
    let length = (to - from).norm();
    let shape = Shape::Cylinder { length, radius: R };
    Primitive::new(
        shape,
        Pose::new(rotation, nalgebra::center(&from, &to).coords),
    )
}

/// An L-shaped pipe in z = 0: a run along +x into the corner at the origin, the
/// elbow of [`BEND`], a run along +y out of it, each straight part 1.5 m; with the
/// true elbow, its points (σ jitter) and the runs as a detector finds them, reaching
/// `overshoot` past the tangent points into the bend.
fn l_pipe(overshoot: f64) -> (Vec<Point3<f64>>, Primitive, [Primitive; 2]) {
    let (a, b) = (Vector3::x(), Vector3::y());
    let start = Point3::origin() - a * BEND;
    let end = Point3::origin() + b * BEND;
    let truth_runs = [tube(start - a * 1.5, start), tube(end, end + b * 1.5)];
    let run = |p: &Primitive| Run::of(p).expect("a cylinder");
    let junction = Junction::of([0, 1], &run(&truth_runs[0]), &run(&truth_runs[1]));
    let elbow = junction.expect("the runs meet").elbow(BEND);
    let truth: Vec<Primitive> = truth_runs.iter().chain([&elbow]).cloned().collect();
    let points = crate::synth::jittered_samples(&truth, SPACING, SIGMA, 7);
    let detected = [
        tube(start - a * 1.5, start + a * overshoot),
        tube(end - b * overshoot, end + b * 1.5),
    ];
    (points, elbow, detected)
}

fn join(points: &[Point3<f64>], model: Vec<Primitive>) -> Vec<Primitive> {
    let index = PointIndex::new(points);
    let cloud = Cloud {
        points,
        index: &index,
        spacing: SPACING,
    };
    let pricing = Pricing {
        cap: 5.0 * SIGMA,
        noise: SIGMA,
        point_weight: 1.0,
    };
    let existence = vec![1.0; model.len()];
    let kept = (model.into_iter())
        .map(|primitive| Kept {
            primitive,
            members: Cow::Owned(Vec::new()),
        })
        .collect();
    let (kept, _) = join_runs(cloud, kept, existence, pricing, SPACING);
    kept.into_iter().map(|k| k.primitive).collect()
}

#[test]
fn the_elbow_is_tangent_to_both_runs() {
    let (_, elbow, _) = l_pipe(0.0);
    // The elbow's end circles are the runs' rings at the tangent points.
    let start = Point3::new(-BEND, 0.0, 0.0);
    let end = Point3::new(0.0, BEND, 0.0);
    for phi in [0.0, 1.0, 2.5, 4.0] {
        let (c, s) = (f64::cos(phi) * R, f64::sin(phi) * R);
        assert!(elbow.distance(&(start + Vector3::new(0.0, c, s))) < 1e-9);
        assert!(elbow.distance(&(end + Vector3::new(c, 0.0, s))) < 1e-9);
    }
    // The bend's middle lies inside the corner, on the circle about (−B, B).
    let middle = Point3::new(-BEND, BEND, 0.0) + Vector3::new(1.0, -1.0, 0.0).normalize() * BEND;
    assert!((elbow.distance(&middle) - R).abs() < 1e-9);
}

#[test]
fn runs_that_meet_at_a_right_angle_get_their_elbow() {
    for overshoot in [-0.2, 0.0, 0.3] {
        let (points, _, detected) = l_pipe(overshoot);
        let model = join(&points, detected.to_vec());
        let elbows: Vec<f64> = (model.iter())
            .filter_map(|p| match p.shape {
                Shape::Elbow { bend, .. } => Some(bend),
                _ => None,
            })
            .collect();
        assert_eq!(elbows.len(), 1, "overshoot {overshoot}: {model:?}");
        assert!(
            (elbows[0] - BEND).abs() < 0.1 * BEND,
            "overshoot {overshoot}: bend {}",
            elbows[0]
        );
        // The runs now end where the elbow starts.
        let ends: Vec<f64> = (model.iter())
            .filter_map(|p| match p.shape {
                Shape::Cylinder { length, .. } => Some(length),
                _ => None,
            })
            .collect();
        for length in ends {
            assert!((length - (1.5 + BEND - elbows[0])).abs() < 1e-9, "{length}");
        }
        let mean = |m: &[Primitive]| {
            let d = |y: &Point3<f64>| {
                m.iter()
                    .map(|p| p.distance(y))
                    .fold(f64::INFINITY, f64::min)
            };
            points.iter().map(d).sum::<f64>() / points.len() as f64
        };
        assert!(
            mean(&model) < 1.5 * SIGMA,
            "overshoot {overshoot}: {}",
            mean(&model)
        );
        assert!(
            mean(&detected) > 2.0 * mean(&model),
            "overshoot {overshoot}"
        );
    }
}

#[test]
fn runs_without_a_bend_between_them_stay_as_they_are() {
    let (points, _, detected) = l_pipe(0.0);
    // The bend's points removed: nothing for an elbow to explain.
    let straight: Vec<Point3<f64>> = (points.into_iter())
        .filter(|p| p.x < -BEND - 0.05 || p.y > BEND + 0.05)
        .collect();
    let model = join(&straight, detected.to_vec());
    assert_eq!(model.len(), 2);
    for (p, q) in model.iter().zip(&detected) {
        assert_eq!(p.pose.translation, q.pose.translation);
    }
    // Parallel runs are no junction.
    let (points, _, [run, _]) = l_pipe(0.0);
    let beside = Primitive::new(
        run.shape.clone(),
        Pose::new(
            run.pose.rotation,
            run.pose.translation + Vector3::new(0.0, 0.5, 0.0),
        ),
    );
    assert_eq!(join(&points, vec![run, beside]).len(), 2);
}

#[test]
fn a_patch_that_stood_in_for_the_bend_is_replaced() {
    let (points, _, detected) = l_pipe(0.0);
    // A square on the outside of the bend (towards the corner, away from the torus
    // centre (−B, B)), where it explains some of its points.
    let outward = Vector3::new(1.0, -1.0, 0.0).normalize();
    let at = Point3::new(-BEND, BEND, 0.0) + outward * (BEND + R);
    let rotation = UnitQuaternion::rotation_between(&Vector3::z(), &outward)
        .unwrap_or_else(UnitQuaternion::identity);
    let patch = Primitive::new(Shape::Square { side: 0.15 }, Pose::new(rotation, at.coords));
    let near = points
        .iter()
        .filter(|y| patch.distance(y) < 2.0 * SIGMA)
        .count();
    assert!(near > 20, "the patch explains {near} points");
    let model = join(
        &points,
        vec![detected[0].clone(), patch, detected[1].clone()],
    );
    let kinds: Vec<&str> = model.iter().map(|p| p.shape.kind().name()).collect();
    assert_eq!(kinds, ["cylinder", "cylinder", "elbow"]);
}

/// A run cut at one end by an elbow is refitted on its points short of the cut: its
/// axis, 1 cm off the points' tube as detection left it, comes back onto it. Points on
/// a tube twice as wide are something else, and the run stays as it was.
#[test]
fn a_cut_run_is_refitted_on_its_straight_part_only_when_the_tube_is_its_own() {
    let truth = tube(Point3::new(-2.0, 0.0, 0.0), Point3::new(0.0, 0.0, 0.0));
    let mut wide = truth.clone();
    wide.shape = Shape::Cylinder {
        length: 2.0,
        radius: 2.0 * R,
    };
    let detected = {
        let mut p = truth.clone();
        p.pose.translation.y += 0.01;
        p
    };
    let run = Run::of(&detected).expect("a cylinder");
    // Cut 0.5 m short of the run's end at x = 0 (the run's axis runs along +x).
    let extent = [(-1.0, 0.5)];
    for (surface, refitted) in [(&truth, true), (&wide, false)] {
        let points =
            crate::synth::jittered_samples(std::slice::from_ref(surface), SPACING, SIGMA, 3);
        let index = PointIndex::new(&points);
        let cloud = Cloud {
            points: &points,
            index: &index,
            spacing: SPACING,
        };
        let kept = [Kept {
            primitive: detected.clone(),
            members: Cow::Owned((0..points.len()).collect()),
        }];
        let out = refit_joined(cloud, &kept, &[Some(run)], &extent);
        assert_eq!(
            out[0].is_some(),
            refitted,
            "refitted on {:?}",
            surface.shape
        );
        if let Some(new) = out[0] {
            let off = new.centre.y.hypot(new.centre.z);
            assert!(off < 0.002, "axis {off} m off the tube");
            assert!(new.axis.x.abs() > 0.9999, "axis {:?}", new.axis);
            assert!(
                (new.half - run.half).abs() < 1e-12,
                "the run keeps its length"
            );
            assert!((new.radius - R).abs() < 0.002, "radius {}", new.radius);
        }
    }
}
