//! Shape detection from the data: segments of a scan and the plane, cylinder or sphere
//! that explains each, the candidates the existence inference starts from.
//!
//! ```text
//! points ─► voxel samples ─► normals + curvature ─► region growing ─► classify + fit
//!        ─► merge ─► every point to its sample's segment ─► curved leftovers ─► Detection
//! ```
//!
//! | step | what | file |
//! |---|---|---|
//! | samples | clouds above [`DEFAULT_MAX_SAMPLES`] points are voxel-subsampled to at most that many | `sample.rs` |
//! | normals | PCA of the `k` nearest samples: normal, flatness ("curvature"), residual | `normals.rs` |
//! | noise | `σ = max(σ_pca, s/√12)` (`surface::noise_sigma`), `s` the point spacing | `surface.rs` |
//! | regions | smoothness-constrained region growing, seeds by increasing curvature | `grow.rs` |
//! | models | plane if it fits within `t σ`, else cylinder / sphere if markedly better, else clutter | `classify.rs`, `plane.rs`, `cylinder.rs`, `sphere.rs` |
//! | split | a region no model explains is split by peeling its dominant plane | `split.rs` |
//! | merge | same-type segments that one model explains within the noise become one | `merge.rs` |
//! | expand | each non-sample point joins its nearest sample's segment if it lies within `t σ` of the model | `expand.rs` |
//! | leftovers | connected pieces of the unassigned points that a cylinder or sphere explains (tubes too thin for growing) | `leftover.rs` |
//!
//! **Derived thresholds.** Nothing needs setting; every threshold follows from the noise
//! σ, the spacing and the neighbourhood size (each [`DetectOptions`] field overrides one):
//!
//! - the **growing angle** is the scatter of the normals that σ alone causes. A PCA
//!   normal from `k` points spread over a disc of radius `R` (the distance to the `k`-th
//!   neighbour) is the least-squares fit of `z = a x + b y`, whose slope has standard
//!   deviation `σ / √(Σx²) = σ / √(k R²/4) = 2σ / (R √k)` per axis; the angle between
//!   two independent such normals has √2 times that. The threshold is
//!   [`ANGLE_SIGMAS`] of these deviations, clamped to
//!   [[`MIN_ANGLE_DEG`], [`MAX_ANGLE_DEG`]]: `θ = clamp(3 · √2 · 2σ / (R √k))`.
//! - a point **propagates** growth only if its residual is at most
//!   [`PROPAGATE_SIGMAS`]` σ` (a crease or clutter neighbourhood spreads far more);
//! - a model **fits** within [`DEFAULT_TOLERANCE`]` σ` RMS.
//!
//! **Deterministic** for any thread count: normals are computed per point, growing and
//! merging run sequentially over fixed orders.

mod classify;
mod cylinder;
mod expand;
mod grow;
mod leftover;
mod model;
mod noise;
mod normals;
mod plane;
mod sample;
mod sphere;
mod split;

#[cfg(test)]
mod tests;

use nalgebra::Point3;
use rayon::prelude::*;

pub use model::SurfaceModel;

pub(crate) use cylinder::{CylinderFit, perpendicular_basis, refit_cylinder};
pub(crate) use grow::{GrowParams, grow_regions};
pub(crate) use noise::NoiseMap;
pub(crate) use normals::Neighbourhoods;
pub(crate) use sample::{voxel_grid, voxel_subsample};

use crate::check;
use crate::schedule::map_largest_first;
use crate::spatial::PointIndex;
use crate::{Error, Primitive, Result, StageTimes, Stopwatch};
use merge::{Part, merge_parts};
use normals::FlatnessOrder;
use split::Splitter;

mod merge;

/// Neighbours per normal estimate (the point itself included): as the noise estimate of
/// the fit (`surface::DEFAULT_NEIGHBOURS`).
pub const DEFAULT_NEIGHBOURS: usize = crate::surface::DEFAULT_NEIGHBOURS;

/// Neighbours examined per region-growing step (the nearest of the `k`, itself
/// excluded): the ring of immediate neighbours, about two spacings. Fewer than `k` so a
/// region reaches a neighbour only through the points between them.
pub const DEFAULT_GROW_NEIGHBOURS: usize = 12;

