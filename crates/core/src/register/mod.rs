//! Particle-filter registration of a mesh in a cloud (thesis §6.3.3, issue 6).
//!
//! The particles are poses of one mesh: rotations and translations (the default),
//! optionally with a uniform scale, or rotations only (about the mesh's local origin,
//! the translation fixed: [`RegisterOptions::translation`] = false).
//!
//! **First population.** Rotation only: prior draws. With translation search, the 6-D
//! prior is far too large to sample a close pose from (thesis §6.3.3), so translations
//! are not drawn but **voted** (`vote.rs`): for each of
//! [`RegisterOptions::screen_draws`] prior rotations (and scales), every (cloud point,
//! model sample) pair votes for the translation that would put the sample on the
//! point; the object's points pile their votes on the true translation while the
//! outliers' votes spread out. Each rotation becomes [`RegisterOptions::vote_peaks`]
//! particles, one per vote peak; the [`RegisterOptions::vote_keep`] with the most votes,
//! their translations refined at point level, form the first population. The search
//! is then in effect over rotations only, where the filter works.
//!
//! **Every round:**
//!
//! 1. the particles form the candidate set, together with an explicit **outlier
//!    primitive** (points uniformly filling the scene's bounding box,
//!    `geometry.rs`) and any objects already found;
//! 2. the probabilistic chamfer (existence model, exact surface distances) is built over
//!    them and [`crate::solve::solve`] gives every particle's existence probability;
//! 3. each particle is measured by the binary chamfer decrease when it is added to the
//!    background (outlier primitive + found objects): `Δ_i = Σ_y max(0, b(y) − d_i(y))
//!    − w_prim g_i` (squared scene units, the sum over all cloud points), the
//!    "exp(−Δloss)" weighting. Existence alone is a poor weight: the existence model
//!    keeps one of two near-identical particles and zeroes the other, which would
//!    collapse the population onto one survivor;
//! 4. weights `∝ exp(Δ_i / T)`, with `T` set so that the effective sample size is a fixed
//!    share of the population ([`RegisterOptions::ess`]); the best particle is kept as
//!    is, the leaders are moved downhill by a few trimmed-ICP steps, the rest is
//!    resampled (systematic) and moved at random on SO(3) (exponential map of a Gaussian
//!    axis-angle vector), ℝ³ (Gaussian) and log-scale (Gaussian).
//!
//! **Symmetry basins.** A nearly symmetric object leaves several basins in the
//! measurement: the pose turned by π about a principal axis of the model
//! ([`symmetry_flips`]) explains almost as many points, and at the coarse kernels of the
//! first rounds sometimes more. Each round the leaders' flips join the population, and
//! every basin of the best particle's flips keeps a share of the particles
//! ([`RegisterOptions::basin_share`]), resampled by its own weights, so that each basin
//! is refined until the fine kernels tell them apart; the best particle of each basin
//! is a candidate of the final choice.
//!
//! The kernel width — the outlier primitive's expected nearest-sample distance, i.e. how
//! close a particle must come to a point to explain it better than "outlier" — starts at
//! [`RegisterOptions::kernel_start`] × the model size and shrinks geometrically each
//! round to [`RegisterOptions::kernel_end`] × size; the move spread shrinks with it. The
//! filter stops when the best pose has been stable for
//! [`RegisterOptions::settle_rounds`] rounds at the final kernel.
//!
//! The best particle and the best of every other basin (or, where a basin is empty, the
//! best particle's flip) are then settled by trimmed ICP and measured; the best is
//! refined by trimmed ICP against the exact mesh surface (`icp.rs`), so the
//! answer is precise, not just particle-close. Its existence is a calibrated
//! probability of the margin by which its pose beats the outlier-only explanation
//! around its surface ([`confidence`]); an object below
//! [`RegisterOptions::min_confidence`] is not reported. Several objects are found one
//! after another, each search conditioned on those already found (they join the
//! background), until a new one falls below `min_confidence`
//! ([`RegisterOptions::count`] = `None`) or `count` objects are found.
//!
//! Units and conventions: lengths in scene units (model size = diagonal of the mesh's
//! bounding box, in mesh units); poses map the mesh's local frame to the scene,
//! `x = s R x_local + t` (DESIGN §3); every random choice comes from one
//! [`rand_chacha::ChaCha8Rng`] seeded with [`RegisterOptions::seed`].

pub mod confidence;
mod geometry;
mod icp;
mod particle_filter;
mod vote;

mod options;
mod report;

