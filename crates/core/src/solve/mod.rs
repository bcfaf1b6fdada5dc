//! Minimising the probabilistic chamfer over existence, then deciding existence.
//!
//! [`solve`] runs, in order:
//!
//! 1. **L-BFGS** (`lbfgs.rs`) on `p ∈ [0, 1]^N` (projected, box-constrained;
//!    default) or on logits `z` with `p = σ(z)` (unconstrained); see [`Parameterization`].
//!    Large clouds run it first on a subset of the points, then briefly on all of them
//!    ([`SolverOptions::search_points`]).
//! 2. **Thresholding** at [`SolverOptions::threshold`].
//! 3. **Discrete polish** (`polish.rs` over the incremental state of
//!    `polish_state.rs`): local moves while the exact binary chamfer decreases (removals
//!    also when it stays equal, so redundant copies go). Replace chains are tried in
//!    parallel on copies of the scene, and trials known to fail again are skipped
//!    (`polish_memo.rs`); the result is that of trying every move in turn, on any number
//!    of threads.
//!
//! The box is the default because most candidates end exactly at 0 or 1, which the
//! projected method reaches and then drops from the quasi-Newton model, while the logit
//! form only approaches them as `z → ±∞`, where the factor `p(1 − p)` vanishes and progress
//! stalls. Measurements: `docs/solver.md`.
//!
//! ```
//! use primfit_core::chamfer::{ChamferOptions, Coefficients, SampleSets};
//! use primfit_core::na::Point3;
//! use primfit_core::Silent;
//! use primfit_core::solve::{SolverOptions, solve};
//!
//! // Ten points on a segment; candidate 0 has samples on it, candidate 1 lies far away.
//! let cloud: Vec<Point3<f64>> = (0..10)
//!     .map(|k| Point3::new(0.1 * k as f64, 0.0, 0.0))
//!     .collect();
//! let samples = [
//!     Point3::new(0.0, 0.0, 0.0),
//!     Point3::new(0.9, 0.0, 0.0),
//!     Point3::new(5.0, 5.0, 0.0),
//! ];
//! let candidates = SampleSets::new(&samples, &[0, 0, 1], 2).unwrap();
//! let loss = ChamferOptions { cap: 1.0, ..Default::default() };
//! let coeffs = Coefficients::build(&cloud, &candidates, &loss, &Silent).unwrap();
//! let solution = solve(&coeffs, &SolverOptions::default(), &Silent).unwrap();
//! assert_eq!(solution.exists, [true, false]);
//! ```

mod candidate_rows;
mod lbfgs;
mod polish;
mod polish_memo;
mod polish_state;

use lbfgs::{LbfgsRun, lbfgs};
pub(crate) use polish::{Moves, polish};

use crate::chamfer::{Coefficients, Evaluator, LossValue};
use crate::check::{self, Interval};
use crate::progress::Progress;
use crate::{Error, Limit, Result};
use lbfgs::lbfgs_on_logits;

/// Default [`SolverOptions::max_iterations`] (a count of iterations): the most L-BFGS
/// iterations of a solve (of its search phase when it has two), a cap on the time spent
/// on a slowly converging problem. The other stops are `ftol` and `pgtol`.
pub const DEFAULT_MAX_ITERATIONS: usize = 200;

/// Default [`SolverOptions::search_points`] (a count of points): clouds of more points
/// are solved in two phases.
pub const DEFAULT_SEARCH_POINTS: Limit = Limit::At(50_000);

/// How existence is parameterised during the continuous optimisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Parameterization {
    /// Projected L-BFGS directly on `p ∈ [0, 1]^N`.
    #[default]
    Box,
    /// Unconstrained L-BFGS on logits `z`, `p = 1 / (1 + e^{−z})`.
    Logit,
}

impl Parameterization {
    /// Name on the CLI and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Parameterization::Box => "box",
            Parameterization::Logit => "logit",
        }
    }
    /// Parses `"box"` or `"logit"`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "box" => Ok(Parameterization::Box),
            "logit" => Ok(Parameterization::Logit),
            o => Err(Error::Unknown {
                what: "parameterization",
                value: o.into(),
                expected: "box or logit",
            }),
        }
    }
}

