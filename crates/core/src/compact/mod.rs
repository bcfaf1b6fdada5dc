//! The compact model of a scan (`--types auto`): primitives proposed from the data's own
//! geometry, kept by the probabilistic chamfer with a description-length cost per
//! primitive, so that few large primitives beat many small ones.
//!
//! | stage | file |
//! |---|---|
//! | planes, cylinders and spheres found in the data | [`crate::detect`] |
//! | candidates: a bounded `plane` per connected part of a planar segment, the bounded primitive of a curved one | `candidates.rs` |
//! | description length of a primitive, in loss units | `mdl.rs` |
//! | the nearest of a partial tube's samples, in constant time | `tube_lattice.rs` |
//! | existence of the candidates | `existence.rs` |
//! | planes trimmed where a larger primitive covers them | `trim.rs` |
//! | the loss of swapping a few primitives for others, where they change it | `swap.rs` |
//! | one cylinder for a run found in collinear pieces | `collinear.rs` |
//! | elbows joining pipe runs that meet at a right angle | `elbows.rs` |
//! | the loss of a trial elbow | `elbow_loss.rs` |
//! | the whole: [`compact_model`] | `model.rs` |

mod candidates;
mod collinear;
mod elbow_loss;
mod elbows;
mod existence;
mod geometry;
mod mdl;
mod model;
mod swap;
mod trim;
mod tube_lattice;

pub(crate) use mdl::primitive_cost;
pub use model::{
    CAP_SIGMAS, CAP_SPACINGS, CompactModel, CompactOptions, EXISTENCE_BETA, MAX_CANDIDATE_SAMPLES,
    PRIMITIVE_TERM_SAMPLES, SAMPLE_SPACINGS, compact_model,
};
