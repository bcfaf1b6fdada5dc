//! The Metropolis–Hastings sampler of thesis §4.2.2 over existence vectors Φ ∈ {0,1}^N.
//!
//! Target: `h(Φ) ∝ p(D | Φ) p(Φ)` (eq. 4.11), likelihood eq. 4.10 via a [`RayTable`],
//! factored prior `p(φ_i)` (§4.2.1). Proposal: `Φ' = Φ xor b` with independent
//! `b_i ~ Bernoulli(λ_i)`, conditioned on `b ≠ 0`. It is symmetric, so a step is accepted
//! with probability `min(1, h(Φ') / h(Φ))`. The flip rates decay geometrically with the
//! number of frames since the candidate was last seen (`λ_i ∝ decay^age_i`,
//! [`flip_rates`]), scaled so that `Σ λ_i` is the requested expected number of flips per
//! step: recent candidates are revisited most, old ones still occasionally.
//!
//! Rates take few distinct values (one per age), so `b` is drawn per rate group by
//! geometric skips: a proposal costs O(flips + groups), not O(N). The chain starts
//! from the empty scene, runs `burn_in + steps` proposals from a seeded
//! [`ChaCha8Rng`] (same input and seed ⇒ same chain), and returns the scene of highest
//! `h` visited and how often each candidate existed after burn-in.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::incremental::SceneState;
use super::raytree::RayTable;
use crate::Result;
use crate::check::{self, Interval};
use crate::progress::Progress;

/// Sampler settings.
#[derive(Debug, Clone, PartialEq)]
pub struct McmcOptions {
    /// Proposals after burn-in (thesis: 1000).
    pub steps: usize,
    /// Proposals before the existence frequencies start counting.
    pub burn_in: usize,
    /// Expected number of candidates flipped per proposal, `Σ λ_i` (> 0).
    pub flips_per_step: f64,
    /// Factor of the flip rate per frame of age, in `(0, 1]` (1: every candidate alike).
    pub decay: f64,
    /// RNG seed.
    pub seed: u64,
    /// After sampling, climb from the best visited scene by single flips while `h`
    /// improves (not in the thesis: it makes the output a local maximum, so e.g. a
    /// candidate hidden behind the points, which only the prior penalises, is dropped
    /// even if the chain happened to carry it at its best moment).
    pub polish: bool,
}

impl Default for McmcOptions {
    fn default() -> Self {
        McmcOptions {
            steps: 1000,
            burn_in: 200,
            flips_per_step: 1.0,
            decay: 0.9,
            seed: 0,
            polish: true,
        }
    }
}

impl McmcOptions {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<()> {
        check::positive("flips_per_step", self.flips_per_step)?;
        check::in_interval("decay", self.decay, Interval::open_closed(0.0, 1.0))
    }
}

/// What the sampler found.
#[derive(Debug, Clone)]
pub struct McmcResult {
    /// The visited scene of highest `log p(D|Φ) + log p(Φ)`.
    pub best: Vec<bool>,
    /// `log p(D | best)` (nats).
    pub best_log_likelihood: f64,
    /// `log p(D | best) + log p(best)` (nats).
    pub best_log_posterior: f64,
    /// Share of the post-burn-in states in which each candidate existed.
    pub frequency: Vec<f64>,
    /// Accepted proposals.
    pub accepted: usize,
    /// Proposals made (`burn_in + steps`).
    pub proposals: usize,
    /// Log posterior of the chain, every `trace_every` proposals (first entry: the start).
    pub trace: Vec<f64>,
    /// Proposals between trace entries.
    pub trace_every: usize,
    /// Single flips applied by the polish.
    pub polish_flips: usize,
}

/// Flip rates `λ_i` (thesis §4.2.2): `λ_i = min(1, c · decay^age_i)` with `age_i` the
/// frames since candidate `i` was last seen (never seen: as old as the oldest frame,
/// plus one) and `c` such that `Σ λ_i = flips_per_step` before clipping. Candidates whose
/// prior is 0 get rate 0 (they never exist).
pub fn flip_rates(table: &RayTable, prior: &[f64], options: &McmcOptions) -> Result<Vec<f64>> {
    options.validate()?;
    check_per_candidate("prior", prior, table, Interval::closed_open(0.0, 1.0))?;
    let newest = table.frames().saturating_sub(1) as i32;
    let weights: Vec<f64> = (0..table.candidates())
        .map(|i| {
            if prior[i] <= 0.0 {
                return 0.0;
            }
            let age = table.last_seen(i).map_or(newest + 1, |f| newest - f as i32);
            options.decay.powi(age)
        })
        .collect();
    let total: f64 = weights.iter().sum();
    if total <= 0.0 {
        return Ok(weights);
    }
    let c = options.flips_per_step / total;
    Ok(weights.iter().map(|w| (c * w).min(1.0)).collect())
}

