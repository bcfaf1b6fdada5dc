//! `primfit synth`: synthetic scenes with ground truth.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use primfit_core::atlas::{MeshShape, ShapeKind};
use primfit_core::fit::result_json;
use primfit_core::io::{self, Encoding};
use primfit_core::synth::{self, Density, Misalignment, Noise, Scene};
use serde::Serialize;
use serde_json::Value;

use super::sizes::SizeArgs;
use super::{Output, check_output};

/// Scene kinds.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Kind {
    /// Floor, two walls and an optional ceiling tiled by squares (thesis §6.3.2).
    Hallway,
    /// A random chain of straight cylinders and right-angle elbows (thesis §6.3.1).
    Pipe,
    /// A subset of nine vertical cylinders on a 3×3 grid (thesis §5.5).
    NineCylinders,
    /// Six candidates in a row in front of a sensor, points on the fourth (thesis §4.3).
    SixInARow,
    /// A posed mesh drowned in uniform outliers (thesis §6.3.3).
    Registration,
    /// A posed mesh seen by a depth sensor from one random viewpoint (self-occluded,
    /// --jitter = range noise), with optional structured clutter (--plane,
    /// --distractors, --clutter-points) and uniform outliers; points carry the sensor.
    PartialView,
}

/// Arguments of `primfit synth`.
#[derive(Debug, Args)]
#[command(
    mut_arg("size", |a| a.help("Hallway square side, pipe segment length [default: 1]")),
    mut_arg("radius", |a| a.help("Pipe / cylinder radius")),
    mut_arg("bend", |a| a.help("Pipe elbow bend radius [default: size / 2]")),
)]
pub struct SynthArgs {
    /// The scene to generate.
    #[arg(value_enum)]
    pub kind: Kind,
    /// Output cloud (PLY).
    #[arg(short, long, value_name = "scene.ply")]
    pub output: PathBuf,
    /// Also write the true primitives as result JSON.
    #[arg(long, value_name = "truth.json")]
    pub truth: Option<PathBuf>,
    /// Write the PLY as ascii.
    #[arg(long)]
    pub ascii: bool,
    /// Random seed.
    #[arg(allow_hyphen_values = true, long, default_value_t = 0)]
    pub seed: u64,
    /// Per-point Gaussian noise σ (scene units) [default: per scene].
    #[arg(allow_hyphen_values = true, long)]
    pub jitter: Option<f64>,
    /// Per-primitive Gaussian offset σ (scene units).
    #[arg(allow_hyphen_values = true, long, default_value_t = 0.0)]
    pub drift: f64,
    /// Largest random shift against the lattice, as a fraction of its spacing
    /// (nine-cylinders: of the grid pitch).
    #[arg(allow_hyphen_values = true, long, default_value_t = 0.0)]
    pub offset: f64,
    /// Largest random rotation against the lattice, degrees.
    #[arg(allow_hyphen_values = true, long, default_value_t = 0.0)]
    pub angle: f64,
    /// Total number of points [default: from a per-scene density].
    #[arg(allow_hyphen_values = true, long)]
    pub points: Option<usize>,
    /// Sizes of the true primitives.
    #[command(flatten)]
    pub sizes: SizeArgs,
    /// Hallway length [default: 10].
    #[arg(allow_hyphen_values = true, long)]
    pub length: Option<f64>,
    /// Hallway width [default: 2].
    #[arg(allow_hyphen_values = true, long)]
    pub width: Option<f64>,
    /// Hallway wall height [default: 2.5].
    #[arg(allow_hyphen_values = true, long)]
    pub height: Option<f64>,
    /// Hallway with a ceiling.
    #[arg(long)]
    pub ceiling: bool,
    /// Pipe: number of straight runs.
    #[arg(allow_hyphen_values = true, long)]
    pub segments: Option<usize>,
    /// Nine cylinders: which of the nine exist, as a 9-bit mask (0..=511).
    #[arg(long, default_value_t = 0b1_1111_1111)]
    pub mask: u16,
    /// Registration: the object mesh (PLY with faces) [default: a built-in asymmetric object].
    #[arg(long, value_name = "object.ply")]
    pub model: Option<PathBuf>,
    /// Registration: points on the object.
    #[arg(allow_hyphen_values = true, long, default_value_t = 100)]
    pub inliers: usize,
    /// Registration: uniform outliers.
    #[arg(allow_hyphen_values = true, long, default_value_t = 1900)]
    pub outliers: usize,
    /// Replace the sampled cloud by a simulated depth-sensor scan of the truth from this
    /// many poses (a walk down the hallway, an orbit around other scenes): points get
    /// sensor origins (for `fit --method mcmc`), normals and labels (flat face-up: 1
    /// ground at the floor; vertical: 2 wall; other: 0). --jitter is the range noise.
    #[arg(allow_hyphen_values = true, long, value_name = "FRAMES")]
    pub scan: Option<usize>,
    /// Registration: number of objects (side by side along x).
    #[arg(allow_hyphen_values = true, long, default_value_t = 1)]
    pub objects: usize,
    /// Registration: largest random translation per axis (scene units) [default: 0,
    /// rotation only].
    #[arg(allow_hyphen_values = true, long, default_value_t = 0.0)]
    pub translation: f64,
    /// Partial view: a plane under the object, facing the sensor.
    #[arg(long)]
    pub plane: bool,
    /// Partial view: other objects (spheres, cylinders) beside the object.
    #[arg(long, default_value_t = 0)]
    pub distractors: usize,
    /// Partial view: points kept from the scan of the plane and the other objects.
    #[arg(long, default_value_t = 0)]
    pub clutter_points: usize,
    /// Partial view: leave the object out (clutter only; the truth is empty).
    #[arg(long)]
    pub no_object: bool,
}