/// Clouds with more points are voxel-subsampled to at most this many samples before
/// normals and growing (then every point is assigned to its nearest sample's segment):
/// 100k samples resolve surfaces of a few hundred spacings and keep a 250k-point scan's
/// detection to about a second on two cores.
pub const DEFAULT_MAX_SAMPLES: usize = 100_000;

/// Model tolerance `t` (in σ): a model fits a segment when the RMS distance of its
/// points is at most `t σ`. 2.5σ leaves room for the estimate of σ itself (a median of
/// local residuals, off by tens of per cent on real scans) and for gentle warping.
pub const DEFAULT_TOLERANCE: f64 = 2.5;

/// The growing angle is this many standard deviations of the noise-induced normal
/// difference (module docs).
pub const ANGLE_SIGMAS: f64 = 3.0;

/// The smallest derived growing angle (degrees): below it, sensor calibration and
/// sampling artefacts split flat surfaces.
pub const MIN_ANGLE_DEG: f64 = 5.0;

/// The largest derived growing angle (degrees): above it, regions leak across
/// rounded edges between faces.
pub const MAX_ANGLE_DEG: f64 = 15.0;

/// A sample propagates growth only if its residual is at most this many σ.
pub const PROPAGATE_SIGMAS: f64 = 3.0;

/// Default smallest segment, in samples: a region must hold at least this many
/// neighbourhoods' worth of points (× `k`) to be a surface rather than a fragment.
pub const MIN_SEGMENT_NEIGHBOURHOODS: usize = 2;

/// Points probed for the median spacing.
const SPACING_PROBES: usize = 20_000;

/// What may be set for [`detect`]; every `None` is derived from the data (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct DetectOptions {
    /// Neighbours per normal (default [`DEFAULT_NEIGHBOURS`]), at least 3.
    pub neighbours: Option<usize>,
    /// Neighbours per growing step (default [`DEFAULT_GROW_NEIGHBOURS`]), at least 1.
    pub grow_neighbours: Option<usize>,
    /// Growing angle (radians, in (0, π/2]); default derived from σ (module docs).
    pub angle: Option<f64>,
    /// Noise σ (scene units, > 0); default `max(σ_pca, s/√12)`.
    pub noise: Option<f64>,
    /// Smallest segment, in samples; default [`MIN_SEGMENT_NEIGHBOURHOODS`]` × k`.
    pub min_points: Option<usize>,
    /// Most samples (default [`DEFAULT_MAX_SAMPLES`]), at least 1.
    pub max_samples: Option<usize>,
    /// Model tolerance `t`, in σ (default [`DEFAULT_TOLERANCE`]), positive.
    pub tolerance: Option<f64>,
    /// Whether spheres are tried (default true).
    pub spheres: bool,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            neighbours: None,
            grow_neighbours: None,
            angle: None,
            noise: None,
            min_points: None,
            max_samples: None,
            tolerance: None,
            spheres: true,
        }
    }
}

impl DetectOptions {
    /// Checks every given value's range.
    pub fn validate(&self) -> Result<()> {
        if let Some(k) = self.neighbours {
            check::at_least("neighbours", k, 3)?;
        }
        if let Some(k) = self.grow_neighbours {
            check::at_least("grow_neighbours", k, 1)?;
        }
        if let Some(a) = self.angle {
            let right = check::Interval::open_closed(0.0, std::f64::consts::FRAC_PI_2);
            check::in_interval("angle", a, right)?;
        }
        if let Some(s) = self.noise {
            check::positive("noise", s)?;
        }
        if let Some(m) = self.max_samples {
            check::at_least("max_samples", m, 1)?;
        }
        if let Some(t) = self.tolerance {
            check::positive("tolerance", t)?;
        }
        Ok(())
    }
}

/// One detected surface.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// Indices of its points in the input cloud (ascending).
    pub points: Vec<usize>,
    /// The surface that explains them.
    pub model: SurfaceModel,
    /// RMS distance of the points from the (unbounded) model surface (scene units).
    pub rms: f64,
}

