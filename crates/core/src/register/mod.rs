//! Particle-filter registration of a mesh in a cloud (thesis §6.3.3, issue 6).
//!
//! The particles are poses of one mesh: rotations only (about the mesh's local origin,
//! the translation fixed), or rotations and translations, optionally with a uniform
//! scale.
//!
//! **First population.** Rotation only: prior draws. With translation search, the 6-D
//! prior is far too large to sample a close pose from (thesis §6.3.3), so translations
//! are not drawn but **voted** ([`vote`]): for each of
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
//!    [`geometry::OutlierBox`]) and any objects already found;
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
//! refined by trimmed ICP against the exact mesh surface ([`icp::refine`]), so the
//! answer is precise, not just particle-close. Its existence is
//! decided by a last chamfer solve over {outlier primitive, found objects, new pose};
//! several objects are found one after another, each search conditioned on those already
//! found (they join the background), until a new one does not exist
//! ([`RegisterOptions::count`] = `None`) or `count` objects are found.
//!
//! Units and conventions: lengths in scene units (model size = diagonal of the mesh's
//! bounding box, in mesh units); poses map the mesh's local frame to the scene,
//! `x = s R x_local + t` (DESIGN §3); every random choice comes from one
//! [`rand_chacha::ChaCha8Rng`] seeded with [`RegisterOptions::seed`].

pub mod geometry;
pub mod icp;
pub mod particle_filter;
pub mod vote;

use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde_json::{Value, json};

use crate::atlas::{MeshShape, Shape};
use crate::check::{self, Interval};
use crate::progress::Progress;
use crate::{Error, PointCloud, Pose, Primitive, Result};
use geometry::DistanceGrid;
use particle_filter::{Context, RoundStats};

