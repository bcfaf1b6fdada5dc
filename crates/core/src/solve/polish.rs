//! The discrete polish: local search on the exact binary chamfer after thresholding, by
//! single flips, add-and-prune moves and replace chains over a [`PolishState`].

use rayon::prelude::*;

use super::polish_memo::{Trial, TrialMemo};
use super::polish_state::{PolishState, PolishTables};
use crate::chamfer::Coefficients;

/// Discrete polish of the binary scene `exists` on the binary chamfer (same entries, same
/// cap). Three moves, repeated in sweeps until none changes anything:
///
/// 1. **single flips**: remove a candidate if the loss does not increase (so redundant
///    copies go), add one if it strictly decreases;
/// 2. **add and prune**: add a candidate, then remove every neighbour it made redundant
///    (a current owner of one of its rows whose removal no longer costs anything); keep
///    the whole move only if the total strictly decreases. This turns an overlapping
///    tiling into a cleaner one, which single flips cannot. A move whose addition costs
///    more than the removals could ever save (their primitive terms) is not tried;
/// 3. **replace chains**: remove a candidate, add the neighbour (a candidate with entries
///    in the same rows) that lowers the loss most, prune as in 2; if that alone does not
///    pay, continue with an existing candidate overlapping the new one (an ejection chain
///    of depth `CHAIN_DEPTH` = 2). Kept only if the whole chain strictly lowers the loss.
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
    let memo = match moves {
        Moves::All => TrialMemo::new(coeffs.candidates()),
        Moves::SingleFlips => TrialMemo::unused(),
    };
    sweeps(
        coeffs,
        probability,
        exists,
        max_sweeps,
        memo,
        |state, memo, visit| {
            if moves == Moves::All {
                run_trials(state, memo, Trial::AddAndPrune, visit)
                    + run_trials(state, memo, Trial::Replace, visit)
            } else {
                0
            }
        },
    )
}

/// The sweeps of [`polish`]: single flips of the candidates to visit, then `trials` (the
/// moves 2 and 3 over the same candidates, with `memo`; returns its flips), until a sweep
/// flips nothing. Returns the number of flips.
fn sweeps(
    coeffs: &Coefficients,
    probability: &[f64],
    exists: &mut [bool],
    max_sweeps: usize,
    mut memo: TrialMemo,
    mut trials: impl FnMut(&mut PolishState, &mut TrialMemo, &[usize]) -> usize,
) -> usize {
    let n = coeffs.candidates();
    let tables = PolishTables::new(coeffs);
    let mut state = PolishState::new(coeffs, &tables, exists);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| probability[a].total_cmp(&probability[b]).then(a.cmp(&b)));
    let mut dirty = vec![true; n];
    let mut flips = 0;
    for _ in 0..max_sweeps {
        let before = flips;
        state.flipped.clear();
        let visit: Vec<usize> = order.iter().copied().filter(|&i| dirty[i]).collect();
        for &i in &visit {
            let delta = state.flip_delta(i);
            if (state.exists[i] && delta <= state.tolerance)
                || (!state.exists[i] && delta < -state.tolerance)
            {
                state.flip(i);
                state.commit(&mut memo);
                flips += 1;
            }
        }
        flips += trials(&mut state, &mut memo, &visit);
        if flips == before {
            break;
        }
        dirty.fill(false);
        let mut flipped = std::mem::take(&mut state.flipped);
        flipped.sort_unstable();
        flipped.dedup();
        for &c in &flipped {
            dirty[c] = true;
            for &k in state.neighbours(c) {
                dirty[k as usize] = true;
            }
        }
    }
    exists.copy_from_slice(&state.exists);
    flips
}

/// Replace chains tried per thread in a parallel batch (dimensionless). Most fail and
/// leave the scene as it was, so a batch's trials all see the same scene; a batch is cut
/// after its first kept move. Add-and-prune trials (~10 µs) cost less than a copy of the
/// scene, so they run one by one on the main state.
const REPLACE_TRIALS_PER_THREAD: usize = 4;

