//! Candidate geometry as the loss sees it: the finite sample sets σ_i
//! ([`CandidateGeometry`]), and explicit sample sets with owners ([`SampleSets`]).

use std::ops::Range;

use nalgebra::Point3;
use rayon::prelude::*;

use crate::spatial::PointIndex;
use crate::{Error, Result, check};

/// What the loss needs to know about candidates: their finite sample sets σ_i.
///
/// Implemented by [`crate::lattice::CandidateSet`] (shared local templates) and by
/// [`SampleSets`] (explicit samples with owners).
pub trait CandidateGeometry: Sync {
    /// Number of candidates N.
    fn len(&self) -> usize;
    /// True when there are no candidates.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// M_i, the number of samples of candidate `i`.
    fn sample_count(&self, i: usize) -> usize;
    /// Candidate `i`'s samples in scene coordinates, written into `out` (cleared first).
    fn scene_samples(&self, i: usize, out: &mut Vec<Point3<f64>>);
    /// A ball `(centre, radius)` containing all samples of candidate `i` and, where
    /// [`CandidateGeometry::surface_distance`] knows a continuous surface, that surface.
    fn bounding_ball(&self, i: usize) -> (Point3<f64>, f64);
    /// `(sample index, squared distance)` of candidate `i`'s sample nearest to `y`.
    fn nearest_sample(&self, i: usize, y: &Point3<f64>) -> (u32, f64);
    /// Squared distance from `y` to candidate `i`'s continuous surface, when the geometry
    /// knows it (the limit of infinitely dense samples). Defaults to the nearest sample.
    fn surface_distance(&self, i: usize, y: &Point3<f64>) -> f64 {
        self.nearest_sample(i, y).1
    }
    /// The `k` samples of candidate `i` nearest to `y` (all when `k` is `None`), sorted by
    /// (squared distance, sample index), written into `out` (cleared first).
    fn nearest_samples(
        &self,
        i: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    );
}

/// Explicit candidate sample sets: samples `(K, 3)` with an owner candidate each, as the
/// Python API takes them. Samples keep their input order within a candidate (the α
/// tie-break is the lower sample index).
#[derive(Debug)]
pub struct SampleSets {
    samples: Vec<Point3<f64>>,
    ranges: Vec<Range<usize>>,
    indexes: Vec<PointIndex>,
    balls: Vec<(Point3<f64>, f64)>,
}

impl SampleSets {
    /// Groups `samples` by `owner` (each in `0..n`). Every candidate needs ≥ 1 sample.
    pub fn new(samples: &[Point3<f64>], owner: &[usize], n: usize) -> Result<Self> {
        check::same_len("owners", owner.len(), "samples", samples.len())?;
        // Checked before anything of size n is allocated: n comes from the caller.
        if n > samples.len() {
            let expected = format!(
                "at most the {} samples (every candidate needs one)",
                samples.len()
            );
            return Err(Error::out_of_range("n", n, expected));
        }
        let mut counts = vec![0usize; n];
        for (k, &o) in owner.iter().enumerate() {
            if o >= n {
                return Err(Error::IndexOutOfRange {
                    what: format!("owner[{k}]"),
                    index: o,
                    item: "candidate",
                    count: n,
                });
            }
            counts[o] += 1;
        }
        if let Some(empty) = counts.iter().position(|&c| c == 0) {
            return Err(Error::invalid(format!("candidate {empty} has no samples")));
        }
        let mut order: Vec<usize> = (0..samples.len()).collect();
        order.sort_by_key(|&k| owner[k]); // stable: input order within a candidate
        let sorted: Vec<Point3<f64>> = order.iter().map(|&k| samples[k]).collect();
        let mut ranges = Vec::with_capacity(n);
        let mut start = 0;
        for c in counts {
            ranges.push(start..start + c);
            start += c;
        }
        let indexes = ranges
            .par_iter()
            .map(|r| PointIndex::new(&sorted[r.clone()]))
            .collect();
        let balls = ranges
            .iter()
            .map(|r| {
                let s = &sorted[r.clone()];
                let centre = Point3::from(
                    s.iter().map(|p| p.coords).sum::<nalgebra::Vector3<f64>>() / s.len() as f64,
                );
                (
                    centre,
                    s.iter().map(|p| (p - centre).norm()).fold(0.0, f64::max),
                )
            })
            .collect();
        Ok(SampleSets {
            samples: sorted,
            ranges,
            indexes,
            balls,
        })
    }
}

impl CandidateGeometry for SampleSets {
    fn len(&self) -> usize {
        self.ranges.len()
    }
    fn sample_count(&self, i: usize) -> usize {
        self.ranges[i].len()
    }
    fn scene_samples(&self, i: usize, out: &mut Vec<Point3<f64>>) {
        out.clear();
        out.extend_from_slice(&self.samples[self.ranges[i].clone()]);
    }
    fn bounding_ball(&self, i: usize) -> (Point3<f64>, f64) {
        self.balls[i]
    }
    fn nearest_sample(&self, i: usize, y: &Point3<f64>) -> (u32, f64) {
        self.indexes[i].nearest(y).unwrap_or((0, f64::INFINITY))
    }
    fn nearest_samples(
        &self,
        i: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    ) {
        out.clear();
        let s = &self.samples[self.ranges[i].clone()];
        match k {
            Some(k) if k < s.len() => out.extend(self.indexes[i].nearest_n(y, k)),
            _ => {
                out.extend(
                    s.iter()
                        .enumerate()
                        .map(|(j, x)| (j as u32, (x - y).norm_squared())),
                );
                out.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            }
        }
    }
}
