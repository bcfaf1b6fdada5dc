//! The candidates as the loss sees them: a candidate judged by all of its surface
//! (planes, spheres) is its exact shape ([`CandidateSet`]); one judged by part of it (a
//! tube seen from one side) is its supported samples ([`SampleSets`]), for both terms,
//! so that it explains only the points near the part that has data.

use nalgebra::Point3;

use crate::Result;
use crate::chamfer::{CandidateGeometry, SampleSets};
use crate::lattice::CandidateSet;

/// Exact shapes for some candidates, explicit samples for the others.
pub(super) struct Supported {
    exact: CandidateSet,
    samples: SampleSets,
    by_samples: Vec<bool>,
}

impl Supported {
    /// `exact` and `samples` describe the same candidates in the same order;
    /// `by_samples[i]` says which of the two judges candidate `i`.
    pub(super) fn new(
        exact: CandidateSet,
        samples: &[Vec<Point3<f64>>],
        by_samples: Vec<bool>,
    ) -> Result<Self> {
        let owner: Vec<usize> = samples
            .iter()
            .enumerate()
            .flat_map(|(i, s)| std::iter::repeat_n(i, s.len()))
            .collect();
        let flat: Vec<Point3<f64>> = samples.iter().flatten().copied().collect();
        let samples = SampleSets::new(&flat, &owner, samples.len())?;
        Ok(Supported {
            exact,
            samples,
            by_samples,
        })
    }

    fn pick(&self, i: usize) -> &dyn CandidateGeometry {
        if self.by_samples[i] {
            &self.samples
        } else {
            &self.exact
        }
    }
}

impl CandidateGeometry for Supported {
    fn len(&self) -> usize {
        self.by_samples.len()
    }
    fn sample_count(&self, i: usize) -> usize {
        self.samples.sample_count(i)
    }
    fn scene_samples(&self, i: usize, out: &mut Vec<Point3<f64>>) {
        self.samples.scene_samples(i, out)
    }
    fn bounding_ball(&self, i: usize) -> (Point3<f64>, f64) {
        self.pick(i).bounding_ball(i)
    }
    fn nearest_sample(&self, i: usize, y: &Point3<f64>) -> (u32, f64) {
        self.pick(i).nearest_sample(i, y)
    }
    fn surface_distance(&self, i: usize, y: &Point3<f64>) -> f64 {
        self.pick(i).surface_distance(i, y)
    }
    fn nearest_samples(
        &self,
        i: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    ) {
        self.pick(i).nearest_samples(i, y, k, out)
    }
}
