//! The measures of DESIGN §4, computed against the **exact** primitive surfaces
//! ([`Primitive::distance`]), in parallel with rayon.
//!
//! | key | meaning | units |
//! |---|---|---|
//! | `point_to_model_mean/p95/max` | per input point, distance to the nearest fitted surface | scene units |
//! | `model_to_point_mean` | per area-uniform sample of the fitted surfaces, distance to the nearest input point | scene units |
//! | `coverage` | share of input points within `coverage_tau` of a fitted surface | fraction in [0, 1] |
//! | `chamfer` | `Σ_y d(y, model)² + Σ_{x ∈ model samples} d(x, cloud)²` | scene units² |
//! | `compactness` | `Σ parameter_count ÷ (3 × points)` | dimensionless |
//! | `precision`, `recall`, `scene_accuracy` | against ground truth (see [`match_primitives`]) | fractions |
//!
//! Not in [`Metrics`] (its JSON is pinned by the golden tests): the overlap of a model
//! with itself, [`overlap_share`] and [`double_cover_share`] (`overlap.rs`).
//!
//! **Empty model.** With no fitted primitive every distance from a point to the model
//! is `+∞`; then `point_to_model_*`, `model_to_point_mean` (no samples to average) and
//! `chamfer` are `f64::INFINITY` in [`Metrics`] and `null` in [`Metrics::to_json`] (JSON
//! has no infinity), `coverage` is 0 and `compactness` 0. The same `null` appears for any
//! other non-finite value. An empty cloud is an error.
//!
//! Speed: point→model uses a primitive index (`spatial::PrimitiveIndex`: kd-trees over
//! primitive centres, one per bounding-radius class), so each point computes exact
//! distances only to primitives whose bounding ball can beat the best distance found so
//! far.

use nalgebra::Point3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::atlas::Shape;
use crate::cloud::bounds_of;
use crate::io::json::nan_as_null;
use crate::spatial::{PointIndex, PrimitiveIndex};
use crate::{Error, Primitive, Result, check};

mod overlap;

pub use overlap::{DOUBLE_COVER_MAX_ANGLE_DEG, double_cover_share, overlap_share};
pub(crate) use overlap::{covers_along, surface_normal};

/// Consecutive points per parallel task of [`point_to_model_distances`].
const NEAREST_CHUNK: usize = 1024;

/// For every point, the distance to the nearest surface of `model` (`+∞` when the model
/// is empty). Parallel.
pub fn point_to_model_distances(points: &[Point3<f64>], model: &[Primitive]) -> Result<Vec<f64>> {
    if model.is_empty() {
        return Ok(vec![f64::INFINITY; points.len()]);
    }
    let index = &PrimitiveIndex::new(model)?;
    // Chunks of consecutive points, each point's search starting from the previous
    // one's answer (scans are stored in scan order, so neighbours share it).
    Ok(points
        .par_chunks(NEAREST_CHUNK)
        .flat_map_iter(|chunk| {
            let mut hint = None;
            chunk.iter().map(move |p| {
                let nearest = index.nearest_from(p, hint);
                hint = nearest.map(|(i, _)| i);
                nearest.map_or(f64::INFINITY, |(_, d)| d)
            })
        })
        .collect())
}

/// Area-uniform samples of all of `model`'s surfaces at about `spacing` apart
/// ([`Primitive::sample_surface`]), concatenated in model order.
pub fn model_samples(model: &[Primitive], spacing: f64) -> Result<Vec<Point3<f64>>> {
    check::positive("sample_spacing", spacing)?;
    let per: Vec<Vec<Point3<f64>>> = model
        .par_iter()
        .map(|p| p.sample_surface(spacing))
        .collect();
    Ok(per.concat())
}

/// For every query, the distance to the nearest point of `cloud` (a kd-tree on the
/// cloud). Errs on an empty cloud. Parallel.
pub fn nearest_cloud_distances(queries: &[Point3<f64>], cloud: &[Point3<f64>]) -> Result<Vec<f64>> {
    if cloud.is_empty() {
        return Err(Error::EmptyCloud);
    }
    Ok(nearest_indexed_distances(queries, &PointIndex::new(cloud)))
}

