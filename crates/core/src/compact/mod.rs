//! The compact model of a scan (`--types auto`): primitives proposed from the data's own
//! geometry, kept by the probabilistic chamfer with a description-length cost per
//! primitive, so that few large primitives beat many small ones.
//!
//! | stage | file |
//! |---|---|
//! | description length of a primitive, in loss units | `mdl.rs` |
//! | existence of the proposed candidates | `existence.rs` |

mod existence;
mod mdl;

pub use existence::{Existence, ExistenceOptions, decide_existence};
pub use mdl::{description_length, primitive_cost};
