//! Golden outputs: `primfit fit` on every bundled example must give the primitives and
//! measures recorded in `tests/golden/` (timings aside), with three pipelines:
//!
//! - `auto`: no flags, the compact model (`--types auto`);
//! - `refined`: the square lattice with the estimated frame and refinement
//!   (`--types square`, the default before the compact model; recorded before the
//!   pipeline was restructured);
//! - `lattice`: the plain lattice (`--types square --frame axis --no-refine`).
//!
//! A change of behaviour shows up here.
//!
//! To re-record after a deliberate change of behaviour: `PRIMFIT_BLESS=1 cargo test -p
//! primfit-cli --test golden`, and say why in the commit message.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// Relative tolerance of every compared number: the fits are deterministic, but a
/// parallel floating-point sum may round differently across thread counts.
const RELATIVE: f64 = 1e-7;
/// Absolute tolerance, for numbers near zero (quaternion components, coordinates).
const ABSOLUTE: f64 = 1e-9;

/// The bundled example scans.
const EXAMPLES: [&str; 3] = ["hallway", "pipe", "plane_scan"];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn golden_path(name: &str, pipeline: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(format!("{name}-{pipeline}.json"))
}

/// Runs `primfit fit` on `examples/NAME.ply` with `extra` flags; returns the result JSON.
fn fit(name: &str, pipeline: &str, extra: &[&str]) -> Value {
    let dir = std::env::temp_dir().join(format!(
        "primfit-golden-{}-{name}-{pipeline}",
        std::process::id()
    ));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    let out_path = dir.join(format!("{name}.json"));
    let scene = root().join("examples").join(format!("{name}.ply"));
    let out = Command::new(env!("CARGO_BIN_EXE_primfit"))
        .arg("fit")
        .arg(&scene)
        .arg("-o")
        .arg(&out_path)
        .arg("--quiet")
        .args(extra)
        .output()
        .expect("run primfit");
    assert!(
        out.status.success(),
        "primfit fit {name} {extra:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = fs::read_to_string(&out_path).unwrap();
    let _ = fs::remove_dir_all(&dir);
    serde_json::from_str(&text).unwrap()
}

/// The part of a result that behaviour decides: primitives, metrics and the resolved
/// settings, without timings or the version.
fn behaviour(result: &Value) -> Value {
    let mut settings = result["settings"].clone();
    if let Some(map) = settings.as_object_mut() {
        map.retain(|k, _| !k.contains("seconds") && k != "threads" && k != "scene");
    }
    serde_json::json!({
        "settings": settings,
        "metrics": result["metrics"],
        "primitives": result["primitives"],
    })
}

/// Compares `got` with `want`, collecting differences as "path: got vs want" lines.
fn compare(path: &str, got: &Value, want: &Value, diffs: &mut Vec<String>) {
    match (got, want) {
        (Value::Number(a), Value::Number(b)) => {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            if (a - b).abs() > ABSOLUTE.max(RELATIVE * b.abs()) {
                diffs.push(format!("{path}: {a} vs {b}"));
            }
        }
        (Value::Array(a), Value::Array(b)) => {
            if a.len() != b.len() {
                diffs.push(format!("{path}: {} items vs {}", a.len(), b.len()));
                return;
            }
            for (i, (x, y)) in a.iter().zip(b).enumerate() {
                compare(&format!("{path}[{i}]"), x, y, diffs);
            }
        }
        (Value::Object(a), Value::Object(b)) => {
            for (k, y) in b {
                match a.get(k) {
                    Some(x) => compare(&format!("{path}.{k}"), x, y, diffs),
                    None => diffs.push(format!("{path}.{k}: missing")),
                }
            }
        }
        _ if got != want => diffs.push(format!("{path}: {got} vs {want}")),
        _ => {}
    }
}

fn check(name: &str, pipeline: &str, extra: &[&str]) {
    let got = behaviour(&fit(name, pipeline, extra));
    let path = golden_path(name, pipeline);
    if std::env::var_os("PRIMFIT_BLESS").is_some() {
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        fs::write(&path, serde_json::to_string_pretty(&got).unwrap() + "\n").unwrap();
        return;
    }
    let want: Value = serde_json::from_str(
        &fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())),
    )
    .unwrap();
    let mut diffs = Vec::new();
    compare("", &got, &want, &mut diffs);
    assert!(
        diffs.is_empty(),
        "{name} ({pipeline}) differs from {}:\n{}",
        path.display(),
        diffs[..diffs.len().min(40)].join("\n")
    );
}

#[test]
fn default_pipeline_is_unchanged_on_every_example() {
    for name in EXAMPLES {
        check(name, "auto", &[]);
    }
}

#[test]
fn refined_lattice_pipeline_is_unchanged_on_every_example() {
    for name in EXAMPLES {
        check(name, "refined", &["--types", "square"]);
    }
}

#[test]
fn lattice_pipeline_is_unchanged_on_every_example() {
    for name in EXAMPLES {
        check(
            name,
            "lattice",
            &["--types", "square", "--frame", "axis", "--no-refine"],
        );
    }
}
