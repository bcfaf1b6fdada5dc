//! Registration with the default options (full pose) on partial views (issue 16): the
//! object seen by a depth sensor from one viewpoint (`synth::partial_view`: its near
//! side only, self-occluded, with range noise), among a plane, other objects and
//! uniform outliers; and the same scenes without the object, where nothing may be
//! reported.
//!
//! Bounds: the benchmark's success criterion, rotation error < 5° and translation error
//! < 2 % of the model size (benches/REGISTRATION.md has the success rates over many
//! seeds; these tests pin a few seeds per outlier level).

use primfit_core::atlas::MeshShape;
use primfit_core::register::{RegisterOptions, Registration, register};
use primfit_core::synth::{PartialViewParams, Scene, asymmetric_object, partial_view};
use primfit_core::{Pose, Silent};

const MAX_ROTATION_DEG: f64 = 5.0;
const MAX_TRANSLATION_REL: f64 = 0.02;

fn model_size(mesh: &MeshShape) -> f64 {
    let (lo, hi) = primfit_core::bounds_of(&mesh.mesh.vertices).unwrap();
    (hi - lo).norm()
}

/// A partial view of `mesh` with 200 object points and `outliers` non-object points
/// (a quarter of them the scan of a plane and two other objects when `clutter`).
fn scene(mesh: &MeshShape, outliers: usize, clutter: bool, object: bool, seed: u64) -> Scene {
    let size = model_size(mesh);
    let structured = if clutter { outliers / 4 } else { 0 };
    partial_view(
        mesh,
        &PartialViewParams {
            inliers: 200,
            outliers: outliers - structured,
            clutter_points: structured,
            plane: clutter,
            distractors: if clutter { 2 } else { 0 },
            object,
            translation: 0.25 * size,
            range_noise: 0.003 * size,
            seed,
            ..Default::default()
        },
    )
    .unwrap()
}

/// `register` with the default options (full pose, as many objects as exist).
fn run(scene: &Scene, mesh: &MeshShape, seed: u64) -> Registration {
    let options = RegisterOptions {
        seed,
        ..Default::default()
    };
    register(&scene.cloud, mesh, &options, &Silent).unwrap()
}

/// `(rotation error in degrees, translation error relative to the model size)`.
fn errors(found: &Pose, truth: &Pose, size: f64) -> (f64, f64) {
    (
        found.rotation.angle_to(&truth.rotation).to_degrees(),
        (found.translation - truth.translation).norm() / size,
    )
}

/// The default registration finds exactly the one object of each seed's partial view
/// with `outliers` outliers per 200 object points, within the bounds.
fn check(outliers: usize, clutter: bool, seeds: &[u64]) {
    let mesh = asymmetric_object();
    let size = model_size(&mesh);
    for &seed in seeds {
        let scene = scene(&mesh, outliers, clutter, true, seed);
        let r = run(&scene, &mesh, seed);
        let found: Vec<(f64, f64, f64)> = r
            .objects
            .iter()
            .map(|o| {
                let (rot, trans) = errors(&o.primitive.pose, &scene.truth[0].pose, size);
                (rot, trans, o.existence)
            })
            .collect();
        println!("outliers {outliers}, clutter {clutter}, seed {seed}: {found:?}");
        assert_eq!(found.len(), 1, "seed {seed}: {found:?}");
        let (rot, trans, existence) = found[0];
        assert!(rot < MAX_ROTATION_DEG, "seed {seed}: rotation {rot:.2}°");
        assert!(
            trans < MAX_TRANSLATION_REL,
            "seed {seed}: translation {trans:.4}"
        );
        assert!(
            (0.5..=0.99).contains(&existence),
            "seed {seed}: {existence}"
        );
    }
}

#[test]
fn partial_view_at_50_percent_outliers() {
    check(200, false, &[0, 1]);
}

#[test]
fn partial_view_at_80_percent_outliers() {
    check(800, false, &[1]);
}

#[test]
fn partial_view_at_90_percent_outliers() {
    // 200 object points among 2 000: where the particle filter alone found 2 of 5
    // seeds (the point-pair hypotheses and point-to-surface ICP find them).
    check(1800, false, &[1, 2]);
}

#[test]
fn partial_view_with_a_plane_and_other_objects_at_80_percent_outliers() {
    check(800, true, &[1]);
}

#[test]
fn a_partial_view_without_the_object_reports_none() {
    let mesh = asymmetric_object();
    for seed in [0, 1] {
        let scene = scene(&mesh, 1800, true, false, seed);
        assert!(scene.truth.is_empty());
        let r = run(&scene, &mesh, seed);
        let existence: Vec<f64> = r.objects.iter().map(|o| o.existence).collect();
        assert!(r.objects.is_empty(), "seed {seed}: found {existence:?}");
    }
}

#[test]
fn partial_view_points_are_the_visible_side_of_the_object() {
    let mesh = asymmetric_object();
    let size = model_size(&mesh);
    let params = PartialViewParams {
        inliers: 300,
        outliers: 50,
        clutter_points: 100,
        plane: true,
        distractors: 2,
        translation: 0.25 * size,
        seed: 3,
        ..Default::default()
    };
    let scene = partial_view(&mesh, &params).unwrap();
    let again = partial_view(&mesh, &params).unwrap();
    assert_eq!(scene.cloud, again.cloud, "deterministic");
    assert_eq!(scene.truth[0].pose, again.truth[0].pose);
    assert_eq!(scene.cloud.len(), 450);
    let truth = &scene.truth[0];
    let sensors = scene.cloud.sensors.as_ref().unwrap();
    let eye = sensors[0];
    assert!(sensors.iter().all(|s| *s == eye));
    let mut facing = 0;
    for p in &scene.cloud.points[..300] {
        // On the surface (no range noise) and the first surface the sensor's ray meets.
        assert!(truth.distance(p) < 1e-9 * size);
        let dir = (p - eye).normalize();
        let hit = truth.first_hit(&eye, &dir).unwrap();
        assert!((hit.depth - (p - eye).norm()).abs() < 1e-9 * size);
        facing += usize::from(hit.normal.dot(&dir) < 0.0);
    }
    assert_eq!(facing, 300);
    // The clutter's points are off the object.
    assert!(
        scene.cloud.points[300..400]
            .iter()
            .all(|p| truth.distance(p) > 1e-6 * size)
    );
    // Without the object: the same clutter, no object points, no truth.
    let without = partial_view(
        &mesh,
        &PartialViewParams {
            object: false,
            ..params.clone()
        },
    )
    .unwrap();
    assert!(without.truth.is_empty());
    assert_eq!(without.cloud.len(), 150);
    // Bad parameters are errors.
    let bad = PartialViewParams {
        range_noise: -1.0,
        ..params
    };
    assert!(partial_view(&mesh, &bad).is_err());
}
