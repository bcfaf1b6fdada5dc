//! Minimising the probabilistic chamfer over existence, then deciding existence.
//!
//! 1. **L-BFGS** ([`lbfgs`]) on `p ∈ [0, 1]^N` (projected, box-constrained; default) or on
//!    logits `z` with `p = σ(z)` (unconstrained).
//! 2. **Thresholding** at [`SolverOptions::threshold`].
//! 3. **Discrete polish** ([`polish`]): single-candidate flips while the exact binary
//!    chamfer decreases (removals also when it stays equal, so redundant copies go).
//!
//! Why the box is the default: at the optimum most candidates sit exactly at 0 or 1. The
//! projected method reaches those bounds exactly and then drops them from the quasi-Newton
//! model, while the logit form can only approach them as `z → ±∞`, where the chain-rule
//! factor `p(1 − p)` vanishes and progress stalls. Measured with
//! `cargo run --release --example parameterization` (3 pipes, 3 hallways): logit stops after
//! ~20 iterations at a continuous loss 5–270 % above the box's (pipe 1: 3.19 vs 0.87;
//! hallway 0: 13.65 vs 13.02), and its thresholded scene is worse in all six; after the
//! discrete polish the box is equal or better in five of six (hallway 2: 12.35 vs 12.55;
//! hallway 1: 12.685 vs 12.681). The box costs more evaluations (60–350 vs ~24), which
//! is cheap next to building the coefficients.

use rayon::prelude::*;

use crate::chamfer::{Coefficients, Evaluator, LossValue};
use crate::progress::Progress;
use crate::{Error, Result};

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
            o => Err(Error::invalid(format!(
                "unknown parameterization {o:?} (box|logit)"
            ))),
        }
    }
}