/// Trials of `kind` per batch on `threads` threads (1: one by one on the main state).
fn batch_len(kind: Trial, threads: usize) -> usize {
    match kind {
        _ if threads < 2 => 1,
        Trial::AddAndPrune => 1,
        Trial::Replace => threads * REPLACE_TRIALS_PER_THREAD,
    }
}

/// Runs trial `kind` from each candidate of `visit` in turn, if it applies to the current
/// scene (add-and-prune from absent candidates, replace chains from existing ones) and is
/// not known to fail; keeps each that pays. Returns the flips kept.
///
/// The same moves, in the same order, as running them one after another: the trials of a
/// batch run in parallel, each on a copy of the scene, and after the first that pays (in
/// `visit` order) the main state runs that one (the same scene, so the same move) and
/// the next batch starts behind it; the later trials of the batch, which saw the scene
/// before it, run again. So the result does not depend on the thread count.
fn run_trials(
    state: &mut PolishState,
    memo: &mut TrialMemo,
    kind: Trial,
    visit: &[usize],
) -> usize {
    let threads = rayon::current_num_threads();
    let batch_len = batch_len(kind, threads);
    let mut flips = 0;
    let mut next = 0;
    while next < visit.len() {
        let mut batch = Vec::new();
        while next < visit.len() && batch.len() < batch_len {
            let i = visit[next];
            next += 1;
            if kind.applies(state.exists[i]) && !memo.known_failure(kind, i) {
                batch.push((next, i));
            }
        }
        let kept = if batch.len() < 2 {
            // Serially on the main state: no copies.
            batch.iter().find_map(|&(after, i)| {
                state.record_reads(i);
                let kept = state.trial(kind, i);
                let read = state.take_reads();
                if kept == 0 {
                    memo.failed(kind, i, read);
                    None
                } else {
                    Some((after, i, kept))
                }
            })
        } else {
            let outcomes = speculate(state, kind, &batch, threads);
            batch
                .iter()
                .zip(outcomes)
                .find_map(|(&(after, i), outcome)| match outcome {
                    Outcome::Failed(read) => {
                        memo.failed(kind, i, read);
                        None
                    }
                    Outcome::Kept => Some((after, i, state.trial(kind, i))),
                })
        };
        if let Some((after, i, kept)) = kept {
            debug_assert!(kept > 0, "a trial kept on a copy is kept on the same scene");
            memo.kept(kind, i);
            state.commit(memo);
            flips += kept;
            next = after;
        }
    }
    flips
}

/// What a trial did on a copy of the scene.
enum Outcome {
    /// It failed, having read the rows of these candidates.
    Failed(Vec<u32>),
    /// It paid.
    Kept,
}