/// Settings of [`register`]. Fractions are of the model size (the diagonal of the mesh's
/// bounding box, scene units after the pose's scale).
#[derive(Debug, Clone, PartialEq)]
pub struct RegisterOptions {
    /// Estimate the translation (else it is [`RegisterOptions::fixed_translation`]).
    pub translation: bool,
    /// The translation when it is not estimated (scene units).
    pub fixed_translation: Vector3<f64>,
    /// Estimate a uniform scale within this range (`None` = scale 1).
    pub scale: Option<(f64, f64)>,
    /// Find exactly this many objects; `None` = as many as exist (at most `max_objects`).
    pub count: Option<usize>,
    /// Upper bound on the objects found automatically.
    pub max_objects: usize,
    /// Particles of the first round (drawn from the prior).
    pub initial_particles: usize,
    /// Prior draws screened for the first population (see
    /// [`RegisterOptions::initial_particles`]); `None` = `initial_particles`, or with
    /// translation search but no votes ([`RegisterOptions::vote_peaks`] = 0), 8 ×
    /// `initial_particles` (the 6-D prior is far larger). With votes, each draw is a
    /// rotation (and scale) that gets `vote_peaks` translations.
    pub screen: Option<usize>,
    /// Cloud points (a stride subsample) of the screening proxy.
    pub screen_points: usize,
    /// With translation search: vote peaks kept per prior rotation of the first
    /// population ([`vote::vote_translation`]; each becomes a particle with that
    /// translation); 0 = draw translations from the prior instead.
    pub vote_peaks: usize,
    /// With translation votes: the candidates (rotation, vote peak) with the most votes
    /// that form the first population, each translation refined at point level
    /// ([`vote::refine_peak`]).
    pub vote_keep: usize,
    /// Bin (grid cell) of the translation vote, fraction of the model size.
    pub vote_bin: f64,
    /// Spacing of the model samples that vote, fraction of the model size.
    pub vote_spacing: f64,
    /// Particles of later rounds.
    pub particles: usize,
    /// Round limit per object.
    pub max_rounds: usize,
    /// First kernel width, fraction of the model size.
    pub kernel_start: f64,
    /// Last kernel width, fraction of the model size.
    pub kernel_end: f64,
    /// Kernel factor per round (in (0, 1)).
    pub kernel_shrink: f64,
    /// Move spread (σ of the translation; rotation σ = spread / lever arm), as a multiple
    /// of the kernel width.
    pub spread: f64,
    /// Translation moves are `translation_spread` × the spread of surface points under
    /// the rotation moves (rotations and translations are searched at different rates:
    /// a wrong rotation can gain a little by sliding, which would drag the population).
    pub translation_spread: f64,
    /// Rounds with a stable best pose at the last kernel before stopping.
    pub settle_rounds: usize,
    /// Target effective sample size, as a share of the particles (in (0, 1]).
    pub ess: f64,
    /// β of the chamfer: candidates kept per point.
    pub beta: usize,
    /// Weight of the chamfer's primitive term (its point term has weight 1); `None` =
    /// calibrated every round so that a typical particle pays what uniform clutter around
    /// its surface would gain it plus [`RegisterOptions::min_support`] points.
    pub primitive_weight: Option<f64>,
    /// Points an object must explain beyond what clutter explains to exist (with the
    /// calibrated primitive weight): the final existence decision.
    pub min_support: f64,
    /// The same, for the primitive weight of the search's measurement (how strongly the
    /// primitive term — model samples far from any point — counts against a particle).
    pub search_support: f64,
    /// Leading particles moved downhill each round by trimmed-ICP steps at the kernel.
    pub local_moves: usize,
    /// Leading particles whose approximate symmetry flips ([`symmetry_flips`]: turns by
    /// π about the model's principal axes) join the next round, each round: a jump
    /// between the basins a nearly symmetric object leaves in the measurement.
    pub flip_moves: usize,
    /// Share of the particles resampled within each other basin of the best particle
    /// (the basins of its symmetry flips), by the basin's own weights, each round.
    pub basin_share: f64,
    /// ICP steps of each such move.
    pub local_steps: usize,
    /// Most samples of the outlier primitive.
    pub max_outlier_samples: usize,
    /// Translation prior: the model, rotated and scaled, lies inside the scene's bounding
    /// box, its extents about its centre first multiplied by this (1 = wholly inside;
    /// less allows objects cut by the box).
    pub prior_margin: f64,
    /// Spacing of the particles' template samples, fraction of the model size.
    pub sample_spacing: f64,
    /// Refine each pose by trimmed ICP.
    pub icp: bool,
    /// Inlier distance: a cloud point within it of a found surface is that object's
    /// inlier (ICP's last correspondence distance); fraction of the model size.
    pub inlier_distance: f64,
    /// Existence threshold of a found object.
    pub threshold: f64,
    /// Seed of every random choice.
    pub seed: u64,
}

impl Default for RegisterOptions {
    fn default() -> Self {
        RegisterOptions {
            translation: false,
            fixed_translation: Vector3::zeros(),
            scale: None,
            count: None,
            max_objects: 8,
            initial_particles: 2000,
            screen: None,
            screen_points: 500,
            vote_peaks: 2,
            vote_keep: 400,
            vote_bin: 0.08,
            vote_spacing: 0.04,
            particles: 200,
            max_rounds: 40,
            kernel_start: 0.08,
            kernel_end: 0.02,
            kernel_shrink: 0.85,
            spread: 0.5,
            translation_spread: 0.25,
            settle_rounds: 2,
            ess: 0.1,
            beta: 8,
            primitive_weight: None,
            min_support: 50.0,
            search_support: 30.0,
            local_moves: 8,
            local_steps: 3,
            flip_moves: 2,
            basin_share: 0.1,
            max_outlier_samples: 200_000,
            prior_margin: 1.0,
            sample_spacing: 1.0 / 15.0,
            icp: true,
            inlier_distance: 0.01,
            threshold: 0.5,
            seed: 0,
        }
    }
}

