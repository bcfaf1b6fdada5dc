//! Particle-filter registration (issue 6) on the thesis's synthetic scene (§6.3.3):
//! `inliers` points on a randomly posed mesh plus uniform outliers in a box around it.
//!
//! Bounds: rotation error < 3°, translation error < 1 % of the model size (the diagonal
//! of the mesh's bounding box); the benchmark's success criterion is 5° and 2 %
//! (benches/REGISTRATION.md has the success rates over 20 seeds per outlier level).

use std::path::Path;

use primfit_core::Silent;
use primfit_core::atlas::MeshShape;
use primfit_core::register::{RegisterOptions, Registration, register};
use primfit_core::synth::{RegistrationParams, asymmetric_object, registration};
use primfit_core::{Pose, io};

const MAX_ROTATION_DEG: f64 = 3.0;
const MAX_TRANSLATION_REL: f64 = 0.01;

fn model_size(mesh: &MeshShape) -> f64 {
    let (lo, hi) = primfit_core::bounds_of(&mesh.mesh.vertices).unwrap();
    (hi - lo).norm()
}

/// `(rotation error in degrees, translation error relative to the model size)`.
fn errors(found: &Pose, truth: &Pose, size: f64) -> (f64, f64) {
    (
        found.rotation.angle_to(&truth.rotation).to_degrees(),
        (found.translation - truth.translation).norm() / size,
    )
}

/// Registers one object in a scene with `outliers` outliers per 100 inliers.
fn run_one(mesh: &MeshShape, outliers: usize, translation: bool, seed: u64) -> (f64, f64) {
    let size = model_size(mesh);
    let scene = registration(
        mesh,
        &RegistrationParams {
            inliers: 100,
            outliers,
            translation: if translation { 0.25 * size } else { 0.0 },
            seed,
            ..Default::default()
        },
    )
    .unwrap();
    let options = RegisterOptions {
        translation,
        count: Some(1),
        min_confidence: 0.0, // the pose is checked here, the existence elsewhere
        seed,
        ..Default::default()
    };
    let r = register(&scene.cloud, mesh, &options, &Silent).unwrap();
    assert_eq!(r.objects.len(), 1);
    let o = &r.objects[0];
    let (rot, trans) = errors(&o.primitive.pose, &scene.truth[0].pose, size);
    println!(
        "outliers {outliers}, translation {translation}, seed {seed}: rotation {rot:.2}°, \
         translation {:.3} %, existence {:.2}, inlier share {:.3}, {} rounds, {:.2} s",
        100.0 * trans,
        o.existence,
        o.inlier_share,
        o.rounds.len(),
        r.seconds
    );
    (rot, trans)
}

/// Registers over `seeds`; at least `min_ok` of them must be within the bounds (the
/// filter is stochastic: the benchmark's success rates are in benches/REGISTRATION.md).
fn check(
    mesh: &MeshShape,
    outliers: usize,
    translation: bool,
    seeds: std::ops::Range<u64>,
    min_ok: usize,
) {
    let mut failures = Vec::new();
    let n = seeds.end - seeds.start;
    for seed in seeds {
        let (rot, trans) = run_one(mesh, outliers, translation, seed);
        if !(rot < MAX_ROTATION_DEG && trans < MAX_TRANSLATION_REL) {
            failures.push(format!(
                "seed {seed}: rotation error {rot:.2}°, translation error {:.3} %",
                100.0 * trans
            ));
        }
    }
    let ok = n as usize - failures.len();
    assert!(
        ok >= min_ok,
        "{outliers} outliers: {ok}/{n} within bounds, need {min_ok}: {failures:?}"
    );
}

#[test]
fn rotation_only_at_50_percent_outliers() {
    check(&asymmetric_object(), 100, false, 0..3, 3);
}

#[test]
fn rotation_only_at_95_percent_outliers() {
    check(&asymmetric_object(), 1900, false, 0..4, 3);
}