/// For every query, the distance to the nearest point of the cloud `tree` indexes
/// (infinite for an empty one). Parallel.
fn nearest_indexed_distances(queries: &[Point3<f64>], tree: &PointIndex) -> Vec<f64> {
    queries
        .par_iter()
        .map(|q| tree.nearest(q).map_or(f64::INFINITY, |(_, d2)| d2.sqrt()))
        .collect()
}

/// Share of `distances` that are ≤ `tau` (0 for an empty slice).
pub fn coverage(distances: &[f64], tau: f64) -> f64 {
    if distances.is_empty() {
        return 0.0;
    }
    distances.iter().filter(|&&d| d <= tau).count() as f64 / distances.len() as f64
}

/// Nearest-rank percentile `q ∈ [0, 1]` of `values` (the ⌈q·n⌉-th smallest; NaN when
/// empty). Copies the slice.
pub fn percentile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut v = values.to_vec();
    let k = ((q.clamp(0.0, 1.0) * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
    let (_, kth, _) = v.select_nth_unstable_by(k, f64::total_cmp);
    *kth
}

/// Mean of `values` (`+∞` when empty: no sample means no evidence of fit).
fn mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        f64::INFINITY
    } else {
        values.iter().sum::<f64>() / values.len() as f64
    }
}

/// A primitive's sizes in scene units (shape sizes × pose scale), for matching.
fn scene_sizes(p: &Primitive) -> Vec<f64> {
    let s = p.pose.scale;
    match &p.shape {
        Shape::Disk { diameter } | Shape::Sphere { diameter } => vec![diameter * s],
        Shape::Square { side } => vec![side * s],
        Shape::Cylinder { length, radius } => vec![length * s, radius * s],
        Shape::Elbow { bend, radius } => vec![bend * s, radius * s],
        Shape::Mesh(_) => vec![s],
        Shape::Plane(p) => vec![p.area() * s * s],
    }
}

/// Same type and scene sizes within `1e-6` relative (meshes: same `source` and scale;
/// planes: same scene area).
pub fn same_type_and_size(a: &Primitive, b: &Primitive) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-6 * x.abs().max(y.abs());
    let meshes_agree = match (&a.shape, &b.shape) {
        (Shape::Mesh(m), Shape::Mesh(n)) => m.source == n.source,
        _ => true,
    };
    a.shape.kind() == b.shape.kind()
        && meshes_agree
        && scene_sizes(a)
            .into_iter()
            .zip(scene_sizes(b))
            .all(|(x, y)| close(x, y))
}

/// Symmetric mean surface distance: the average of (mean distance from `a`'s samples to
/// `b`'s surface) and (mean distance from `b`'s samples to `a`'s surface), with samples
/// about `spacing` apart (at least ~64 per primitive). Scene units.
pub fn surface_distance(a: &Primitive, b: &Primitive, spacing: f64) -> f64 {
    let one_way = |x: &Primitive, y: &Primitive| {
        let h = spacing.min(x.area().sqrt() / 8.0).max(1e-12);
        let s = x.sample_surface(h);
        s.iter().map(|p| y.distance(p)).sum::<f64>() / s.len().max(1) as f64
    };
    0.5 * (one_way(a, b) + one_way(b, a))
}

/// The result of matching fitted primitives against ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Matching {
    /// Matched `(fitted index, truth index)` pairs, best first.
    pub pairs: Vec<(usize, usize)>,
    /// Matched ÷ fitted (1 when nothing was fitted).
    pub precision: f64,
    /// Matched ÷ truth (1 when the truth is empty).
    pub recall: f64,
    /// 1 when every truth primitive is matched and nothing extra was fitted, else 0.
    pub scene_accuracy: f64,
}