/// Solver settings.
#[derive(Debug, Clone, PartialEq)]
pub struct SolverOptions {
    /// Box (default) or logit.
    pub parameterization: Parameterization,
    /// Maximum L-BFGS iterations.
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
    /// exact binary loss for single flips. `usize::MAX`: always one phase on all points.
    pub search_points: usize,
    /// L-BFGS iterations on all points after the search phase (see `search_points`).
    pub full_iterations: usize,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            parameterization: Parameterization::Box,
            max_iterations: 200,
            memory: 10,
            ftol: 1e-6,
            pgtol: 1e-7,
            initial: 0.5,
            threshold: 0.5,
            polish: true,
            max_polish_sweeps: 20,
            search_points: 50_000,
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

/// Minimises the loss of `coeffs` over existence, thresholds and polishes.
pub fn solve(
    coeffs: &Coefficients,
    options: &SolverOptions,
    progress: &dyn Progress,
) -> Result<Solution> {
    validate(options)?;
    let n = coeffs.candidates();
    let search =
        (coeffs.points() > options.search_points).then(|| coeffs.row_sample(options.search_points));
    progress.start("solve", options.max_iterations as u64);
    let run = match &search {
        None => minimise(coeffs, vec![options.initial; n], options, progress),
        Some(sub) => {
            let first = minimise(sub, vec![options.initial; n], options, progress);
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
    let binary = evaluator.binary_value(&exists);
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
    match options.parameterization {
        Parameterization::Box => lbfgs(start, true, options, progress, |x, g| {
            evaluator.evaluate(x, g).total
        }),
        Parameterization::Logit => {
            let n = start.len();
            // Clamped so that a warm start at 0 or 1 has a finite logit.
            let z0 = start
                .iter()
                .map(|&p| logit(p.clamp(1e-9, 1.0 - 1e-9)))
                .collect();
            let mut p = vec![0.0; n];
            let mut gp = vec![0.0; n];
            let mut run = lbfgs(z0, false, options, progress, |z, gz| {
                for (pi, zi) in p.iter_mut().zip(z) {
                    *pi = sigmoid(*zi);
                }
                let f = evaluator.evaluate(&p, &mut gp).total;
                for ((g, gpi), pi) in gz.iter_mut().zip(&gp).zip(&p) {
                    *g = gpi * pi * (1.0 - pi);
                }
                f
            });
            run.x.iter_mut().for_each(|z| *z = sigmoid(*z));
            run
        }
    }
}

fn validate(o: &SolverOptions) -> Result<()> {
    if o.memory == 0 {
        return Err(Error::invalid("L-BFGS memory must be at least 1"));
    }
    if !(0.0..=1.0).contains(&o.initial) || !(0.0..=1.0).contains(&o.threshold) {
        return Err(Error::invalid(
            "initial probability and threshold must lie in [0, 1]",
        ));
    }
    if o.parameterization == Parameterization::Logit && (o.initial <= 0.0 || o.initial >= 1.0) {
        return Err(Error::invalid(
            "the logit parameterization needs an initial probability in (0, 1)",
        ));
    }
    Ok(())
}

fn sigmoid(z: f64) -> f64 {
    1.0 / (1.0 + (-z).exp())
}

fn logit(p: f64) -> f64 {
    (p / (1.0 - p)).ln()
}

/// Result of [`lbfgs`].
#[derive(Debug, Clone)]
pub struct LbfgsRun {
    /// Final point.
    pub x: Vec<f64>,
    /// Loss after each iteration (first: at the start).
    pub history: Vec<f64>,
    /// Iterations.
    pub iterations: usize,
    /// Function evaluations.
    pub evaluations: usize,
    /// Why it stopped.
    pub stop: StopReason,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// L-BFGS (two-loop recursion, Nocedal & Wright alg. 7.4) minimising `f(x, grad) -> value`.
///
/// With `unit_box`, the iterate is kept in `[0, 1]^n`: variables at a bound whose gradient
/// points outward are *active* and left out of the direction, and the line search
/// backtracks along the projection arc `P(x + t d)` with an Armijo test on the actual
/// step (the projected method of Bertsekas). Without it, this is plain L-BFGS with
/// Armijo backtracking. Sums run sequentially so results never depend on thread count.
pub fn lbfgs(
    mut x: Vec<f64>,
    unit_box: bool,
    options: &SolverOptions,
    progress: &dyn Progress,
    mut f: impl FnMut(&[f64], &mut [f64]) -> f64,
) -> LbfgsRun {
    let n = x.len();
    let m = options.memory;
    let project = |v: f64| if unit_box { v.clamp(0.0, 1.0) } else { v };
    x.iter_mut().for_each(|v| *v = project(*v));
    let mut g = vec![0.0; n];
    let mut fx = f(&x, &mut g);
    let mut evaluations = 1;
    let mut history = vec![fx];
    let (mut s_mem, mut y_mem, mut rho_mem): (Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<f64>) =
        (vec![], vec![], vec![]);
    let mut alpha = vec![0.0; m];
    let (mut d, mut x_new, mut g_new) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut active = vec![false; n];
    let projected_norm = |x: &[f64], g: &[f64]| -> f64 {
        x.iter()
            .zip(g)
            .map(|(xi, gi)| (xi - project(xi - gi)).abs())
            .fold(0.0, f64::max)
    };
    let pg0 = projected_norm(&x, &g);
    let mut stop = StopReason::Iterations;
    let mut iterations = 0;
    for _ in 0..options.max_iterations {
        if n == 0 || projected_norm(&x, &g) <= options.pgtol * pg0.max(f64::MIN_POSITIVE) {
            stop = StopReason::Gradient;
            break;
        }
        for i in 0..n {
            active[i] = unit_box && ((x[i] <= 0.0 && g[i] > 0.0) || (x[i] >= 1.0 && g[i] < 0.0));
            d[i] = if active[i] { 0.0 } else { g[i] };
        }
        // Two-loop recursion: d ← H · d.
        let k = s_mem.len();
        for j in (0..k).rev() {
            alpha[j] = rho_mem[j] * dot(&s_mem[j], &d);
            d.iter_mut()
                .zip(&y_mem[j])
                .for_each(|(di, yi)| *di -= alpha[j] * yi);
        }
        if k > 0 {
            let gamma = dot(&s_mem[k - 1], &y_mem[k - 1]) / dot(&y_mem[k - 1], &y_mem[k - 1]);
            d.iter_mut().for_each(|di| *di *= gamma);
        }
        for j in 0..k {
            let beta = rho_mem[j] * dot(&y_mem[j], &d);
            d.iter_mut()
                .zip(&s_mem[j])
                .for_each(|(di, si)| *di += (alpha[j] - beta) * si);
        }
        for i in 0..n {
            d[i] = if active[i] { 0.0 } else { -d[i] };
        }
        if dot(&g, &d) >= 0.0 || k == 0 {
            // Not a descent direction (or no curvature yet): steepest descent on the
            // free variables, scaled so that no variable moves by more than 1.
            s_mem.clear();
            y_mem.clear();
            rho_mem.clear();
            let scale = g
                .iter()
                .zip(&active)
                .filter(|(_, a)| !**a)
                .map(|(gi, _)| gi.abs())
                .fold(0.0, f64::max);
            for i in 0..n {
                d[i] = if active[i] || scale == 0.0 {
                    0.0
                } else {
                    -g[i] / scale
                };
            }
        }
        // Backtracking Armijo line search along the projection arc.
        let mut t = 1.0;
        let mut accepted = None;
        for _ in 0..40 {
            for i in 0..n {
                x_new[i] = project(x[i] + t * d[i]);
            }
            let f_new = f(&x_new, &mut g_new);
            evaluations += 1;
            let decrease: f64 = g
                .iter()
                .zip(x_new.iter().zip(&x))
                .map(|(gi, (a, b))| gi * (a - b))
                .sum();
            if f_new.is_finite() && f_new <= fx + 1e-4 * decrease {
                accepted = Some(f_new);
                break;
            }
            t *= 0.5;
        }
        let Some(f_new) = accepted else {
            stop = StopReason::LineSearch;
            break;
        };
        iterations += 1;
        // Curvature pair.
        let s: Vec<f64> = x_new.iter().zip(&x).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = g_new.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-12 * dot(&y, &y).max(f64::MIN_POSITIVE) {
            if s_mem.len() == m {
                s_mem.remove(0);
                y_mem.remove(0);
                rho_mem.remove(0);
            }
            s_mem.push(s);
            y_mem.push(y);
            rho_mem.push(1.0 / sy);
        }
        std::mem::swap(&mut x, &mut x_new);
        std::mem::swap(&mut g, &mut g_new);
        let f_old = fx;
        fx = f_new;
        history.push(fx);
        progress.advance(1);
        if f_old - fx <= options.ftol * f_old.abs().max(fx.abs()).max(1.0) {
            stop = StopReason::Decrease;
            break;
        }
    }
    LbfgsRun {
        x,
        history,
        iterations,
        evaluations,
        stop,
    }
}

/// Discrete polish of the binary scene `exists` on the binary chamfer (same entries, same
/// cap). Two moves, repeated in sweeps until neither changes anything:
///
/// 1. **single flips**: remove a candidate if the loss does not increase (so redundant
///    copies go), add one if it strictly decreases;
/// 2. **add and prune**: add a candidate, then remove every neighbour it made redundant
///    (a current owner of one of its rows whose removal no longer costs anything); keep
///    the whole move only if the total strictly decreases. This turns an overlapping
///    tiling into a cleaner one, which single flips cannot;
/// 3. **replace chains**: remove a candidate, add the neighbour (a candidate with entries
///    in the same rows) that lowers the loss most, prune as in 2; if that alone does not
///    pay, continue with an existing candidate overlapping the new one (an ejection chain
///    of depth [`CHAIN_DEPTH`]). Kept only if the whole chain strictly lowers the loss.
///    This shifts a row of tiles by a lattice step, e.g. five half-overlapping tiles
///    into four abutting ones.
///
/// Candidates are visited in ascending continuous probability; after the first sweep only
/// candidates near a flipped one are revisited. Incremental: each point keeps its best and
/// runner-up explanation (owner and distance of the two nearest existing candidates, or
/// `d_cap`), so a move's change is a sum over the moved candidate's rows with no row scans;
/// only a removal rescans the rows it owned, and a rejected trial move is rolled back from
/// an undo log of the explanations it changed. Returns the number of flips.
pub fn polish(
    coeffs: &Coefficients,
    probability: &[f64],
    exists: &mut [bool],
    max_sweeps: usize,
    moves: Moves,
) -> usize {
    let n = coeffs.candidates();
    let mut state = PolishState::new(coeffs, exists);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| probability[a].total_cmp(&probability[b]).then(a.cmp(&b)));
    let mut dirty = vec![true; n];
    let mut flips = 0;
    for _ in 0..max_sweeps {
        let before = flips;
        state.flipped.clear();
        for &i in order.iter().filter(|&&i| dirty[i]) {
            let delta = state.flip_delta(i);
            if (state.exists[i] && delta <= state.tolerance)
                || (!state.exists[i] && delta < -state.tolerance)
            {
                state.flip(i);
                state.commit();
                flips += 1;
            }
        }
        if moves == Moves::All {
            for &i in order.iter().filter(|&&i| dirty[i]) {
                if !state.exists[i] {
                    flips += state.add_and_prune(i);
                    state.commit();
                }
            }
            for &i in order.iter().filter(|&&i| dirty[i]) {
                if state.exists[i] {
                    flips += state.replace(i);
                    state.commit();
                }
            }
        }
        if flips == before {
            break;
        }
        dirty.fill(false);
        let mut flipped = std::mem::take(&mut state.flipped);
        flipped.sort_unstable();
        flipped.dedup();
        for &c in &flipped {
            dirty[c] = true;
            for k in state.neighbours(c) {
                dirty[k] = true;
            }
        }
    }
    exists.copy_from_slice(&state.exists);
    flips
}

/// Which moves [`polish`] makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Moves {
    /// Single flips, add-and-prune and replace chains.
    All,
    /// Single flips only (linear in the entries per sweep).
    SingleFlips,
}

/// Links of a replace chain (move 3 of [`polish`]).
const CHAIN_DEPTH: usize = 2;

/// Replacement candidates evaluated exactly per chain link (ranked by what they gain on
/// the freed points).
const CHAIN_CHOICES: usize = 3;

/// Rows sampled per candidate when listing its neighbours.
const NEIGHBOUR_ROWS: usize = 512;

/// A point's current explanation: the nearest existing candidate and the runner-up
/// (a different candidate), each with its squared distance; `u32::MAX` / `d_cap` if none.
#[derive(Debug, Clone, Copy)]
struct Explanation {
    owner: u32,
    cost: f64,
    second_owner: u32,
    second_cost: f64,
}

/// One change to [`PolishState`], recorded so that a trial move can be rolled back without
/// rescanning rows.
#[derive(Debug, Clone, Copy)]
enum Undo {
    /// Point `j` had this explanation.
    Point(u32, Explanation),
    /// Candidate `i` was flipped.
    Flip(u32),
}

/// A position in the undo log (see [`PolishState::rollback`]).
#[derive(Debug, Clone, Copy)]
struct Mark {
    undo: usize,
    flipped: usize,
}

/// The binary scene and each point's current explanation, for [`polish`].
struct PolishState<'c> {
    coeffs: &'c Coefficients,
    rows: Vec<Vec<(u32, f64)>>,
    exists: Vec<bool>,
    point: Vec<Explanation>,
    neighbour_cache: Vec<Option<Vec<u32>>>,
    gain: Vec<f64>,
    /// Candidates flipped by kept moves since the sweep began (rolled-back flips are not).
    flipped: Vec<usize>,
    /// Changes since the last [`PolishState::commit`].
    undo: Vec<Undo>,
    tolerance: f64,
}

impl<'c> PolishState<'c> {
    fn new(coeffs: &'c Coefficients, exists: &[bool]) -> Self {
        let n = coeffs.candidates();
        let point = (0..coeffs.points())
            .into_par_iter()
            .map(|j| explain(coeffs, j, exists))
            .collect();
        let mut s = PolishState {
            coeffs,
            rows: transpose(coeffs),
            exists: exists.to_vec(),
            point,
            neighbour_cache: vec![None; n],
            gain: vec![0.0; n],
            flipped: Vec::new(),
            undo: Vec::new(),
            tolerance: 0.0,
        };
        let o = &coeffs.options;
        let cost: f64 = s.point.iter().map(|e| e.cost).sum();
        let scale = coeffs.g.iter().sum::<f64>() * o.primitive_weight + cost * o.point_weight;
        s.tolerance = 1e-12 * scale.abs().max(1e-300);
        s
    }

