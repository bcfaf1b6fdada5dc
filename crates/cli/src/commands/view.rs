//! `primfit view`: a self-contained HTML page to orbit a scan and its fit.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use primfit_core::io;
use primfit_core::render::{DEFAULT_HTML_POINTS, HtmlOptions, write_html};

use super::model::read_model;
use super::{Output, check_output};

/// Arguments of `primfit view`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// The scan (any cloud format `fit` reads).
    pub scene: PathBuf,
    /// A result JSON (from `fit`, `register`, or a `synth` truth).
    pub result: PathBuf,
    /// The page to write (HTML; opens offline in any browser with WebGL 2).
    #[arg(short, long, value_name = "fit.html")]
    pub output: PathBuf,
    /// The most points embedded in the page (an even subsample of larger clouds; about
    /// 17 bytes per point).
    #[arg(allow_hyphen_values = true, long, default_value_t = DEFAULT_HTML_POINTS)]
    pub max_points: usize,
    /// Distance (scene units) at the top of the points' colour scale [default: the 95th
    /// percentile of the embedded points' distances to the model].
    #[arg(allow_hyphen_values = true, long)]
    pub scale: Option<f64>,
}

/// Runs `primfit view`.
pub fn run(args: ViewArgs, out: &Output) -> Result<()> {
    check_output(&args.output, &[&args.scene, &args.result])?;
    let cloud = io::read_cloud(&args.scene)?;
    let (primitives, existence) = read_model(&args.result)?;
    let title = args.scene.file_name().map_or_else(
        || args.scene.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let options = HtmlOptions {
        title,
        max_points: args.max_points,
        scale: args.scale,
    };
    let summary = write_html(
        &args.output,
        &cloud,
        &primitives,
        existence.as_deref(),
        &options,
    )
    .with_context(|| format!("writing {}", args.output.display()))?;
    if !out.quiet {
        println!(
            "wrote {} ({:.1} MB): {} of {} points, {} primitives",
            args.output.display(),
            summary.bytes as f64 / 1e6,
            summary.points_embedded,
            summary.points_total,
            primitives.len()
        );
    }
    Ok(())
}