/// Solver settings.
#[derive(Debug, Clone, PartialEq)]
pub struct SolverOptions {
    /// Box (default) or logit.
    pub parameterization: Parameterization,
    /// Maximum L-BFGS iterations (default [`DEFAULT_MAX_ITERATIONS`]).
    pub max_iterations: usize,
    /// Number of stored (s, y) pairs.
    pub memory: usize,
    /// Stop when the loss decrease of an iteration is below `ftol · max(|f|, 1)`.
    pub ftol: f64,
    /// Stop when the projected gradient's max-norm falls below `pgtol` × its initial value.
    pub pgtol: f64,
    /// Starting probability of every candidate.
    pub initial: f64,
    /// Existence threshold on the continuous solution.
    pub threshold: f64,
    /// Run the discrete polish after thresholding.
    pub polish: bool,
    /// Maximum polish sweeps over all candidates.
    pub max_polish_sweeps: usize,
    /// Clouds of more points are solved in two phases: L-BFGS and the polish's search
    /// moves (add-and-prune, replace chains) run on about this many points (a fixed
    /// pseudo-random subset, point term reweighted: [`Coefficients::row_sample`]), then
    /// L-BFGS continues on all points for at most [`SolverOptions::full_iterations`] and
    /// single flips are polished on all points, so the answer is a local minimum of the
    /// exact binary loss for single flips. [`Limit::All`]: always one phase on all points.
    pub search_points: Limit,
    /// L-BFGS iterations on all points after the search phase (see `search_points`).
    pub full_iterations: usize,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            parameterization: Parameterization::Box,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            memory: 10,
            ftol: 1e-6,
            pgtol: 1e-7,
            initial: 0.5,
            threshold: 0.5,
            polish: true,
            max_polish_sweeps: 20,
            search_points: DEFAULT_SEARCH_POINTS,
            full_iterations: 10,
        }
    }
}

/// Why the continuous optimisation stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// Projected gradient small enough.
    Gradient,
    /// Loss decrease below `ftol`.
    Decrease,
    /// `max_iterations` reached.
    Iterations,
    /// No step along the search direction decreased the loss.
    LineSearch,
}

impl StopReason {
    /// Its name in reports: `gradient`, `decrease`, `iterations` or `line_search`.
    pub fn name(self) -> &'static str {
        match self {
            StopReason::Gradient => "gradient",
            StopReason::Decrease => "decrease",
            StopReason::Iterations => "iterations",
            StopReason::LineSearch => "line_search",
        }
    }
}

/// Outcome of [`solve`].
#[derive(Debug, Clone)]
pub struct Solution {
    /// Continuous existence probabilities at the end of L-BFGS.
    pub probability: Vec<f64>,
    /// Decided existence after thresholding and polish.
    pub exists: Vec<bool>,
    /// Loss after every L-BFGS iteration (the first entry is the starting loss).
    pub history: Vec<f64>,
    /// L-BFGS iterations run.
    pub iterations: usize,
    /// Loss + gradient evaluations.
    pub evaluations: usize,
    /// Why L-BFGS stopped.
    pub stop: StopReason,
    /// Binary chamfer of the thresholded scene, before polish.
    pub thresholded: LossValue,
    /// Binary chamfer of the final scene.
    pub binary: LossValue,
    /// Candidates flipped by the polish.
    pub flips: usize,
}

impl Solution {
    /// The solution of a problem in which none of `n` candidates can exist (all were
    /// dominated): every probability 0, nothing exists, the loss `loss` throughout.
    pub fn nothing(n: usize, loss: LossValue) -> Solution {
        Solution {
            probability: vec![0.0; n],
            exists: vec![false; n],
            history: vec![loss.total],
            iterations: 0,
            evaluations: 0,
            stop: StopReason::Gradient,
            thresholded: loss,
            binary: loss,
            flips: 0,
        }
    }
}

/// Minimises the loss of `coeffs` over existence, thresholds and polishes; every
/// candidate starts at [`SolverOptions::initial`].
pub fn solve(
    coeffs: &Coefficients,
    options: &SolverOptions,
    progress: &dyn Progress,
) -> Result<Solution> {
    solve_from(
        coeffs,
        vec![options.initial; coeffs.candidates()],
        options,
        progress,
    )
}