impl Segment {
    /// The bounded primitive of a cylinder or sphere segment ([`SurfaceModel::to_primitive`]);
    /// `None` for a plane.
    pub fn primitive(&self) -> Option<Primitive> {
        self.model.to_primitive()
    }
}

/// The result of [`detect`].
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// The explained segments, largest first (ties: lower first point).
    pub segments: Vec<Segment>,
    /// Point lists (ascending) of segments no model explains, largest first.
    pub clutter: Vec<Vec<usize>>,
    /// Points in no segment and no clutter list (ascending): fragments smaller than the
    /// smallest segment, and points farther than `t σ` from their segment's model.
    pub unassigned: Vec<usize>,
    /// The noise σ over the whole cloud at the fine scale (scene units): the median
    /// local residual of the flattest half of the samples' neighbourhoods, at least
    /// `spacing / √12`. Region growing uses its local values (`noise.rs`).
    pub noise: f64,
    /// The noise σ models are judged against, over the whole cloud (scene units): the
    /// larger of [`Detection::noise`] and the σ at the coarse scale (`noise.rs`).
    pub model_noise: f64,
    /// The median nearest-neighbour distance of the input (scene units).
    pub spacing: f64,
    /// The growing angle (radians): the median over the samples of the local angle
    /// derived from the fine σ (or the angle given); also the merge angle.
    pub angle: f64,
    /// The voxel edge of the subsampling (scene units), `None` when every point was a sample.
    pub voxel: Option<f64>,
    /// Number of samples normals and regions were computed on.
    pub samples: usize,
}

/// Detects planes, cylinders and spheres in `points` (indexed by `index`, built over
/// exactly these points). See the module docs for the steps and thresholds.
///
/// Errors: an empty cloud ([`Error::EmptyCloud`]), a non-finite point
/// ([`Error::NonFinite`]), a mismatched index ([`Error::Mismatch`]), options out of
/// range ([`Error::OutOfRange`]).
pub fn detect(
    points: &[Point3<f64>],
    index: &PointIndex,
    options: &DetectOptions,
) -> Result<Detection> {
    detect_timed(points, index, options).map(|(detection, _)| detection)
}

