//! Coarse to fine: a finer lattice fitted where a refined fit leaves points unexplained.

use nalgebra::Point3;

use super::FitResult;
use super::pass::{fit_pass, refine_context};
use super::result::binary_chamfer_indexed;
use crate::metrics::point_to_model_distances;
use crate::progress::Progress;
use crate::refine::refine;
use crate::spatial::PointIndex;
use crate::{Error, PointCloud, Result};

/// Coarse to fine: when a refined fit leaves points unexplained (farther than
/// `max(4σ̂, h / 2)` from every primitive, at least 1 % of the points and 20 of them),
/// fits a lattice of half the spacing to those points alone, adds what it finds to the
/// model and refines the union (with merging) on the whole cloud. The result is kept
/// only if its binary chamfer is lower. Returns `result` unchanged without refinement.
///
/// `σ̂ = 1.4826 · median` of the point→model distances is the noise the refined model
/// sees (a robust σ of the residuals), `h` the point spacing. The cloud's own noise
/// estimate ([`Settings::noise`]) is no good here: on tubes thinner than its
/// neighbourhoods it measures their curvature (σ ≈ 0.02 for a 0.1 radius pipe with
/// 5 mm of noise), and a threshold of 4 of it hides a whole missing elbow.
pub(super) fn fill_gaps(
    cloud: &PointCloud,
    index: &PointIndex,
    result: FitResult,
    progress: &dyn Progress,
) -> Result<FitResult> {
    let Some(options) = result.settings.refine.clone() else {
        return Ok(result);
    };
    if !options.fill || result.primitives.is_empty() {
        return Ok(result);
    }
    let s = &result.settings;
    let distances = point_to_model_distances(&cloud.points, &result.primitives)?;
    let threshold = (4.0 * robust_sigma(&distances)).max(s.point_spacing / 2.0);
    let residual: Vec<Point3<f64>> = cloud
        .points
        .iter()
        .zip(&distances)
        .filter(|(_, d)| **d > threshold)
        .map(|(p, _)| *p)
        .collect();
    if residual.len() < 20 || residual.len() * 100 < cloud.len() {
        return Ok(result);
    }
    let fine = s.finer();
    let sub = PointCloud::from_points(residual);
    let sub_index = PointIndex::new(&sub.points);
    // A finer pass that cannot run (over a budget, no candidate) leaves the result as
    // it is; only a cancellation ends the fit.
    let extra = match fit_pass(&sub, &sub_index, fine, progress) {
        Ok(extra) => extra,
        Err(Error::Cancelled) => return Err(Error::Cancelled),
        Err(_) => return Ok(result),
    };
    if extra.primitives.is_empty() {
        return Ok(result);
    }
    let mut union = result.primitives.clone();
    union.extend(extra.primitives.iter().cloned());
    let mut existence = result.existence.clone();
    existence.extend(extra.existence.iter().copied());
    let shapes = s.shapes();
    let ctx = refine_context(cloud, index, s, &shapes);
    let refined = refine(&ctx, &union, &options)?;
    let before = binary_chamfer_indexed(cloud, index, &result.primitives, s)?.total;
    progress.message(&format!(
        "coarse to fine: {} unexplained points, {} primitives added, binary chamfer {before:.6} → {:.6}",
        sub.len(),
        extra.primitives.len(),
        refined.loss_after
    ));
    if refined.loss_after >= before {
        return Ok(result);
    }
    let mut out = result;
    out.existence = refined.source.iter().map(|&i| existence[i]).collect();
    out.primitives = refined.primitives;
    out.stats.refine_seconds += refined.seconds + extra.stats.solve_seconds;
    out.stats.filled += extra.primitives.len();
    Ok(out)
}

/// `1.4826 · median` of the finite `distances` (0 when there are none): the σ of a
/// normal residual whose absolute values these are.
fn robust_sigma(distances: &[f64]) -> f64 {
    let mut d: Vec<f64> = distances
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * d[mid]
}
