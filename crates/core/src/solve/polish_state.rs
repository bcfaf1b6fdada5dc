//! The incremental state of the discrete polish: the binary scene, each point's best and
//! runner-up explanation, and an undo log, so that the change of the binary chamfer for a
//! flip is a sum over the flipped candidate's rows and a rejected trial move is rolled
//! back without row scans.

use std::sync::OnceLock;

use rayon::prelude::*;

use super::candidate_rows::CandidateRows;
use super::polish_memo::TrialMemo;
use crate::chamfer::Coefficients;

/// Rows sampled per candidate when listing its neighbours.
const NEIGHBOUR_ROWS: usize = 512;

/// Longest row whose existing entries are kept as a bit mask ([`ExistingMasks`]).
const MASK_BITS: usize = u64::BITS as usize;

/// Rows of at most this many entries keep no masks: scanning one reads no more than
/// half a cache line of candidate ids (the default pipeline's rows hold 8), so a mask
/// (8 bytes a row, and a byte an entry for the places) would buy nothing.
const MASK_MIN_ROW: usize = 8;

/// Changes of the binary loss within this fraction of the starting scene's loss
/// (dimensionless) count as zero, so that rounding in the incremental sums neither makes
/// nor blocks a move.
const RELATIVE_TOLERANCE: f64 = 1e-12;

/// Smallest loss scale the tolerance is taken of (loss units), so that the tolerance of a
/// scene with zero loss is positive.
const MIN_LOSS_SCALE: f64 = 1e-300;

/// A point's current explanation: the nearest existing candidate and the runner-up
/// (a different candidate), each with its squared distance; `u32::MAX` / `d_cap` if none.
#[derive(Debug, Clone, Copy)]
pub(super) struct Explanation {
    pub(super) owner: u32,
    pub(super) cost: f64,
    pub(super) second_owner: u32,
    pub(super) second_cost: f64,
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
pub(super) struct Mark {
    undo: usize,
    pub(super) flipped: usize,
}

/// What the polish reads and never changes, shared by the main state and the copies that
/// try moves in parallel: each candidate's rows ([`CandidateRows`]) and its neighbours,
/// each list built the first time it is asked for.
pub(super) struct PolishTables {
    /// Per candidate, its rows with its nearest distance there.
    rows: CandidateRows,
    /// Per candidate, its neighbours once listed ([`PolishState::neighbours`]).
    neighbours: Vec<OnceLock<Box<[u32]>>>,
    /// Whether the states keep [`ExistingMasks`]: the longest row holds more than
    /// [`MASK_MIN_ROW`] and at most [`MASK_BITS`] entries, all rows of distinct
    /// candidates.
    masks: bool,
}

impl PolishTables {
    pub(super) fn new(coeffs: &Coefficients) -> Self {
        let long_rows = (MASK_MIN_ROW + 1..=MASK_BITS).contains(&coeffs.max_row);
        let mut rows = CandidateRows::new(coeffs, long_rows);
        // Distinct candidates in every row exactly when the transpose kept every entry.
        let masks = long_rows && rows.len() == coeffs.entries();
        if !masks {
            rows.drop_places();
        }
        Self::with_masks(coeffs, rows, masks)
    }

    fn with_masks(coeffs: &Coefficients, rows: CandidateRows, masks: bool) -> Self {
        PolishTables {
            rows,
            neighbours: (0..coeffs.candidates()).map(|_| OnceLock::new()).collect(),
            masks,
        }
    }

    /// Each candidate's rows (for the memo's tests).
    #[cfg(test)]
    pub(super) fn rows_for_tests(&self) -> &CandidateRows {
        &self.rows
    }
}

/// The binary scene and each point's current explanation, for [`super::polish()`]. A
/// clone is an independent copy of the scene over the same tables.
#[derive(Clone)]
pub(super) struct PolishState<'a> {
    pub(super) coeffs: &'a Coefficients,
    /// Per candidate, its rows with its nearest distance there.
    pub(super) rows: &'a CandidateRows,
    /// Per candidate, its neighbours once listed.
    neighbour_lists: &'a [OnceLock<Box<[u32]>>],
    /// The current binary scene.
    pub(super) exists: Vec<bool>,
    /// Per point (row), its current explanation.
    pub(super) point: Vec<Explanation>,
    /// Per row, which of its entries exist (empty when the tables keep no masks).
    masks: ExistingMasks,
    /// Scratch of [`PolishState::best_replacement`]: per candidate, what it gains on the
    /// freed points (all zero between calls).
    pub(super) gain: Vec<f64>,
    /// Candidates flipped by kept moves since the sweep began (rolled-back flips are not).
    pub(super) flipped: Vec<usize>,
    /// Changes since the last [`PolishState::commit`].
    undo: Vec<Undo>,
    /// Loss changes within ± this count as zero (see [`RELATIVE_TOLERANCE`]).
    pub(super) tolerance: f64,
    /// Candidates whose rows were read since [`PolishState::record_reads`] (`None`: not
    /// recording); what a trial move depends on ([`TrialMemo`]).
    reads: Option<Vec<u32>>,
}

