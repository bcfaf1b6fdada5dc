//! The work budget of a lattice pass: an estimate, made before the coefficients are
//! built, of the nearest-neighbour queries the pass will make.
//!
//! Memory alone does not bound a fit's run time: a lattice spacing 10× finer than the
//! default, or `beta = inf`, fits in memory and runs for many minutes. The estimate
//! counts what such settings multiply:
//!
//! * the primitive term: one nearest-point query per candidate sample (`Σ M_i`);
//! * the point term: one query per (point, candidate) entry, `P · β` (β capped by the
//!   candidate count; the independent model's α samples come from the same query);
//! * the solver: every entry evaluated twice per L-BFGS iteration, up to
//!   `max_iterations`, counted as [`ENTRY_EVALUATIONS_PER_QUERY`] evaluations a query.
//!
//! The limit is [`FitOptions::work_budget`](super::FitOptions::work_budget) queries per
//! point, for a cloud of at least [`MIN_BUDGET_POINTS`] points (a small cloud may do
//! as much work as a 10 000-point one). On the bundled 20 k-point hallway the default
//! lattice fit (`--types square`) makes about 100 queries per point;
//! [`DEFAULT_WORK_PER_POINT`] allows 20× that.

use super::Settings;
use super::pass::describe_fit;
use crate::error::Remedy;
use crate::lattice::CandidateSet;
use crate::{Result, budget};

/// The default work budget: nearest-neighbour queries per input point of one pass.
pub const DEFAULT_WORK_PER_POINT: f64 = 2000.0;

/// The budget is per point, but never less than for a cloud of this many points.
pub const MIN_BUDGET_POINTS: f64 = 10_000.0;

/// Loss (and gradient) evaluations per L-BFGS iteration, counting line-search steps.
const EVALUATIONS_PER_ITERATION: f64 = 2.0;

/// Entry evaluations of the solver that cost about one kd-tree query (≈ 2 ns against
/// ≈ 1 µs).
const ENTRY_EVALUATIONS_PER_QUERY: f64 = 500.0;

/// Estimated nearest-neighbour queries of one lattice pass over `points` points with
/// `candidates` under `settings` (module docs).
pub fn estimate_work(points: usize, candidates: &CandidateSet, settings: &Settings) -> f64 {
    let p = points as f64;
    let samples: f64 = candidates
        .template_of
        .iter()
        .map(|&t| candidates.templates[t as usize].samples.len() as f64)
        .sum();
    let n = candidates.len();
    let entries = p * settings.chamfer.beta.unwrap_or(n).min(n) as f64;
    let iterations = settings.solver.max_iterations as f64;
    let solver = entries * EVALUATIONS_PER_ITERATION * iterations / ENTRY_EVALUATIONS_PER_QUERY;
    samples + entries + solver
}

/// Refuses a pass whose [`estimate_work`] is over `settings.work_budget` queries per
/// point (for at least [`MIN_BUDGET_POINTS`] points).
pub(super) fn check_work(
    points: usize,
    candidates: &CandidateSet,
    settings: &Settings,
) -> Result<()> {
    let need = estimate_work(points, candidates, settings);
    let limit = settings.work_budget * (points as f64).max(MIN_BUDGET_POINTS);
    budget::check_count(
        &describe_fit(points, candidates, settings),
        need,
        limit,
        "nearest-neighbour queries",
        vec![
            Remedy::Raise("spacing"),
            Remedy::Lower("beta"),
            Remedy::Raise("sample_spacing"),
            Remedy::Raise("work_budget"),
        ],
    )
}