pub use options::RegisterOptions;
pub use particle_filter::RoundStats;
pub use report::{FoundObject, Registration};

use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::atlas::{MeshShape, Shape};
use crate::progress::Progress;
use crate::{Error, PointCloud, Pose, Primitive, Result};
use geometry::DistanceGrid;
use particle_filter::{Context, FilterResult};

/// The search context of [`register`] and the model's symmetry flips.
fn context<'a>(
    cloud: &'a PointCloud,
    mesh: &MeshShape,
    options: &'a RegisterOptions,
) -> Result<(Context<'a>, Vec<Pose>)> {
    options.validate()?;
    let Some((lo, hi)) = crate::cloud::bounds_of(&cloud.points) else {
        return Err(Error::EmptyCloud);
    };
    let (mut mlo, mut mhi) = (
        Point3::from(Vector3::repeat(f64::INFINITY)),
        Point3::from(Vector3::repeat(f64::NEG_INFINITY)),
    );
    for v in &mesh.mesh.vertices {
        mlo = mlo.inf(v);
        mhi = mhi.sup(v);
    }
    let size = (mhi - mlo).norm();
    let centre = nalgebra::center(&mlo, &mhi);
    let shape = Shape::Mesh(mesh.clone());
    // The grid covers what the largest kernel can see; beyond it distances are bounds.
    let grid = Arc::new(DistanceGrid::new(mesh, 48, 0.25 * size));
    let spacing = options.sample_spacing * size;
    let samples = shape.sample_surface(spacing);
    // Moments (centre of area, principal axes) from a fine area-uniform sample.
    let fine = shape.sample_surface(size / 60.0);
    let mean = Point3::from(
        fine.iter().map(|p| p.coords).sum::<Vector3<f64>>() / fine.len().max(1) as f64,
    );
    let pivot = if options.translation {
        mean
    } else {
        Point3::origin()
    };
    let lever = (samples
        .iter()
        .map(|p| (p - pivot).norm_squared())
        .sum::<f64>()
        / samples.len().max(1) as f64)
        .sqrt()
        .max(1e-9 * size);
    let flips = symmetry_flips(&fine, &pivot);
    let voting = options.translation && options.vote_peaks > 0;
    let (vote_index, vote_samples) = if voting {
        (
            Some(vote::VoteIndex::new(&cloud.points, options.vote_bin * size)),
            shape
                .sample_surface(options.vote_spacing * size)
                .iter()
                .map(|p| p.coords)
                .collect(),
        )
    } else {
        (None, Vec::new())
    };
    let context = Context {
        cloud: &cloud.points,
        grid: grid.clone(),
        mesh: mesh.clone(),
        hull: samples.iter().map(|p| p - centre).collect(),
        area: shape.area(),
        template_spacing: spacing,
        shape: shape.clone(),
        lo,
        hi,
        size,
        centre,
        lever,
        vote_index,
        vote_samples,
        flips: flips.clone(),
        options,
    };
    Ok((context, flips))
}

/// The filter's measurement of `poses` in `cloud` with the kernel `kernel` (scene
/// units), next to the outlier primitive and the objects `found`: the binary chamfer
/// decrease of adding each pose alone (squared scene units; > 0 = it explains more
/// than clutter plus [`RegisterOptions::min_support`] points), and its existence in the
/// polished chamfer solve over all of them.
pub fn score_poses(
    cloud: &PointCloud,
    mesh: &MeshShape,
    options: &RegisterOptions,
    found: &[Pose],
    poses: Vec<Pose>,
    kernel: f64,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let (context, _) = context(cloud, mesh, options)?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let m = context.measure(found, poses, kernel, options.min_support, true, &mut rng)?;
    Ok((m.score, m.existence))
}

/// `count` objects can be found in a cloud of `points` points only if each explains at
/// least `min_support` of them (and one point at the least): refused up front
/// otherwise, so that no count asks for an unbounded search.
fn check_count(count: Option<usize>, points: usize, min_support: f64) -> Result<()> {
    let Some(count) = count else { return Ok(()) };
    let most = (points as f64 / min_support.max(1.0)).floor().max(1.0) as usize;
    if count > most {
        let expected = format!(
            "at most {most}: each object explains at least {min_support} of the {points} points"
        );
        return Err(Error::out_of_range("count", count, expected));
    }
    Ok(())
}