#[test]
fn full_pose_at_50_percent_outliers() {
    check(&asymmetric_object(), 100, true, 0..3, 3);
}

#[test]
fn full_pose_at_80_percent_outliers() {
    check(&asymmetric_object(), 400, true, 0..4, 3);
}

#[test]
fn full_pose_at_95_percent_outliers() {
    check(&asymmetric_object(), 1900, true, 0..5, 5);
}

/// The same seed gives the same full pose (votes, filter and ICP are deterministic).
#[test]
fn full_pose_is_deterministic_for_a_seed() {
    let mesh = asymmetric_object();
    let size = model_size(&mesh);
    let scene = registration(
        &mesh,
        &RegistrationParams {
            outliers: 400,
            translation: 0.25 * size,
            seed: 7,
            ..Default::default()
        },
    )
    .unwrap();
    let options = RegisterOptions {
        translation: true,
        count: Some(1),
        seed: 7,
        ..Default::default()
    };
    let a = register(&scene.cloud, &mesh, &options, &Silent).unwrap();
    let b = register(&scene.cloud, &mesh, &options, &Silent).unwrap();
    assert_eq!(a.objects[0].primitive.pose, b.objects[0].primitive.pose);
    assert_eq!(a.objects[0].filter_pose, b.objects[0].filter_pose);
}

/// `--scale`: scenes whose object is scaled by a known factor (50, 80 and 90 %
/// outliers); the scale is searched in (0.5, 2) together with the full pose. Bounds:
/// scale within 1 % of the truth, rotation < 3°, translation < 1 % of the scaled
/// model's size.
#[test]
fn scale_is_recovered_with_the_full_pose() {
    let mesh = asymmetric_object();
    let size = model_size(&mesh);
    for (seed, outliers, scale) in [(0, 100, 1.4), (1, 400, 0.7), (2, 900, 1.25)] {
        let scene = registration(
            &mesh,
            &RegistrationParams {
                inliers: 100,
                outliers,
                translation: 0.25 * size,
                scale: Some((scale, scale)),
                seed,
                ..Default::default()
            },
        )
        .unwrap();
        let options = RegisterOptions {
            translation: true,
            scale: Some((0.5, 2.0)),
            count: Some(1),
            min_confidence: 0.0, // the pose is checked here, the existence elsewhere
            seed,
            ..Default::default()
        };
        let r = register(&scene.cloud, &mesh, &options, &Silent).unwrap();
        let truth = scene.truth[0].pose;
        let found = r.objects[0].primitive.pose;
        let (rot, trans) = errors(&found, &truth, size * scale);
        let scale_err = (found.scale - truth.scale).abs() / truth.scale;
        println!(
            "seed {seed}, {outliers} outliers, scale {scale}: found scale {:.4} ({:.2} %), \
             rotation {rot:.2}°, translation {:.3} %, {:.2} s",
            found.scale,
            100.0 * scale_err,
            100.0 * trans,
            r.seconds
        );
        assert!(
            scale_err < 0.01,
            "seed {seed}: scale {} vs {scale}",
            found.scale
        );
        assert!(rot < MAX_ROTATION_DEG && trans < MAX_TRANSLATION_REL);
    }
}

/// Rotation and scale with the translation known (`--scale` without `--translation`).
#[test]
fn scale_is_recovered_with_the_rotation() {
    let mesh = asymmetric_object();
    let size = model_size(&mesh);
    let scale = 1.6;
    let scene = registration(
        &mesh,
        &RegistrationParams {
            inliers: 100,
            outliers: 400,
            scale: Some((scale, scale)),
            seed: 3,
            ..Default::default()
        },
    )
    .unwrap();
    let options = RegisterOptions {
        translation: false, // rotation only
        scale: Some((0.5, 2.0)),
        count: Some(1),
        seed: 3,
        ..Default::default()
    };
    let r = register(&scene.cloud, &mesh, &options, &Silent).unwrap();
    let found = r.objects[0].primitive.pose;
    let (rot, _) = errors(&found, &scene.truth[0].pose, size * scale);
    println!("found scale {:.4}, rotation {rot:.2}°", found.scale);
    assert!(
        (found.scale - scale).abs() / scale < 0.01,
        "scale {}",
        found.scale
    );
    assert!(rot < MAX_ROTATION_DEG);
    assert_eq!(found.translation, scene.truth[0].pose.translation);
}

