//! The point term transposed: for each candidate, the rows (points) where it has entries,
//! with its smallest distance there — what the polish sums over when a candidate flips.
//!
//! Stored as one array ordered by candidate (16 bytes an entry, and a byte for the
//! entry's place in its row) with `n + 1` offsets.
//! Built in parallel and exactly: a counting pass over chunks of rows sizes every
//! candidate's list, then the candidates are cut into ranges of about equal entry
//! counts and each range fills its own part of the array, scanning the rows in order.

use std::ops::Index;

use rayon::prelude::*;

use crate::chamfer::Coefficients;

/// Rows per parallel task of the counting pass (at least the candidate count, so that
/// each task's counts, `n` of them, cost less than its rows).
const COUNT_CHUNK: usize = 16_384;

/// Candidate ranges filled in parallel per worker thread: each range scans every row's
/// candidate ids (4 bytes an entry) and writes only its own entries, so a few ranges a
/// thread balance the load at a small cost in repeated scans.
const RANGES_PER_THREAD: usize = 2;

/// For each candidate, its rows (point indices, increasing) with its smallest squared
/// distance there. `rows[i]` is candidate i's list.
pub(super) struct CandidateRows {
    /// Candidate i's entries are `entries[offsets[i]..offsets[i + 1]]`.
    offsets: Vec<usize>,
    /// `(row, squared distance)`, grouped by candidate.
    entries: Vec<(u32, f64)>,
    /// Each entry's place in its row (`u8::MAX` from 255 on), as `entries`; empty when
    /// not asked for.
    places: Vec<u8>,
}

impl Index<usize> for CandidateRows {
    type Output = [(u32, f64)];
    fn index(&self, i: usize) -> &[(u32, f64)] {
        &self.entries[self.offsets[i]..self.offsets[i + 1]]
    }
}

impl CandidateRows {
    /// Candidate i's place in each of its rows (`u8::MAX` from 255 on), as `self[i]`;
    /// empty when the places were not asked for.
    pub(super) fn places(&self, i: usize) -> &[u8] {
        self.places
            .get(self.offsets[i]..self.offsets[i + 1])
            .unwrap_or_default()
    }

    /// Frees the places (only the polish's masks read them).
    pub(super) fn drop_places(&mut self) {
        self.places = Vec::new();
    }

    /// Entries in all lists: the coefficients' entry count exactly when no candidate has
    /// two entries in one row.
    pub(super) fn len(&self) -> usize {
        self.entries.len()
    }

    /// Transposes the entries of `coeffs`, with each entry's place in its row if
    /// `with_places`. A candidate with several entries in one row (the independent model)
    /// keeps the first, its nearest: rows are sorted by distance.
    pub(super) fn new(coeffs: &Coefficients, with_places: bool) -> Self {
        let n = coeffs.candidates();
        let counts = count_rows_per_candidate(coeffs);
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        for &k in &counts {
            offsets.push(offsets[offsets.len() - 1] + k);
        }
        let total = offsets[n];
        let mut entries = vec![(0u32, 0.0f64); total];
        let mut places = vec![0u8; if with_places { total } else { 0 }];
        let ranges = candidate_ranges(&offsets, rayon::current_num_threads() * RANGES_PER_THREAD);
        let mut parts = Vec::with_capacity(ranges.len());
        let (mut rest, mut rest_places) = (&mut entries[..], &mut places[..]);
        for r in &ranges {
            let len = offsets[r.end] - offsets[r.start];
            let (part, tail) = std::mem::take(&mut rest).split_at_mut(len);
            let places_len = if with_places { len } else { 0 };
            let (part_places, tail_places) =
                std::mem::take(&mut rest_places).split_at_mut(places_len);
            parts.push((r.clone(), part, part_places));
            (rest, rest_places) = (tail, tail_places);
        }
        parts
            .into_par_iter()
            .for_each(|(range, part, part_places)| {
                fill_range(coeffs, &offsets, range, part, part_places)
            });
        CandidateRows {
            offsets,
            entries,
            places,
        }
    }
}

/// Per candidate, the number of rows where it has an entry.
fn count_rows_per_candidate(coeffs: &Coefficients) -> Vec<usize> {
    let n = coeffs.candidates();
    let chunk = COUNT_CHUNK.max(n);
    let rows: Vec<usize> = (0..coeffs.points()).step_by(chunk).collect();
    rows.into_par_iter()
        .map(|first| {
            let mut counts = vec![0usize; n];
            let mut last = vec![u32::MAX; n];
            for j in first..(first + chunk).min(coeffs.points()) {
                for &c in &coeffs.cand[coeffs.row(j)] {
                    if last[c as usize] != j as u32 {
                        last[c as usize] = j as u32;
                        counts[c as usize] += 1;
                    }
                }
            }
            counts
        })
        .reduce(
            || vec![0usize; n],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        )
}