impl RegisterOptions {
    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("kernel_start", self.kernel_start),
            ("kernel_end", self.kernel_end),
            ("spread", self.spread),
            ("translation_spread", self.translation_spread),
            ("sample_spacing", self.sample_spacing),
            ("vote_bin", self.vote_bin),
            ("vote_spacing", self.vote_spacing),
            ("inlier_distance", self.inlier_distance),
        ] {
            check::positive(name, v)?;
        }
        check::in_interval(
            "kernel_shrink",
            self.kernel_shrink,
            Interval::open(0.0, 1.0),
        )?;
        check::in_interval("basin_share", self.basin_share, Interval::closed(0.0, 0.3))?;
        check::in_interval("ess", self.ess, Interval::open_closed(0.0, 1.0))?;
        check::in_interval("threshold", self.threshold, Interval::UNIT)?;
        if let Some(w) = self.primitive_weight {
            check::non_negative("primitive_weight", w)?;
        }
        check::non_negative("min_support", self.min_support)?;
        check::non_negative("search_support", self.search_support)?;
        check::non_negative("prior_margin", self.prior_margin)?;
        for (name, k) in [
            ("initial_particles", self.initial_particles),
            ("particles", self.particles),
            ("max_rounds", self.max_rounds),
            ("vote_keep", self.vote_keep),
            ("beta", self.beta),
        ] {
            check::at_least(name, k, 1)?;
        }
        if let Some(k) = self.count {
            check::at_least("count", k, 1)?;
        }
        if let Some(range) = self.scale {
            check::positive_range("scale", range)?;
        }
        check::finite("fixed_translation", self.fixed_translation.as_slice())
    }

    /// Prior draws screened for the first population (resolves `screen: None`).
    pub fn screen_draws(&self) -> usize {
        self.screen
            .unwrap_or(if self.translation && self.vote_peaks == 0 {
                8 * self.initial_particles
            } else {
                self.initial_particles
            })
    }

    /// The options as JSON (the `settings` of `result.json`).
    pub fn to_json(&self) -> Value {
        let t = &self.fixed_translation;
        json!({
            "method": "particle_filter",
            "translation": self.translation,
            "fixed_translation": if self.translation { Value::Null } else { json!([t.x, t.y, t.z]) },
            "scale": self.scale.map(|(a, b)| json!([a, b])),
            "count": self.count,
            "max_objects": self.max_objects,
            "initial_particles": self.initial_particles,
            "screen": self.screen_draws(),
            "screen_points": self.screen_points,
            "vote_peaks": self.vote_peaks,
            "vote_keep": self.vote_keep,
            "vote_bin": self.vote_bin,
            "vote_spacing": self.vote_spacing,
            "particles": self.particles,
            "max_rounds": self.max_rounds,
            "kernel_start": self.kernel_start,
            "kernel_end": self.kernel_end,
            "kernel_shrink": self.kernel_shrink,
            "spread": self.spread,
            "translation_spread": self.translation_spread,
            "settle_rounds": self.settle_rounds,
            "ess": self.ess,
            "beta": self.beta,
            "primitive_weight": self.primitive_weight,
            "min_support": self.min_support,
            "search_support": self.search_support,
            "local_moves": self.local_moves,
            "local_steps": self.local_steps,
            "flip_moves": self.flip_moves,
            "basin_share": self.basin_share,
            "prior_margin": self.prior_margin,
            "sample_spacing": self.sample_spacing,
            "icp": self.icp,
            "inlier_distance": self.inlier_distance,
            "threshold": self.threshold,
            "seed": self.seed,
        })
    }
}

/// One object found by [`register`].
#[derive(Debug, Clone)]
pub struct FoundObject {
    /// The posed mesh.
    pub primitive: Primitive,
    /// Its existence probability in the final chamfer solve.
    pub existence: f64,
    /// Share of all cloud points within the inlier distance of its surface (0‥1).
    pub inlier_share: f64,
    /// RMS surface distance of those inliers (scene units).
    pub rms: f64,
    /// The filter's pose before ICP.
    pub filter_pose: Pose,
    /// Per-round statistics of its search.
    pub rounds: Vec<RoundStats>,
}

/// The result of [`register`].
#[derive(Debug, Clone)]
pub struct Registration {
    /// Objects found, in the order found (the strongest first).
    pub objects: Vec<FoundObject>,
    /// Model size used for the relative settings (scene units, scale 1).
    pub model_size: f64,
    /// Wall time (seconds).
    pub seconds: f64,
}

