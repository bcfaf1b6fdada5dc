//! The discrete polish: local search on the exact binary chamfer after thresholding, by
//! single flips, add-and-prune moves and replace chains over a [`PolishState`].

use super::polish_state::PolishState;
use crate::chamfer::Coefficients;

/// Discrete polish of the binary scene `exists` on the binary chamfer (same entries, same
/// cap). Three moves, repeated in sweeps until none changes anything:
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

/// The moves of [`polish`], each a trial of flips kept only if it pays.
impl PolishState<'_> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chamfer::test_problems::clusters;
    use crate::chamfer::{ChamferOptions, Evaluator};
    use crate::progress::Silent;

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
