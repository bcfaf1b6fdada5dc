//! Unit tests of poses and primitives: JSON round trips, anchoring, ray hits.

use super::*;
use serde_json::json;

#[test]
fn json_round_trip_of_every_analytic_type() {
    let pose = Pose {
        rotation: UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        translation: Vector3::new(1.0, -2.0, 0.5),
        scale: 1.5,
    };
    for shape in [
        Shape::Square { side: 1.0 },
        Shape::Disk { diameter: 0.7 },
        Shape::Sphere { diameter: 0.3 },
        Shape::Cylinder {
            length: 2.0,
            radius: 0.1,
        },
        Shape::Elbow {
            bend: 0.5,
            radius: 0.1,
        },
    ] {
        let p = Primitive::new(shape, pose);
        let back = Primitive::from_json(&p.to_json(), &|_| unreachable!()).unwrap();
        let (a, b) = (back.to_json(), p.to_json());
        assert_eq!((&a["type"], &a["size"]), (&b["type"], &b["size"]));
        assert!(back.pose.rotation.angle_to(&p.pose.rotation) < 1e-12);
        assert_eq!(
            (back.pose.translation, back.pose.scale),
            (p.pose.translation, p.pose.scale)
        );
        let x = Point3::new(0.3, 0.2, -0.1);
        assert!((back.distance(&x) - p.distance(&x)).abs() < 1e-12);
    }
}

#[test]
fn poses_are_design_json_through_serde() {
    let pose = Pose {
        rotation: UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3),
        translation: Vector3::new(1.0, -2.0, 0.5),
        scale: 1.5,
    };
    let v = serde_json::to_value(pose).unwrap();
    let q = pose.rotation.quaternion();
    assert_eq!(
        v,
        json!({"translation": [1.0, -2.0, 0.5], "rotation": [q.w, q.i, q.j, q.k], "scale": 1.5})
    );
    let back: Pose = serde_json::from_value(v.clone()).unwrap();
    assert_eq!(back, Pose::from_json(&v).unwrap());
    assert!(back.rotation.angle_to(&pose.rotation) < 1e-15);
    let unscaled: Pose =
        serde_json::from_value(json!({"translation": [0, 0, 0], "rotation": [2, 0, 0, 0]}))
            .unwrap();
    assert_eq!(unscaled, Pose::identity());
    let zero = json!({"translation": [0, 0, 0], "rotation": [0, 0, 0, 0]});
    assert!(serde_json::from_value::<Pose>(zero).is_err());
}

#[test]
fn json_round_trip_of_a_plane() {
    let p2 = |x: f64, y: f64| nalgebra::Point2::new(x, y);
    let outline = vec![p2(-1.0, -0.5), p2(1.25, -0.5), p2(1.0, 0.75), p2(-1.0, 0.5)];
    let hole = vec![p2(-0.2, -0.1), p2(0.1, -0.1), p2(0.1 / 3.0, 0.2)];
    let shape = PlaneShape::new(outline, vec![hole]).unwrap();
    let pose = Pose {
        rotation: UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        translation: Vector3::new(1.0, -2.0, 0.5),
        scale: 1.5,
    };
    let p = Primitive::new(Shape::Plane(shape.clone()), pose);
    let json = p.to_json();
    assert_eq!(json["type"], "plane");
    assert_eq!(json["outline"].as_array().unwrap().len(), 4);
    assert_eq!(json["holes"][0].as_array().unwrap().len(), 3);
    let text = serde_json::to_string(&json).unwrap();
    let back =
        Primitive::from_json(&serde_json::from_str(&text).unwrap(), &|_| unreachable!()).unwrap();
    let Shape::Plane(b) = &back.shape else {
        panic!("not a plane")
    };
    assert_eq!((b.outline(), b.holes()), (shape.outline(), shape.holes()));
    let again = back.to_json();
    for key in ["type", "size", "outline", "holes"] {
        assert_eq!(again[key], json[key], "{key}");
    }
    assert!(back.pose.rotation.angle_to(&p.pose.rotation) < 1e-12);
    let x = Point3::new(0.3, 0.2, -0.1);
    assert!((back.distance(&x) - p.distance(&x)).abs() < 1e-12);
    // Holes are optional; broken rings are errors.
    let mut no_holes = json.clone();
    no_holes.as_object_mut().unwrap().remove("holes");
    assert!(Primitive::from_json(&no_holes, &|_| unreachable!()).is_ok());
    for (field, bad) in [
        ("outline", json!([[0, 0], [1, 1], [1, 0], [0, 1]])),
        ("outline", json!([[0, 0], [1, 0]])),
        ("outline", json!([[0, 0], [1, "x"], [1, 1]])),
        ("outline", json!(null)),
        ("holes", json!([[[5, 5], [6, 5], [6, 6]]])),
        ("holes", json!(3)),
    ] {
        let mut v = json.clone();
        v[field] = bad.clone();
        assert!(
            Primitive::from_json(&v, &|_| unreachable!()).is_err(),
            "{field}: {bad}"
        );
    }
}

#[test]
fn bad_json_is_an_error_not_a_panic() {
    let load = |_: &str| Err(Error::invalid("no meshes here"));
    for bad in [
        json!({}),
        json!({"type": "cone"}),
        json!({"type": "square", "size": {"side": -1.0}, "pose": {"translation": [0,0,0], "rotation": [1,0,0,0]}}),
        json!({"type": "square", "size": {"side": 1.0}, "pose": {"translation": [0,0], "rotation": [1,0,0,0]}}),
        json!({"type": "square", "size": {"side": 1.0}, "pose": {"translation": [0,0,0], "rotation": [0,0,0,0]}}),
        json!({"type": "mesh", "size": {"source": "x.ply"}, "pose": {"translation": [0,0,0], "rotation": [1,0,0,0]}}),
    ] {
        assert!(Primitive::from_json(&bad, &load).is_err(), "{bad}");
    }
}