/// At most `parts` contiguous candidate ranges covering `0..n` with about equal entry
/// counts (`offsets` as in [`CandidateRows`]); empty ranges are left out.
fn candidate_ranges(offsets: &[usize], parts: usize) -> Vec<std::ops::Range<usize>> {
    let n = offsets.len() - 1;
    let total = offsets[n];
    let parts = parts.max(1);
    let mut ranges = Vec::with_capacity(parts);
    let mut start = 0;
    for p in 1..=parts {
        let goal = total * p / parts;
        let end = if p == parts {
            n
        } else {
            (start + offsets[start..=n].partition_point(|&o| o < goal)).min(n)
        };
        if end > start {
            ranges.push(start..end);
            start = end;
        }
    }
    ranges
}

/// Writes the lists of the candidates in `range` into `part` (their slice of the
/// entries) and their places into `places`, scanning every row in order.
fn fill_range(
    coeffs: &Coefficients,
    offsets: &[usize],
    range: std::ops::Range<usize>,
    part: &mut [(u32, f64)],
    places: &mut [u8],
) {
    let base = offsets[range.start];
    let mut cursor: Vec<usize> = offsets[range.clone()].iter().map(|&o| o - base).collect();
    let mut last = vec![u32::MAX; range.len()];
    let (lo, hi) = (range.start as u32, range.end as u32);
    for j in 0..coeffs.points() {
        let r = coeffs.row(j);
        let row = coeffs.cand[r.clone()].iter().zip(&coeffs.dist[r]);
        for (place, (&c, &d)) in row.enumerate() {
            if c < lo || c >= hi {
                continue;
            }
            let k = (c - lo) as usize;
            // Rows are sorted, so the first entry of a candidate is its nearest.
            if last[k] != j as u32 {
                last[k] = j as u32;
                part[cursor[k]] = (j as u32, d);
                if let Some(p) = places.get_mut(cursor[k]) {
                    *p = place.min(u8::MAX as usize) as u8;
                }
                cursor[k] += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chamfer::{ChamferOptions, PointModel, SampleSets};
    use crate::progress::Silent;
    use nalgebra::Point3;

    /// Each candidate's lists as defined: every row where it has an entry, in row order,
    /// once, with its first (smallest) distance there.
    fn by_definition(c: &Coefficients) -> Vec<Vec<(u32, f64)>> {
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
        expect
    }

    /// The parallel transpose equals the definition on both point models, with rows
    /// spread over several counting chunks and candidates over 1 to 7 ranges (pools of
    /// 1, 2 and 3 threads).
    #[test]
    fn transpose_keeps_each_candidates_first_entry_per_row() {
        let points = 2 * COUNT_CHUNK + 1000;
        let cloud: Vec<Point3<f64>> = (0..points)
            .map(|k| {
                let t = k as f64 * 0.37;
                Point3::new(t.sin() * 2.0, (1.7 * t).cos(), 1e-4 * t)
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
            let expect = by_definition(&c);
            for threads in [1, 2, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let rows = pool.install(|| CandidateRows::new(&c, true));
                let bare = pool.install(|| CandidateRows::new(&c, false));
                assert!(
                    (0..c.candidates()).all(|i| bare[i] == rows[i] && bare.places(i).is_empty())
                );
                let got: Vec<Vec<(u32, f64)>> =
                    (0..c.candidates()).map(|i| rows[i].to_vec()).collect();
                assert_eq!(got, expect, "{model:?}, {threads} threads");
                for i in 0..c.candidates() {
                    for (&(j, _), &place) in rows[i].iter().zip(rows.places(i)) {
                        let r = c.row(j as usize);
                        let first = c.cand[r.clone()].iter().position(|&k| k as usize == i);
                        assert_eq!(Some(place as usize), first, "{model:?}, candidate {i}");
                    }
                }
            }
            if model == PointModel::Independent {
                assert!(c.entries() > expect.iter().map(Vec::len).sum::<usize>());
            }
        }
    }

    #[test]
    fn ranges_cover_every_candidate_once_in_order() {
        // Entry counts 5, 0, 0, 7, 1, 0, 3.
        let offsets = [0, 5, 5, 5, 12, 13, 13, 16];
        for parts in 1..10 {
            let ranges = candidate_ranges(&offsets, parts);
            assert!(ranges.len() <= parts.max(1));
            assert_eq!(ranges[0].start, 0);
            assert_eq!(ranges.last().unwrap().end, 7);
            for w in ranges.windows(2) {
                assert_eq!(w[0].end, w[1].start, "{parts}: {ranges:?}");
            }
            assert!(ranges.iter().all(|r| r.end > r.start));
        }
    }
}
