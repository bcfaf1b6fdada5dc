//! `primfit register` end to end: synth scene → register → result JSON.

use std::process::Command;

use primfit_core::io::{self, Encoding};
use primfit_core::synth::asymmetric_object;

fn primfit() -> Command {
    Command::new(env!("CARGO_BIN_EXE_primfit"))
}

#[test]
fn register_writes_one_mesh_entry_per_object() {
    let dir = std::env::temp_dir().join(format!("primfit-register-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("object.ply");
    io::write_mesh(&model, &asymmetric_object().mesh, None, Encoding::Ascii).unwrap();
    let scene = dir.join("scene.ply");
    let truth = dir.join("truth.json");
    let status = primfit()
        .args([
            "--quiet",
            "synth",
            "registration",
            "--seed",
            "2",
            "--outliers",
            "400",
        ])
        .arg("-o")
        .arg(&scene)
        .arg("--truth")
        .arg(&truth)
        .status()
        .unwrap();
    assert!(status.success());
    let result = dir.join("result.json");
    let out = primfit()
        .arg("register")
        .arg(&scene)
        .arg("--model")
        .arg(&model)
        .arg("-o")
        .arg(&result)
        .args(["--seed", "2"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&result).unwrap()).unwrap();
    let list = doc["primitives"].as_array().unwrap();
    assert_eq!(list.len(), 1);
    assert_eq!(list[0]["type"], "mesh");
    assert!(list[0]["existence"].as_f64().unwrap() >= 0.5);
    assert!(list[0]["inlier_share"].as_f64().unwrap() > 0.15);
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    let q = |v: &serde_json::Value| -> Vec<f64> {
        v["rotation"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (a, b) = (q(&list[0]["pose"]), q(&truth["primitives"][0]["pose"]));
    let dot: f64 = a
        .iter()
        .zip(&b)
        .map(|(x, y)| x * y)
        .sum::<f64>()
        .abs()
        .min(1.0);
    let angle = 2.0 * dot.acos().to_degrees();
    assert!(angle < 3.0, "rotation error {angle}°");
    assert!(doc["settings"]["seed"] == 2);

    // Errors: one line, exit status 1.
    let out = primfit()
        .arg("register")
        .arg(&scene)
        .arg("--model")
        .arg(dir.join("missing.ply"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `primfit register --translation --scale`: a scene (written with the library) whose
/// object is scaled by 1.3 among 80 % outliers; the scale is recovered within 1 %.
#[test]
fn register_scale_recovers_a_known_scale() {
    use primfit_core::synth::{RegistrationParams, registration};
    let dir = std::env::temp_dir().join(format!("primfit-register-scale-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = asymmetric_object();
    let model = dir.join("object.ply");
    io::write_mesh(&model, &mesh.mesh, None, Encoding::BinaryLittleEndian).unwrap();
    let scene = registration(
        &mesh,
        &RegistrationParams {
            inliers: 100,
            outliers: 400,
            translation: 0.3,
            scale: Some((1.3, 1.3)),
            seed: 5,
            ..Default::default()
        },
    )
    .unwrap();
    let cloud = dir.join("scene.ply");
    io::write_cloud(&cloud, &scene.cloud, Encoding::BinaryLittleEndian).unwrap();
    let result = dir.join("result.json");
    let out = primfit()
        .args(["--quiet", "register"])
        .arg(&cloud)
        .arg("--model")
        .arg(&model)
        .arg("-o")
        .arg(&result)
        .args(["--translation", "--scale", "--scale-range", "0.5,2"])
        .args(["--count", "1", "--seed", "5"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&result).unwrap()).unwrap();
    let pose = primfit_core::Pose::from_json(&doc["primitives"][0]["pose"]).unwrap();
    let truth = scene.truth[0].pose;
    assert!(
        (pose.scale - 1.3).abs() < 0.013,
        "scale {} (truth 1.3)",
        pose.scale
    );
    assert!(pose.rotation.angle_to(&truth.rotation).to_degrees() < 3.0);
    assert!((pose.translation - truth.translation).norm() < 0.01 * 1.3 * 1.43);
    assert_eq!(doc["settings"]["scale"], serde_json::json!([0.5, 2.0]));
    // A bad range is an error, not a panic.
    let out = primfit()
        .args(["--quiet", "register"])
        .arg(&cloud)
        .arg("--model")
        .arg(&model)
        .args(["--scale", "--scale-range", "2,0.5"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.starts_with("error: --scale-range must be"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `primfit synth partial-view` then `primfit register` with the defaults: the full pose
/// of the object in a partial view (near side only, a plane and two other objects,
/// uniform outliers), its calibrated existence and margin in the JSON; `--min-confidence`
/// filters; bad confidences and `--at` without `--rotation-only` are errors.
#[test]
fn register_defaults_to_the_full_pose_on_a_partial_view() {
    let dir = std::env::temp_dir().join(format!("primfit-register-view-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("object.ply");
    io::write_mesh(&model, &asymmetric_object().mesh, None, Encoding::Ascii).unwrap();
    let (scene, truth) = (dir.join("view.ply"), dir.join("truth.json"));
    let status = primfit()
        .args([
            "--quiet",
            "synth",
            "partial-view",
            "--seed",
            "1",
            "--translation",
            "0.3",
        ])
        .args([
            "--inliers",
            "200",
            "--outliers",
            "600",
            "--clutter-points",
            "200",
        ])
        .args(["--plane", "--distractors", "2", "--jitter", "0.004"])
        .arg("-o")
        .arg(&scene)
        .arg("--truth")
        .arg(&truth)
        .status()
        .unwrap();
    assert!(status.success());
    let cloud = io::read_cloud(&scene).unwrap();
    assert_eq!(cloud.len(), 1000);
    assert_eq!(cloud.sensors.as_ref().map(Vec::len), Some(1000));
    let read = |p: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let truth = primfit_core::Pose::from_json(&read(&truth)["primitives"][0]["pose"]).unwrap();
    let result = dir.join("result.json");
    let register = |extra: &[&str]| {
        primfit()
            .args(["--quiet", "register"])
            .arg(&scene)
            .arg("--model")
            .arg(&model)
            .arg("-o")
            .arg(&result)
            .args(["--seed", "1"])
            .args(extra)
            .output()
            .unwrap()
    };
    let out = register(&[]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc = read(&result);
    let list = doc["primitives"].as_array().unwrap();
    assert_eq!(list.len(), 1, "{list:?}");
    let pose = primfit_core::Pose::from_json(&list[0]["pose"]).unwrap();
    assert!(pose.rotation.angle_to(&truth.rotation).to_degrees() < 5.0);
    assert!((pose.translation - truth.translation).norm() < 0.02 * 1.43);
    let existence = list[0]["existence"].as_f64().unwrap();
    assert!((0.5..=0.99).contains(&existence), "{existence}");
    assert!(list[0]["margin"].as_f64().unwrap() > 10.0);
    assert_eq!(doc["settings"]["translation"], true);
    // Nothing is certain: --min-confidence 1 reports nothing.
    let out = register(&["--min-confidence", "1"]);
    assert!(out.status.success());
    assert!(read(&result)["primitives"].as_array().unwrap().is_empty());
    // Errors: one line, non-zero exit.
    for bad in [&["--min-confidence", "2"][..], &["--at", "0,0,0"][..]] {
        let out = register(bad);
        assert!(!out.status.success(), "{bad:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("confidence") || err.contains("rotation-only"),
            "{err}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
