//! Georeferenced clouds (LAS/LAZ/E57 values near 10⁶ m): the same scene near the origin
//! and moved by (10⁶, 2·10⁶, 100) m is fitted to the same primitives, moved.
//!
//! At 2·10⁶ m an `f64` still resolves 4·10⁻¹⁰ m, but sums of squares over a
//! neighbourhood (covariances, distances to far points) lose what cancels; the fit must
//! not depend on where the scene sits.

use primfit_core::fit::{FitOptions, FitResult, fit};
use primfit_core::frame::FrameChoice;
use primfit_core::na::{Point3, Vector3};
use primfit_core::progress::Silent;
use primfit_core::refine::RefineOptions;
use primfit_core::synth::{PipeParams, Scene, pipe};
use primfit_core::{PointCloud, Primitive, Shape};

/// The shift: a multiple of every lattice spacing used here, so an axis-aligned lattice
/// anchored at the origin sits on the moved scene as on the original.
const SHIFT: [f64; 3] = [1_000_000.0, 2_000_000.0, 100.0];

/// Translation agreement (m) after moving back.
const TRANSLATION_TOL: f64 = 1e-6;

/// Rotation agreement (rad) and relative size agreement.
const ROTATION_TOL: f64 = 1e-6;

fn shifted(cloud: &PointCloud) -> PointCloud {
    let d = Vector3::from(SHIFT);
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

/// Asserts that `moved` is `near` translated by [`SHIFT`], primitive for primitive.
fn assert_same_moved(what: &str, near: &FitResult, moved: &FitResult) {
    assert!(!near.primitives.is_empty(), "{what}: nothing fitted");
    assert_eq!(
        near.primitives.len(),
        moved.primitives.len(),
        "{what}: primitive counts"
    );
    let d = Vector3::from(SHIFT);
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
        Shape::Mesh(_) => vec![],
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
    let moved = fit(&shifted(&scene.cloud), &options, &Silent).expect("moved");
    assert_same_moved("lattice", &near, &moved);
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
    let moved = fit(&shifted(&scene.cloud), &options, &Silent).expect("moved");
    assert_same_moved("refined", &near, &moved);
    // The outputs are in the input's frame: near the moved data.
    let first = moved.primitives[0].pose.translation;
    let p: Point3<f64> = Point3::from(first);
    assert!(p.coords.x > 0.9 * SHIFT[0] && p.coords.y > 0.9 * SHIFT[1]);
}