/// Greedy one-to-one matching: a fitted and a true primitive may match when
/// [`same_type_and_size`] holds and their [`surface_distance`] is below `tolerance`
/// (scene units); pairs are taken in increasing distance (ties: lower indices).
/// `spacing` is the sample spacing used for the surface distance.
pub fn match_primitives(
    fitted: &[Primitive],
    truth: &[Primitive],
    tolerance: f64,
    spacing: f64,
) -> Result<Matching> {
    check::non_negative("tolerance", tolerance)?;
    match_with(fitted, truth, spacing, |_, _| tolerance)
}

/// [`match_primitives`] with a per-pair tolerance of `fraction` × the smaller bounding
/// radius of the two primitives (dimensionless `fraction`, e.g. 0.1).
pub fn match_primitives_relative(
    fitted: &[Primitive],
    truth: &[Primitive],
    fraction: f64,
    spacing: f64,
) -> Result<Matching> {
    check::non_negative("fraction", fraction)?;
    match_with(fitted, truth, spacing, |a, b| {
        fraction * a.bounding_radius().min(b.bounding_radius())
    })
}

/// Greedy matching with a per-pair tolerance function.
fn match_with(
    fitted: &[Primitive],
    truth: &[Primitive],
    spacing: f64,
    tolerance: impl Fn(&Primitive, &Primitive) -> f64 + Sync,
) -> Result<Matching> {
    check::positive("sample_spacing", spacing)?;
    let tolerance = &tolerance;
    let mut candidates: Vec<(f64, usize, usize)> = (0..fitted.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let f = &fitted[i];
            truth.iter().enumerate().filter_map(move |(j, t)| {
                // Disjoint bounding balls: every sample is at least the gap away, so the
                // mean surface distance is too.
                let tol = tolerance(f, t);
                let gap =
                    (f.center() - t.center()).norm() - f.bounding_radius() - t.bounding_radius();
                if gap >= tol || !same_type_and_size(f, t) {
                    return None;
                }
                let d = surface_distance(f, t, spacing);
                (d < tol).then_some((d, i, j))
            })
        })
        .collect();
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let (mut used_f, mut used_t) = (vec![false; fitted.len()], vec![false; truth.len()]);
    let mut pairs = Vec::new();
    for (_, i, j) in candidates {
        if !used_f[i] && !used_t[j] {
            used_f[i] = true;
            used_t[j] = true;
            pairs.push((i, j));
        }
    }
    let m = pairs.len() as f64;
    let ratio = |n: usize| if n == 0 { 1.0 } else { m / n as f64 };
    Ok(Matching {
        precision: ratio(fitted.len()),
        recall: ratio(truth.len()),
        scene_accuracy: if pairs.len() == fitted.len() && pairs.len() == truth.len() {
            1.0
        } else {
            0.0
        },
        pairs,
    })
}

/// Options of [`evaluate`]; `None` fields take the documented defaults.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MetricsOptions {
    /// Coverage threshold τ (scene units). Default: [`default_coverage_tau`], twice the
    /// cloud's median nearest-neighbour distance.
    pub coverage_tau: Option<f64>,
    /// Spacing of the model samples for model→point and chamfer (scene units). Default:
    /// `sqrt(model area / n)` with `n` = the number of input points clamped to
    /// `[1000, 1 000 000]`, i.e. about as many samples as input points.
    pub sample_spacing: Option<f64>,
    /// Surface-distance tolerance for primitive matching (scene units). Default: per
    /// pair, 10 % of the smaller bounding radius.
    pub match_tolerance: Option<f64>,
}

/// The measures of DESIGN §4 for one model against one cloud (see the module docs).
/// Serde reads and writes the flat JSON of [`Metrics::to_json`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(into = "MetricsDoc", from = "MetricsDoc")]
pub struct Metrics {
    /// Number of input points.
    pub points: usize,
    /// Number of fitted primitives.
    pub primitives: usize,
    /// Mean point→model distance.
    pub point_to_model_mean: f64,
    /// 95th percentile (nearest rank) of the point→model distances.
    pub point_to_model_p95: f64,
    /// Largest point→model distance.
    pub point_to_model_max: f64,
    /// Mean model→point distance.
    pub model_to_point_mean: f64,
    /// Share of points within `coverage_tau` of the model.
    pub coverage: f64,
    /// The τ used for `coverage`.
    pub coverage_tau: f64,
    /// Squared, summed, two-way chamfer error.
    pub chamfer: f64,
    /// Fitted parameters ÷ (3 × points).
    pub compactness: f64,
    /// The model sample spacing used.
    pub sample_spacing: f64,
    /// Precision, recall, scene accuracy when a truth was given.
    pub truth: Option<Matching>,
}

