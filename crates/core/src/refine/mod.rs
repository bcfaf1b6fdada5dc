//! Continuous refinement of the primitives the lattice fit chose: pose and sizes by
//! damped Gauss–Newton (Levenberg–Marquardt) on a chamfer, off the lattice.
//!
//! In pipeline order ([`refine`]):
//!
//! 1. a cloud of more than [`MAX_REFINE_POINTS`] points is refined on an evenly strided
//!    subset, the point weight scaled by the subsampling factor;
//! 2. [`RefineOptions::rounds`] rounds, each of which assigns every point to the
//!    primitive that owns it (`ownership`: nearest surface within the trim distance,
//!    overlapping tubes split at their bisector) and moves every primitive, independently
//!    and in parallel, to lower its cost on its own points (`lm`: the cost, its
//!    parameters and Jacobians);
//! 3. once, after the second round, re-typing (`retype`): each primitive is compared
//!    with the other configured types refined on its points;
//! 4. the existence re-check (`recheck`): the discrete polish on the binary chamfer drops
//!    redundant primitives;
//! 5. merging (`merge`): each primitive, fewest points first, is removed if its
//!    neighbours, re-refined on its points, explain them at no higher local chamfer.
//!
//! The reasoning and the measurements behind each step (why not the plain chamfer, the
//! ownership tie rule, the merge's missing dead zone) are in `docs/refine.md`.

mod lm;
mod merge;
mod ownership;
mod recheck;
mod retype;
#[cfg(test)]
mod tests;

use std::time::Instant;

use nalgebra::{Point3, UnitQuaternion};
use rayon::prelude::*;

use self::lm::{Fitter, Weights};
pub use self::lm::{MAX_FIT_POINTS, MIN_DECREASE};
use self::merge::Merger;
use self::ownership::assign;
use self::recheck::{binary_loss, recheck};
use self::retype::{RETYPE_AFTER_ROUNDS, Retyped, retype};
use crate::atlas::Shape;
use crate::chamfer::ChamferOptions;
use crate::spatial::PointIndex;
use crate::{Primitive, Result, check};

/// Clouds larger than this are refined on an evenly strided subset of this many points
/// (see [`refine`]); the binary chamfer before and after is still the whole cloud's.
pub const MAX_REFINE_POINTS: usize = 50_000;

/// Points probed for the median point spacing of a subsampled cloud (as the fit probes
/// the whole cloud's).
const SPACING_PROBES: usize = 2000;

/// The most refinement rounds (default 4; refinement settles in 2–4): a bound on the
/// work a round count can ask for.
pub const MAX_ROUNDS: usize = 100;
/// The most Levenberg–Marquardt iterations per primitive and round (default 6).
pub const MAX_ITERATIONS: usize = 1000;

/// Options of [`refine`].
#[derive(Debug, Clone, PartialEq)]
pub struct RefineOptions {
    /// Assignment / LM rounds.
    pub rounds: usize,
    /// LM iterations per primitive and round.
    pub iterations: usize,
    /// Points farther than this from every primitive are ignored (scene units);
    /// `None` = the fit's `cap`.
    pub trim: Option<f64>,
    /// Each size stays within `[s₀ / g, s₀ · g]` of its start `s₀` (g ≥ 1).
    pub max_growth: f64,
    /// Re-check existence with the binary chamfer after refinement.
    pub recheck: bool,
    /// Try to merge each primitive into its neighbours (see the module docs).
    pub merge: bool,
    /// Coarse to fine: fit a finer lattice where refined primitives leave points
    /// unexplained (done by [`crate::fit::fit`], see there).
    pub fill: bool,
    /// Try the other configured types in place of each primitive (see the module docs).
    pub retype: bool,
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions {
            rounds: 4,
            iterations: 6,
            trim: None,
            max_growth: 2.0,
            recheck: true,
            merge: true,
            fill: true,
            retype: true,
        }
    }
}