    /// Change of the binary loss if candidate `i` flipped.
    fn flip_delta(&self, i: usize) -> f64 {
        let (wp, wq) = (
            self.coeffs.options.primitive_weight,
            self.coeffs.options.point_weight,
        );
        let mut delta = 0.0;
        if self.exists[i] {
            for &(j, _) in &self.rows[i] {
                let e = &self.point[j as usize];
                if e.owner == i as u32 {
                    delta += e.second_cost - e.cost;
                }
            }
            wq * delta - wp * self.coeffs.g[i]
        } else {
            for &(j, d) in &self.rows[i] {
                let e = &self.point[j as usize];
                // An unexplained point costs d_cap until anything exists, however far.
                delta += if e.owner == u32::MAX {
                    d - e.cost
                } else {
                    (d - e.cost).min(0.0)
                };
            }
            wq * delta + wp * self.coeffs.g[i]
        }
    }

    /// Flips candidate `i` and updates the points it touches (logged for rollback).
    fn flip(&mut self, i: usize) {
        self.exists[i] = !self.exists[i];
        self.flipped.push(i);
        let c = i as u32;
        self.undo.push(Undo::Flip(c));
        for &(j, d) in &self.rows[i] {
            let e = &mut self.point[j as usize];
            let old = *e;
            if self.exists[i] {
                if e.owner == u32::MAX || d < e.cost {
                    (e.second_owner, e.second_cost) = (e.owner, e.cost);
                    (e.owner, e.cost) = (c, d);
                } else if e.second_owner == u32::MAX || d < e.second_cost {
                    (e.second_owner, e.second_cost) = (c, d);
                } else {
                    continue;
                }
            } else if e.owner == c || e.second_owner == c {
                *e = explain(self.coeffs, j as usize, &self.exists);
            } else {
                continue;
            }
            self.undo.push(Undo::Point(j, old));
        }
    }