/// [`detect`], and the wall time of each of its steps (module docs: `spacing`,
/// `subsample`, `normals`, `noise`, `grow`, `split`, `merge`, `expand`, `leftovers`).
pub fn detect_timed(
    points: &[Point3<f64>],
    index: &PointIndex,
    options: &DetectOptions,
) -> Result<(Detection, StageTimes)> {
    options.validate()?;
    check_input(points, index)?;
    let mut clock = Stopwatch::start();
    let Some(spacing) = index.median_spacing(points, SPACING_PROBES) else {
        let nothing = Detection::nothing(points.len(), options.noise.unwrap_or(0.0));
        return Ok((nothing, clock.times));
    };
    clock.lap("spacing");
    let sub = voxel_subsample(
        points,
        spacing,
        options.max_samples.unwrap_or(DEFAULT_MAX_SAMPLES),
    );
    let (sample_ids, voxel) = match sub {
        Some((ids, edge)) => (ids, Some(edge)),
        None => ((0..points.len()).collect(), None),
    };
    let samples: Vec<Point3<f64>> = sample_ids.iter().map(|&i| points[i]).collect();
    let own_index;
    let sample_index = if voxel.is_some() {
        own_index = PointIndex::new(&samples);
        &own_index
    } else {
        index
    };
    clock.lap("subsample");
    let k = options.neighbours.unwrap_or(DEFAULT_NEIGHBOURS);
    let nb = Neighbourhoods::new(&samples, sample_index, k);
    clock.lap("normals");
    let radius = median_radius(&nb);
    // The order the regions grow in does not depend on the noise: sorted alongside it.
    let (noise, flatness) = rayon::join(
        || SampleNoise::new(options, &samples, &nb, k, spacing, radius, voxel),
        || FlatnessOrder::new(&nb),
    );
    let SampleNoise {
        fine,
        coarse,
        sigma,
        model_sigma,
        angles,
    } = noise;
    let tolerance = options.tolerance.unwrap_or(DEFAULT_TOLERANCE);
    clock.lap("noise");
    let grow = GrowParams {
        neighbours: options.grow_neighbours.unwrap_or(DEFAULT_GROW_NEIGHBOURS),
        cos_angle: angles.iter().map(|a| a.cos()).collect(),
        max_residual: sigma.iter().map(|s| PROPAGATE_SIGMAS * s).collect(),
    };
    let min_points = options
        .min_points
        .unwrap_or(MIN_SEGMENT_NEIGHBOURHOODS * nb.k)
        .max(3);
    // Growing is sequential; the samples' curvature-free residuals, which the models
    // are judged by (`split.rs`), are computed beside it.
    let (regions, quadric) = rayon::join(
        || grow_regions(&nb, &flatness, &grow),
        || noise::quadric_residuals(&samples, &nb),
    );
    let regions: Vec<Vec<usize>> = regions
        .into_iter()
        .filter(|r| r.len() >= min_points)
        .collect();
    clock.lap("grow");
    let splitter = Splitter {
        samples: &samples,
        nb: &nb,
        flatness: &flatness,
        model_sigma: &model_sigma,
        tolerance,
        spheres: options.spheres,
        min_points,
        neighbours: grow.neighbours,
        quadric: &quadric,
        cos_angle: &grow.cos_angle,
    };
    let parts: Vec<Part> = map_largest_first(regions, Vec::len, |ids| splitter.parts(ids))
        .into_iter()
        .flatten()
        .collect();
    clock.lap("split");
    let angle = normals::median(&mut angles.clone()).unwrap_or(0.0);
    let parts = merge_parts(parts, &samples, angle.cos(), tolerance);
    clock.lap("merge");
    let sampled = expand::Samples {
        points: &samples,
        ids: &sample_ids,
        index: sample_index,
        nb: &nb,
    };
    let mut detection = expand::expand(points, &sampled, parts, grow.neighbours, tolerance);
    clock.lap("expand");
    let model_noise = coarse
        .as_ref()
        .map_or(fine.global(), |c| c.global().max(fine.global()));
    leftover::Leftovers {
        spacing,
        k,
        sigma: model_noise,
        tolerance,
        spheres: options.spheres,
        min_points,
        cos_angle: angle.cos(),
        reach: radius,
        neighbours: grow.neighbours,
    }
    .absorb(points, &mut detection);
    clock.lap("leftovers");
    detection.noise = fine.global();
    detection.model_noise = model_noise;
    detection.spacing = spacing;
    detection.angle = angle;
    detection.voxel = voxel;
    detection.samples = samples.len();
    Ok((detection, clock.times))
}

/// The noise levels of the samples and the growing angles they set.
struct SampleNoise {
    /// σ at the fine scale (the neighbourhoods of the normals).
    fine: NoiseMap,
    /// σ at the coarse scale, when the samples see finer than it.
    coarse: Option<NoiseMap>,
    /// Each sample's fine σ (scene units).
    sigma: Vec<f64>,
    /// Each sample's σ that models are judged against: the larger of both scales.
    model_sigma: Vec<f64>,
    /// Each sample's growing angle (radians).
    angles: Vec<f64>,
}

impl SampleNoise {
    /// Measured from `nb` (or as `options` set them): `k` is the neighbours asked for,
    /// `spacing` the cloud's point spacing, `radius` the neighbourhoods' median radius,
    /// `voxel` the subsampling edge.
    fn new(
        options: &DetectOptions,
        samples: &[Point3<f64>],
        nb: &Neighbourhoods,
        k: usize,
        spacing: f64,
        radius: f64,
        voxel: Option<f64>,
    ) -> Self {
        let pitch = voxel.unwrap_or(spacing);
        let (fine, coarse) = match options.noise {
            Some(s) => (NoiseMap::uniform(s), None),
            // Two independent maps: their serial parts (the coarse grid's voxels and
            // kd-tree, each map's global level) overlap.
            None => rayon::join(
                || NoiseMap::new(samples, nb, spacing, radius),
                || {
                    sees_finer_than_coarse(voxel, spacing)
                        .then(|| coarse_noise(samples, pitch, k, spacing))
                },
            ),
        };
        let sigma: Vec<f64> = samples.par_iter().map(|p| fine.at(p)).collect();
        let model_sigma: Vec<f64> = samples
            .par_iter()
            .zip(&sigma)
            .map(|(p, s)| coarse.as_ref().map_or(*s, |c| c.at(p).max(*s)))
            .collect();
        let angles: Vec<f64> = match options.angle {
            Some(a) => vec![a; samples.len()],
            None => sigma
                .par_iter()
                .map(|s| growing_angle(*s, radius, nb.k))
                .collect(),
        };
        SampleNoise {
            fine,
            coarse,
            sigma,
            model_sigma,
            angles,
        }
    }
}