impl RefineOptions {
    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        check::not_below("max_growth", self.max_growth, 1.0)?;
        check::at_most("rounds", self.rounds, MAX_ROUNDS)?;
        check::at_most("iterations", self.iterations, MAX_ITERATIONS)?;
        match self.trim {
            Some(t) => check::positive("trim", t),
            None => Ok(()),
        }
    }
}

/// Output of [`refine`].
#[derive(Debug, Clone)]
pub struct Refined {
    /// The refined primitives that survived the existence re-check.
    pub primitives: Vec<Primitive>,
    /// For each survivor, its index in the input slice.
    pub source: Vec<usize>,
    /// Binary chamfer (weighted total) of the input set.
    pub loss_before: f64,
    /// Binary chamfer of the output set.
    pub loss_after: f64,
    /// Primitives removed by the re-check.
    pub dropped: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// What refinement needs from the fit: the cloud with its index and point spacing, the
/// sample spacing of candidate surfaces, the chamfer options (weights, `d_cap`, β), and
/// the lattice's types and frame (for re-typing).
pub struct RefineContext<'a> {
    /// Input points.
    pub points: &'a [Point3<f64>],
    /// kd-tree over `points`.
    pub index: &'a PointIndex,
    /// The cloud's median nearest-neighbour distance `h` (scene units): a surface sample
    /// within `h` of an input point lies on the data and costs nothing (`docs/refine.md`).
    pub point_spacing: f64,
    /// Spacing of primitive surface samples σ (scene units).
    pub sample_spacing: f64,
    /// Loss options of the fit.
    pub chamfer: &'a ChamferOptions,
    /// The fit's shapes at their configured sizes (the types re-typing may switch to).
    pub shapes: &'a [Shape],
    /// The lattice frame (lattice → scene): re-typed primitives start in its orientations.
    pub frame: UnitQuaternion<f64>,
}

