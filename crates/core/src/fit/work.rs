//! The work budget of a lattice pass: an estimate, made before the coefficients are
//! built, of the distance evaluations the pass will make, per input point.
//!
//! Memory alone does not bound a fit's run time: a lattice spacing 10× finer than the
//! default, or `beta = inf`, fits in memory and runs for many minutes. The estimate
//! counts the two terms that settings blow up:
//!
//! * the primitive term: every candidate sample's nearest cloud point, a kd-tree query
//!   of about `log₂ P` distance evaluations (`Σ M_i · log₂ P`);
//! * the solver: every coefficient entry evaluated [`EVALUATIONS_PER_ITERATION`] times
//!   per L-BFGS iteration, up to `max_iterations` (`P · E · 2 · iterations`, `E` the
//!   entries per point before the dominance reduction: `β`, or `β·α`).
//!
//! On the bundled 20 k-point hallway, the default lattice fit (`--types square`) is
//! about 1.4·10⁴ evaluations per point; [`DEFAULT_WORK_PER_POINT`] allows about 14× that.

use super::Settings;
use crate::chamfer::PointModel;
use crate::error::Remedy;
use crate::lattice::CandidateSet;
use crate::{Result, budget};

/// The default work budget: distance evaluations per input point of one lattice pass.
pub const DEFAULT_WORK_PER_POINT: f64 = 2e5;

/// Loss (and gradient) evaluations per L-BFGS iteration, counting line-search steps.
const EVALUATIONS_PER_ITERATION: f64 = 2.0;

/// Estimated distance evaluations of one lattice pass over `points` points with
/// `candidates` under `settings` (module docs).
pub fn estimate_work(points: usize, candidates: &CandidateSet, settings: &Settings) -> f64 {
    let p = points as f64;
    let samples: f64 = candidates
        .template_of
        .iter()
        .map(|&t| candidates.templates[t as usize].samples.len() as f64)
        .sum();
    let chamfer = &settings.chamfer;
    let n = candidates.len();
    let distinct = chamfer.beta.unwrap_or(n).min(n) as f64;
    let per_point = match chamfer.model {
        PointModel::Existence => distinct,
        PointModel::Independent => {
            let most = candidates
                .templates
                .iter()
                .map(|t| t.samples.len())
                .max()
                .unwrap_or(1);
            distinct * chamfer.alpha.unwrap_or(most).min(most) as f64
        }
    };
    let iterations = settings.solver.max_iterations as f64;
    samples * p.max(2.0).log2() + p * per_point * EVALUATIONS_PER_ITERATION * iterations
}

/// Refuses a pass whose [`estimate_work`] is over `settings.work_budget` per point.
pub(super) fn check_work(
    points: usize,
    candidates: &CandidateSet,
    settings: &Settings,
) -> Result<()> {
    let need = estimate_work(points, candidates, settings) / points.max(1) as f64;
    let what = format!(
        "a fit of {points} points × {} candidates (β = {})",
        candidates.len(),
        settings
            .chamfer
            .beta
            .map_or("inf".to_string(), |b| b.to_string())
    );
    budget::check_count(
        &what,
        need,
        settings.work_budget,
        "distance evaluations per point",
        vec![
            Remedy::Raise("spacing"),
            Remedy::Lower("beta"),
            Remedy::Raise("sample_spacing"),
            Remedy::Raise("work_budget"),
        ],
    )
}