    /// The current position of the undo log.
    fn mark(&self) -> Mark {
        Mark {
            undo: self.undo.len(),
            flipped: self.flipped.len(),
        }
    }

    /// Undoes every flip since `mark`, restoring the saved explanations (no row scans).
    fn rollback(&mut self, mark: Mark) {
        while self.undo.len() > mark.undo {
            match self.undo.pop() {
                Some(Undo::Point(j, e)) => self.point[j as usize] = e,
                Some(Undo::Flip(i)) => self.exists[i as usize] = !self.exists[i as usize],
                None => break,
            }
        }
        self.flipped.truncate(mark.flipped);
    }

    /// Forgets the undo log: the changes so far are kept.
    fn commit(&mut self) {
        self.undo.clear();
    }

    /// Move 3 of [`polish`]; returns the number of flips kept (0 if reverted).
    fn replace(&mut self, i: usize) -> usize {
        let mut journal = Vec::new();
        if self.chain(i, 0.0, CHAIN_DEPTH, &mut journal) {
            journal.len()
        } else {
            0
        }
    }

    /// One link of an ejection chain: remove `i`, add the neighbour `k` that lowers the
    /// loss most (among the few that gain most on the freed points), prune what `k` made
    /// redundant. If the running total (`so_far` plus this link) has not yet decreased,
    /// continue from each existing candidate that overlaps `k`. Flips are recorded in
    /// `journal`; on failure this link's flips are undone.
    fn chain(&mut self, i: usize, so_far: f64, depth: usize, journal: &mut Vec<usize>) -> bool {
        let mark = self.mark();
        let journal_mark = journal.len();
        let freed: Vec<u32> = self.rows[i]
            .iter()
            .filter(|&&(j, _)| self.point[j as usize].owner == i as u32)
            .map(|&(j, _)| j)
            .collect();
        let mut total = so_far + self.flip_delta(i);
        self.flip(i);
        journal.push(i);
        if let Some((addition, k)) = self.best_replacement(&freed, journal) {
            total += addition;
            self.flip(k);
            journal.push(k);
            total += self.prune_displaced_by(k, journal);
            if total < -self.tolerance {
                return true;
            }
            if depth > 1 {
                for c in self.existing_overlapping(k) {
                    if !journal.contains(&c) && self.chain(c, total, depth - 1, journal) {
                        return true;
                    }
                }
            }
        }
        self.rollback(mark);
        journal.truncate(journal_mark);
        false
    }