impl Registration {
    /// `result.json` (DESIGN §3): one `"type": "mesh"` entry per object found, with its
    /// pose, `existence` and `inlier_share`.
    pub fn to_json(&self, settings: Value, metrics: Value) -> Value {
        let prims: Vec<Primitive> = self.objects.iter().map(|o| o.primitive.clone()).collect();
        let existence: Vec<f64> = self.objects.iter().map(|o| o.existence).collect();
        let mut doc = crate::fit::result_json(settings, metrics, &prims, &existence);
        if let Some(list) = doc["primitives"].as_array_mut() {
            for (v, o) in list.iter_mut().zip(&self.objects) {
                v["inlier_share"] = json!(o.inlier_share);
            }
        }
        doc
    }
}

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

/// Registers `mesh` (local frame, mesh units) in `cloud`: finds the pose(s) of the
/// object(s) the cloud contains (see the module documentation).
///
/// Finding the built-in asymmetric object under a random rotation and translation among
/// 100 surface points and 100 uniform outliers:
///
/// ```
/// use primfit_core::progress::Silent;
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
///     translation: true, // search the translation too (default: rotation only)
///     count: Some(1),
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
    let (context, flips) = context(cloud, mesh, options)?;
    let (grid, size, shape) = (context.grid.clone(), context.size, context.shape.clone());
    let largest_scale = options.scale.map_or(1.0, |s| s.1);
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let wanted = options.count.unwrap_or(options.max_objects);
    progress.start("register", (wanted * options.max_rounds) as u64);
    let mut objects: Vec<FoundObject> = Vec::new();
    let inlier_distance = options.inlier_distance * size;
    for _ in 0..wanted {
        let found: Vec<Pose> = objects.iter().map(|o| o.primitive.pose).collect();
        let filtered = context.run(&found, &mut rng, progress)?;
        let scale = filtered.pose.scale;
        let kernel = options.kernel_end * size * scale;
        let freedom = context.freedom();
        // Approximate symmetries: also try the pose turned by π about each principal axis
        // of the model (through the rotation pivot), each polished by ICP at the kernel.
        let settle = icp::IcpOptions {
            start_distance: options.kernel_start * size * scale,
            min_distance: kernel,
            shrink: 0.8,
            max_iterations: 15,
            tolerance: 1e-6 * size * scale,
            scale_range: options.scale,
        };
        let tries: Vec<Pose> = flips
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
                    icp::refine(mesh, &grid, &cloud.points, p, freedom, &settle).pose
                } else {
                    p
                }
            })
            .collect();
        let m = context.measure(
            &found,
            tries.clone(),
            kernel,
            options.search_support,
            false,
            &mut rng,
        )?;
        let pick = (0..tries.len())
            .max_by(|&a, &b| m.score[a].total_cmp(&m.score[b]).then(b.cmp(&a)))
            .unwrap_or(0);

        let chosen = tries[pick];
        let refined = icp::refine(
            mesh,
            &grid,
            &cloud.points,
            chosen,
            if options.icp {
                freedom
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
        );
        // Existence of the new object next to the outlier primitive and those found.
        let m = context.measure(
            &found,
            vec![refined.pose],
            kernel,
            options.min_support,
            true,
            &mut rng,
        )?;
        let existence = m.existence[0];
        if options.count.is_none() && existence < options.threshold {
            break;
        }
        objects.push(FoundObject {
            primitive: Primitive::new(shape.clone(), refined.pose),
            existence,
            inlier_share: refined.inliers.len() as f64 / cloud.len() as f64,
            rms: refined.rms,
            filter_pose: filtered.pose,
            rounds: filtered.rounds,
        });
    }
    progress.finish();
    // Final joint existence of everything found.
    if objects.len() > 1 {
        let poses: Vec<Pose> = objects.iter().map(|o| o.primitive.pose).collect();
        let kernel = options.kernel_end * size;
        let m = context.measure(&[], poses, kernel, options.min_support, true, &mut rng)?;
        for (o, p) in objects.iter_mut().zip(m.existence) {
            o.existence = p;
        }
    }
    Ok(Registration {
        objects,
        model_size: size,
        seconds: start.elapsed().as_secs_f64(),
    })
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
