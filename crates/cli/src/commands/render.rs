//! `primfit render`: a PNG of a scan and its fit.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use primfit_core::io;
use primfit_core::render::{RenderOptions, View, render};

use super::model::read_model;
use super::{Output, check_output};

/// Arguments of `primfit render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The scan (any cloud format `fit` reads).
    pub scene: PathBuf,
    /// A result JSON (from `fit`, `register`, or a `synth` truth).
    pub result: PathBuf,
    /// The picture to write (PNG).
    #[arg(short, long, value_name = "fit.png")]
    pub output: PathBuf,
    /// Look from `azimuth,elevation` in degrees about the scene's +z axis (azimuth 0 =
    /// from +x, 90 = from +y; elevation 90 = from straight above), as matplotlib's
    /// azim, elev [default: from above and in front of the cloud's principal frame].
    #[arg(long, value_name = "AZ,EL", allow_hyphen_values = true)]
    pub view: Option<String>,
    /// Image size in pixels, `WIDTHxHEIGHT`.
    #[arg(long, value_name = "WxH", default_value = "1200x900")]
    pub size: String,
    /// Distance (scene units) at the top of the points' colour scale [default: the 95th
    /// percentile of the drawn points' distances to the model].
    #[arg(allow_hyphen_values = true, long)]
    pub scale: Option<f64>,
}

/// Parses `WIDTHxHEIGHT`.
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let parsed = s
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)));
    match parsed {
        Some(size) => Ok(size),
        None => bail!("--size must be WIDTHxHEIGHT in pixels (e.g. 1200x900), got {s:?}"),
    }
}

/// Runs `primfit render`.
pub fn run(args: RenderArgs, out: &Output) -> Result<()> {
    let view = args.view.as_deref().map(str::parse::<View>).transpose()?;
    let (width, height) = parse_size(&args.size)?;
    check_output(&args.output, &[&args.scene, &args.result])?;
    let cloud = io::read_cloud(&args.scene)?;
    let (primitives, _) = read_model(&args.result)?;
    let options = RenderOptions {
        width,
        height,
        view,
        scale: args.scale,
        max_points: None,
    };
    let picture = render(&cloud.points, &primitives, &options)
        .with_context(|| format!("rendering {}", args.scene.display()))?;
    picture.write_png(&args.output)?;
    if !out.quiet {
        println!(
            "wrote {} ({width}×{height}): {} of {} points coloured by distance to {} primitives, \
             violet 0 → yellow {:.4} scene units",
            args.output.display(),
            picture.points_drawn,
            cloud.len(),
            primitives.len(),
            picture.scale
        );
    }
    Ok(())
}
