//! The candidates as the loss sees them: a candidate judged by all of its surface
//! (planes, spheres) is its exact shape ([`CandidateSet`]); one judged by part of it (a
//! tube seen from one side) is its supported samples ([`SampleSets`]), for both terms,
//! so that it explains only the points near the part that has data.

use nalgebra::Point3;

use super::candidates::CandidateSamples;
use crate::Result;
use crate::chamfer::{CandidateGeometry, SampleSets};
use crate::lattice::CandidateSet;

/// Exact shapes for some candidates, explicit samples for the others. Every
/// candidate's primitive term sums over the samples it was given (its weight is the
/// caller's); only the candidates judged by their samples get kd-trees over them.
pub(super) struct Supported<'a> {
    exact: CandidateSet,
    samples: &'a [CandidateSamples],
    /// The candidates judged by their samples, as sample sets of their own.
    partial: SampleSets,
    /// Each candidate's place in `partial`, `None` for one judged by its exact shape.
    slot: Vec<Option<usize>>,
}

impl<'a> Supported<'a> {
    /// `exact` and `samples` describe the same candidates in the same order; a
    /// candidate whose samples are `partial` is judged by them.
    pub(super) fn new(exact: CandidateSet, samples: &'a [CandidateSamples]) -> Result<Self> {
        let mut slot = Vec::with_capacity(samples.len());
        let (mut flat, mut owner) = (Vec::new(), Vec::new());
        let mut partial = 0;
        for s in samples {
            slot.push(s.partial.then_some(partial));
            if s.partial {
                flat.extend_from_slice(&s.points);
                owner.extend(std::iter::repeat_n(partial, s.points.len()));
                partial += 1;
            }
        }
        let partial = SampleSets::new(&flat, &owner, partial)?;
        Ok(Supported {
            exact,
            samples,
            partial,
            slot,
        })
    }

    /// The geometry that judges candidate `i`, and its index there.
    fn pick(&self, i: usize) -> (&dyn CandidateGeometry, usize) {
        match self.slot[i] {
            Some(k) => (&self.partial, k),
            None => (&self.exact, i),
        }
    }
}

impl CandidateGeometry for Supported<'_> {
    fn len(&self) -> usize {
        self.slot.len()
    }
    fn sample_count(&self, i: usize) -> usize {
        self.samples[i].points.len()
    }
    fn scene_samples(&self, i: usize, out: &mut Vec<Point3<f64>>) {
        out.clear();
        out.extend_from_slice(&self.samples[i].points);
    }
    fn bounding_ball(&self, i: usize) -> (Point3<f64>, f64) {
        let (g, k) = self.pick(i);
        g.bounding_ball(k)
    }
    fn nearest_sample(&self, i: usize, y: &Point3<f64>) -> (u32, f64) {
        if let Some(tube) = &self.samples[i].tube {
            return tube.nearest(&self.samples[i].points, y);
        }
        let (g, k) = self.pick(i);
        g.nearest_sample(k, y)
    }
    fn surface_distance(&self, i: usize, y: &Point3<f64>) -> f64 {
        if let Some(tube) = &self.samples[i].tube {
            return tube.nearest(&self.samples[i].points, y).1;
        }
        let (g, k) = self.pick(i);
        g.surface_distance(k, y)
    }
    fn nearest_samples(
        &self,
        i: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    ) {
        let (g, j) = self.pick(i);
        g.nearest_samples(j, y, k, out)
    }
}
