//! One module per subcommand.

use std::path::Path;

use anyhow::{Result, bail};
use primfit_core::{Limit, PointCloud, io};

pub mod eval;
pub mod fit;
pub mod model;
pub mod register;
pub mod render;
pub mod sizes;
pub mod synth;
pub mod tiles;
pub mod view;

/// How much to print.
#[derive(Debug, Clone, Copy)]
pub struct Output {
    /// Print nothing but errors.
    pub quiet: bool,
    /// Print details.
    pub verbose: bool,
}

/// Reads the scan a command works on: an error naming the file when no point is left
/// (all of them NaN or infinite, or none at all), a warning when some were skipped.
pub fn read_scene(path: &Path, out: &Output) -> Result<PointCloud> {
    let (cloud, report) = io::read_cloud_report(path)?;
    if cloud.is_empty() && report.skipped_non_finite > 0 {
        bail!(
            "{}: the cloud has no points: all {} have a NaN or infinite coordinate",
            path.display(),
            report.skipped_non_finite
        );
    }
    if cloud.is_empty() {
        bail!("{}: the cloud has no points", path.display());
    }
    if report.skipped_non_finite > 0 && !out.quiet {
        eprintln!(
            "warning: {}: skipped {} of {} points with a NaN or infinite coordinate",
            path.display(),
            report.skipped_non_finite,
            report.vertices_in_file
        );
    }
    Ok(cloud)
}

/// Parses a comma-separated list of three numbers (`x,y,z`).
pub fn parse_point(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| e.to_string())?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => Err(format!("expected three finite numbers x,y,z, got {s:?}")),
    }
}

/// Parses a count or `inf` (unlimited).
pub fn parse_limit(s: &str) -> Result<Limit, String> {
    match s {
        "inf" | "all" | "none" => Ok(Limit::All),
        _ => match s.parse::<usize>() {
            Ok(0) => Err("must be at least 1 (or inf)".into()),
            Ok(n) => Ok(Limit::At(n)),
            Err(e) => Err(format!("{e} (expected a count or inf)")),
        },
    }
}

/// Parses two comma-separated numbers (`a,b`).
pub fn parse_pair(s: &str) -> Result<[f64; 2], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{e} (expected two numbers a,b)"))?;
    match v[..] {
        [a, b] => Ok([a, b]),
        _ => Err(format!("expected two numbers a,b, got {s:?}")),
    }
}

/// Checks, before any work is done, that `path` can be written as an output file: its
/// folder exists and it is not a folder itself, nor one of the `inputs`.
pub fn check_output(path: &Path, inputs: &[&Path]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if path.file_name().is_none() || path.is_dir() {
        bail!("{}: is a folder, not an output file", path.display());
    }
    if !dir.is_dir() {
        bail!(
            "{}: cannot write: the folder {} does not exist",
            path.display(),
            dir.display()
        );
    }
    io::writable_target(path)?;
    for input in inputs {
        if same_file(path, input) {
            bail!(
                "{}: refusing to overwrite an input file with output",
                path.display()
            );
        }
    }
    Ok(())
}

/// Whether two paths name the same existing file.
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}
