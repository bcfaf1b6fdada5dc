//! The whole fitting pipeline: cloud → lattice → coefficients → solver → primitives.
//!
//! [`fit`] runs these stages, in this order, one file each:
//!
//! | stage | file | what it does |
//! |---|---|---|
//! | validate | `mod.rs` | the cloud is non-empty and finite |
//! | options | `options.rs` | [`FitOptions`] (what a user may set); its `Default` is the one table of fixed defaults, `primfit fit`'s and `primfit.fit`'s |
//! | resolve | [`settings`](Settings::resolve) | [`FitOptions`] → [`Settings`] (every value used; the defaults that depend on the cloud) |
//! | pass | `pass.rs` | lattice candidates near the data → memory and work checks ([`estimate_bytes`], [`estimate_work`]) → coefficients (+ the free-space cost, [`crate::ray::FreeSpace`], when [`Settings::free_space`]) → L-BFGS and polish → optional refinement |
//! | gaps | `gaps.rs` | coarse to fine: a finer lattice where the refined pass leaves points unexplained |
//! | re-aligned pass | `mod.rs` | with an estimated frame and refinement: the lattice re-aligned to the first pass's primitives, then pass and gaps again; skipped when the re-aligned lattice moves no candidate by [`REALIGN_MIN_SAMPLE_SHIFT`] sample spacings |
//! | pick | `mod.rs` | of the two passes, the one with the lower [`binary_chamfer`] |
//!
//! What comes out is a [`FitResult`] (`result.rs`: stats, `result.json`, mesh; the JSON
//! schema is `document.rs`). The
//! ray-likelihood method of thesis ch. 4 ([`MethodOptions::Mcmc`]) is a separate
//! pipeline over the same settings (`mcmc.rs`).
//!
//! Defaults (those derived from the cloud are decided in `settings.rs`, the fixed ones are
//! [`FitOptions::default`] in `options.rs`):
//!
//! | setting | default |
//! |---|---|
//! | `size` | the bounding-box diagonal ÷ 8, rounded down to 1, 2 or 5 × 10^k |
//! | `spacing` | `size / 2` (the thesis's hallway: 1 m squares on a 0.5 m lattice); when `mesh` is the only type, the mesh's bounding radius (as in the registration scenes) |
//! | `radius` | `size / 10` (tube radius of cylinders and elbows) |
//! | `bend` | `spacing` (elbow centre-line radius) |
//! | `cap` | `max(spacing, 5σ)`: every point is within half a step of some lattice position, so a point farther than a whole step from every chosen primitive is treated as unexplained; on very noisy scans (noise σ, see below) a point within 5σ of a surface still counts as explained. `d_cap = cap²` |
//! | noise σ | the median off-plane spread of the flattest half of the k = 32 nearest-neighbour neighbourhoods of up to 4 000 evenly strided points (`surface::noise_level`, `surface::NOISE_MAX_POINTS`) |
//! | `sample_spacing` | `min(size / 16, 2π·radius / 12)` but never finer than the cloud's median point spacing |
//! | `beta` | 32 candidates per point ([`DEFAULT_BETA`]; 24 was the least that recovered every synthetic pipe) |
//! | `alpha` | 10 samples per candidate ([`DEFAULT_ALPHA`], thesis §6.3), `independent` model only |
//! | frame | `auto` ([`DEFAULT_FRAME`]): the scan's dominant axes (`frame::estimate_frame`); [`FitOptions::lattice`] is the plain lattice on the scene axes, without refinement |
//! | lattice origin | `axis`: the scene origin; `auto` and a given frame without origin: grid planes on the data (`frame::grid_origin`) |
//! | refinement | on ([`crate::refine::RefineOptions::default`]) |

mod compact;
pub(crate) mod document;
#[cfg(test)]
mod free_space_tests;
mod gaps;
mod mcmc;
mod options;
mod pass;
mod problem;
mod recentre;
mod result;
mod settings;
#[cfg(test)]
mod tests;
mod work;

