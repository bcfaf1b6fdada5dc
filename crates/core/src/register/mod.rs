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
//!    primitive** (the scene's bounding box uniformly filled at the density whose
//!    expected nearest-sample distance is the round's kernel, `geometry.rs`) and any
//!    objects already found;
//! 2. each particle is measured by the binary chamfer decrease when it is added to the
//!    background (outlier primitive + found objects): `Δ_i = Σ_y max(0, b(y) − d_i(y))
//!    − w_prim g_i` (squared scene units, the sum over all cloud points; `g_i` the
//!    chamfer's primitive term), the "exp(−Δloss)" weighting. The existence
//!    probabilities of the continuous solve are not the weight: the existence model
//!    keeps one of two near-identical particles and zeroes the other, which would
//!    collapse the population onto one survivor; so the rounds build only `g` and no
//!    solve ([`score_poses`] gives both, for study);
//! 3. weights `∝ exp(Δ_i / T)`, with `T` set so that the effective sample size is a fixed
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
//! [`RegisterOptions::settle_rounds`] rounds at the final kernel, and gives up after
//! [`RegisterOptions::give_up_rounds`] rounds in a row in which no particle paid its
//! primitive term (the search for one more object in a scene that has no more).
//!
//! **Point-pair hypotheses.** On a partial view the filter's search over rotations can
//! settle in a wrong basin whose surface also lies along the seen side. With translation
//! search, each seen surface patch also votes directly for the poses that put a model
//! patch on it (point-pair features, `ppf.rs`); the
//! [`RegisterOptions::pair_hypotheses`] poses with the most votes are tries of the final
//! choice. They are settled first: when the best of them is already sure
//! ([`RegisterOptions::accept_without_search`]), the filter does not run.
//!
//! **Final choice** (`choice.rs`). The point-pair hypotheses, the best particle and the
//! best of every other basin (or, where a basin is empty, the best particle's flip) are
//! settled by ICP (point-to-surface Gauss–Newton steps, `icp.rs`) and measured; the
//! best is refined against the exact mesh surface down to the inlier distance, so the
//! answer is precise, not just particle-close. Its existence is a calibrated
//! probability of the margin by which its pose beats the outlier-only explanation
//! around its surface, and of its lead over the best other answer ([`confidence`]; with
//! sensor origins, points the posed object would hide from their sensor do not count
//! for it); an object below
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
mod ppf;
mod vote;

mod choice;
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
use crate::spatial::{BoxTree, PointIndex};
use crate::{Error, PointCloud, Pose, Result, Stopwatch};
use choice::Unexplained;
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
        cloud_index: PointIndex::new(&cloud.points),
        cloud_boxes: BoxTree::new(&cloud.points),
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
    let m = context.measure(found, poses, kernel, options.min_support, &mut rng)?;
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
    let mut clock = Stopwatch::start();
    check_count(options.count, cloud.len(), options.min_support)?;
    let (context, flips) = context(cloud, mesh, options)?;
    clock.lap("model");
    let size = context.size;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let wanted = options.count.unwrap_or(options.max_objects);
    progress.start("register", (wanted * options.max_rounds) as u64);
    let mut objects: Vec<FoundObject> = Vec::new();
    // The points no object found so far explains: each new object's margin is measured
    // on them, so a second copy of a found object has no support.
    let mut unexplained = Unexplained::all(cloud);
    let hypotheses = pair_hypotheses(&context, cloud, mesh);
    clock.lap("point_pairs");
    // Polished once: each search measures them on the points still unexplained.
    let pair_tries = choice::polish_all(&context, cloud, mesh, &hypotheses, 1.0);
    clock.lap("polish");
    for _ in 0..wanted {
        let found: Vec<Pose> = objects.iter().map(|o| o.primitive.pose).collect();
        let object = find_object(
            &context,
            cloud,
            &unexplained,
            (mesh, &flips),
            &pair_tries,
            (&found, &mut rng),
            (progress, &mut clock),
        )?;
        if object.existence < options.min_confidence {
            if options.count.is_none() {
                break;
            }
            // Asked for `count` objects: keep searching, but do not report this one.
            continue;
        }
        let inlier = options.inlier_distance * size * object.primitive.pose.scale;
        unexplained.remove_near(&object.primitive, inlier);
        objects.push(object);
    }
    progress.finish();
    Ok(Registration {
        objects,
        model_size: size,
        seconds: start.elapsed().as_secs_f64(),
        timings: clock.times,
    })
}

/// The next object: the point-pair hypotheses `pair_tries`, polished by ICP
/// (`choice.rs`) and measured on the points `unexplained`, are accepted as they are when the best of them already reaches
/// [`RegisterOptions::accept_without_search`]; otherwise the particle filter searches
/// (conditioned on the objects `found`) and its answer's symmetry tries join them in
/// the final choice.
fn find_object(
    context: &Context,
    cloud: &PointCloud,
    unexplained: &Unexplained,
    (mesh, flips): (&MeshShape, &[Pose]),
    pair_tries: &[choice::Polished],
    (found, rng): (&[Pose], &mut ChaCha8Rng),
    (progress, clock): (&dyn Progress, &mut Stopwatch),
) -> Result<FoundObject> {
    let options = context.options;
    let mut tries = choice::measure_all(context, unexplained, pair_tries);
    let sure = choice::choose(context, unexplained, &tries);
    clock.lap("measure");
    if let Some(answer) = sure
        && answer.existence >= options.accept_without_search
    {
        progress.advance(options.max_rounds as u64);
        let start = tries[answer.pick].start;
        return Ok(choice::found_object(
            cloud,
            tries,
            answer,
            start,
            Vec::new(),
            context,
        ));
    }
    let filtered = context.run(found, rng, progress)?;
    clock.lap("filter");
    let scale = filtered.pose.scale;
    let starts = symmetry_starts(flips, &filtered);
    tries.extend(choice::settle_all(
        context,
        cloud,
        unexplained,
        mesh,
        &starts,
        scale,
    ));
    let answer =
        choice::choose(context, unexplained, &tries).expect("the filter's answer is a try");
    clock.lap("settle");
    Ok(choice::found_object(
        cloud,
        tries,
        answer,
        filtered.pose,
        filtered.rounds,
        context,
    ))
}

/// The point-pair-feature hypotheses of the object's pose in `cloud` (`ppf.rs`), with
/// translation search and no scale search (the features are not scale-invariant);
/// none otherwise or with [`RegisterOptions::pair_hypotheses`] = 0.
fn pair_hypotheses(context: &Context, cloud: &PointCloud, mesh: &MeshShape) -> Vec<Pose> {
    let options = context.options;
    if !options.translation || options.scale.is_some() || options.pair_hypotheses == 0 {
        return Vec::new();
    }
    ppf::PpfModel::new(mesh, context.size).hypotheses(
        &cloud.points,
        &context.cloud_index,
        cloud.sensors.as_deref(),
        options.pair_hypotheses,
    )
}

/// Approximate symmetries: the filter's best pose turned by π about each principal
/// axis of the model (through the rotation pivot) — or where the filter kept a particle
/// in that basin, its best there; the first is the best pose itself.
fn symmetry_starts(flips: &[Pose], filtered: &FilterResult) -> Vec<Pose> {
    flips
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let basin = k
                .checked_sub(1)
                .and_then(|b| filtered.basins.get(b).copied());
            basin.flatten().unwrap_or_else(|| filtered.pose.compose(f))
        })
        .collect()
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