#[test]
fn bunny_rotation_only_at_95_percent_outliers() {
    let path = Path::new("/work/shared/data/bunny.ply");
    let mesh = match io::read_mesh(path) {
        Ok(m) => MeshShape::new(path.display().to_string(), m).unwrap(),
        Err(e) => {
            println!("note: {e}; using the procedural asymmetric object instead of the bunny");
            asymmetric_object()
        }
    };
    check(&mesh, 1900, false, 0..1, 1);
}

#[test]
fn two_objects_at_once() {
    let mesh = asymmetric_object();
    let size = model_size(&mesh);
    let scene = registration(
        &mesh,
        &RegistrationParams {
            inliers: 100,
            outliers: 200,
            translation: 0.1 * size,
            objects: 2,
            seed: 1,
            ..Default::default()
        },
    )
    .unwrap();
    let options = RegisterOptions {
        translation: true,
        seed: 1,
        ..Default::default()
    };
    let r = register(&scene.cloud, &mesh, &options, &Silent).unwrap();
    assert_eq!(r.objects.len(), 2, "found {} objects", r.objects.len());
    for truth in &scene.truth {
        let best = r
            .objects
            .iter()
            .map(|o| errors(&o.primitive.pose, &truth.pose, size))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        println!(
            "object: rotation {:.2}°, translation {:.3} %",
            best.0,
            100.0 * best.1
        );
        assert!(best.0 < MAX_ROTATION_DEG && best.1 < MAX_TRANSLATION_REL);
    }
    for o in &r.objects {
        assert!(o.existence >= 0.5);
        assert!((0.2..0.35).contains(&o.inlier_share), "{}", o.inlier_share);
    }
}

#[test]
fn a_scene_without_the_object_reports_none() {
    let mesh = asymmetric_object();
    // Only the outliers of the 95 % scene: 2000 uniform points, no object.
    let scene = registration(
        &mesh,
        &RegistrationParams {
            inliers: 0,
            outliers: 2000,
            seed: 4,
            ..Default::default()
        },
    )
    .unwrap();
    for translation in [false, true] {
        let options = RegisterOptions {
            translation,
            seed: 4,
            ..Default::default()
        };
        let r = register(&scene.cloud, &mesh, &options, &Silent).unwrap();
        assert!(
            r.objects.is_empty(),
            "translation {translation}: found {:?}",
            r.objects.iter().map(|o| o.existence).collect::<Vec<_>>()
        );
    }
}

#[test]
fn the_search_gives_up_where_no_particle_pays_for_itself() {
    let mesh = asymmetric_object();
    let size = model_size(&mesh);
    let scene = |inliers: usize| {
        registration(
            &mesh,
            &RegistrationParams {
                inliers,
                outliers: 400,
                translation: 0.25 * size,
                seed: 2,
                ..Default::default()
            },
        )
        .unwrap()
    };
    let options = RegisterOptions {
        count: Some(1),
        min_confidence: 0.0,
        pair_hypotheses: 0, // the particle filter searches alone
        seed: 2,
        ..Default::default()
    };
    let give_up = options.give_up_rounds;
    assert!(give_up > 0);
    let rounds = |cloud, options: &RegisterOptions| {
        let r = register(cloud, &mesh, options, &Silent).unwrap();
        r.objects[0].rounds.len()
    };
    // Clutter alone: once the kernel is fine, no particle explains enough points to
    // pay for itself; the search stops after `give_up` such rounds instead of settling.
    let empty = scene(0);
    let patient = RegisterOptions {
        give_up_rounds: 0,
        ..options.clone()
    };
    let (quick, slow) = (
        rounds(&empty.cloud, &options),
        rounds(&empty.cloud, &patient),
    );
    assert!(quick >= give_up && quick < slow, "{quick} vs {slow} rounds");
    // With the object (80 % outliers) the search goes on and finds it.
    let present = scene(100);
    let r = register(&present.cloud, &mesh, &options, &Silent).unwrap();
    let o = &r.objects[0];
    assert!(o.rounds.len() > give_up, "{} rounds", o.rounds.len());
    let (rot, trans) = errors(&o.primitive.pose, &present.truth[0].pose, size);
    assert!(
        rot < MAX_ROTATION_DEG && trans < MAX_TRANSLATION_REL,
        "{rot}° {trans}"
    );
}

