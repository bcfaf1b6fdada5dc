//! The existence re-check after refinement, and the binary chamfer it judges by.
//!
//! Refinement can make primitives redundant (two squares slide onto the same wall
//! section). The refined set is scored with the binary chamfer ([`crate::chamfer`], same
//! options as the fit) and the discrete [`polish`], started from "all exist", removes
//! every primitive whose removal does not increase it.

use super::RefineContext;
use crate::chamfer::{Coefficients, Evaluator};
use crate::lattice::CandidateSet;
use crate::progress::Silent;
use crate::solve::{Moves, polish};
use crate::{Primitive, Result};

/// Most sweeps of the discrete polish in the re-check (it stops earlier, once a sweep
/// flips nothing): a bound on its time.
const RECHECK_SWEEPS: usize = 20;

/// The binary chamfer (weighted total) of `prims`, all existing, with the fit's options
/// ([`crate::chamfer::ChamferOptions::for_all_existing`]: under the existence model one
/// entry a point gives the value of any β).
pub(super) fn binary_loss(ctx: &RefineContext<'_>, prims: &[Primitive]) -> Result<f64> {
    if prims.is_empty() {
        return Ok(ctx.chamfer.point_weight * ctx.chamfer.cap * ctx.points.len() as f64);
    }
    let set = CandidateSet::from_primitives(prims, ctx.sample_spacing)?;
    let options = ctx.chamfer.for_all_existing();
    let coeffs = Coefficients::build_indexed(ctx.points, ctx.index, &set, &options, &Silent)?;
    Ok(Evaluator::new(&coeffs)
        .binary_value(&vec![true; set.len()])
        .total)
}

/// Which primitives stay: the discrete polish started from "all exist".
pub(super) fn recheck(ctx: &RefineContext<'_>, prims: &[Primitive]) -> Result<Vec<bool>> {
    let set = CandidateSet::from_primitives(prims, ctx.sample_spacing)?;
    let coeffs = Coefficients::build_indexed(ctx.points, ctx.index, &set, ctx.chamfer, &Silent)?;
    let mut exists = vec![true; set.len()];
    polish(
        &coeffs,
        &vec![1.0; set.len()],
        &mut exists,
        RECHECK_SWEEPS,
        Moves::All,
    );
    Ok(exists)
}
