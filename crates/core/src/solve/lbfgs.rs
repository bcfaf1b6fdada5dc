//! Projected L-BFGS (two-loop recursion, Nocedal & Wright alg. 7.4) on the unit box or
//! unconstrained, and the logit change of variables `p = σ(z)` of
//! [`Parameterization::Logit`](super::Parameterization::Logit).

use super::{SolverOptions, StopReason};
use crate::progress::Progress;

/// Armijo sufficient-decrease constant c₁ (dimensionless): a step is accepted when the
/// loss falls by at least `c₁` times the decrease the gradient predicts for it. The usual
/// small value (Nocedal & Wright §3.1), so almost any decrease is accepted.
const ARMIJO_C1: f64 = 1e-4;

/// Factor by which the line search shortens a rejected step (dimensionless).
const BACKTRACK_FACTOR: f64 = 0.5;

/// Step halvings before the line search gives up ([`StopReason::LineSearch`]): the last
/// step tried is `0.5^39` of the first, far below any useful change of `p ∈ [0, 1]`.
const MAX_BACKTRACKS: usize = 40;

/// A curvature pair `(s, y)` is stored only if `sᵀy > CURVATURE_TOLERANCE · yᵀy`
/// (dimensionless), so that the inverse-Hessian model stays positive definite.
const CURVATURE_TOLERANCE: f64 = 1e-12;

/// Probabilities are clamped to `[LOGIT_CLAMP, 1 − LOGIT_CLAMP]` before the logit, so that
/// a warm start at exactly 0 or 1 has a finite logit (±20.7).
const LOGIT_CLAMP: f64 = 1e-9;

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

/// The logistic function `1 / (1 + e^{−z})`.
fn sigmoid(z: f64) -> f64 {
    1.0 / (1.0 + (-z).exp())
}

