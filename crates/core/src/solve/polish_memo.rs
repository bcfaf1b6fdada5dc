//! Which trial moves of the discrete polish are known to fail again, so that a sweep does
//! not repeat them.
//!
//! A trial move (add-and-prune or a replace chain from candidate `i`) is a deterministic
//! function of what it reads: the explanations of the rows of every candidate it
//! evaluates or flips, and the existence of the candidates with entries in those rows.
//! Both change only when a candidate with an entry in one of those rows is flipped by a
//! *kept* move. So the memo stores, for each failed trial, the candidates whose rows it
//! read and the commit count at the time; each kept flip of `c` stamps every candidate
//! sharing a row with `c`. If none of a failed trial's read candidates has been stamped
//! since, the trial would read exactly the same state and fail again: it is skipped. The
//! polish's answer is unchanged; only repeated work goes.

use super::candidate_rows::CandidateRows;
use crate::chamfer::Coefficients;

/// The trial moves of the polish (the memo keeps them apart: the same candidate fails
/// them independently).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Trial {
    /// Move 2 of the polish, from an absent candidate.
    AddAndPrune,
    /// Move 3 of the polish, from an existing candidate.
    Replace,
}

impl Trial {
    /// Whether this trial starts from a candidate that does (`exists`) or does not exist.
    pub(super) fn applies(self, exists: bool) -> bool {
        match self {
            Trial::AddAndPrune => !exists,
            Trial::Replace => exists,
        }
    }
}

/// A failed trial: the commit count when it ran and the candidates whose rows it read.
#[derive(Debug, Clone)]
struct Failure {
    at: u64,
    read: Vec<u32>,
}

/// The memo of failed trials (module docs).
#[derive(Debug)]
pub(super) struct TrialMemo {
    /// Kept commits so far (the stamp of the next changes).
    commits: u64,
    /// Per candidate, the commit count when a row it has entries in last changed.
    stamped: Vec<u64>,
    /// Per trial kind and candidate, its last failure.
    failed: [Vec<Option<Failure>>; 2],
}

impl TrialMemo {
    /// An empty memo over `n` candidates.
    pub(super) fn new(n: usize) -> Self {
        TrialMemo {
            commits: 0,
            stamped: vec![0; n],
            failed: [vec![None; n], vec![None; n]],
        }
    }

    /// A memo for a polish that runs no trials: it stamps nothing (so kept single flips
    /// cost no row scans) and knows no failure.
    pub(super) fn unused() -> Self {
        Self::new(0)
    }

    /// Whether trial `kind` from `i` is known to fail in the current state.
    pub(super) fn known_failure(&self, kind: Trial, i: usize) -> bool {
        self.failed[kind as usize]
            .get(i)
            .and_then(Option::as_ref)
            .is_some_and(|f| f.read.iter().all(|&c| self.stamped[c as usize] <= f.at))
    }

    /// Remembers that trial `kind` from `i` failed, having read the rows of `read`.
    pub(super) fn failed(&mut self, kind: Trial, i: usize, mut read: Vec<u32>) {
        read.sort_unstable();
        read.dedup();
        self.failed[kind as usize][i] = Some(Failure {
            at: self.commits,
            read,
        });
    }

    /// Forgets trial `kind` from `i` (it was kept).
    pub(super) fn kept(&mut self, kind: Trial, i: usize) {
        self.failed[kind as usize][i] = None;
    }

    /// Records kept flips of `flipped`, whose rows are `rows`: stamps every candidate
    /// with an entry in one of those rows.
    pub(super) fn commit(
        &mut self,
        coeffs: &Coefficients,
        rows: &CandidateRows,
        flipped: impl Iterator<Item = usize>,
    ) {
        if self.stamped.is_empty() {
            return;
        }
        let mut any = false;
        for c in flipped {
            if !any {
                self.commits += 1;
                any = true;
            }
            for &(j, _) in &rows[c] {
                for &k in &coeffs.cand[coeffs.row(j as usize)] {
                    self.stamped[k as usize] = self.commits;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chamfer::{ChamferOptions, SampleSets};
    use crate::progress::Silent;
    use nalgebra::Point3;

    /// A failure stays known until a kept flip touches a row of a candidate it read, and
    /// only then.
    #[test]
    fn a_failure_is_forgotten_when_a_row_it_read_changes() {
        // Points at x = 0..9; candidate 0 covers x 0–2, 1 covers 1–3, 2 covers 7–9; each
        // row holds its two nearest candidates, so no row holds both 0 and 2.
        let cloud: Vec<Point3<f64>> = (0..10).map(|k| Point3::new(k as f64, 0.0, 0.0)).collect();
        let samples: Vec<Point3<f64>> = [0.0, 2.0, 1.0, 3.0, 7.0, 9.0]
            .iter()
            .map(|&x| Point3::new(x, 0.0, 0.0))
            .collect();
        let sets = SampleSets::new(&samples, &[0, 0, 1, 1, 2, 2], 3).unwrap();
        let opts = ChamferOptions {
            cap: 1.5,
            beta: Some(2),
            ..Default::default()
        };
        let c = Coefficients::build(&cloud, &sets, &opts, &Silent).unwrap();
        let rows = super::super::polish_state::PolishTables::new(&c);
        let rows = rows.rows_for_tests();
        let mut memo = TrialMemo::new(3);
        memo.failed(Trial::Replace, 0, vec![0, 0]);
        assert!(memo.known_failure(Trial::Replace, 0));
        assert!(!memo.known_failure(Trial::AddAndPrune, 0));
        // Candidate 2 shares no row with candidate 0: the failure stands.
        memo.commit(&c, rows, [2].into_iter());
        assert!(memo.known_failure(Trial::Replace, 0));
        // Candidate 1 shares rows with 0: forgotten.
        memo.commit(&c, rows, [1].into_iter());
        assert!(!memo.known_failure(Trial::Replace, 0));
        // Recorded again after that commit, it holds again; a kept trial clears it.
        memo.failed(Trial::Replace, 0, vec![0]);
        assert!(memo.known_failure(Trial::Replace, 0));
        memo.kept(Trial::Replace, 0);
        assert!(!memo.known_failure(Trial::Replace, 0));
    }
}