    /// The absent candidate (not moved in this chain) that lowers the loss most, among the
    /// [`CHAIN_CHOICES`] that gain most on the `freed` points, with that change.
    fn best_replacement(&mut self, freed: &[u32], journal: &[usize]) -> Option<(f64, usize)> {
        let mut touched: Vec<usize> = Vec::new();
        for &j in freed {
            let cost = self.point[j as usize].cost;
            let r = self.coeffs.row(j as usize);
            for (&c, &d) in self.coeffs.cand[r.clone()].iter().zip(&self.coeffs.dist[r]) {
                let c = c as usize;
                if d < cost && !self.exists[c] && !journal.contains(&c) {
                    if self.gain[c] == 0.0 {
                        touched.push(c);
                    }
                    self.gain[c] += cost - d;
                }
            }
        }
        touched.sort_by(|&a, &b| self.gain[b].total_cmp(&self.gain[a]).then(a.cmp(&b)));
        for &c in &touched {
            self.gain[c] = 0.0;
        }
        touched
            .into_iter()
            .take(CHAIN_CHOICES)
            .map(|k| (self.flip_delta(k), k))
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
    }

    /// Candidates with entries in (a sample of at most [`NEIGHBOUR_ROWS`] of) the rows of
    /// `i`, sorted, without `i`; cached.
    fn neighbours(&mut self, i: usize) -> Vec<usize> {
        if self.neighbour_cache[i].is_none() {
            let rows = &self.rows[i];
            let stride = rows.len().div_ceil(NEIGHBOUR_ROWS).max(1);
            let mut n: Vec<u32> = rows
                .iter()
                .step_by(stride)
                .flat_map(|&(j, _)| {
                    self.coeffs.cand[self.coeffs.row(j as usize)]
                        .iter()
                        .copied()
                })
                .filter(|&c| c as usize != i)
                .collect();
            n.sort_unstable();
            n.dedup();
            self.neighbour_cache[i] = Some(n);
        }
        self.neighbour_cache[i]
            .iter()
            .flatten()
            .map(|&c| c as usize)
            .collect()
    }

    /// Existing neighbours of `k`.
    fn existing_overlapping(&mut self, k: usize) -> Vec<usize> {
        let n = self.neighbours(k);
        n.into_iter().filter(|&c| self.exists[c]).collect()
    }

