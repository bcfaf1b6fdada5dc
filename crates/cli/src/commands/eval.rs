//! `primfit eval`: the measures of DESIGN §4 for a result against a scan.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use primfit_core::metrics::{Metrics, MetricsOptions, evaluate};
use primfit_core::{PointCloud, Primitive};
use serde_json::Value;

use super::{Output, read_scene};

/// Arguments of `primfit eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// The scan (PLY).
    pub scene: PathBuf,
    /// A result JSON (from `fit`, `register`, or a `synth` truth).
    pub result: PathBuf,
    /// Ground truth (result JSON) for precision, recall and scene accuracy.
    #[arg(long, value_name = "truth.json")]
    pub truth: Option<PathBuf>,
    /// Coverage threshold τ in scene units [default: twice the median point spacing].
    #[arg(allow_hyphen_values = true, long)]
    pub tau: Option<f64>,
    /// Always print JSON, even on a terminal.
    #[arg(long)]
    pub json: bool,
}

/// The DESIGN §4 measures with default options.
pub fn measure(
    cloud: &PointCloud,
    model: &[Primitive],
    truth: Option<&[Primitive]>,
) -> Result<Metrics> {
    Ok(evaluate(
        &cloud.points,
        model,
        truth,
        &MetricsOptions::default(),
    )?)
}

/// Reads the primitives of a result JSON; mesh sources are resolved relative to it.
pub fn read_primitives(path: &Path) -> Result<Vec<Primitive>> {
    let doc = super::model::read_document(path)?;
    let list = doc
        .get("primitives")
        .and_then(Value::as_array)
        .with_context(|| format!("{}: no \"primitives\" array", path.display()))?;
    let load = super::model::mesh_loader(path);
    list.iter()
        .enumerate()
        .map(|(k, v)| {
            Primitive::from_json(v, &load)
                .with_context(|| format!("{}: primitive {k}", path.display()))
        })
        .collect()
}

/// Runs `primfit eval`.
pub fn run(a: EvalArgs, out: &Output) -> Result<()> {
    let cloud = read_scene(&a.scene, out)?;
    let model = read_primitives(&a.result)?;
    let truth = a.truth.as_deref().map(read_primitives).transpose()?;
    let options = MetricsOptions {
        coverage_tau: a.tau,
        ..Default::default()
    };
    let m = evaluate(&cloud.points, &model, truth.as_deref(), &options)
        .with_context(|| format!("evaluating {}", a.result.display()))?;
    let json = m.to_json();
    if !a.json && std::io::stdout().is_terminal() && !out.quiet {
        print_table(&json);
    } else {
        println!("{}", serde_json::to_string_pretty(&json)?);
    }
    Ok(())
}

fn print_table(json: &Value) {
    if let Some(map) = json.as_object() {
        let width = map.keys().map(String::len).max().unwrap_or(0);
        for (k, v) in map {
            let text = v
                .as_f64()
                .map_or_else(|| v.to_string(), |x| format!("{x:.6}"));
            println!("{k:<width$}  {text}");
        }
    }
}