#[test]
fn result_json_lists_found_objects() {
    let mesh = asymmetric_object();
    let scene = registration(
        &mesh,
        &RegistrationParams {
            outliers: 100,
            seed: 2,
            ..Default::default()
        },
    )
    .unwrap();
    let options = RegisterOptions {
        seed: 2,
        ..Default::default()
    };
    let r: Registration = register(&scene.cloud, &mesh, &options, &Silent).unwrap();
    let doc = r.to_json(options.to_json(), serde_json::json!({}));
    let list = doc["primitives"].as_array().unwrap();
    assert_eq!(list.len(), 1);
    let p = &list[0];
    assert_eq!(p["type"], "mesh");
    assert!(p["existence"].as_f64().unwrap() >= 0.5);
    let share = p["inlier_share"].as_f64().unwrap();
    assert!((0.45..0.6).contains(&share), "{share}");
    let pose = Pose::from_json(&p["pose"]).unwrap();
    assert!(
        pose.rotation
            .angle_to(&scene.truth[0].pose.rotation)
            .to_degrees()
            < 3.0
    );
    assert_eq!(doc["settings"]["method"], "particle_filter");
    // Same seed, same answer.
    let again = register(&scene.cloud, &mesh, &options, &Silent).unwrap();
    assert_eq!(again.objects[0].primitive.pose, r.objects[0].primitive.pose);
}

#[test]
fn bad_options_are_errors() {
    let mesh = asymmetric_object();
    let scene = registration(&mesh, &RegistrationParams::default()).unwrap();
    for options in [
        RegisterOptions {
            kernel_shrink: 1.5,
            ..Default::default()
        },
        RegisterOptions {
            count: Some(0),
            ..Default::default()
        },
        RegisterOptions {
            scale: Some((2.0, 1.0)),
            ..Default::default()
        },
        RegisterOptions {
            translation: true,
            vote_bin: 0.0,
            ..Default::default()
        },
        RegisterOptions {
            translation: true,
            vote_keep: 0,
            ..Default::default()
        },
        RegisterOptions {
            basin_share: 0.5,
            ..Default::default()
        },
    ] {
        assert!(register(&scene.cloud, &mesh, &options, &Silent).is_err());
    }
    let empty = primfit_core::PointCloud::default();
    assert!(register(&empty, &mesh, &RegisterOptions::default(), &Silent).is_err());
    // Odd but valid vote settings degrade, they do not panic: no sample votes (spacing
    // beyond the model), or one huge vote cell.
    for (vote_spacing, vote_bin) in [(1e6, 0.08), (0.04, 1e6)] {
        let options = RegisterOptions {
            translation: true,
            count: Some(1),
            initial_particles: 50,
            vote_keep: 20,
            particles: 20,
            max_rounds: 2,
            vote_spacing,
            vote_bin,
            min_confidence: 0.0, // report the degraded answer, however poor
            ..Default::default()
        };
        let r = register(&scene.cloud, &mesh, &options, &Silent).unwrap();
        assert_eq!(r.objects.len(), 1);
    }
}
