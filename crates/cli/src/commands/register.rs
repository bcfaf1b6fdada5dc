//! `primfit register`: find the pose(s) of a mesh in a scan (particle filter with the
//! probabilistic chamfer as measurement, then trimmed ICP), each with its calibrated
//! existence.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use primfit_core::atlas::MeshShape;
use primfit_core::io;
use primfit_core::na::Vector3;
use primfit_core::register::{RegisterOptions, register};

use super::{Output, check_output, parse_point, read_scene};
use crate::progress::Bars;

/// Arguments of `primfit register`. Relative sizes are fractions of the model size (the
/// diagonal of the mesh's bounding box).
#[derive(Debug, Args)]
pub struct RegisterArgs {
    /// The scan: a PLY point cloud.
    pub scene: PathBuf,
    /// The object: a triangle mesh (PLY with faces), in its own local frame.
    #[arg(long, value_name = "object.ply")]
    pub model: PathBuf,
    /// Write the result JSON here (one `"type": "mesh"` entry per object found).
    #[arg(short, long, value_name = "result.json")]
    pub output: Option<PathBuf>,
    /// Seed for every random choice.
    #[arg(allow_hyphen_values = true, long, default_value_t = 0)]
    pub seed: u64,
    /// Search for K objects (those below --min-confidence are not reported) [default:
    /// as many as exist].
    #[arg(allow_hyphen_values = true, long, value_name = "K")]
    pub count: Option<usize>,
    /// Estimate the rotation only, about the mesh's origin placed at `--at` (by default
    /// the full pose: rotation and translation).
    #[arg(long)]
    pub rotation_only: bool,
    /// The full pose (the default; kept for old command lines).
    #[arg(long, hide = true, conflicts_with = "rotation_only")]
    pub translation: bool,
    /// With `--rotation-only`: where the mesh's origin is, `x,y,z` [default: 0,0,0].
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true, requires = "rotation_only")]
    pub at: Option<[f64; 3]>,
    /// Report only objects whose calibrated existence (the probability that the object
    /// is there at that pose) is at least this, in 0..1.
    #[arg(allow_hyphen_values = true, long, value_name = "P")]
    pub min_confidence: Option<f64>,
    /// Also estimate a uniform scale, within `--scale-range`.
    #[arg(long)]
    pub scale: bool,
    /// Scale range `lo,hi` for `--scale`.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0.5,2",
        allow_hyphen_values = true
    )]
    pub scale_range: Vec<f64>,
    /// Particles of the first round.
    #[arg(allow_hyphen_values = true, long)]
    pub initial_particles: Option<usize>,
    /// Particles of later rounds.
    #[arg(allow_hyphen_values = true, long)]
    pub particles: Option<usize>,
    /// Round limit per object.
    #[arg(allow_hyphen_values = true, long)]
    pub max_rounds: Option<usize>,
    /// Points an object must explain beyond clutter to exist.
    #[arg(allow_hyphen_values = true, long)]
    pub min_support: Option<f64>,
    /// Inlier distance, fraction of the model size.
    #[arg(allow_hyphen_values = true, long)]
    pub inlier_distance: Option<f64>,
    /// Skip the final ICP refinement.
    #[arg(long)]
    pub no_icp: bool,
}

impl RegisterArgs {
    fn options(&self) -> Result<RegisterOptions> {
        let d = RegisterOptions::default();
        let scale = match (self.scale, self.scale_range.as_slice()) {
            (false, _) => None,
            (true, [a, b]) => Some((*a, *b)),
            (true, _) => bail!("--scale-range needs two numbers lo,hi"),
        };
        let options = RegisterOptions {
            translation: !self.rotation_only,
            fixed_translation: self.at.map_or(Vector3::zeros(), Vector3::from),
            scale,
            count: self.count,
            initial_particles: self.initial_particles.unwrap_or(d.initial_particles),
            particles: self.particles.unwrap_or(d.particles),
            max_rounds: self.max_rounds.unwrap_or(d.max_rounds),
            min_support: self.min_support.unwrap_or(d.min_support),
            inlier_distance: self.inlier_distance.unwrap_or(d.inlier_distance),
            min_confidence: self.min_confidence.unwrap_or(d.min_confidence),
            icp: !self.no_icp,
            seed: self.seed,
            ..d
        };
        options.validate()?;
        Ok(options)
    }
}

/// Runs `primfit register`.
pub fn run(args: RegisterArgs, out: &Output) -> Result<()> {
    let options = args.options()?;
    if let Some(path) = &args.output {
        check_output(path, &[&args.scene, &args.model])?;
    }
    let mesh = MeshShape::new(
        args.model.display().to_string(),
        io::read_mesh(&args.model)?,
    )?;
    let cloud = read_scene(&args.scene, out)?;
    let bars = Bars::new(out.quiet, out.verbose);
    let result = register(&cloud, &mesh, &options, &bars)
        .with_context(|| format!("registering {}", args.scene.display()))?;
    let prims: Vec<_> = result.objects.iter().map(|o| o.primitive.clone()).collect();
    let metrics = super::eval::measure(&cloud, &prims, None)?;
    if let Some(path) = &args.output {
        let mut settings = options.to_json();
        settings["scene"] = args.scene.display().to_string().into();
        settings["model"] = args.model.display().to_string().into();
        let doc = result.to_json(settings, metrics.to_json());
        io::write_json_atomic(path, &doc)?;
    }
    if !out.quiet {
        println!(
            "{}: {} points → {} object(s) in {:.2} s",
            args.scene.display(),
            cloud.len(),
            result.objects.len(),
            result.seconds
        );
        if out.verbose {
            println!("stages: {}", result.timings.summary());
        }
        for (k, o) in result.objects.iter().enumerate() {
            let p = &o.primitive.pose;
            let (axis, angle) = p
                .rotation
                .axis_angle()
                .map_or((Vector3::z(), 0.0), |(a, t)| (a.into_inner(), t));
            println!(
                "  #{k}: rotation {:.2}° about [{:.3}, {:.3}, {:.3}], translation [{:.4}, {:.4}, {:.4}], scale {:.4}; existence {:.2} (margin {:.1} over clutter), inlier share {:.3}, rms {:.4}",
                angle.to_degrees(),
                axis.x,
                axis.y,
                axis.z,
                p.translation.x,
                p.translation.y,
                p.translation.z,
                p.scale,
                o.existence,
                o.margin,
                o.inlier_share,
                o.rms
            );
        }
        if let Some(path) = &args.output {
            println!("wrote result {}", path.display());
        }
    }
    Ok(())
}