/// Refines `primitives` against the cloud (see the module docs).
pub fn refine(
    ctx: &RefineContext<'_>,
    primitives: &[Primitive],
    options: &RefineOptions,
) -> Result<Refined> {
    options.validate()?;
    let start = Instant::now();
    let loss_before = binary_loss(ctx, primitives)?;
    let weights = Weights::new(ctx, primitives);
    let (refined, source, dropped) = if ctx.points.len() > MAX_REFINE_POINTS {
        refine_subsampled(ctx, &weights, primitives, options)?
    } else {
        refine_on(ctx, &weights, primitives, options)?
    };
    let loss_after = binary_loss(ctx, &refined)?;
    Ok(Refined {
        primitives: refined,
        source,
        dropped,
        loss_before,
        loss_after,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// [`refine_on`] an evenly strided subset of at most [`MAX_REFINE_POINTS`] of `ctx`'s
/// points: the point weight grows by the subsampling factor k so every cost still
/// estimates the whole cloud's, and the sample slack is the subset's point spacing.
fn refine_subsampled(
    ctx: &RefineContext<'_>,
    weights: &Weights,
    primitives: &[Primitive],
    options: &RefineOptions,
) -> Result<(Vec<Primitive>, Vec<usize>, usize)> {
    let stride = ctx.points.len().div_ceil(MAX_REFINE_POINTS);
    let points: Vec<Point3<f64>> = ctx.points.iter().step_by(stride).copied().collect();
    let index = PointIndex::new(&points);
    let k = ctx.points.len() as f64 / points.len() as f64;
    let point_spacing = index
        .median_spacing(&points, SPACING_PROBES)
        .unwrap_or(ctx.point_spacing * k.sqrt());
    let chamfer = ChamferOptions {
        point_weight: ctx.chamfer.point_weight * k,
        ..ctx.chamfer.clone()
    };
    let sub = RefineContext {
        points: &points,
        index: &index,
        point_spacing,
        sample_spacing: ctx.sample_spacing,
        chamfer: &chamfer,
        shapes: ctx.shapes,
        frame: ctx.frame,
    };
    let weights = Weights {
        point: weights.point * k,
        slack: point_spacing,
        ..*weights
    };
    refine_on(&sub, &weights, primitives, options)
}

/// Refinement proper on `ctx`'s points: rounds of assignment and LM (with re-typing),
/// the existence re-check and the merge. Returns the survivors, their indices in
/// `primitives`, and how many were removed.
fn refine_on(
    ctx: &RefineContext<'_>,
    weights: &Weights,
    primitives: &[Primitive],
    options: &RefineOptions,
) -> Result<(Vec<Primitive>, Vec<usize>, usize)> {
    let trim = options.trim.unwrap_or(ctx.chamfer.cap.sqrt());
    let mut limits: Vec<Vec<(f64, f64)>> = primitives
        .iter()
        .map(|p| p.shape.size_limits(options.max_growth))
        .collect();
    let mut current = primitives.to_vec();
    // Re-typing comes after the second round (the first when there is only one), so the
    // primitives it judges have already settled onto their points.
    let retype_after =
        (options.retype && options.rounds > 0).then(|| options.rounds.min(RETYPE_AFTER_ROUNDS) - 1);
    for round in 0..options.rounds {
        current = lm_round(ctx, weights, &current, &limits, trim, options)?;
        if retype_after == Some(round) {
            retype_round(ctx, weights, &mut current, &mut limits, trim, options)?;
        }
    }
    let keep = if options.recheck && !current.is_empty() {
        recheck(ctx, &current)?
    } else {
        vec![true; current.len()]
    };
    let mut source: Vec<usize> = (0..current.len()).filter(|&i| keep[i]).collect();
    let mut primitives: Vec<Primitive> = source.iter().map(|&i| current[i].clone()).collect();
    if options.merge {
        let lims: Vec<Vec<(f64, f64)>> = source.iter().map(|&i| limits[i].clone()).collect();
        let merged = Merger {
            ctx,
            weights,
            trim,
            iterations: options.iterations,
        }
        .run(primitives, lims)?;
        source = merged.1.iter().map(|&k| source[k]).collect();
        primitives = merged.0;
    }
    let dropped = current.len() - primitives.len();
    Ok((primitives, source, dropped))
}

/// One round: assigns the points to `current` and refines each primitive on its own.
fn lm_round(
    ctx: &RefineContext<'_>,
    weights: &Weights,
    current: &[Primitive],
    limits: &[Vec<(f64, f64)>],
    trim: f64,
    options: &RefineOptions,
) -> Result<Vec<Primitive>> {
    let groups = assign(ctx.points, current, trim, ctx.point_spacing)?;
    Ok(current
        .par_iter()
        .zip(&groups)
        .zip(limits)
        .map(|((p, group), lim)| {
            let assigned: Vec<Point3<f64>> = group.iter().map(|&j| ctx.points[j]).collect();
            Fitter::new(ctx, weights, &assigned, lim).run(p.clone(), options.iterations)
        })
        .collect())
}

/// Re-assigns the points to `current` and replaces each primitive (and its size limits)
/// that another configured type explains better ([`retype()`]).
fn retype_round(
    ctx: &RefineContext<'_>,
    weights: &Weights,
    current: &mut [Primitive],
    limits: &mut [Vec<(f64, f64)>],
    trim: f64,
    options: &RefineOptions,
) -> Result<()> {
    let groups = assign(ctx.points, current, trim, ctx.point_spacing)?;
    let switched: Vec<Option<Retyped>> = current
        .par_iter()
        .zip(&groups)
        .map(|(p, group)| {
            let assigned: Vec<Point3<f64>> = group.iter().map(|&j| ctx.points[j]).collect();
            retype(ctx, weights, p, &assigned, options)
        })
        .collect();
    for (i, q) in switched.into_iter().enumerate() {
        if let Some((q, lim)) = q {
            limits[i] = lim;
            current[i] = q;
        }
    }
    Ok(())
}