/// The inverse of [`sigmoid`], `ln(p / (1 − p))`.
fn logit(p: f64) -> f64 {
    (p / (1.0 - p)).ln()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `v` projected onto `[0, 1]` with `unit_box`, unchanged without.
fn project(v: f64, unit_box: bool) -> f64 {
    if unit_box { v.clamp(0.0, 1.0) } else { v }
}

/// Max-norm of the projected gradient `x − P(x − g)`: zero exactly at a stationary point
/// of the (box-constrained) problem.
fn projected_norm(x: &[f64], g: &[f64], unit_box: bool) -> f64 {
    x.iter()
        .zip(g)
        .map(|(xi, gi)| (xi - project(xi - gi, unit_box)).abs())
        .fold(0.0, f64::max)
}

/// The stored curvature pairs `(s, y)` with `ρ = 1 / sᵀy`, oldest first, at most
/// `capacity` of them: the limited-memory inverse-Hessian model.
struct CurvatureMemory {
    s: Vec<Vec<f64>>,
    y: Vec<Vec<f64>>,
    rho: Vec<f64>,
    /// Scratch of the two-loop recursion, one per pair.
    alpha: Vec<f64>,
    capacity: usize,
}

impl CurvatureMemory {
    fn new(capacity: usize) -> Self {
        CurvatureMemory {
            s: vec![],
            y: vec![],
            rho: vec![],
            alpha: vec![0.0; capacity],
            capacity,
        }
    }

    fn len(&self) -> usize {
        self.s.len()
    }

    fn clear(&mut self) {
        self.s.clear();
        self.y.clear();
        self.rho.clear();
    }

    /// Two-loop recursion: `d ← H · d` (initial Hessian `γ I`, `γ = sᵀy / yᵀy` of the
    /// newest pair).
    fn apply_inverse_hessian(&mut self, d: &mut [f64]) {
        let k = self.len();
        for j in (0..k).rev() {
            self.alpha[j] = self.rho[j] * dot(&self.s[j], d);
            d.iter_mut()
                .zip(&self.y[j])
                .for_each(|(di, yi)| *di -= self.alpha[j] * yi);
        }
        if k > 0 {
            let gamma = dot(&self.s[k - 1], &self.y[k - 1]) / dot(&self.y[k - 1], &self.y[k - 1]);
            d.iter_mut().for_each(|di| *di *= gamma);
        }
        for j in 0..k {
            let beta = self.rho[j] * dot(&self.y[j], d);
            d.iter_mut()
                .zip(&self.s[j])
                .for_each(|(di, si)| *di += (self.alpha[j] - beta) * si);
        }
    }

    /// Stores the pair `(s, y)` if its curvature is positive enough, dropping the oldest
    /// when full.
    fn push(&mut self, s: Vec<f64>, y: Vec<f64>) {
        let sy = dot(&s, &y);
        if sy > CURVATURE_TOLERANCE * dot(&y, &y).max(f64::MIN_POSITIVE) {
            if self.len() == self.capacity {
                self.s.remove(0);
                self.y.remove(0);
                self.rho.remove(0);
            }
            self.s.push(s);
            self.y.push(y);
            self.rho.push(1.0 / sy);
        }
    }
}

/// The search direction `d` at `(x, g)`: `−H g` on the free variables, zero on the active
/// ones (with `unit_box`, at a bound with the gradient pointing outward; marked in
/// `active`). Falls back to steepest descent on the free variables, scaled so that no
/// variable moves by more than 1, when that is not a descent direction or there is no
/// curvature yet (the memory is then cleared).
fn search_direction(
    x: &[f64],
    g: &[f64],
    unit_box: bool,
    memory: &mut CurvatureMemory,
    active: &mut [bool],
    d: &mut [f64],
) {
    let n = x.len();
    for i in 0..n {
        active[i] = unit_box && ((x[i] <= 0.0 && g[i] > 0.0) || (x[i] >= 1.0 && g[i] < 0.0));
        d[i] = if active[i] { 0.0 } else { g[i] };
    }
    let k = memory.len();
    memory.apply_inverse_hessian(d);
    for i in 0..n {
        d[i] = if active[i] { 0.0 } else { -d[i] };
    }
    if dot(g, d) >= 0.0 || k == 0 {
        memory.clear();
        let scale = g
            .iter()
            .zip(active.iter())
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
}

/// Backtracking Armijo line search along the projection arc `P(x + t d)`, `t = 1, ½, ¼, …`,
/// with the test on the actual step `P(x + t d) − x`. Writes the last point tried and its
/// gradient into `x_new`, `g_new`; returns the accepted loss (`None` if no step within
/// [`MAX_BACKTRACKS`] decreased the loss enough) and the evaluations used.
///
/// A halved step whose projection is the point already tried (every moving variable
/// still at its bound, as when the direction overshoots the box many times over) fails
/// the same test again, so it is not evaluated again: the same steps are accepted.
fn line_search(
    (x, g, fx): (&[f64], &[f64], f64),
    d: &[f64],
    unit_box: bool,
    x_new: &mut [f64],
    g_new: &mut [f64],
    f: &mut impl FnMut(&[f64], &mut [f64]) -> f64,
) -> (Option<f64>, usize) {
    let mut t = 1.0;
    let mut evaluations = 0;
    for _ in 0..MAX_BACKTRACKS {
        let mut moved = evaluations == 0;
        for i in 0..x.len() {
            let v = project(x[i] + t * d[i], unit_box);
            moved |= v.to_bits() != x_new[i].to_bits();
            x_new[i] = v;
        }
        t *= BACKTRACK_FACTOR;
        if !moved {
            continue;
        }
        let f_new = f(x_new, g_new);
        evaluations += 1;
        let decrease: f64 = g
            .iter()
            .zip(x_new.iter().zip(x))
            .map(|(gi, (a, b))| gi * (a - b))
            .sum();
        if f_new.is_finite() && f_new <= fx + ARMIJO_C1 * decrease {
            return (Some(f_new), evaluations);
        }
    }
    (None, evaluations)
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
    x.iter_mut().for_each(|v| *v = project(*v, unit_box));
    let mut g = vec![0.0; n];
    let mut fx = f(&x, &mut g);
    let mut evaluations = 1;
    let mut history = vec![fx];
    let mut memory = CurvatureMemory::new(options.memory);
    let (mut d, mut x_new, mut g_new) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut active = vec![false; n];
    let pg0 = projected_norm(&x, &g, unit_box);
    let mut stop = StopReason::Iterations;
    let mut iterations = 0;
    for _ in 0..options.max_iterations {
        if n == 0 || projected_norm(&x, &g, unit_box) <= options.pgtol * pg0.max(f64::MIN_POSITIVE)
        {
            stop = StopReason::Gradient;
            break;
        }
        search_direction(&x, &g, unit_box, &mut memory, &mut active, &mut d);
        let current = (&x[..], &g[..], fx);
        let (accepted, used) = line_search(current, &d, unit_box, &mut x_new, &mut g_new, &mut f);
        evaluations += used;
        let Some(f_new) = accepted else {
            stop = StopReason::LineSearch;
            break;
        };
        iterations += 1;
        let s: Vec<f64> = x_new.iter().zip(&x).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = g_new.iter().zip(&g).map(|(a, b)| a - b).collect();
        memory.push(s, y);
        std::mem::swap(&mut x, &mut x_new);
        std::mem::swap(&mut g, &mut g_new);
        let f_old = fx;
        fx = f_new;
        history.push(fx);
        progress.advance(1);
        if progress.cancelled() {
            break; // `solve` turns this into an error.
        }
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

/// [`lbfgs`] on logits `z`, `p = σ(z)`, for a loss `f(p, ∂f/∂p)` over probabilities: the
/// gradient is chained as `∂f/∂z = ∂f/∂p · p(1 − p)`. `start` and the returned `x` are
/// probabilities.
pub(super) fn lbfgs_on_logits(
    start: Vec<f64>,
    options: &SolverOptions,
    progress: &dyn Progress,
    mut f: impl FnMut(&[f64], &mut [f64]) -> f64,
) -> LbfgsRun {
    let n = start.len();
    let z0 = start
        .iter()
        .map(|&p| logit(p.clamp(LOGIT_CLAMP, 1.0 - LOGIT_CLAMP)))
        .collect();
    let mut p = vec![0.0; n];
    let mut gp = vec![0.0; n];
    let mut run = lbfgs(z0, false, options, progress, |z, gz| {
        for (pi, zi) in p.iter_mut().zip(z) {
            *pi = sigmoid(*zi);
        }
        let value = f(&p, &mut gp);
        for ((g, gpi), pi) in gz.iter_mut().zip(&gp).zip(&p) {
            *g = gpi * pi * (1.0 - pi);
        }
        value
    });
    run.x.iter_mut().for_each(|z| *z = sigmoid(*z));
    run
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::Silent;

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

    /// On the box, shorter steps whose projection is still the bound are the same point:
    /// each point is evaluated once.
    #[test]
    fn line_search_evaluates_each_projected_point_once() {
        let x = [0.2];
        let loss = |v: f64| (v - 0.5).powi(2) + 10.0 * (v - 0.6).max(0.0).powi(2);
        let slope = |v: f64| 2.0 * (v - 0.5) + 20.0 * (v - 0.6).max(0.0);
        let g = [slope(0.2)];
        let (mut x_new, mut g_new) = ([0.0], [0.0]);
        let mut tried = Vec::new();
        let mut f = |x: &[f64], g: &mut [f64]| {
            tried.push(x[0]);
            g[0] = slope(x[0]);
            loss(x[0])
        };
        let (accepted, evaluations) = line_search(
            (&x, &g, loss(0.2)),
            &[1000.0],
            true,
            &mut x_new,
            &mut g_new,
            &mut f,
        );
        assert!(accepted.unwrap() < loss(0.2));
        assert_eq!(evaluations, tried.len());
        // With d = 1000 the projection stays at the bound 1 from t = 1 down to t = 2⁻¹⁰.
        assert_eq!(tried.iter().filter(|&&v| v == 1.0).count(), 1, "{tried:?}");
        let mut distinct = tried.clone();
        distinct.sort_by(f64::total_cmp);
        distinct.dedup();
        assert_eq!(distinct.len(), tried.len(), "{tried:?}");
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
}