fn density(points: Option<usize>, default: Density) -> Density {
    points.map_or(default, Density::Total)
}

/// Runs `primfit synth`.
pub fn run(a: SynthArgs, out: &Output) -> Result<()> {
    check_args(&a)?;
    let (scene, extra) = generate(&a)?;
    let scene = match a.scan {
        Some(frames) => rescan(scene, frames, &a)?,
        None => scene,
    };
    if scene.cloud.is_empty() {
        bail!("the scene would have no points (see --points, --inliers, --outliers)");
    }
    write(&a, &scene, extra)?;
    if !out.quiet {
        println!(
            "{}: {} points, {} true primitives (lattice spacing {}); wrote {}",
            a.kind
                .to_possible_value()
                .map_or("scene".into(), |v| v.get_name().to_string()),
            scene.cloud.len(),
            scene.truth.len(),
            scene.lattice.spacing,
            a.output.display()
        );
    }
    Ok(())
}

/// Checks the output paths (not an input, not the same file twice) and `--points`.
fn check_args(a: &SynthArgs) -> Result<()> {
    let inputs: Vec<&std::path::Path> = a.model.as_deref().into_iter().collect();
    check_output(&a.output, &inputs)?;
    if let Some(truth) = &a.truth {
        check_output(truth, &inputs)?;
        if truth == &a.output {
            bail!("{}: given both as -o and as --truth", truth.display());
        }
    }
    if a.points == Some(0) {
        bail!("--points must be at least 1");
    }
    Ok(())
}

/// The scene-specific fields of a truth's settings (`settings.scene`).
#[derive(Debug, Serialize)]
#[serde(untagged)]
enum SceneFields {
    /// Hallway, pipe: none.
    Plain {},
    /// Nine cylinders: which exist.
    NineCylinders { mask: u16 },
    /// Six in a row: the one the points lie on.
    SixInARow { true_index: usize },
    /// Registration: the scene's counts.
    Registration {
        inliers: usize,
        outliers: usize,
        objects: usize,
        translation: f64,
    },
}

/// `settings` of a truth's `result.json`: the scene's parameters and lattice.
#[derive(Debug, Serialize)]
struct TruthSettings {
    kind: Option<String>,
    seed: u64,
    jitter: Option<f64>,
    drift: f64,
    offset: f64,
    angle_degrees: f64,
    lattice: TruthLattice,
    scene: SceneFields,
}

/// `settings.lattice` of a truth: the lattice its primitives lie on.
#[derive(Debug, Serialize)]
struct TruthLattice {
    spacing: f64,
    origin: [f64; 3],
}

