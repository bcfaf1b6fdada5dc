//! The `plane` type through the binary: a result JSON with bounded planes (outline and
//! hole in their local frames) is read by `primfit eval` and measured against a scan of
//! exactly those surfaces.

use std::fs;
use std::path::PathBuf;
use std::process::Command;

use serde_json::{Value, json};

/// Point pitch of the synthetic scan (m).
const PITCH: f64 = 0.02;

/// A 2 m × 1 m floor (z = 0) with a 0.4 m × 0.2 m hole at its centre, and a 2 m × 1 m
/// wall (y = 0.5, x ∈ [−1, 1], z ∈ [0, 1]), sampled every [`PITCH`] at cell centres.
fn scene() -> Vec<[f64; 3]> {
    let mut points = Vec::new();
    let (nx, ny) = ((2.0 / PITCH) as usize, (1.0 / PITCH) as usize);
    for i in 0..nx {
        for j in 0..ny {
            let (u, v) = (
                -1.0 + (i as f64 + 0.5) * PITCH,
                -0.5 + (j as f64 + 0.5) * PITCH,
            );
            if !(u.abs() < 0.2 && v.abs() < 0.1) {
                points.push([u, v, 0.0]);
            }
            points.push([u, 0.5, (j as f64 + 0.5) * PITCH]);
        }
    }
    points
}

#[test]
fn eval_measures_a_result_with_bounded_planes() {
    let dir = std::env::temp_dir().join(format!("primfit-cli-{}-plane", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    let points = scene();
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nend_header\n",
        points.len()
    );
    for p in &points {
        ply += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    fs::write(dir.join("scene.ply"), ply).expect("write scene");
    // The wall's local frame: x along scene x, y up (scene z), normal −y; origin at its
    // bottom edge's middle.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let result = json!({ "primitives": [
        { "type": "plane", "size": { "area": 1.92 },
          "pose": { "translation": [0.0, 0.0, 0.0], "rotation": [1.0, 0.0, 0.0, 0.0], "scale": 1.0 },
          "outline": [[-1.0, -0.5], [1.0, -0.5], [1.0, 0.5], [-1.0, 0.5]],
          "holes": [[[-0.2, -0.1], [-0.2, 0.1], [0.2, 0.1], [0.2, -0.1]]],
          "existence": 1.0 },
        { "type": "plane", "size": { "area": 2.0 },
          "pose": { "translation": [0.0, 0.5, 0.0], "rotation": [s, s, 0.0, 0.0], "scale": 1.0 },
          "outline": [[-1.0, 0.0], [1.0, 0.0], [1.0, 1.0], [-1.0, 1.0]],
          "existence": 1.0 } ] });
    fs::write(dir.join("planes.json"), result.to_string()).expect("write result");
    let out = Command::new(env!("CARGO_BIN_EXE_primfit"))
        .args(["eval", "scene.ply", "planes.json", "--json", "-q"])
        .current_dir(&dir)
        .env("RUST_BACKTRACE", "1")
        .output()
        .expect("run primfit");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let metrics: Value = serde_json::from_str(&stdout).expect("metrics JSON");
    let get = |k: &str| metrics[k].as_f64().unwrap_or(f64::NAN);
    assert_eq!(metrics["primitives"], 2);
    assert!(get("point_to_model_max") < 1e-9, "{metrics}");
    assert_eq!(get("coverage"), 1.0, "{metrics}");
    // The planes end where the points end: model samples are within a pitch of them.
    assert!(get("model_to_point_mean") < PITCH, "{metrics}");
    let _ = fs::remove_dir_all(PathBuf::from(&dir));
}