impl Metrics {
    /// Flat JSON object with the keys of the module table (plus `points`, `primitives`,
    /// `sample_spacing`); `precision`, `recall`, `scene_accuracy` only with a truth.
    /// Non-finite values are written as `null` (and read back as NaN).
    pub fn to_json(&self) -> Value {
        serde_json::to_value(self).unwrap_or(Value::Null)
    }
}

/// The JSON form of [`Metrics`] (`result.json`'s `"metrics"`). The matched pairs of a
/// truth are not written; read back, a truth has none.
#[derive(Serialize, Deserialize)]
struct MetricsDoc {
    points: usize,
    primitives: usize,
    #[serde(with = "nan_as_null")]
    point_to_model_mean: f64,
    #[serde(with = "nan_as_null")]
    point_to_model_p95: f64,
    #[serde(with = "nan_as_null")]
    point_to_model_max: f64,
    #[serde(with = "nan_as_null")]
    model_to_point_mean: f64,
    #[serde(with = "nan_as_null")]
    coverage: f64,
    #[serde(with = "nan_as_null")]
    coverage_tau: f64,
    #[serde(with = "nan_as_null")]
    chamfer: f64,
    #[serde(with = "nan_as_null")]
    compactness: f64,
    #[serde(with = "nan_as_null")]
    sample_spacing: f64,
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    truth: Option<TruthDoc>,
}

/// The scores of a [`Matching`] in `"metrics"`.
#[derive(Serialize, Deserialize)]
struct TruthDoc {
    #[serde(with = "nan_as_null")]
    precision: f64,
    #[serde(with = "nan_as_null")]
    recall: f64,
    #[serde(with = "nan_as_null")]
    scene_accuracy: f64,
}

impl From<Metrics> for MetricsDoc {
    fn from(m: Metrics) -> Self {
        MetricsDoc {
            points: m.points,
            primitives: m.primitives,
            point_to_model_mean: m.point_to_model_mean,
            point_to_model_p95: m.point_to_model_p95,
            point_to_model_max: m.point_to_model_max,
            model_to_point_mean: m.model_to_point_mean,
            coverage: m.coverage,
            coverage_tau: m.coverage_tau,
            chamfer: m.chamfer,
            compactness: m.compactness,
            sample_spacing: m.sample_spacing,
            truth: m.truth.map(|t| TruthDoc {
                precision: t.precision,
                recall: t.recall,
                scene_accuracy: t.scene_accuracy,
            }),
        }
    }
}

impl From<MetricsDoc> for Metrics {
    fn from(m: MetricsDoc) -> Self {
        Metrics {
            points: m.points,
            primitives: m.primitives,
            point_to_model_mean: m.point_to_model_mean,
            point_to_model_p95: m.point_to_model_p95,
            point_to_model_max: m.point_to_model_max,
            model_to_point_mean: m.model_to_point_mean,
            coverage: m.coverage,
            coverage_tau: m.coverage_tau,
            chamfer: m.chamfer,
            compactness: m.compactness,
            sample_spacing: m.sample_spacing,
            truth: m.truth.map(|t| Matching {
                pairs: Vec::new(),
                precision: t.precision,
                recall: t.recall,
                scene_accuracy: t.scene_accuracy,
            }),
        }
    }
}

/// Default coverage τ: twice the cloud's median nearest-neighbour distance (its sampling
/// resolution), estimated on an evenly strided subsample of at most 10 000 points; when
/// that is 0 (duplicates, a single point) 1 % of the bounding-box diagonal. Scene units.
pub fn default_coverage_tau(points: &[Point3<f64>]) -> f64 {
    let diagonal = bounds_of(points).map_or(0.0, |(lo, hi)| (hi - lo).norm());
    if points.len() < 2 {
        return 0.01 * diagonal;
    }
    coverage_tau_indexed(points, &PointIndex::new(points))
}