/// The scene of `a.kind` with its parameters from `a` (the rest per-scene defaults),
/// and the scene-specific fields of the truth's settings.
fn generate(a: &SynthArgs) -> Result<(Scene, SceneFields)> {
    Ok(match a.kind {
        Kind::Hallway => (hallway(a)?, SceneFields::Plain {}),
        Kind::Pipe => (pipe(a)?, SceneFields::Plain {}),
        Kind::NineCylinders => {
            if a.mask > 511 {
                bail!("--mask must be in 0..=511, got {}", a.mask);
            }
            (
                nine_cylinders(a)?,
                SceneFields::NineCylinders { mask: a.mask },
            )
        }
        Kind::SixInARow => {
            let d = synth::SixInARowParams::default();
            let p = synth::SixInARowParams {
                points: a.points.unwrap_or(d.points),
                jitter: a.jitter.unwrap_or(d.jitter),
                seed: a.seed,
                ..d
            };
            let six = synth::six_in_a_row(&p)?;
            let fields = SceneFields::SixInARow {
                true_index: six.true_index,
            };
            (six.scene, fields)
        }
        Kind::PartialView => (
            partial_view(a)?,
            SceneFields::Registration {
                inliers: if a.no_object { 0 } else { a.inliers },
                outliers: a.outliers,
                objects: usize::from(!a.no_object),
                translation: a.translation,
            },
        ),
        Kind::Registration => (
            registration(a)?,
            SceneFields::Registration {
                inliers: a.inliers,
                outliers: a.outliers,
                objects: a.objects,
                translation: a.translation,
            },
        ),
    })
}

/// The noise of `a` (`--jitter`, else `default_jitter`; `--drift`).
fn noise(a: &SynthArgs, default_jitter: f64) -> Noise {
    Noise {
        jitter: a.jitter.unwrap_or(default_jitter),
        drift: a.drift,
    }
}

/// The misalignment against the lattice of `a` (`--offset`, `--angle`).
fn misalignment(a: &SynthArgs) -> Misalignment {
    Misalignment {
        offset: a.offset,
        angle: a.angle.to_radians(),
    }
}

/// The hallway scene of `a` (per-scene defaults for what `a` leaves out).
fn hallway(a: &SynthArgs) -> Result<Scene> {
    let d = synth::HallwayParams::default();
    let p = synth::HallwayParams {
        length: a.length.unwrap_or(d.length),
        width: a.width.unwrap_or(d.width),
        height: a.height.unwrap_or(d.height),
        side: a.sizes.size.unwrap_or(d.side),
        ceiling: a.ceiling,
        density: density(a.points, d.density),
        noise: noise(a, d.noise.jitter),
        misalignment: misalignment(a),
        seed: a.seed,
    };
    Ok(synth::hallway(&p)?)
}

/// The pipe scene of `a` (per-scene defaults for what `a` leaves out).
fn pipe(a: &SynthArgs) -> Result<Scene> {
    let d = synth::PipeParams::default();
    let p = synth::PipeParams {
        segments: a.segments.unwrap_or(d.segments),
        segment_length: a.sizes.size.unwrap_or(d.segment_length),
        bend: a.sizes.bend.or(d.bend),
        radius: a.sizes.radius.or(d.radius),
        density: density(a.points, d.density),
        noise: noise(a, d.noise.jitter),
        misalignment: misalignment(a),
        seed: a.seed,
        ..d
    };
    Ok(synth::pipe(&p)?)
}

/// The nine-cylinder scene of `a` (`--mask` already checked).
fn nine_cylinders(a: &SynthArgs) -> Result<Scene> {
    let d = synth::NineCylinderParams::default();
    let p = synth::NineCylinderParams {
        mask: a.mask,
        radius: a.sizes.radius.unwrap_or(d.radius),
        density: density(a.points, d.density),
        noise: noise(a, d.noise.jitter),
        offset: a.offset,
        seed: a.seed,
        ..d
    };
    Ok(synth::nine_cylinders(&p)?)
}

/// The registration scene: `--model` (or the built-in asymmetric object) posed among
/// uniform outliers.
fn registration(a: &SynthArgs) -> Result<Scene> {
    let mesh = match &a.model {
        Some(path) => MeshShape::new(path.display().to_string(), io::read_mesh(path)?)?,
        None => synth::asymmetric_object(),
    };
    let d = synth::RegistrationParams::default();
    let p = synth::RegistrationParams {
        inliers: a.inliers,
        outliers: a.outliers,
        objects: a.objects,
        translation: a.translation,
        noise: noise(a, d.noise.jitter),
        seed: a.seed,
        ..d
    };
    Ok(synth::registration(&mesh, &p)?)
}