/// [`solve`] from a start of one's own: `start[i]` is candidate i's starting
/// probability (a warm start, e.g. a network's existence; in `[0, 1]`, or `(0, 1)` for
/// [`Parameterization::Logit`]). [`SolverOptions::initial`] is not used.
pub fn solve_from(
    coeffs: &Coefficients,
    start: Vec<f64>,
    options: &SolverOptions,
    progress: &dyn Progress,
) -> Result<Solution> {
    validate(options)?;
    validate_start(&start, coeffs.candidates(), options.parameterization)?;
    let search = match options.search_points {
        Limit::At(m) if coeffs.points() > m => Some(coeffs.row_sample(m)),
        _ => None,
    };
    progress.start("solve", options.max_iterations as u64);
    let run = match &search {
        None => minimise(coeffs, start, options, progress),
        Some(sub) => {
            let first = minimise(sub, start, options, progress);
            let full = SolverOptions {
                max_iterations: options.full_iterations,
                ..options.clone()
            };
            let mut second = minimise(coeffs, first.x, &full, progress);
            let mut history = first.history;
            history.extend(second.history.drain(1..));
            LbfgsRun {
                history,
                iterations: first.iterations + second.iterations,
                evaluations: first.evaluations + second.evaluations,
                ..second
            }
        }
    };
    progress.finish();
    progress.checkpoint()?;
    let mut evaluator = Evaluator::new(coeffs);
    let mut exists: Vec<bool> = run.x.iter().map(|&p| p >= options.threshold).collect();
    let thresholded = evaluator.binary_value(&exists);
    let mut flips = 0;
    if options.polish {
        let sweeps = options.max_polish_sweeps;
        match &search {
            None => flips += polish(coeffs, &run.x, &mut exists, sweeps, Moves::All),
            Some(sub) => {
                flips += polish(sub, &run.x, &mut exists, sweeps, Moves::All);
                flips += polish(coeffs, &run.x, &mut exists, sweeps, Moves::SingleFlips);
            }
        }
    }
    // Only a flip changes the scene: without one the thresholded loss stands.
    let binary = if flips == 0 {
        thresholded
    } else {
        evaluator.binary_value(&exists)
    };
    Ok(Solution {
        probability: run.x,
        exists,
        history: run.history,
        iterations: run.iterations,
        evaluations: run.evaluations,
        stop: run.stop,
        thresholded,
        binary,
        flips,
    })
}

/// L-BFGS on `coeffs` from `start` (probabilities) in the chosen parameterization; the
/// returned `x` are probabilities.
fn minimise(
    coeffs: &Coefficients,
    start: Vec<f64>,
    options: &SolverOptions,
    progress: &dyn Progress,
) -> LbfgsRun {
    let mut evaluator = Evaluator::new(coeffs);
    let loss = |p: &[f64], grad: &mut [f64]| evaluator.evaluate(p, grad).total;
    match options.parameterization {
        Parameterization::Box => lbfgs(start, true, options, progress, loss),
        Parameterization::Logit => lbfgs_on_logits(start, options, progress, loss),
    }
}

/// Checks the ranges of `o` ([`solve`] rejects what L-BFGS cannot start from).
fn validate(o: &SolverOptions) -> Result<()> {
    check::at_least("memory", o.memory, 1)?;
    if let Limit::At(m) = o.search_points {
        check::at_least("search_points", m, 1)?;
    }
    check::in_interval("threshold", o.threshold, Interval::UNIT)?;
    check::in_interval("initial", o.initial, starts(o.parameterization))
}

/// The starting probabilities L-BFGS accepts in `parameterization`.
fn starts(parameterization: Parameterization) -> Interval {
    match parameterization {
        Parameterization::Box => Interval::UNIT,
        // Logits of 0 and 1 are infinite.
        Parameterization::Logit => Interval::open(0.0, 1.0),
    }
}