/// [`default_coverage_tau`] with `tree`, a kd-tree over exactly `points`, already built.
fn coverage_tau_indexed(points: &[Point3<f64>], tree: &PointIndex) -> f64 {
    let diagonal = bounds_of(points).map_or(0.0, |(lo, hi)| (hi - lo).norm());
    let stride = points.len().div_ceil(10_000);
    let nn: Vec<f64> = points
        .par_iter()
        .step_by(stride)
        .map(|q| {
            let hits = tree.nearest_n(q, 2);
            hits.iter().map(|h| h.1).fold(0.0, f64::max).sqrt()
        })
        .collect();
    let median = percentile(&nn, 0.5);
    if median > 0.0 {
        2.0 * median
    } else {
        0.01 * diagonal
    }
}

/// Default model sample spacing (see [`MetricsOptions::sample_spacing`]); 1 for an
/// empty or zero-area model.
pub fn default_sample_spacing(model: &[Primitive], points: usize) -> f64 {
    let area: f64 = model.iter().map(Primitive::area).sum();
    let n = points.clamp(1000, 1_000_000) as f64;
    if area > 0.0 && area.is_finite() {
        (area / n).sqrt()
    } else {
        1.0
    }
}

/// All measures of DESIGN §4 for `model` against `cloud`, and precision / recall /
/// scene accuracy when `truth` is given. Errs on an empty cloud or bad options.
pub fn evaluate(
    cloud: &[Point3<f64>],
    model: &[Primitive],
    truth: Option<&[Primitive]>,
    options: &MetricsOptions,
) -> Result<Metrics> {
    evaluate_indexed(cloud, &PointIndex::new(cloud), model, truth, options)
}

/// [`evaluate`] with `index`, a kd-tree over exactly `cloud`, already built (the fit's:
/// [`crate::fit_indexed`]).
pub fn evaluate_indexed(
    cloud: &[Point3<f64>],
    index: &PointIndex,
    model: &[Primitive],
    truth: Option<&[Primitive]>,
    options: &MetricsOptions,
) -> Result<Metrics> {
    if cloud.is_empty() {
        return Err(Error::EmptyCloud);
    }
    check::same_len("indexed points", index.len(), "points", cloud.len())?;
    let tau = (options.coverage_tau).unwrap_or_else(|| coverage_tau_indexed(cloud, index));
    check::non_negative("coverage_tau", tau)?;
    let spacing = options
        .sample_spacing
        .unwrap_or_else(|| default_sample_spacing(model, cloud.len()));
    let d_pm = point_to_model_distances(cloud, model)?;
    let samples = model_samples(model, spacing)?;
    let d_mp = nearest_indexed_distances(&samples, index);
    let chamfer = if model.is_empty() {
        f64::INFINITY
    } else {
        // Serial sums: rayon's split of a parallel float sum varies from run to run, and
        // with it the last bits (seen as a flake of formats_cli under load).
        d_pm.iter().map(|d| d * d).sum::<f64>() + d_mp.iter().map(|d| d * d).sum::<f64>()
    };
    let params: usize = model.iter().map(Primitive::parameter_count).sum();
    let truth = match truth {
        None => None,
        Some(t) => Some(match options.match_tolerance {
            Some(tol) => match_primitives(model, t, tol, spacing)?,
            None => match_primitives_relative(model, t, 0.1, spacing)?,
        }),
    };
    Ok(Metrics {
        points: cloud.len(),
        primitives: model.len(),
        point_to_model_mean: mean(&d_pm),
        point_to_model_p95: percentile(&d_pm, 0.95),
        point_to_model_max: d_pm.iter().copied().fold(0.0, f64::max),
        model_to_point_mean: mean(&d_mp),
        coverage: coverage(&d_pm, tau),
        coverage_tau: tau,
        chamfer,
        compactness: params as f64 / (3.0 * cloud.len() as f64),
        sample_spacing: spacing,
        truth,
    })
}