/// The partial-view registration scene of `a`.
fn partial_view(a: &SynthArgs) -> Result<Scene> {
    let mesh = match &a.model {
        Some(path) => MeshShape::new(path.display().to_string(), io::read_mesh(path)?)?,
        None => synth::asymmetric_object(),
    };
    let d = synth::PartialViewParams::default();
    let p = synth::PartialViewParams {
        inliers: a.inliers,
        outliers: a.outliers,
        clutter_points: a.clutter_points,
        plane: a.plane,
        distractors: a.distractors,
        object: !a.no_object,
        translation: a.translation,
        range_noise: a.jitter.unwrap_or(d.range_noise),
        seed: a.seed,
        ..d
    };
    Ok(synth::partial_view(&mesh, &p)?)
}

/// Replaces the cloud of `scene` by a depth-sensor scan of its truth.
fn rescan(mut scene: Scene, frames: usize, a: &SynthArgs) -> Result<Scene> {
    use primfit_core::na::{Point3, Vector3};
    if frames == 0 {
        bail!("--scan needs at least one frame");
    }
    let (lo, hi) = primfit_core::bounds_of(&scene.cloud.points)
        .context("the scene has no points to place the sensor")?;
    let centre = Point3::from((lo.coords + hi.coords) / 2.0);
    let extent = hi - lo;
    let poses = match a.kind {
        Kind::Hallway => {
            let eye = |x: f64| Point3::new(x, centre.y, lo.z + 1.2f64.min(extent.z * 0.6));
            synth::walk_poses(eye(lo.x + 0.3), eye(hi.x - 2.0), frames, 3.0, 0.6)?
        }
        _ => synth::orbit_poses(
            centre,
            1.5 * extent.norm().max(1e-3),
            0.5 * extent.z,
            frames,
        )?,
    };
    let labels = scene
        .truth
        .iter()
        .map(|p| {
            let n = p.pose.rotation * Vector3::z();
            let flat = matches!(
                p.shape.kind(),
                ShapeKind::Square | ShapeKind::Disk | ShapeKind::Plane
            );
            match (flat, n.z.abs()) {
                (true, c) if c > 0.9 && p.center().z <= lo.z + 1e-6 => 1,
                (true, c) if c < 1e-6 => 2,
                _ => 0,
            }
        })
        .collect();
    let params = synth::SensorParams {
        poses,
        columns: 160,
        rows: 120,
        max_range: 4.0 * extent.norm().max(1.0),
        range_noise: a.jitter.unwrap_or(0.01),
        labels: Some(labels),
        normals: true,
        seed: a.seed,
        ..Default::default()
    };
    scene.cloud = synth::depth_sensor(&scene.truth, &params)?;
    Ok(scene)
}

fn write(a: &SynthArgs, scene: &Scene, extra: SceneFields) -> Result<()> {
    let encoding = if a.ascii {
        Encoding::Ascii
    } else {
        Encoding::BinaryLittleEndian
    };
    // Both outputs or neither: the truth is staged, the cloud written, then the truth
    // renamed into place.
    let mut staged = None;
    if let Some(path) = &a.truth {
        let h = &scene.lattice;
        let settings = TruthSettings {
            kind: a.kind.to_possible_value().map(|v| v.get_name().to_string()),
            seed: a.seed,
            jitter: a.jitter,
            drift: a.drift,
            offset: a.offset,
            angle_degrees: a.angle,
            lattice: TruthLattice {
                spacing: h.spacing,
                origin: h.origin.coords.into(),
            },
            scene: extra,
        };
        let existence = vec![1.0; scene.truth.len()];
        let no_metrics = Value::Object(Default::default());
        let doc = result_json(
            serde_json::to_value(settings)?,
            no_metrics,
            &scene.truth,
            &existence,
        );
        staged = Some(io::stage_json(path, &doc).context("writing the truth")?);
    }
    io::write_cloud(&a.output, &scene.cloud, encoding)?;
    if let Some(truth) = staged {
        truth.commit().context("writing the truth")?;
    }
    Ok(())
}