impl<'a> PolishState<'a> {
    pub(super) fn new(coeffs: &'a Coefficients, tables: &'a PolishTables, exists: &[bool]) -> Self {
        let n = coeffs.candidates();
        let point = (0..coeffs.points())
            .into_par_iter()
            .map(|j| explain(coeffs, j, exists))
            .collect();
        let masks = if tables.masks {
            ExistingMasks::new(coeffs, exists)
        } else {
            ExistingMasks(Vec::new())
        };
        let mut s = PolishState {
            coeffs,
            rows: &tables.rows,
            neighbour_lists: &tables.neighbours,
            exists: exists.to_vec(),
            point,
            masks,
            gain: vec![0.0; n],
            flipped: Vec::new(),
            undo: Vec::new(),
            tolerance: 0.0,
            reads: None,
        };
        let o = &coeffs.options;
        let cost: f64 = s.point.iter().map(|e| e.cost).sum();
        let scale = coeffs.g.iter().sum::<f64>() * o.primitive_weight + cost * o.point_weight;
        s.tolerance = RELATIVE_TOLERANCE * scale.abs().max(MIN_LOSS_SCALE);
        s
    }

    /// Starts recording which candidates' rows are read, beginning with `i`'s.
    pub(super) fn record_reads(&mut self, i: usize) {
        self.reads = Some(vec![i as u32]);
    }

    /// Stops recording; the candidates whose rows were read since [`Self::record_reads`].
    pub(super) fn take_reads(&mut self) -> Vec<u32> {
        self.reads.take().unwrap_or_default()
    }

    #[inline]
    fn note_read(&mut self, c: usize) {
        if let Some(r) = &mut self.reads {
            r.push(c as u32);
        }
    }

    /// Change of the binary loss if candidate `i` flipped.
    pub(super) fn flip_delta(&mut self, i: usize) -> f64 {
        self.note_read(i);
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
    pub(super) fn flip(&mut self, i: usize) {
        self.note_read(i);
        self.exists[i] = !self.exists[i];
        self.flipped.push(i);
        let c = i as u32;
        self.undo.push(Undo::Flip(c));
        self.masks.toggle(&self.rows[i], self.rows.places(i));
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
                *e = match self.masks.row(j as usize) {
                    Some(mask) => explain_masked(self.coeffs, j as usize, mask),
                    None => explain(self.coeffs, j as usize, &self.exists),
                };
            } else {
                continue;
            }
            self.undo.push(Undo::Point(j, old));
        }
    }

    /// The current position of the undo log.
    pub(super) fn mark(&self) -> Mark {
        Mark {
            undo: self.undo.len(),
            flipped: self.flipped.len(),
        }
    }

    /// Undoes every flip since `mark`, restoring the saved explanations (no row scans).
    pub(super) fn rollback(&mut self, mark: Mark) {
        while self.undo.len() > mark.undo {
            match self.undo.pop() {
                Some(Undo::Point(j, e)) => self.point[j as usize] = e,
                Some(Undo::Flip(i)) => {
                    let i = i as usize;
                    self.exists[i] = !self.exists[i];
                    self.masks.toggle(&self.rows[i], self.rows.places(i));
                }
                None => break,
            }
        }
        self.flipped.truncate(mark.flipped);
    }

    /// Forgets the undo log: the changes so far are kept (and stamped in `memo`).
    pub(super) fn commit(&mut self, memo: &mut TrialMemo) {
        let kept = self.undo.iter().filter_map(|u| match *u {
            Undo::Flip(c) => Some(c as usize),
            Undo::Point(..) => None,
        });
        memo.commit(self.coeffs, self.rows, kept);
        self.undo.clear();
    }

    /// Candidates with entries in (a sample of at most [`NEIGHBOUR_ROWS`] of) the rows of
    /// `i`, sorted, without `i`; listed once and shared by every copy of the state.
    pub(super) fn neighbours(&self, i: usize) -> &'a [u32] {
        let (coeffs, rows) = (self.coeffs, &self.rows[i]);
        self.neighbour_lists[i].get_or_init(|| {
            let stride = rows.len().div_ceil(NEIGHBOUR_ROWS).max(1);
            let mut n: Vec<u32> = rows
                .iter()
                .step_by(stride)
                .flat_map(|&(j, _)| coeffs.cand[coeffs.row(j as usize)].iter().copied())
                .filter(|&c| c as usize != i)
                .collect();
            n.sort_unstable();
            n.dedup();
            n.into_boxed_slice()
        })
    }
}

/// Per row, bit `k` set when the candidate of the row's `k`-th entry exists: a row's
/// explanation is then its first two set bits, with no scan of the row. Kept only when
/// [`PolishTables`] says so (the longest row holds more than [`MASK_MIN_ROW`] and at most
/// [`MASK_BITS`] entries, of distinct candidates); empty otherwise.
#[derive(Clone)]
struct ExistingMasks(Vec<u64>);

