//! `primfit fit --tiles` through the binary: the same outputs as a fit, close to its
//! primitives; bad tile flags and a missing Python fail with one line.

mod common;

use common::{example, fails, ok, primfit, temp_dir};
use serde_json::Value;

fn primitives(dir: &std::path::Path, name: &str) -> usize {
    let text = std::fs::read_to_string(dir.join(name)).expect("result json");
    let doc: Value = serde_json::from_str(&text).expect("json");
    doc["primitives"].as_array().expect("primitives").len()
}

#[test]
fn a_tiled_fit_writes_the_same_outputs_close_to_one_fit() {
    let dir = temp_dir("tiles");
    let scene = example("hallway");
    ok(&dir, &["fit", &scene, "-o", "one.json", "--quiet"]);
    let (out, _) = ok(
        &dir,
        &[
            "fit",
            &scene,
            "--tiles",
            "--tile-size",
            "4",
            "-o",
            "tiled.json",
            "--mesh",
            "tiled.ply",
        ],
    );
    assert!(out.contains("primitives"), "{out}");
    assert!(dir.join("tiled.ply").is_file());
    let (a, b) = (primitives(&dir, "one.json"), primitives(&dir, "tiled.json"));
    assert!(a.abs_diff(b) <= 2, "one fit {a}, tiled {b}");
}

#[test]
fn bad_tile_flags_fail_with_one_line() {
    let dir = temp_dir("tiles-bad");
    let scene = example("hallway");
    fails(
        &dir,
        &["fit", &scene, "--tiles", "--tile-size", "-1"],
        "tile_size",
    );
    fails(
        &dir,
        &["fit", &scene, "--tiles", "--tile-size", "4", "--halo", "9"],
        "halo",
    );
    let out = primfit(&dir, &["fit", &scene, "--tile-size", "4"]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "--tile-size without --tiles is a usage error"
    );
    let out = common::command(&dir, &["fit", &scene, "--tiles", "--scheduler", "local"])
        .env("PRIMFIT_PYTHON", dir.join("no-such-python"))
        .output()
        .expect("run primfit");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("primfit[dask]"), "{err}");
}