/// The outcomes of `batch`'s trials, each on a copy of `state`'s scene, in parallel over
/// `threads` slices; a slice stops at its first kept trial (the rest of the batch runs
/// again anyway), so the outcomes cover a prefix of the batch up to its first kept one.
fn speculate(
    state: &PolishState,
    kind: Trial,
    batch: &[(usize, usize)],
    threads: usize,
) -> Vec<Outcome> {
    let per = batch.len().div_ceil(threads).max(1);
    let slices: Vec<Vec<Outcome>> = batch
        .par_chunks(per)
        .map(|slice| {
            let mut copy = state.clone();
            let mut out = Vec::with_capacity(slice.len());
            for &(_, i) in slice {
                copy.record_reads(i);
                let mark = copy.mark();
                if copy.trial(kind, i) > 0 {
                    out.push(Outcome::Kept);
                    break;
                }
                copy.rollback(mark);
                out.push(Outcome::Failed(copy.take_reads()));
            }
            out
        })
        .collect();
    slices.into_iter().flatten().collect()
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

/// The moves of [`polish`], each a trial of flips kept only if it pays.
impl PolishState<'_> {
    /// Trial `kind` from `i`; returns the number of flips kept (0 if reverted).
    fn trial(&mut self, kind: Trial, i: usize) -> usize {
        match kind {
            Trial::AddAndPrune => self.add_and_prune(i),
            Trial::Replace => self.replace(i),
        }
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
    /// Existing neighbours of `k`.
    fn existing_overlapping(&self, k: usize) -> Vec<usize> {
        let n = self.neighbours(k);
        n.iter()
            .map(|&c| c as usize)
            .filter(|&c| self.exists[c])
            .collect()
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

    /// Whether an add-and-prune move whose addition changes the loss by `added` fails
    /// whichever of `displaced` it removes: removing `k` changes the loss by
    /// `w_point · (Σ runner-up − nearest over the rows k owns) − w_prim g_k`, at least
    /// `−w_prim g_k` (the runner-up is never nearer). The bound is summed in the move's
    /// order and each rounding is monotone, so the move's own total is never below it.
    fn cannot_pay(&self, added: f64, displaced: &[u32]) -> bool {
        let wp = self.coeffs.options.primitive_weight;
        let lowest = displaced
            .iter()
            .fold(added, |total, &k| total - wp * self.coeffs.g[k as usize]);
        lowest >= -self.tolerance
    }

    /// Move 2 of [`polish`]; returns the number of flips kept (0 if reverted). Skips
    /// the move without trying it when [`PolishState::cannot_pay`].
    fn add_and_prune(&mut self, i: usize) -> usize {
        let Some(displaced) = self.displaced_by(i) else {
            return 0;
        };
        let added = self.flip_delta(i);
        if self.cannot_pay(added, &displaced) {
            return 0;
        }
        self.try_add_and_prune(i, added, &displaced)
    }

    /// Owners of the rows that `i` would explain at least as well, ascending: the
    /// neighbours it may make redundant (`None` if there are none). Ties count, so one tile
    /// can replace two half-overlapping ones even when the points are already perfectly
    /// explained.
    fn displaced_by(&self, i: usize) -> Option<Vec<u32>> {
        let mut displaced: Vec<u32> = self.rows[i]
            .iter()
            .map(|&(j, d)| (self.point[j as usize], d))
            .filter(|(e, d)| *d <= e.cost && e.owner != u32::MAX)
            .map(|(e, _)| e.owner)
            .collect();
        displaced.sort_unstable();
        displaced.dedup();
        (!displaced.is_empty()).then_some(displaced)
    }

    /// Adds `i` (which changes the loss by `added`), removes each of `displaced` whose
    /// removal then costs nothing, and keeps the whole only if the loss strictly falls;
    /// returns the number of flips kept (0 if reverted).
    fn try_add_and_prune(&mut self, i: usize, added: f64, displaced: &[u32]) -> usize {
        let mark = self.mark();
        let mut gain = added;
        self.flip(i);
        let mut removed = Vec::new();
        for &k in displaced {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chamfer::test_problems::clusters;
    use crate::chamfer::{ChamferOptions, Evaluator, SampleSets};
    use crate::progress::Silent;
    use nalgebra::Point3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

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

    /// Noisy points on two lines; candidates: unit segments every quarter unit along and
    /// beside them, so tiles overlap fourfold and rows of tiles can shift.
    fn tiles(seed: u64) -> (Vec<Point3<f64>>, SampleSets) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut cloud = Vec::new();
        for line in 0..2 {
            let (start, end) = (rng.random_range(0.0..0.6), rng.random_range(3.4..4.0));
            for k in 0..120 {
                let x = start + (end - start) * k as f64 / 120.0;
                let y = line as f64 + rng.random_range(-0.02..0.02);
                cloud.push(Point3::new(x, y, 0.0));
            }
        }
        let (mut samples, mut owner) = (Vec::new(), Vec::new());
        let mut n = 0;
        for y in [0.0, 0.15, 1.0, 1.1] {
            for k in 0..14 {
                let x0 = 0.25 * k as f64 + rng.random_range(-0.01..0.01);
                for s in 0..11 {
                    samples.push(Point3::new(x0 + 0.1 * s as f64, y, 0.0));
                    owner.push(n);
                }
                n += 1;
            }
        }
        (cloud, SampleSets::new(&samples, &owner, n).unwrap())
    }

    /// The coefficients of [`tiles`] (`d_cap` 0.05, β 12).
    fn tile_coefficients(seed: u64) -> Coefficients {
        let (cloud, sets) = tiles(seed);
        let opts = ChamferOptions {
            cap: 0.05,
            beta: Some(12),
            ..Default::default()
        };
        Coefficients::build(&cloud, &sets, &opts, &Silent).unwrap()
    }

    /// Move 2 tried whatever [`PolishState::cannot_pay`] says.
    fn add_and_prune_unchecked(state: &mut PolishState, i: usize) -> usize {
        match state.displaced_by(i) {
            Some(displaced) => {
                let added = state.flip_delta(i);
                state.try_add_and_prune(i, added, &displaced)
            }
            None => 0,
        }
    }

    /// The polish with moves 2 and 3 as they ran before the trial memo, the parallel
    /// trials and the bound that skips add-and-prune moves: every trial run on the one
    /// state, in order, and kept when it pays.
    fn polish_one_by_one(
        coeffs: &Coefficients,
        probability: &[f64],
        exists: &mut [bool],
        max_sweeps: usize,
    ) -> usize {
        sweeps(
            coeffs,
            probability,
            exists,
            max_sweeps,
            TrialMemo::new(coeffs.candidates()),
            |state, memo, visit| {
                let mut flips = 0;
                for kind in [Trial::AddAndPrune, Trial::Replace] {
                    for &i in visit {
                        if kind.applies(state.exists[i]) {
                            flips += match kind {
                                Trial::AddAndPrune => add_and_prune_unchecked(state, i),
                                Trial::Replace => state.trial(kind, i),
                            };
                            state.commit(memo);
                        }
                    }
                }
                flips
            },
        )
    }

    /// Skipping the trials the memo knows to fail or the bound proves to fail, and trying
    /// the others in parallel batches, changes nothing: the same scene and flip count as
    /// trying every move one by one, on 1 and on 3 threads, from random and from full
    /// starting scenes.
    #[test]
    fn memo_and_parallel_trials_give_the_one_by_one_result() {
        let mut moved = 0;
        for seed in 0..12 {
            let c = tile_coefficients(seed);
            let n = c.candidates();
            let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
            let probability: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..1.0)).collect();
            let start: Vec<bool> = if seed % 2 == 0 {
                probability.iter().map(|&p| p > 0.6).collect()
            } else {
                vec![true; n]
            };
            let mut expected = start.clone();
            let expected_flips = polish_one_by_one(&c, &probability, &mut expected, 20);
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut got = start.clone();
                let flips = pool.install(|| polish(&c, &probability, &mut got, 20, Moves::All));
                assert_eq!(got, expected, "seed {seed}, {threads} threads");
                assert_eq!(flips, expected_flips, "seed {seed}, {threads} threads");
            }
            moved += expected_flips;
        }
        assert!(moved > 0, "the scenes exercise the moves");
    }

    /// Every add-and-prune move that the bound skips fails when tried, and the bound does
    /// skip moves on these scenes (tiles overlapping fourfold, random scenes).
    #[test]
    fn skipped_add_and_prune_moves_fail_when_tried() {
        let (mut skipped, mut tried) = (0, 0);
        for seed in 0..12 {
            let c = tile_coefficients(seed);
            let n = c.candidates();
            let mut rng = ChaCha8Rng::seed_from_u64(200 + seed);
            let exists: Vec<bool> = (0..n).map(|_| rng.random_range(0.0..1.0) < 0.4).collect();
            let tables = PolishTables::new(&c);
            let mut state = PolishState::new(&c, &tables, &exists);
            for i in (0..n).filter(|&i| !exists[i]) {
                let Some(displaced) = state.displaced_by(i) else {
                    continue;
                };
                let added = state.flip_delta(i);
                let skip = state.cannot_pay(added, &displaced);
                let mut copy = state.clone();
                let kept = copy.try_add_and_prune(i, added, &displaced);
                assert!(
                    !(skip && kept > 0),
                    "seed {seed}: move from {i} skipped but pays"
                );
                skipped += usize::from(skip);
                tried += usize::from(!skip);
            }
        }
        assert!(skipped > 0 && tried > 0, "skipped {skipped}, tried {tried}");
    }
}
