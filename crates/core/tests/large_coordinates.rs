//! Georeferenced clouds (LAS/LAZ/E57 values near 10⁶ m): the same scene near the origin
//! and moved by (10⁶, 2·10⁶, 100) m is fitted to the same primitives, moved.
//!
//! At 2·10⁶ m an `f64` still resolves 4·10⁻¹⁰ m, but sums of squares over a
//! neighbourhood (covariances, distances to far points) lose what cancels; the fit must
//! not depend on where the scene sits.

use primfit_core::Silent;
use primfit_core::fit::FrameChoice;
use primfit_core::fit::{FitOptions, FitResult, fit};
use primfit_core::na::Vector3;
use primfit_core::refine::RefineOptions;
use primfit_core::synth::{PipeParams, Scene, pipe};
use primfit_core::{PointCloud, Primitive, Shape};

/// The shifts: (10⁶, 2·10⁶, 100) m, and a UTM-like easting and northing. Multiples of
/// every lattice spacing used here, so an axis-aligned lattice anchored at the origin
/// sits on the moved scene as on the original.
const SHIFTS: [[f64; 3]; 2] = [
    [1_000_000.0, 2_000_000.0, 100.0],
    [400_000.0, 6_000_000.0, 300.0],
];

/// Translation agreement (m) after moving back. Measured with the local frame of
/// `fit/recentre.rs`: 1.1·10⁻¹⁰ m at 2·10⁶ m, 4.4·10⁻¹⁰ m at 6·10⁶ m (the rounding of the
/// moved input itself); without it, 5·10⁻⁷ m and, at 6·10⁶ m, a different primitive.
const TRANSLATION_TOL: f64 = 1e-8;

/// Rotation agreement (rad) and relative size agreement.
const ROTATION_TOL: f64 = 1e-8;

fn shifted(cloud: &PointCloud, shift: [f64; 3]) -> PointCloud {
    let d = Vector3::from(shift);
    PointCloud {
        points: cloud.points.iter().map(|p| p + d).collect(),
        ..cloud.clone()
    }
}

/// The pipe scene's lattice, as `fit_synthetic` sets it.
fn lattice_options(scene: &Scene) -> FitOptions {
    let h = &scene.lattice;
    let mut o = FitOptions {
        spacing: Some(h.spacing),
        ..Default::default()
    };
    for s in &h.shapes {
        o.kinds.push(s.kind());
        match *s {
            Shape::Cylinder { length, radius } => {
                o.size = Some(length);
                o.radius = Some(radius);
            }
            Shape::Elbow { bend, radius } => {
                o.bend = Some(bend);
                o.radius = Some(radius);
            }
            _ => {}
        }
    }
    o
}

/// Asserts that `moved` is `near` translated by `shift`, primitive for primitive.
fn assert_same_moved(what: &str, near: &FitResult, moved: &FitResult, shift: [f64; 3]) {
    assert!(!near.primitives.is_empty(), "{what}: nothing fitted");
    assert_eq!(
        near.primitives.len(),
        moved.primitives.len(),
        "{what}: primitive counts"
    );
    let d = Vector3::from(shift);
    let worst = near
        .primitives
        .iter()
        .map(|a| {
            moved
                .primitives
                .iter()
                .map(|b| (b.pose.translation - d - a.pose.translation).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max);
    eprintln!(
        "{what}: {} primitives, worst translation difference {worst:.3e} m",
        near.primitives.len()
    );
    for a in &near.primitives {
        let found = moved.primitives.iter().any(|b| same(a, b, &d));
        assert!(found, "{what}: no moved counterpart of {a:?}");
    }
}

/// True when `b` is `a` moved by `d`.
fn same(a: &Primitive, b: &Primitive, d: &Vector3<f64>) -> bool {
    let shape = a.shape.kind() == b.shape.kind()
        && sizes(&a.shape)
            .iter()
            .zip(sizes(&b.shape))
            .all(|(x, y)| (x - y).abs() <= ROTATION_TOL * x.abs().max(1.0));
    let t = (b.pose.translation - d - a.pose.translation).norm() <= TRANSLATION_TOL;
    let r = a.pose.rotation.angle_to(&b.pose.rotation) <= ROTATION_TOL;
    let s = (a.pose.scale - b.pose.scale).abs() <= ROTATION_TOL * a.pose.scale;
    shape && t && r && s
}

/// A shape's size parameters.
fn sizes(s: &Shape) -> Vec<f64> {
    match *s {
        Shape::Disk { diameter } | Shape::Sphere { diameter } => vec![diameter],
        Shape::Square { side } => vec![side],
        Shape::Cylinder { length, radius } => vec![length, radius],
        Shape::Elbow { bend, radius } => vec![bend, radius],
        Shape::Mesh(_) | Shape::Plane(_) => vec![],
    }
}

fn scene() -> Scene {
    pipe(&PipeParams {
        seed: 1,
        ..Default::default()
    })
    .expect("pipe")
}

#[test]
fn lattice_fit_is_the_same_a_million_metres_away() {
    let scene = scene();
    let options = lattice_options(&scene);
    let near = fit(&scene.cloud, &options, &Silent).expect("near");
    for shift in SHIFTS {
        let moved = fit(&shifted(&scene.cloud, shift), &options, &Silent).expect("moved");
        assert_same_moved("lattice", &near, &moved, shift);
    }
}

#[test]
fn refined_auto_frame_fit_is_the_same_a_million_metres_away() {
    let scene = scene();
    let options = FitOptions {
        frame: FrameChoice::Auto,
        refine: Some(RefineOptions::default()),
        ..lattice_options(&scene)
    };
    let near = fit(&scene.cloud, &options, &Silent).expect("near");
    for shift in SHIFTS {
        let moved = fit(&shifted(&scene.cloud, shift), &options, &Silent).expect("moved");
        assert_same_moved("refined", &near, &moved, shift);
        // The outputs are in the input's frame: on the moved data, and so is the
        // lattice the settings report (its origin moved by a whole number of steps).
        let first = moved.primitives[0].pose.translation;
        assert!((first - Vector3::from(shift)).norm() < 10.0, "{first:?}");
        let s = &moved.settings;
        let steps = s.frame.inverse() * (s.origin - Vector3::from(shift) - near.settings.origin)
            / s.spacing;
        let whole = steps.iter().all(|v| (v - v.round()).abs() < 1e-6);
        assert!(whole, "lattice origins {steps:?} steps apart");
    }
}