    /// Removes every existing neighbour of `k` whose removal costs nothing, in index
    /// order, recording them in `journal`; returns the summed change.
    fn prune_displaced_by(&mut self, k: usize, journal: &mut Vec<usize>) -> f64 {
        let mut total = 0.0;
        for c in self.existing_overlapping(k) {
            let delta = self.flip_delta(c);
            if delta <= self.tolerance {
                total += delta;
                self.flip(c);
                journal.push(c);
            }
        }
        total
    }

    /// Move 2 of [`polish`]; returns the number of flips kept (0 if reverted).
    fn add_and_prune(&mut self, i: usize) -> usize {
        // Owners of the rows that `i` would explain at least as well: the neighbours it
        // may make redundant. Ties count, so one tile can replace two half-overlapping ones
        // even when the points are already perfectly explained.
        let mut displaced: Vec<u32> = self.rows[i]
            .iter()
            .map(|&(j, d)| (self.point[j as usize], d))
            .filter(|(e, d)| *d <= e.cost && e.owner != u32::MAX)
            .map(|(e, _)| e.owner)
            .collect();
        if displaced.is_empty() {
            return 0;
        }
        displaced.sort_unstable();
        displaced.dedup();
        let mark = self.mark();
        let mut gain = self.flip_delta(i);
        self.flip(i);
        let mut removed = Vec::new();
        for &k in &displaced {
            let k = k as usize;
            let delta = self.flip_delta(k);
            if delta <= self.tolerance {
                gain += delta;
                self.flip(k);
                removed.push(k);
            }
        }
        if gain < -self.tolerance {
            1 + removed.len()
        } else {
            self.rollback(mark);
            0
        }
    }
}

/// The two nearest existing candidates of row `j` (distinct owners), as an [`Explanation`].
fn explain(coeffs: &Coefficients, j: usize, exists: &[bool]) -> Explanation {
    let cap = coeffs.options.cap;
    let mut e = Explanation {
        owner: u32::MAX,
        cost: cap,
        second_owner: u32::MAX,
        second_cost: cap,
    };
    let r = coeffs.row(j);
    for (&c, &d) in coeffs.cand[r.clone()].iter().zip(&coeffs.dist[r]) {
        if !exists[c as usize] || c == e.owner {
            continue;
        }
        if e.owner == u32::MAX {
            (e.owner, e.cost) = (c, d);
        } else {
            (e.second_owner, e.second_cost) = (c, d);
            break;
        }
    }
    e
}

/// For each candidate, the rows (points) where it has entries, with its smallest distance there.
///
/// Linear in the entries: a per-candidate stamp of the last row seen replaces a search of
/// the row so far (quadratic in the row length, 320 entries per row for the independent
/// model), and a counting pass sizes every list exactly (no `Vec` growth slack).
fn transpose(coeffs: &Coefficients) -> Vec<Vec<(u32, f64)>> {
    let n = coeffs.candidates();
    let mut last = vec![u32::MAX; n];
    let mut counts = vec![0usize; n];
    for j in 0..coeffs.points() {
        for &c in &coeffs.cand[coeffs.row(j)] {
            if last[c as usize] != j as u32 {
                last[c as usize] = j as u32;
                counts[c as usize] += 1;
            }
        }
    }
    let mut rows: Vec<Vec<(u32, f64)>> = counts.iter().map(|&k| Vec::with_capacity(k)).collect();
    last.fill(u32::MAX);
    for j in 0..coeffs.points() {
        let r = coeffs.row(j);
        for (&c, &d) in coeffs.cand[r.clone()].iter().zip(&coeffs.dist[r]) {
            // Entries are sorted, so the first occurrence of a candidate is its nearest.
            if last[c as usize] != j as u32 {
                last[c as usize] = j as u32;
                rows[c as usize].push((j as u32, d));
            }
        }
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chamfer::{ChamferOptions, Evaluator, SampleSets};
    use crate::progress::Silent;
    use nalgebra::Point3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Rosenbrock-like separable quadratic with a known box-constrained minimiser.
    #[test]
    fn projected_lbfgs_finds_box_constrained_minimum() {
        let target = [-0.5, 0.3, 1.7, 0.9, 0.0];
        let opts = SolverOptions {
            ftol: 1e-15,
            ..Default::default()
        };
        let run = lbfgs(vec![0.5; 5], true, &opts, &Silent, |x, g| {
            let mut f = 0.0;
            for i in 0..5 {
                let w = (i + 1) as f64;
                f += w * (x[i] - target[i]).powi(2);
                g[i] = 2.0 * w * (x[i] - target[i]);
            }
            f
        });
        let expect = [0.0, 0.3, 1.0, 0.9, 0.0];
        for (a, b) in run.x.iter().zip(expect) {
            assert!((a - b).abs() < 1e-6, "{:?}", run.x);
        }
        assert!(run.history.windows(2).all(|w| w[1] <= w[0]));
    }

    #[test]
    fn unconstrained_lbfgs_minimises_rosenbrock() {
        let opts = SolverOptions {
            max_iterations: 500,
            ftol: 1e-15,
            ..Default::default()
        };
        let run = lbfgs(vec![-1.2, 1.0], false, &opts, &Silent, |x, g| {
            let (a, b) = (x[0], x[1]);
            g[0] = -2.0 * (1.0 - a) - 400.0 * a * (b - a * a);
            g[1] = 200.0 * (b - a * a);
            (1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2)
        });
        assert!(
            (run.x[0] - 1.0).abs() < 1e-4 && (run.x[1] - 1.0).abs() < 1e-4,
            "{:?}",
            run.x
        );
    }

    /// Two clusters of points; candidates: one on each cluster, one duplicate of the
    /// first, one far away. The solution keeps exactly one per cluster.
    fn clusters() -> (Vec<Point3<f64>>, SampleSets) {
        let cloud: Vec<Point3<f64>> = (0..20)
            .map(|k| {
                let c = if k < 10 { 0.0 } else { 5.0 };
                Point3::new(c + 0.01 * (k % 10) as f64, 0.0, 0.0)
            })
            .collect();
        let samples = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.09, 0.0, 0.0),
            Point3::new(5.0, 0.0, 0.0),
            Point3::new(5.09, 0.0, 0.0),
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.09, 0.0, 0.0),
            Point3::new(2.5, 3.0, 0.0),
        ];
        let owner = vec![0, 0, 1, 1, 2, 2, 3];
        (cloud.clone(), SampleSets::new(&samples, &owner, 4).unwrap())
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