pub use crate::chamfer::{BYTES_PER_POINT, estimate_bytes};
/// The lattice frame a fit uses ([`FitOptions::frame`]).
pub use crate::frame::FrameChoice;
pub use mcmc::McmcRun;
pub use options::{
    AUTO_TYPES, DEFAULT_ALPHA, DEFAULT_BETA, DEFAULT_DECAY, DEFAULT_FLIPS_PER_STEP, DEFAULT_FRAME,
    DEFAULT_KIND, DEFAULT_MAX_ITERATIONS, DEFAULT_MEMORY_SHARE, DEFAULT_MIN_COS, DEFAULT_PRIOR,
    DEFAULT_SEARCH_POINTS, DEFAULT_SEED, DEFAULT_WEIGHT, FitOptions, McmcFitOptions, MethodOptions,
    parse_types,
};
pub use problem::{candidate_samples, fit_candidates, fit_problem};
pub use result::{FitResult, FitStats, binary_chamfer, primitives_mesh, result_json};
pub use settings::{CompactSettings, McmcSettings, MethodSettings, Settings};
pub use work::{DEFAULT_WORK_PER_POINT, estimate_work};

use crate::frame::realign;
use crate::progress::Progress;
use crate::spatial::PointIndex;
use crate::{Error, PointCloud, Result, Stopwatch};
use gaps::fill_gaps;
use pass::fit_pass;

/// The smallest and largest cloud extent (bounding-box diagonal, scene units) a fit
/// accepts: squared distances, and sums of millions of them, then stay far inside the
/// range of `f64` (1e±308). A cloud outside it is refused with the advice to rescale.
pub const EXTENT_RANGE: (f64, f64) = (1e-100, 1e100);

/// The re-aligned pass runs only when the re-aligned lattice moves some candidate by at
/// least this many sample spacings: below half a sample spacing the two lattices sample
/// the same surfaces, and the second pass would repeat the first.
pub const REALIGN_MIN_SAMPLE_SHIFT: f64 = 0.5;

/// How far (scene units) moving the lattice of `settings` to `frame` and `origin` moves
/// a candidate at most, over a cloud within `extent` of the lattice origin (scene units): the rotation
/// angle times the reach (`extent` plus a candidate's size), plus the shift of the grid's
/// phase (the origin difference modulo the spacing, per lattice axis).
pub(crate) fn lattice_shift(
    settings: &Settings,
    frame: &nalgebra::UnitQuaternion<f64>,
    origin: &nalgebra::Point3<f64>,
    extent: f64,
) -> f64 {
    let angle = settings.frame.angle_to(frame);
    let s = settings.spacing;
    let delta = settings.frame.inverse() * (origin - settings.origin);
    let phase = delta.map(|d| d - s * (d / s).round()).norm();
    angle * (extent + settings.size) + phase
}

/// A cloud a fit can work on: not empty, every coordinate finite, and an extent within
/// [`EXTENT_RANGE`].
fn validate_cloud(cloud: &PointCloud) -> Result<()> {
    if let Some(index) = cloud
        .points
        .iter()
        .position(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(Error::NonFinite {
            what: "point".into(),
            index,
        });
    }
    let (lo, hi) = cloud.bounds().ok_or(Error::EmptyCloud)?;
    // The largest axis span, not the diagonal, which overflows first.
    let extent = (hi - lo).amax();
    let (min, max) = EXTENT_RANGE;
    if !(min..=max).contains(&extent) {
        let name = "the cloud's extent (largest side of its bounding box)";
        let expected = if extent == 0.0 {
            "positive: the points must not all coincide".to_string()
        } else {
            format!("between {min:e} and {max:e} scene units: rescale the cloud")
        };
        return Err(Error::out_of_range(name, format!("{extent:e}"), expected));
    }
    Ok(())
}

/// Fits primitives to `cloud`: a lattice pass (candidates, coefficients, L-BFGS, polish),
/// then, with [`FitOptions::refine`], continuous refinement ([`crate::refine`]). With an
/// estimated frame (`auto`) and refinement, the lattice is then re-aligned to the refined
/// primitives (`frame::realign`: their axes and the grid phase of their centres)
/// and fitted and refined once more; the pass with the lower binary chamfer is kept.
///
/// With [`MethodOptions::Mcmc`] the ray likelihood and Metropolis–Hastings decide
/// existence instead (thesis ch. 4; the cloud needs sensor origins).
pub fn fit(cloud: &PointCloud, options: &FitOptions, progress: &dyn Progress) -> Result<FitResult> {
    validate_cloud(cloud)?;
    if let Some(result) = own_pipeline(cloud, options, progress) {
        return result;
    }
    let mut clock = Stopwatch::start();
    let index = PointIndex::new(&cloud.points);
    clock.lap("index");
    let mut result = fit_on_index(cloud, &index, options, progress)?;
    clock.nest("fit", &result.stats.stages);
    result.stats.stages = clock.times;
    Ok(result)
}