/// Registers `mesh` (local frame, mesh units) in `cloud`: finds the pose(s) of the
/// object(s) the cloud contains (see the module documentation).
///
/// Finding the built-in asymmetric object under a random rotation and translation among
/// 100 surface points and 100 uniform outliers:
///
/// ```
/// use primfit_core::Silent;
/// use primfit_core::register::{RegisterOptions, register};
/// use primfit_core::synth::{RegistrationParams, asymmetric_object, registration};
///
/// let mesh = asymmetric_object();
/// let scene = registration(&mesh, &RegistrationParams {
///     outliers: 100,
///     translation: 0.2,
///     ..Default::default()
/// })?;
/// let options = RegisterOptions {
///     count: Some(1), // the full pose (rotation and translation) is the default
///     ..Default::default()
/// };
/// let found = register(&scene.cloud, &mesh, &options, &Silent)?;
/// let (pose, truth) = (&found.objects[0].primitive.pose, &scene.truth[0].pose);
/// assert!(pose.rotation.angle_to(&truth.rotation).to_degrees() < 3.0);
/// assert!((pose.translation - truth.translation).norm() < 0.01 * found.model_size);
/// # Ok::<(), primfit_core::Error>(())
/// ```
pub fn register(
    cloud: &PointCloud,
    mesh: &MeshShape,
    options: &RegisterOptions,
    progress: &dyn Progress,
) -> Result<Registration> {
    let start = Instant::now();
    check_count(options.count, cloud.len(), options.min_support)?;
    let (context, flips) = context(cloud, mesh, options)?;
    let size = context.size;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let wanted = options.count.unwrap_or(options.max_objects);
    progress.start("register", (wanted * options.max_rounds) as u64);
    let mut objects: Vec<FoundObject> = Vec::new();
    // The points no object found so far explains: each new object's margin is measured
    // on them, so a second copy of a found object has no support.
    let mut unexplained = cloud.points.clone();
    for _ in 0..wanted {
        let found: Vec<Pose> = objects.iter().map(|o| o.primitive.pose).collect();
        let filtered = context.run(&found, &mut rng, progress)?;
        let object = settle_object(&context, cloud, &unexplained, mesh, &flips, filtered);
        if object.existence < options.min_confidence {
            if options.count.is_none() {
                break;
            }
            // Asked for `count` objects: keep searching, but do not report this one.
            continue;
        }
        let inlier = options.inlier_distance * size * object.primitive.pose.scale;
        unexplained.retain(|y| object.primitive.distance(y) > inlier);
        objects.push(object);
    }
    progress.finish();
    Ok(Registration {
        objects,
        model_size: size,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The object the filter's answer `filtered` stands for: each of its symmetry tries
/// ([`symmetry_tries`]) refined by trimmed ICP against the exact surface
/// ([`refine_object`]), the one with the largest margin over the outlier-only
/// explanation of the points `unexplained` by the objects found before kept
/// ([`confidence`]), with its calibrated existence (which also weighs how close the
/// best other try came).
fn settle_object(
    context: &Context,
    cloud: &PointCloud,
    unexplained: &[Point3<f64>],
    mesh: &MeshShape,
    flips: &[Pose],
    filtered: FilterResult,
) -> FoundObject {
    let options = context.options;
    let scale = filtered.pose.scale;
    let kernel = options.kernel_end * context.size * scale;
    let tries = symmetry_tries(context, cloud, mesh, flips, &filtered);
    let settled: Vec<(icp::IcpResult, f64)> = tries
        .iter()
        .map(|t| {
            let refined = refine_object(context, cloud, mesh, *t, kernel, scale);
            let margin = margin_of(context, unexplained, &refined.pose);
            (refined, margin)
        })
        .collect();
    let pick = (0..settled.len())
        .max_by(|&a, &b| settled[a].1.total_cmp(&settled[b].1).then(b.cmp(&a)))
        .unwrap_or(0);
    let chosen = settled[pick].0.pose;
    let runner_up = (0..settled.len())
        .filter(|&k| !same_pose(context, &chosen, &settled[k].0.pose))
        .map(|k| settled[k].1)
        .fold(f64::NEG_INFINITY, f64::max);
    let (refined, margin) = settled.into_iter().nth(pick).expect("one try at least");
    FoundObject {
        primitive: Primitive::new(context.shape.clone(), refined.pose),
        existence: confidence::existence(margin, runner_up),
        margin,
        runner_up_margin: runner_up,
        inlier_share: refined.inliers.len() as f64 / cloud.len() as f64,
        rms: refined.rms,
        filter_pose: filtered.pose,
        rounds: filtered.rounds,
    }
}

/// Whether two poses are the same answer: rotations within [`SAME_ROTATION_DEG`] and
/// translations within the inlier distance × [`confidence::SHELL_FACTOR`].
fn same_pose(context: &Context, a: &Pose, b: &Pose) -> bool {
    let reach = confidence::SHELL_FACTOR * context.options.inlier_distance * context.size;
    a.rotation.angle_to(&b.rotation) < SAME_ROTATION_DEG.to_radians()
        && (a.translation - b.translation).norm() < reach * a.scale
}

/// Rotations closer than this (degrees) are one answer (see [`same_pose`]).
const SAME_ROTATION_DEG: f64 = 5.0;

/// The margin of the mesh at `pose` over the outlier-only explanation of `points`
/// ([`confidence::margin`]) at the inlier distance.
fn margin_of(context: &Context, points: &[Point3<f64>], pose: &Pose) -> f64 {
    let primitive = Primitive::new(context.shape.clone(), *pose);
    let inlier = context.options.inlier_distance * context.size * pose.scale;
    confidence::margin(confidence::support(points, &primitive, inlier))
}

/// Approximate symmetries: the filter's best pose turned by π about each principal
/// axis of the model (through the rotation pivot) — or where the filter kept a particle
/// in that basin, its best there — each polished by ICP from the first kernel down to
/// the last (with [`RegisterOptions::icp`]); the first is the best pose itself.
fn symmetry_tries(
    context: &Context,
    cloud: &PointCloud,
    mesh: &MeshShape,
    flips: &[Pose],
    filtered: &FilterResult,
) -> Vec<Pose> {
    let options = context.options;
    let (size, scale) = (context.size, filtered.pose.scale);
    let freedom = context.freedom();
    let settle = icp::IcpOptions {
        start_distance: options.kernel_start * size * scale,
        min_distance: options.kernel_end * size * scale,
        shrink: 0.8,
        max_iterations: 15,
        tolerance: 1e-6 * size * scale,
        scale_range: options.scale,
    };
    flips
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let p = match k
                .checked_sub(1)
                .and_then(|b| filtered.basins.get(b).copied().flatten())
            {
                Some(b) => b,
                None => filtered.pose.compose(f),
            };
            if options.icp {
                icp::refine(mesh, &context.grid, &cloud.points, p, freedom, &settle).pose
            } else {
                p
            }
        })
        .collect()
}

/// `chosen` refined by trimmed ICP against the exact mesh surface, from the kernel
/// `kernel` down to the inlier distance (at the pose's `scale`); without
/// [`RegisterOptions::icp`], no steps: only its inliers and RMS.
fn refine_object(
    context: &Context,
    cloud: &PointCloud,
    mesh: &MeshShape,
    chosen: Pose,
    kernel: f64,
    scale: f64,
) -> icp::IcpResult {
    let options = context.options;
    let size = context.size;
    let largest_scale = options.scale.map_or(1.0, |s| s.1);
    let inlier_distance = options.inlier_distance * size;
    icp::refine(
        mesh,
        &context.grid,
        &cloud.points,
        chosen,
        if options.icp {
            context.freedom()
        } else {
            icp::Freedom {
                translation: false,
                scale: false,
            }
        },
        &icp::IcpOptions {
            start_distance: kernel,
            min_distance: inlier_distance * scale,
            shrink: 0.8,
            max_iterations: if options.icp { 60 } else { 0 },
            tolerance: 1e-6 * size * largest_scale,
            scale_range: options.scale,
        },
    )
}

/// The identity and the turns by π about the three principal axes of `samples` (local
/// frame) through `pivot`, as poses to compose on the right of a found pose.
pub fn symmetry_flips(samples: &[Point3<f64>], pivot: &Point3<f64>) -> Vec<Pose> {
    let n = samples.len().max(1) as f64;
    let mean = samples.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n;
    let cov = samples
        .iter()
        .map(|p| (p.coords - mean) * (p.coords - mean).transpose())
        .sum::<nalgebra::Matrix3<f64>>()
        / n;
    let eigen = cov.symmetric_eigen();
    let mut out = vec![Pose::identity()];
    for k in 0..3 {
        let axis = nalgebra::Unit::new_normalize(eigen.eigenvectors.column(k).into_owned());
        let rotation = nalgebra::UnitQuaternion::from_axis_angle(&axis, std::f64::consts::PI);
        // x ↦ pivot + F (x − pivot)
        out.push(Pose::new(rotation, pivot.coords - rotation * pivot.coords));
    }
    out
}
