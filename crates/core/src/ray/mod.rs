//! The thesis's first approach (chapter 4): a ray-based measurement model, RayTrees for
//! fast ray ↔ primitive lookups, and Metropolis–Hastings over which candidates exist.
//!
//! Every point is a ray from its sensor origin ([`Rays`], needs
//! [`crate::PointCloud::sensors`]). The likelihood of a scene Φ is a sum over rays of
//! eq. 4.10 in log space ([`ray_log_likelihood`], `likelihood.rs`); the candidates
//! crossing each ray are found once with per-frame [`RayTree`]s and stored, with their
//! per-crossing terms, in a [`RayTable`] (Algorithm 2); [`SceneState`] re-evaluates
//! only the rays of flipped candidates (Algorithm 3); [`sample`] is the §4.2.2 sampler
//! with the §4.2.1 prior ([`existence_prior`]); [`crate::fit::fit`] with
//! [`crate::fit::MethodOptions::Mcmc`] is the pipeline behind `primfit fit --method mcmc`.
//!
//! Units: lengths in scene units (metres), log-likelihoods in nats, the noise rate in
//! points per scene unit of ray.
//!
//! ```
//! use primfit_core::ray::{RayModel, RayTable, Rays};
//! use primfit_core::synth::{SixInARowParams, six_in_a_row};
//!
//! let toy = six_in_a_row(&SixInARowParams::default()).unwrap();
//! let rays = Rays::from_cloud(&toy.scene.cloud).unwrap();
//! let table = RayTable::build(&rays, &toy.candidates, RayModel::default()).unwrap();
//! let mut only_the_true_one = vec![false; 6];
//! only_the_true_one[toy.true_index] = true;
//! let truth = table.log_likelihood(&only_the_true_one).unwrap();
//! let nearest = table.log_likelihood(&[true, false, false, false, false, false]).unwrap();
//! assert!(truth > nearest);
//! ```

mod free_space;
#[cfg(test)]
mod free_space_tests;
mod incremental;
mod likelihood;
mod mcmc;
mod prior;
mod raytree;
#[cfg(test)]
pub(crate) mod tests;
mod unseen;

pub use free_space::{
    FreeSpace, MAX_FREE_SPACE_RAYS, crossing_cost, marched_free_space, marches_into,
};
pub use incremental::SceneState;
pub use likelihood::{RayModel, crossing_terms, log_upper_tail, ray_log_likelihood};
pub use mcmc::{McmcOptions, McmcResult, flip_rates, sample};
pub use prior::{PriorOptions, existence_prior};
pub use raytree::{Entry, RayTable, RayTree, Rays, SEEN_SIGMAS, naive_log_likelihood};
pub use unseen::{UNOBSERVED_POINT_NATS, local_spacings, occupancy_prior, unobserved_points};