/// [`fit()`] with `index`, a kd-tree over exactly `cloud.points`, already built: a caller
/// that measures the result afterwards ([`crate::metrics::evaluate_indexed`]) builds
/// it once for both.
pub fn fit_indexed(
    cloud: &PointCloud,
    index: &PointIndex,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<FitResult> {
    validate_cloud(cloud)?;
    crate::check::same_len("indexed points", index.len(), "points", cloud.len())?;
    match own_pipeline(cloud, options, progress) {
        Some(result) => result,
        None => fit_on_index(cloud, index, options, progress),
    }
}

/// The fits that do not use the caller's index: the ray likelihood (mcmc) and a
/// cloud far from the origin, fitted in a local frame (`recentre.rs`); `None` for the
/// rest.
fn own_pipeline(
    cloud: &PointCloud,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Option<Result<FitResult>> {
    if let MethodOptions::Mcmc(_) = options.method {
        return Some(mcmc::fit_mcmc(cloud, options, progress));
    }
    let shift = recentre::local_shift(cloud)?;
    Some(recentre::fit_shifted(cloud, options, progress, shift))
}

/// The compact model or the lattice pipeline of a validated cloud near the origin.
fn fit_on_index(
    cloud: &PointCloud,
    index: &PointIndex,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<FitResult> {
    if options.kinds.is_empty() {
        return compact::fit_compact(cloud, index, options, progress);
    }
    let mut clock = Stopwatch::start();
    let settings = Settings::resolve(cloud, index, options)?;
    clock.lap("settings");
    progress.checkpoint()?;
    progress.message(&format!("settings: {}", settings.to_json()));
    let pass = fit_pass(cloud, index, settings, progress)?;
    clock.nest("pass", &pass.stats.stages);
    let mut first = fill_gaps(cloud, index, pass, progress)?;
    clock.lap("gaps");
    let realign_pass = first.settings.refine.is_some()
        && first.settings.frame_source == "auto"
        && !first.primitives.is_empty();
    if !realign_pass {
        first.stats.stages = clock.times;
        return Ok(first);
    }
    let (frame, origin) = realign(
        &first.primitives,
        &first.settings.frame,
        first.settings.spacing,
    );
    // The farthest a point of the cloud's bounding box lies from the lattice origin.
    let extent = cloud.bounds().map_or(0.0, |(lo, hi)| {
        let centre = nalgebra::center(&lo, &hi);
        (centre - first.settings.origin).norm() + (hi - lo).norm() / 2.0
    });
    let moved = lattice_shift(&first.settings, &frame, &origin, extent);
    if moved < REALIGN_MIN_SAMPLE_SHIFT * first.settings.sample_spacing {
        progress.message(&format!(
            "re-aligned lattice skipped: it moves candidates by {moved:.3e} at most, under \
             {REALIGN_MIN_SAMPLE_SHIFT} sample spacing"
        ));
        first.stats.stages = clock.times;
        return Ok(first);
    }
    let settings = first.settings.realigned(frame, origin);
    progress.checkpoint()?;
    progress.message(&format!(
        "re-aligned lattice: frame {:?}, origin {origin:?}, candidates move by {moved:.3e} at most",
        frame.quaternion().coords
    ));
    let pass = fit_pass(cloud, index, settings, progress)?;
    clock.nest("realigned_pass", &pass.stats.stages);
    let second = fill_gaps(cloud, index, pass, progress)?;
    clock.lap("realigned_gaps");
    let loss = |r: &FitResult| {
        result::binary_chamfer_indexed(cloud, index, &r.primitives, &r.settings).map(|l| l.total)
    };
    let (a, b) = (loss(&first)?, loss(&second)?);
    progress.checkpoint()?;
    progress.message(&format!(
        "binary chamfer: first pass {a:.6}, re-aligned pass {b:.6}"
    ));
    let mut best = if b <= a { second } else { first };
    clock.lap("pick");
    best.stats.passes = 2;
    best.stats.stages = clock.times;
    Ok(best)
}