/// `values` has one entry per candidate of `table`, each in `range`.
fn check_per_candidate(
    name: &'static str,
    values: &[f64],
    table: &RayTable,
    range: Interval,
) -> Result<()> {
    check::same_len(name, values.len(), "candidates", table.candidates())?;
    for (k, &v) in values.iter().enumerate() {
        check::in_interval(&format!("{name}[{k}]"), v, range)?;
    }
    Ok(())
}

/// Candidates grouped by equal flip rate, for drawing `b` by geometric skips.
#[derive(Debug, Clone)]
struct RateGroups {
    /// `(λ, ln(1 − λ), members)` per distinct positive rate.
    groups: Vec<(f64, f64, Vec<u32>)>,
}

impl RateGroups {
    fn new(rates: &[f64]) -> Self {
        let mut groups: Vec<(f64, f64, Vec<u32>)> = Vec::new();
        for (i, &r) in rates.iter().enumerate() {
            if r <= 0.0 {
                continue;
            }
            match groups.iter_mut().find(|g| g.0 == r) {
                Some(g) => g.2.push(i as u32),
                None => groups.push((r, (-r).ln_1p(), vec![i as u32])),
            }
        }
        RateGroups { groups }
    }

    fn is_empty(&self) -> bool {
        self.groups.is_empty()
    }

    /// Draws the members with `b_i = 1` into `out` (cleared first).
    fn draw<R: Rng>(&self, rng: &mut R, out: &mut Vec<u32>) {
        out.clear();
        for (rate, log_keep, members) in &self.groups {
            if *rate >= 1.0 {
                out.extend_from_slice(members);
                continue;
            }
            // Gap to the next success of a Bernoulli(λ) sequence: ⌊ln U / ln(1 − λ)⌋.
            let mut k = 0usize;
            loop {
                let u = unit_open(rng);
                let gap = (u.ln() / log_keep).floor();
                if gap.is_nan() || gap >= (members.len() - k) as f64 {
                    break;
                }
                k += gap as usize;
                out.push(members[k]);
                k += 1;
                if k >= members.len() {
                    break;
                }
            }
        }
    }
}

/// A uniform draw in (0, 1].
fn unit_open<R: Rng>(rng: &mut R) -> f64 {
    ((rng.next_u64() >> 11) as f64 + 1.0) * (1.0 / (1u64 << 53) as f64)
}

/// The chain's bookkeeping of existence time after burn-in.
struct Occupancy {
    on_since: Vec<usize>,
    time_on: Vec<usize>,
    first: usize,
    last: usize,
}

impl Occupancy {
    /// Counted states are those after proposals `first..=last`.
    fn new(n: usize, first: usize, last: usize) -> Self {
        Occupancy {
            on_since: vec![0; n],
            time_on: vec![0; n],
            first,
            last,
        }
    }

    /// Candidate `i` changed after proposal `k`; `now` is its new state.
    fn changed(&mut self, i: usize, now: bool, k: usize) {
        if now {
            self.on_since[i] = k;
        } else {
            self.close(i, k);
        }
    }

    /// Adds the counted states in `[on_since, k − 1]`.
    fn close(&mut self, i: usize, k: usize) {
        let lo = self.on_since[i].max(self.first);
        let hi = (k - 1).min(self.last);
        if hi >= lo {
            self.time_on[i] += hi - lo + 1;
        }
    }

    fn frequencies(mut self, exists: &[bool]) -> Vec<f64> {
        let end = self.last + 1;
        for (i, e) in exists.iter().enumerate() {
            if *e {
                self.close(i, end);
            }
        }
        let counted = (self.last + 1).saturating_sub(self.first).max(1) as f64;
        self.time_on.iter().map(|&t| t as f64 / counted).collect()
    }
}