    /// A random planar problem: points on a few true segments, candidate segments on a grid.
    fn segments(seed: u64) -> (Vec<Point3<f64>>, SampleSets) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut samples = Vec::new();
        let mut owner = Vec::new();
        let mut cloud = Vec::new();
        for i in 0..30 {
            let (x0, y0) = ((i % 6) as f64 * 0.5, (i / 6) as f64 * 0.5);
            for k in 0..10 {
                let p = Point3::new(x0 + 0.1 * k as f64, y0, 0.0);
                samples.push(p);
                owner.push(i);
                if i % 4 == 1 {
                    for _ in 0..8 {
                        let jitter = rng.random_range(-0.05..0.05);
                        cloud.push(Point3::new(p.x + jitter, p.y + 0.2 * jitter, 0.0));
                    }
                }
            }
        }
        (cloud, SampleSets::new(&samples, &owner, 30).unwrap())
    }

    /// Row sampling keeps whole rows and rescales the point weight by J / rows kept.
    #[test]
    fn row_sample_keeps_whole_rows_and_reweights() {
        let (cloud, sets) = segments(1);
        let o = ChamferOptions {
            cap: 0.05,
            beta: Some(4),
            ..Default::default()
        };
        let c = Coefficients::build(&cloud, &sets, &o, &Silent).unwrap();
        let sub = c.row_sample(c.points() / 4);
        let kept = sub.points();
        assert!(kept > 0 && kept < c.points(), "{kept} of {}", c.points());
        let scale = sub.options.point_weight / c.options.point_weight;
        assert!((scale - c.points() as f64 / kept as f64).abs() < 1e-12);
        // Each kept row is a row of the full coefficients.
        let full: Vec<(Vec<u32>, Vec<u64>)> = (0..c.points())
            .map(|j| {
                let r = c.row(j);
                (
                    c.cand[r.clone()].to_vec(),
                    c.dist[r].iter().map(|d| d.to_bits()).collect(),
                )
            })
            .collect();
        for j in 0..kept {
            let r = sub.row(j);
            let row = (
                sub.cand[r.clone()].to_vec(),
                sub.dist[r].iter().map(|d| d.to_bits()).collect(),
            );
            assert!(full.contains(&row));
        }
        assert_eq!(c.row_sample(usize::MAX).entries(), c.entries());
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
                    search_points: c.points() / 3,
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

    /// The linear transpose equals the definition: for each candidate, every row where it
    /// has an entry, once, with its first (smallest) distance there.
    #[test]
    fn transpose_keeps_each_candidates_first_entry_per_row() {
        use crate::chamfer::PointModel;
        let cloud: Vec<Point3<f64>> = (0..40)
            .map(|k| {
                let t = k as f64 * 0.37;
                Point3::new(t.sin() * 2.0, (1.7 * t).cos(), 0.1 * t)
            })
            .collect();
        let samples: Vec<Point3<f64>> = (0..60)
            .map(|k| {
                let t = k as f64 * 0.61;
                Point3::new(t.cos() * 2.0, (0.9 * t).sin(), 0.05 * t)
            })
            .collect();
        let owner: Vec<usize> = (0..60).map(|k| k % 7).collect();
        let sets = SampleSets::new(&samples, &owner, 7).unwrap();
        for (model, alpha) in [
            (PointModel::Existence, None),
            (PointModel::Independent, Some(4)),
        ] {
            let opts = ChamferOptions {
                model,
                alpha,
                beta: Some(5),
                cap: 1.0,
                ..Default::default()
            };
            let c = Coefficients::build(&cloud, &sets, &opts, &Silent).unwrap();
            let mut expect: Vec<Vec<(u32, f64)>> = vec![Vec::new(); c.candidates()];
            for j in 0..c.points() {
                let r = c.row(j);
                for k in r.clone() {
                    let cand = c.cand[k];
                    if !c.cand[r.start..k].contains(&cand) {
                        expect[cand as usize].push((j as u32, c.dist[k]));
                    }
                }
            }
            assert_eq!(transpose(&c), expect, "{model:?}");
            if model == PointModel::Independent {
                assert!(c.entries() > expect.iter().map(Vec::len).sum::<usize>());
            }
        }
    }

    #[test]
    fn polish_matches_exhaustive_single_flip_optimality() {
        // After polish, no single flip lowers the binary loss.
        let (cloud, sets) = clusters();
        let opts = ChamferOptions {
            cap: 1.0,
            ..Default::default()
        };
        let c = Coefficients::build(&cloud, &sets, &opts, &Silent).unwrap();
        let mut exists = vec![true; 4];
        polish(&c, &[0.5; 4], &mut exists, 20, Moves::All);
        let mut ev = Evaluator::new(&c);
        let base = ev.binary_value(&exists).total;
        for i in 0..4 {
            let mut e = exists.clone();
            e[i] = !e[i];
            assert!(
                ev.binary_value(&e).total >= base - 1e-12,
                "flip {i} improves"
            );
        }
    }
}
#[cfg(test)]
mod polish_tests {
    use super::*;
    use crate::chamfer::{ChamferOptions, Evaluator, SampleSets};
    use crate::progress::Silent;
    use nalgebra::Point3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The incremental explanations stay equal to a fresh scan of every row after long
    /// random flip sequences, including candidates farther than d_cap.
    #[test]
    fn incremental_explanations_match_a_fresh_scan() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut pt = |s: f64| Point3::new(rng.random_range(-s..s), rng.random_range(-s..s), 0.0);
        let cloud: Vec<Point3<f64>> = (0..60).map(|_| pt(3.0)).collect();
        let samples: Vec<Point3<f64>> = (0..40).map(|_| pt(3.0)).collect();
        let owner: Vec<usize> = (0..40).map(|k| k % 12).collect();
        let sets = SampleSets::new(&samples, &owner, 12).unwrap();
        for beta in [None, Some(3)] {
            let o = ChamferOptions {
                cap: 0.05,
                beta,
                ..Default::default()
            };
            let c = Coefficients::build(&cloud, &sets, &o, &Silent).unwrap();
            let mut ev = Evaluator::new(&c);
            let mut st = PolishState::new(&c, &[false; 12]);
            let mut rng = ChaCha8Rng::seed_from_u64(4);
            for _ in 0..300 {
                let i = rng.random_range(0..12usize);
                let before = ev.binary_value(&st.exists).total;
                let predicted = st.flip_delta(i);
                st.flip(i);
                let after = ev.binary_value(&st.exists).total;
                assert!(
                    (after - before - predicted).abs() < 1e-9,
                    "flip {i}: {predicted} vs {}",
                    after - before
                );
                for j in 0..c.points() {
                    let fresh = explain(&c, j, &st.exists);
                    let kept = st.point[j];
                    assert_eq!(
                        (fresh.cost, fresh.second_cost),
                        (kept.cost, kept.second_cost),
                        "row {j}"
                    );
                }
                // A trial of a few flips rolled back leaves the state exactly as it was.
                let (exists, point) = (st.exists.clone(), st.point.clone());
                st.commit();
                let mark = st.mark();
                for _ in 0..rng.random_range(1..5) {
                    st.flip(rng.random_range(0..12usize));
                }
                st.rollback(mark);
                assert_eq!(st.exists, exists);
                for (a, b) in st.point.iter().zip(&point) {
                    assert_eq!(
                        (a.owner, a.cost, a.second_owner, a.second_cost),
                        (b.owner, b.cost, b.second_owner, b.second_cost)
                    );
                }
            }
        }
    }
}
