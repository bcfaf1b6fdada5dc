//! The harness the CLI test files share: a temp folder per test, running the binary, and
//! the two outcomes every test checks (success; one `error:` line naming the fault).
#![allow(dead_code)] // each test file uses a part

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A fresh, empty folder for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("primfit-cli-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// The repository root (for `examples/`).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A bundled example scan, `examples/NAME.ply`, as a path string.
pub fn example(name: &str) -> String {
    root()
        .join("examples")
        .join(format!("{name}.ply"))
        .display()
        .to_string()
}

/// The `primfit` command, run in `dir`, with backtraces on and colours off.
pub fn command(dir: &Path, args: &[&str]) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_primfit"));
    command
        .args(args)
        .current_dir(dir)
        .env("RUST_BACKTRACE", "1")
        .env("NO_COLOR", "1");
    command
}

/// Runs `primfit ARGS` in `dir` with piped output; asserts that nothing panicked.
pub fn primfit(dir: &Path, args: &[&str]) -> Output {
    let out = command(dir, args).output().expect("run primfit");
    let (stdout, stderr) = texts(&out);
    for text in [&stdout, &stderr] {
        assert!(
            !text.contains("panicked") && !text.contains("stack backtrace"),
            "primfit {args:?} panicked:\n{text}"
        );
    }
    out
}

/// stdout and stderr as text.
pub fn texts(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs `primfit ARGS` and asserts success; returns (stdout, stderr).
pub fn ok(dir: &Path, args: &[&str]) -> (String, String) {
    let out = primfit(dir, args);
    let (stdout, stderr) = texts(&out);
    assert!(
        out.status.success(),
        "primfit {args:?} failed ({:?}):\n{stdout}\n{stderr}",
        out.status.code()
    );
    (stdout, stderr)
}

/// Runs `primfit ARGS`, asserts exit code 1 and a single `error:` line on stderr that
/// contains `needle` (the file or flag at fault); returns that line.
pub fn fails(dir: &Path, args: &[&str], needle: &str) -> String {
    let out = primfit(dir, args);
    let (stdout, stderr) = texts(&out);
    assert_eq!(
        out.status.code(),
        Some(1),
        "primfit {args:?} should fail with 1:\n{stdout}\n{stderr}"
    );
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "one error line expected:\n{stderr}");
    assert_eq!(
        stderr.trim_end().lines().count(),
        1,
        "nothing but the error line expected on stderr:\n{stderr}"
    );
    let line = errors[0].to_string();
    assert!(
        line.contains(needle),
        "the error should name {needle:?}: {line}"
    );
    line
}

/// The names in a folder.
pub fn file_names(dir: &Path) -> BTreeSet<String> {
    fs::read_dir(dir)
        .expect("list dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect()
}

/// Writes an ascii PLY of `points` (x y z doubles), with `extra` appended after the
/// header's vertex element (more elements) and `body_extra` after the vertices.
pub fn write_ascii_ply(path: &Path, points: &[[f64; 3]], extra: &str, body_extra: &str) {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\n{extra}end_header\n",
        points.len()
    );
    for p in points {
        text.push_str(&format!("{:?} {:?} {:?}\n", p[0], p[1], p[2]));
    }
    text.push_str(body_extra);
    fs::write(path, text).expect("write ply");
}

/// A 1 m × 1 m floor and a wall sampled on a 5 cm grid, with a little deterministic
/// jitter: a small scene every command accepts.
pub fn floor_and_wall() -> Vec<[f64; 3]> {
    let mut pts = Vec::new();
    for i in 0..20 {
        for j in 0..20 {
            let (u, v) = (i as f64 * 0.05, j as f64 * 0.05);
            let e = 0.001 * (((i * 7 + j * 13) % 11) as f64 / 11.0 - 0.5);
            pts.push([u, v, e]);
            pts.push([u, e, v]);
        }
    }
    pts
}