/// Checks a warm start: one probability per candidate, each one L-BFGS can start from.
fn validate_start(start: &[f64], n: usize, parameterization: Parameterization) -> Result<()> {
    check::same_len("start probabilities", start.len(), "candidate", n)?;
    let range = starts(parameterization);
    start
        .iter()
        .try_for_each(|&p| check::in_interval("start", p, range))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chamfer::test_problems::{clusters, segments};
    use crate::chamfer::{ChamferOptions, Evaluator};
    use crate::progress::Silent;

    #[test]
    fn a_warm_start_at_the_answer_needs_no_iteration_and_keeps_it() {
        let (cloud, sets) = clusters();
        let opts = ChamferOptions {
            cap: 1.0,
            ..Default::default()
        };
        let c = Coefficients::build(&cloud, &sets, &opts, &Silent).unwrap();
        let cold = solve(&c, &SolverOptions::default(), &Silent).unwrap();
        assert!(cold.iterations > 0);
        let answer = cold
            .exists
            .iter()
            .map(|&e| f64::from(u8::from(e)))
            .collect();
        let warm = solve_from(&c, answer, &SolverOptions::default(), &Silent).unwrap();
        assert_eq!(warm.iterations, 0);
        assert_eq!(warm.exists, cold.exists);
    }

    #[test]
    fn a_warm_start_needs_one_probability_per_candidate_in_range() {
        let (cloud, sets) = clusters();
        let c = Coefficients::build(&cloud, &sets, &ChamferOptions::default(), &Silent).unwrap();
        let n = c.candidates();
        let o = SolverOptions::default();
        assert!(solve_from(&c, vec![0.5; n - 1], &o, &Silent).is_err());
        let mut outside = vec![0.5; n];
        outside[0] = 1.5;
        assert!(solve_from(&c, outside, &o, &Silent).is_err());
        let logit = SolverOptions {
            parameterization: Parameterization::Logit,
            ..Default::default()
        };
        assert!(solve_from(&c, vec![0.0; n], &logit, &Silent).is_err());
        assert!(solve_from(&c, vec![0.3; n], &logit, &Silent).is_ok());
    }

    #[test]
    fn solve_keeps_one_candidate_per_cluster() {
        let (cloud, sets) = clusters();
        for parameterization in [Parameterization::Box, Parameterization::Logit] {
            let opts = ChamferOptions {
                cap: 1.0,
                ..Default::default()
            };
            let c = Coefficients::build(&cloud, &sets, &opts, &Silent).unwrap();
            let sol = solve(
                &c,
                &SolverOptions {
                    parameterization,
                    ..Default::default()
                },
                &Silent,
            )
            .unwrap();
            assert!(
                sol.exists[1] && !sol.exists[3],
                "{parameterization:?}: {:?}",
                sol.exists
            );
            assert!(
                sol.exists[0] ^ sol.exists[2],
                "duplicate kept: {:?}",
                sol.exists
            );
            assert!(sol.binary.total <= sol.thresholded.total);
        }
    }

    /// With fewer search points than points, the answer is still a local minimum of the
    /// exact binary loss for single flips (checked by brute force), and close to the
    /// one-phase answer.
    #[test]
    fn two_phase_solve_ends_at_a_single_flip_minimum_of_the_full_loss() {
        for seed in 0..5 {
            let (cloud, sets) = segments(seed);
            let o = ChamferOptions {
                cap: 0.05,
                beta: Some(6),
                ..Default::default()
            };
            let c = Coefficients::build(&cloud, &sets, &o, &Silent).unwrap();
            let one = solve(&c, &SolverOptions::default(), &Silent).unwrap();
            let two = solve(
                &c,
                &SolverOptions {
                    search_points: Limit::At(c.points() / 3),
                    ..Default::default()
                },
                &Silent,
            )
            .unwrap();
            let mut ev = Evaluator::new(&c);
            let value = two.binary.total;
            assert_eq!(value, ev.binary_value(&two.exists).total);
            for i in 0..c.candidates() {
                let mut e = two.exists.clone();
                e[i] = !e[i];
                assert!(
                    ev.binary_value(&e).total >= value - 1e-9 * value.abs(),
                    "seed {seed}: flip {i}"
                );
            }
            assert!(
                value <= one.binary.total * 1.05,
                "seed {seed}: {value} vs {}",
                one.binary.total
            );
        }
    }
}
