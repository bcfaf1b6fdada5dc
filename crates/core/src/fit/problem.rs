//! The lattice fit's optimisation problem on its own, for research and the bindings: the
//! candidates a fit would optimise over and the loss it would minimise, under the same
//! settings and the same memory budget as [`super::fit`].

use nalgebra::Point3;

use super::pass::check_memory;
use super::work::check_work;
use super::{FitOptions, Settings};
use crate::budget;
use crate::chamfer::{CandidateGeometry, Coefficients};
use crate::error::Remedy;
use crate::lattice::CandidateSet;
use crate::progress::Progress;
use crate::spatial::PointIndex;
use crate::{PointCloud, Result};

/// Bytes per materialised sample in [`candidate_samples`]: the point (24) and its owner (8).
const BYTES_PER_SAMPLE: u64 = 32;

/// The settings and the candidate set (the lattice after the occupancy prior) of a
/// lattice fit of `cloud` with `options`.
pub fn fit_candidates(
    cloud: &PointCloud,
    options: &FitOptions,
) -> Result<(Settings, CandidateSet)> {
    let index = PointIndex::new(&cloud.points);
    let settings = Settings::resolve(cloud, &index, options)?;
    let set = CandidateSet::build(&settings.lattice(), cloud)?;
    Ok((settings, set))
}

/// Every candidate's samples in scene coordinates and the candidate of each sample,
/// refused up front when they would take more than `memory_budget` bytes.
pub fn candidate_samples(
    set: &CandidateSet,
    memory_budget: u64,
) -> Result<(Vec<Point3<f64>>, Vec<usize>)> {
    let count: u64 = (0..set.len()).map(|i| set.sample_count(i) as u64).sum();
    budget::check_memory(
        &format!("the samples of {} candidates ({count} samples)", set.len()),
        count.saturating_mul(BYTES_PER_SAMPLE),
        memory_budget,
        vec![
            Remedy::Raise("spacing"),
            Remedy::Raise("sample_spacing"),
            Remedy::Raise("memory_budget"),
        ],
    )?;
    let (mut samples, mut owner, mut buf) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..set.len() {
        set.scene_samples(i, &mut buf);
        samples.extend_from_slice(&buf);
        owner.extend(std::iter::repeat_n(i, buf.len()));
    }
    Ok((samples, owner))
}

/// The loss a lattice fit of `cloud` with `options` minimises: its settings and the
/// chamfer coefficients over its candidates, refused up front (like the fit) when their
/// estimated peak memory or work is over the settings' budgets.
pub fn fit_problem(
    cloud: &PointCloud,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<(Settings, Coefficients)> {
    let (settings, set) = fit_candidates(cloud, options)?;
    check_memory(cloud.len(), &set, &settings)?;
    check_work(cloud.len(), &set, &settings)?;
    let coefficients = Coefficients::build(&cloud.points, &set, &settings.chamfer, progress)?;
    Ok((settings, coefficients))
}