impl ExistingMasks {
    fn new(coeffs: &Coefficients, exists: &[bool]) -> Self {
        ExistingMasks(
            (0..coeffs.points())
                .into_par_iter()
                .map(|j| {
                    let row = &coeffs.cand[coeffs.row(j)];
                    row.iter()
                        .enumerate()
                        .filter(|&(_, &c)| exists[c as usize])
                        .fold(0u64, |mask, (k, _)| mask | 1 << k)
                })
                .collect(),
        )
    }

    /// Row `j`'s mask, if masks are kept.
    #[inline]
    fn row(&self, j: usize) -> Option<u64> {
        self.0.get(j).copied()
    }

    /// Flips the bits of one candidate's entries: `rows` and `places` as
    /// [`CandidateRows`] lists them.
    #[inline]
    fn toggle(&mut self, rows: &[(u32, f64)], places: &[u8]) {
        if self.0.is_empty() {
            return;
        }
        for (&(j, _), &place) in rows.iter().zip(places) {
            self.0[j as usize] ^= 1 << place;
        }
    }
}

/// [`explain`] from row `j`'s mask of existing entries (its candidates distinct): the
/// first set bit is the owner, the next the runner-up.
fn explain_masked(coeffs: &Coefficients, j: usize, mask: u64) -> Explanation {
    let cap = coeffs.options.cap;
    let start = coeffs.row(j).start;
    let entry = |bits: u64| {
        if bits == 0 {
            (u32::MAX, cap)
        } else {
            let k = start + bits.trailing_zeros() as usize;
            (coeffs.cand[k], coeffs.dist[k])
        }
    };
    let (owner, cost) = entry(mask);
    let (second_owner, second_cost) = entry(mask & mask.wrapping_sub(1));
    Explanation {
        owner,
        cost,
        second_owner,
        second_cost,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chamfer::{ChamferOptions, Evaluator, SampleSets};
    use crate::progress::Silent;
    use nalgebra::Point3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The incremental explanations stay equal to a fresh scan of every row after long
    /// random flip sequences, including candidates farther than d_cap; with the rows'
    /// masks of existing entries (what the tables choose here) and without, the states
    /// stay identical, owners included.
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
            assert_eq!(
                PolishTables::new(&c).masks,
                c.max_row > MASK_MIN_ROW,
                "beta {beta:?}"
            );
            let masked = PolishTables::with_masks(&c, CandidateRows::new(&c, true), true);
            let scanned = PolishTables::with_masks(&c, CandidateRows::new(&c, true), false);
            let mut memo = TrialMemo::new(12);
            let mut st = PolishState::new(&c, &masked, &[false; 12]);
            let mut plain = PolishState::new(&c, &scanned, &[false; 12]);
            let mut rng = ChaCha8Rng::seed_from_u64(4);
            for _ in 0..300 {
                let i = rng.random_range(0..12usize);
                let before = ev.binary_value(&st.exists).total;
                let predicted = st.flip_delta(i);
                st.flip(i);
                plain.flip(i);
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
                assert_same(&st, &plain);
                // A trial of a few flips rolled back leaves the state exactly as it was.
                let before = st.clone();
                st.commit(&mut memo);
                let mark = st.mark();
                for _ in 0..rng.random_range(1..5) {
                    st.flip(rng.random_range(0..12usize));
                }
                st.rollback(mark);
                assert_same(&st, &before);
                assert_eq!(st.masks.0, before.masks.0);
            }
        }
    }

    /// The same scene and explanations, owners included.
    fn assert_same(a: &PolishState, b: &PolishState) {
        assert_eq!(a.exists, b.exists);
        for (x, y) in a.point.iter().zip(&b.point) {
            assert_eq!(
                (x.owner, x.cost, x.second_owner, x.second_cost),
                (y.owner, y.cost, y.second_owner, y.second_cost)
            );
        }
    }

    /// Rows of repeated candidates (the independent model) keep no masks.
    #[test]
    fn repeated_candidates_keep_no_masks() {
        let cloud: Vec<Point3<f64>> = (0..30)
            .map(|k| Point3::new(k as f64 * 0.1, 0.0, 0.0))
            .collect();
        let samples: Vec<Point3<f64>> = (0..20)
            .map(|k| Point3::new(k as f64 * 0.15, 0.05, 0.0))
            .collect();
        let owner: Vec<usize> = (0..20).map(|k| k % 4).collect();
        let sets = SampleSets::new(&samples, &owner, 4).unwrap();
        let o = ChamferOptions {
            model: crate::chamfer::PointModel::Independent,
            alpha: Some(3),
            cap: 0.05,
            ..Default::default()
        };
        let c = Coefficients::build(&cloud, &sets, &o, &Silent).unwrap();
        // Rows long enough for masks: only the repeated candidates rule them out.
        assert!(
            (MASK_MIN_ROW + 1..=MASK_BITS).contains(&c.max_row),
            "{}",
            c.max_row
        );
        let tables = PolishTables::new(&c);
        assert!(!tables.masks);
        // Without masks nothing reads the places: they are not kept.
        assert!((0..4).all(|i| tables.rows.places(i).is_empty()));
    }
}