#[test]
fn anchored_pose_takes_the_local_point_to_the_scene_point() {
    let rotation = UnitQuaternion::from_euler_angles(0.4, -0.1, 0.7);
    let (local, scene) = (Point3::new(0.3, -1.0, 2.0), Point3::new(5.0, 1.0, -2.0));
    let pose = Pose::anchored(rotation, 1.5, &local, &scene);
    assert!((pose.to_scene(&local) - scene).norm() < 1e-12);
    assert_eq!((pose.rotation, pose.scale), (rotation, 1.5));
}

#[test]
fn first_hits_and_normals_of_every_analytic_type() {
    let x = Vector3::x();
    let o = Point3::origin();
    let at = |shape: Shape, rot: UnitQuaternion<f64>| {
        Primitive::new(shape, Pose::new(rot, Vector3::new(5.0, 0.0, 0.0)))
    };
    let facing = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2);
    let square = at(Shape::Square { side: 1.0 }, facing)
        .first_hit(&o, &x)
        .unwrap();
    assert!((square.depth - 5.0).abs() < 1e-12);
    assert!((square.normal + x).norm() < 1e-12);
    let cyl = Shape::Cylinder {
        length: 1.0,
        radius: 0.5,
    };
    let h = at(cyl, UnitQuaternion::identity())
        .first_hit(&o, &x)
        .unwrap();
    assert!((h.depth - 4.5).abs() < 1e-12 && (h.normal + x).norm() < 1e-12);
    let sph = at(Shape::Sphere { diameter: 2.0 }, UnitQuaternion::identity())
        .first_hit(&o, &x)
        .unwrap();
    assert!((sph.depth - 4.0).abs() < 1e-12 && (sph.normal + x).norm() < 1e-12);
    // From the torus centre (5, 0, 0) along the bisector of the quarter: the inner wall
    // at bend − radius, normal pointing back to the centre.
    let elbow = Shape::Elbow {
        bend: 1.0,
        radius: 0.2,
    };
    let d = Vector3::new(1.0, 1.0, 0.0).normalize();
    let c = Point3::new(5.0, 0.0, 0.0);
    let h = at(elbow, UnitQuaternion::identity())
        .first_hit(&c, &d)
        .unwrap();
    assert!((h.depth - 0.8).abs() < 1e-9, "{}", h.depth);
    assert!((h.normal + d).norm() < 1e-9);
    // Oblique incidence on a square: |cos| = cos 60°.
    let tilted = at(Shape::Square { side: 20.0 }, facing)
        .first_hit(&o, &Vector3::new(0.5, 0.75f64.sqrt(), 0.0))
        .unwrap();
    assert!((tilted.incidence(&Vector3::new(0.5, 0.75f64.sqrt(), 0.0)) - 0.5).abs() < 1e-12);
    assert!((tilted.depth - 10.0).abs() < 1e-9);
}

#[test]
fn scaled_poses_keep_hit_depth_in_scene_units_and_misses_are_none() {
    let mut pose = Pose::new(UnitQuaternion::identity(), Vector3::new(5.0, 0.0, 0.0));
    pose.scale = 2.0;
    let sphere = Primitive::new(Shape::Sphere { diameter: 1.0 }, pose);
    let h = sphere.first_hit(&Point3::origin(), &Vector3::x()).unwrap();
    assert!((h.depth - 4.0).abs() < 1e-12);
    assert!(sphere.first_hit(&Point3::origin(), &Vector3::y()).is_none());
    let nan = Point3::new(f64::NAN, 0.0, 0.0);
    assert!(sphere.first_hit(&nan, &Vector3::x()).is_none());
}

#[test]
fn distance_within_rules_out_only_what_lies_beyond_the_bound() {
    let p2 = |x: f64, y: f64| nalgebra::Point2::new(x, y);
    let outline = vec![p2(-1.0, -0.5), p2(1.25, -0.5), p2(1.0, 0.75), p2(-1.0, 0.5)];
    let plane = PlaneShape::new(outline, Vec::new()).unwrap();
    let pose = Pose {
        rotation: UnitQuaternion::from_euler_angles(0.4, -0.7, 1.1),
        translation: Vector3::new(0.3, -0.2, 0.1),
        scale: 2.5,
    };
    let shapes = [
        Shape::Plane(plane),
        Shape::Square { side: 0.8 },
        Shape::Disk { diameter: 0.6 },
        Shape::Sphere { diameter: 0.5 },
        Shape::Cylinder {
            length: 1.0,
            radius: 0.2,
        },
    ];
    let mut ruled_out = [0usize; 2];
    for shape in shapes {
        let flat = matches!(
            shape,
            Shape::Plane(_) | Shape::Square { .. } | Shape::Disk { .. }
        );
        let p = Primitive::new(shape, pose);
        for i in 0..1000 {
            let t = i as f64;
            let q = Point3::new(
                3.0 * (t * 0.37).sin(),
                3.0 * (t * 0.71).cos(),
                3.0 * (t * 0.13).sin(),
            );
            let d = p.distance(&q);
            for bound in [0.0, 0.5 * d, d, 1.5 * d, f64::INFINITY] {
                match p.distance_within(&q, bound) {
                    Some(got) => assert_eq!(got.to_bits(), d.to_bits()),
                    None => {
                        assert!(d > bound, "{q} at {d} ruled out by {bound}");
                        ruled_out[usize::from(flat)] += 1;
                    }
                }
            }
        }
    }
    // Flat shapes are ruled out by their height; the others always measured.
    assert_eq!(ruled_out[0], 0);
    assert!(ruled_out[1] > 1000, "{ruled_out:?}");
}
