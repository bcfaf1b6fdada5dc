//! Re-typing: trying the other configured types in place of a primitive.
//!
//! LM cannot change a type, and a misaligned lattice often explains a straight run of
//! pipe with elbows (short arcs fit pieces of a run better than cylinders at the wrong
//! lattice positions). So once, after [`RETYPE_AFTER_ROUNDS`] refinement rounds, every
//! primitive is compared with each other configured type: the configured shape in each
//! lattice orientation ([`orientations`] in the lattice frame), centred on the centroid
//! of the primitive's points and refined on them; the best replaces the primitive when
//! its refinement cost is lower (`docs/refine.md`, *Re-typing*).

use nalgebra::{Point3, Vector3};

use super::lm::{Fitter, MIN_FIT_POINTS, Weights};
use super::{RefineContext, RefineOptions};
use crate::atlas::{Shape, ShapeKind};
use crate::lattice::orientations;
use crate::{Pose, Primitive};

/// Re-typing runs after this many refinement rounds (or after the last, when there are
/// fewer), so the primitives it judges have already settled onto their points.
pub(super) const RETYPE_AFTER_ROUNDS: usize = 2;

/// A re-typed primitive and its size limits.
pub(super) type Retyped = (Primitive, Vec<(f64, f64)>);

/// The best primitive of another configured type for the points `assigned` to `p`, with
/// its size limits (from the configured size), if it explains them at a lower refinement
/// cost than `p` (see the module docs).
pub(super) fn retype(
    ctx: &RefineContext<'_>,
    weights: &Weights,
    p: &Primitive,
    assigned: &[Point3<f64>],
    options: &RefineOptions,
) -> Option<Retyped> {
    if assigned.len() < MIN_FIT_POINTS {
        return None;
    }
    let kind = p.shape.kind();
    let others: Vec<&Shape> = ctx
        .shapes
        .iter()
        .filter(|s| s.kind() != kind && !matches!(s.kind(), ShapeKind::Mesh | ShapeKind::Plane))
        .collect();
    if others.is_empty() {
        return None;
    }
    let centroid = assigned.iter().map(|y| y.coords).sum::<Vector3<f64>>() / assigned.len() as f64;
    let no_limits: [(f64, f64); 0] = [];
    let mut best = (
        Fitter::new(ctx, weights, assigned, &no_limits).cost(p),
        None,
    );
    for shape in others {
        let samples = shape.sample_surface(ctx.sample_spacing);
        if samples.is_empty() {
            continue;
        }
        let local = samples.iter().map(|x| x.coords).sum::<Vector3<f64>>() / samples.len() as f64;
        let limits = shape.size_limits(options.max_growth);
        let fitter = Fitter::new(ctx, weights, assigned, &limits);
        for r in orientations(shape.kind()) {
            let rotation = ctx.frame * r;
            let start = Primitive::new(
                shape.clone(),
                Pose::new(rotation, centroid - rotation * local),
            );
            let q = fitter.run(start, options.iterations);
            let cost = fitter.cost(&q);
            if cost < best.0 {
                best = (cost, Some((q, limits.clone())));
            }
        }
    }
    best.1
}