/// Runs the sampler. `prior[i] = p(φ_i = 1)` in `[0, 1)`; `rates` from [`flip_rates`].
pub fn sample(
    table: &RayTable,
    prior: &[f64],
    rates: &[f64],
    options: &McmcOptions,
    progress: &dyn Progress,
) -> Result<McmcResult> {
    options.validate()?;
    check_per_candidate("prior", prior, table, Interval::closed_open(0.0, 1.0))?;
    check_per_candidate("rates", rates, table, Interval::UNIT)?;
    let n = table.candidates();
    let logit: Vec<f64> = prior.iter().map(|p| p.ln() - (-p).ln_1p()).collect();
    let mut state = SceneState::new(table, vec![false; n])?;
    let mut log_prior: f64 = prior.iter().map(|p| (-p).ln_1p()).sum();
    let groups = RateGroups::new(rates);
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let total = options.burn_in + options.steps;
    let trace_every = (total / 10_000).max(1);
    let mut out = McmcResult {
        best: state.exists().to_vec(),
        best_log_likelihood: state.log_likelihood(),
        best_log_posterior: state.log_likelihood() + log_prior,
        frequency: Vec::new(),
        accepted: 0,
        proposals: total,
        trace: vec![state.log_likelihood() + log_prior],
        trace_every,
        polish_flips: 0,
    };
    let mut occupancy = Occupancy::new(n, options.burn_in + 1, total);
    let mut flips = Vec::new();
    progress.start("mcmc", total as u64);
    for k in 1..=total {
        if !groups.is_empty() {
            draw_nonempty(&groups, &mut rng, &mut flips);
        }
        let d_prior: f64 = flips
            .iter()
            .map(|&i| {
                let l = logit[i as usize];
                if state.exists()[i as usize] { -l } else { l }
            })
            .sum();
        let d_ll = state.propose(&flips)?;
        let log_alpha = d_ll + d_prior;
        if log_alpha >= 0.0 || unit_open(&mut rng).ln() < log_alpha {
            state.accept();
            log_prior += d_prior;
            out.accepted += 1;
            for &i in &flips {
                occupancy.changed(i as usize, state.exists()[i as usize], k);
            }
            if out.accepted.is_multiple_of(4096) {
                state.resum();
            }
            let post = state.log_likelihood() + log_prior;
            if post > out.best_log_posterior {
                out.best_log_posterior = post;
                out.best_log_likelihood = state.log_likelihood();
                out.best.copy_from_slice(state.exists());
            }
        } else {
            state.reject();
        }
        if k.is_multiple_of(trace_every) {
            out.trace.push(state.log_likelihood() + log_prior);
        }
        if k.is_multiple_of(1024) {
            progress.advance(1024);
        }
    }
    progress.finish();
    out.frequency = occupancy.frequencies(state.exists());
    if options.polish {
        polish(table, prior, &logit, &mut out)?;
    }
    Ok(out)
}

/// Single-flip hill climbing on `out.best` (candidates with a positive prior only).
fn polish(table: &RayTable, prior: &[f64], logit: &[f64], out: &mut McmcResult) -> Result<()> {
    let mut state = SceneState::new(table, out.best.clone())?;
    let mut post = out.best_log_posterior;
    for _pass in 0..100 {
        let mut improved = false;
        for i in (0..prior.len()).filter(|&i| prior[i] > 0.0) {
            let d_prior = if state.exists()[i] {
                -logit[i]
            } else {
                logit[i]
            };
            let d = state.propose(&[i as u32])? + d_prior;
            if d > 1e-9 {
                state.accept();
                post += d;
                out.polish_flips += 1;
                improved = true;
            } else {
                state.reject();
            }
        }
        if !improved {
            break;
        }
    }
    state.resum();
    out.best.copy_from_slice(state.exists());
    out.best_log_likelihood = state.log_likelihood();
    out.best_log_posterior = post;
    Ok(())
}

/// Draws `b` until it is non-empty (the conditioned proposal stays symmetric).
fn draw_nonempty<R: Rng>(groups: &RateGroups, rng: &mut R, flips: &mut Vec<u32>) {
    for _ in 0..10_000 {
        groups.draw(rng, flips);
        if !flips.is_empty() {
            return;
        }
    }
}