/// Checks that `points` is not empty, is finite and is what `index` indexes.
fn check_input(points: &[Point3<f64>], index: &PointIndex) -> Result<()> {
    if points.is_empty() {
        return Err(Error::EmptyCloud);
    }
    check::same_len("indexed points", index.len(), "points", points.len())?;
    match points
        .iter()
        .position(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        Some(index) => Err(Error::NonFinite {
            what: "point".into(),
            index,
        }),
        None => Ok(()),
    }
}

impl Detection {
    /// No segments: every one of `n` points unassigned.
    fn nothing(n: usize, noise: f64) -> Self {
        Detection {
            segments: Vec::new(),
            clutter: Vec::new(),
            unassigned: (0..n).collect(),
            noise,
            model_noise: noise,
            spacing: 0.0,
            angle: 0.0,
            voxel: None,
            samples: 0,
        }
    }
}

/// Whether the coarse noise scale (`noise.rs`) is wider than the samples' own: the
/// scale of correlated sensor noise is [`noise::COARSE_FACTOR`] point spacings. A cloud
/// subsampled to a voxel at least that wide already spans it in its fine neighbourhoods;
/// a coarse grid `COARSE_FACTOR` voxels wide would measure the scene's layout (on a 2M-
/// point floor plan, 0.8 m voxels: neighbourhoods across floor–wall corners, σ 0.25 m
/// against 4 mm), not the sensor.
fn sees_finer_than_coarse(voxel: Option<f64>, spacing: f64) -> bool {
    voxel.is_none_or(|v| v < noise::COARSE_FACTOR * spacing)
}

/// The coarse-scale noise map: neighbourhoods of `k` points of a voxel grid of
/// [`noise::COARSE_FACTOR`] × `pitch` over `samples`, their residuals taken off a
/// height quadric so that curvature at the coarse scale does not count as noise.
fn coarse_noise(samples: &[Point3<f64>], pitch: f64, k: usize, spacing: f64) -> NoiseMap {
    let ids = voxel_grid(samples, noise::COARSE_FACTOR * pitch);
    let coarse: Vec<Point3<f64>> = ids.iter().map(|&i| samples[i]).collect();
    let index = PointIndex::new(&coarse);
    let mut nb = Neighbourhoods::new(&coarse, &index, k);
    nb.residual = noise::quadric_residuals(&coarse, &nb);
    NoiseMap::new(&coarse, &nb, spacing, median_radius(&nb))
}

/// The median distance from a sample to its `k`-th neighbour (scene units; infinite
/// when no neighbourhood has extent).
fn median_radius(nb: &Neighbourhoods) -> f64 {
    let mut radii: Vec<f64> = nb.radius.iter().copied().filter(|r| *r > 0.0).collect();
    normals::median(&mut radii).unwrap_or(f64::INFINITY)
}

/// The growing angle at noise `sigma` for `k`-neighbourhoods of `radius` (module docs),
/// radians.
fn growing_angle(sigma: f64, radius: f64, k: usize) -> f64 {
    let tilt = 2.0 * sigma / (radius * (k as f64).sqrt());
    let angle = ANGLE_SIGMAS * std::f64::consts::SQRT_2 * tilt;
    angle.clamp(MIN_ANGLE_DEG.to_radians(), MAX_ANGLE_DEG.to_radians())
}
