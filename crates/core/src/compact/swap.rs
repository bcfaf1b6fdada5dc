//! The loss of swapping a few primitives of the model for others, measured where they
//! change it: the one evaluator behind the collinear merge (`collinear.rs`) and the
//! elbows (`elbow_loss.rs`), in the existence decision's own units (`model.rs`,
//! `mdl.rs`).
//!
//! A swap replaces some primitives (`old`) by others (`new`). Small primitives lying
//! where the new ones reach (`patches`: strips or planes that stood in for a run or a
//! bend) are either kept or replaced too, whichever costs less. Only what changes is
//! measured:
//! - **points** within the cap of a changed primitive pay their capped squared distance
//!   to the model (`w · min(d, cap)²`);
//! - **changed primitives** pay their samples' capped squared distances to the cloud
//!   (one sample per sample spacing) and their description length.
//!
//! [`SwapLoss`] holds each near point's distance to the primitives that stay, so that
//! trying many `new` (an elbow's bend radii) costs one distance per point and primitive.

use nalgebra::Point3;
use rayon::prelude::*;

use super::trim::Pricing;
use crate::Primitive;
use crate::spatial::{BoxTree, Hint, PointIndex};

/// The most samples a sampled primitive term is estimated from (each weighted by the
/// area it stands for, as `model.rs`'s `PRIMITIVE_TERM_SAMPLES`): an elbow's bend radius
/// is tried some forty times per junction.
const MAX_TERM_SAMPLES: f64 = 256.0;

/// The most near points a [`NearTree`] copies into its own box tree; beyond it the
/// cloud's kd-tree answers (a dense scan's junction would otherwise copy much of the
/// cloud per thread).
const MAX_TREE_POINTS: usize = 200_000;

/// Nearest-point distances for samples of primitives near a swap: a box tree of the near
/// points (samples beside the data are settled after a few tight boxes, where a kd-tree
/// query opens many leaves, `spatial/box_tree.rs`), or the cloud's kd-tree.
pub(super) struct NearTree<'a> {
    tree: Option<BoxTree>,
    index: &'a PointIndex,
    cap: f64,
    /// The sample spacing of the primitive term (scene units).
    pub spacing: f64,
}

impl<'a> NearTree<'a> {
    /// A box tree of `near` (every point within `cap` of the samples to be measured)
    /// where they are at most [`MAX_TREE_POINTS`], else the cloud's `index`.
    pub fn of_near(near: &[Point3<f64>], index: &'a PointIndex, cap: f64, spacing: f64) -> Self {
        NearTree {
            tree: (near.len() <= MAX_TREE_POINTS).then(|| BoxTree::new(near)),
            index,
            cap,
            spacing,
        }
    }

    /// The cloud's `index` itself.
    pub fn of_cloud(index: &'a PointIndex, cap: f64, spacing: f64) -> Self {
        NearTree {
            tree: None,
            index,
            cap,
            spacing,
        }
    }

    /// `weight` × Σ over `samples` of `min(d², cap²)`, `d` the distance to the cloud.
    pub fn term(&self, samples: impl Iterator<Item = Point3<f64>>, weight: f64) -> f64 {
        let mut hint = Hint::default();
        let cap2 = self.cap * self.cap;
        let mut d2 = |x: &Point3<f64>| match &self.tree {
            Some(tree) => tree.nearest(x, &mut hint),
            None => self.index.nearest(x).map_or(cap2, |(_, d2)| d2),
        };
        weight * samples.map(|x| d2(&x).min(cap2)).sum::<f64>()
    }

    /// The primitive term of `primitive`, one sample per sample spacing.
    pub fn exact_term(&self, primitive: &Primitive) -> f64 {
        let samples = primitive.sample_surface(self.spacing);
        self.term(samples.into_iter(), 1.0)
    }

    /// The primitive term of `primitive`, from at most [`MAX_TERM_SAMPLES`] samples each
    /// weighted by the area it stands for.
    pub fn sampled_term(&self, primitive: &Primitive) -> f64 {
        let coarse = (self.spacing).max((primitive.area() / MAX_TERM_SAMPLES).sqrt());
        let weight = (coarse / self.spacing).powi(2);
        self.term(primitive.sample_surface(coarse).into_iter(), weight)
    }
}

/// The point term of a swap and the price of its patches, for any `new`.
pub(super) struct SwapLoss {
    /// The near points measured, each standing for `share` near points.
    points: Vec<Point3<f64>>,
    share: f64,
    /// Each point's distance (capped) to the primitives that stay, and to the patches.
    stay: Vec<f64>,
    patch: Vec<f64>,
    /// The patches' primitive terms and description lengths.
    patch_price: f64,
    point_weight: f64,
}

/// A swap's cost with its patches kept and with them replaced (loss units), for the
/// primitives it adds; the patches' price is in the first.
#[derive(Debug, Clone, Copy)]
pub(super) struct PatchChoice {
    pub keep: f64,
    pub replace: f64,
}

impl PatchChoice {
    /// The lower cost, and whether it replaces the patches.
    pub fn best(self) -> (f64, bool) {
        (self.keep.min(self.replace), self.replace < self.keep)
    }
}

impl SwapLoss {
    /// The swap measured over `points` (each standing for `share` near points), with
    /// `stay` the primitives that stay and `patches` those kept or replaced, priced
    /// `patch_price` in all.
    pub fn new(
        points: Vec<Point3<f64>>,
        share: f64,
        stay: &[&Primitive],
        patches: &[&Primitive],
        patch_price: f64,
        pricing: Pricing,
    ) -> Self {
        let cap = pricing.cap;
        let nearest = |to: &[&Primitive], y: &Point3<f64>| {
            (to.iter().map(|p| p.distance(y))).fold(cap, f64::min)
        };
        let (stay, patch): (Vec<f64>, Vec<f64>) = (points.par_iter())
            .map(|y| (nearest(stay, y), nearest(patches, y)))
            .unzip();
        SwapLoss {
            points,
            share,
            stay,
            patch,
            patch_price,
            point_weight: pricing.point_weight,
        }
    }

    /// The point term with `with` added to the primitives that stay, with the patches
    /// kept (their price included) and replaced. `with` = the old primitives gives the
    /// loss before the swap ([`PatchChoice::keep`]).
    pub fn point_cost(&self, with: &[&Primitive]) -> PatchChoice {
        // Per point in parallel, summed in order: the same cost on any number of threads.
        let terms: Vec<(f64, f64)> = (self.points.par_iter())
            .zip(self.stay.par_iter().zip(&self.patch))
            .map(|(y, (&stay, &patch))| {
                let d = (with.iter().map(|p| p.distance(y))).fold(stay, f64::min);
                (d.min(patch).powi(2), d * d)
            })
            .collect();
        let (kept, replaced) = terms.iter().fold((0.0, 0.0), |s, t| (s.0 + t.0, s.1 + t.1));
        let w = self.point_weight * self.share;
        PatchChoice {
            keep: w * kept + self.patch_price,
            replace: w * replaced,
        }
    }
}

/// At most `max` of `near`, taken with a stride, and how many near points each stands for.
pub(super) fn strided(near: &[Point3<f64>], max: usize) -> (Vec<Point3<f64>>, f64) {
    let stride = near.len().div_ceil(max).max(1);
    let points: Vec<Point3<f64>> = near.iter().step_by(stride).copied().collect();
    let share = near.len() as f64 / points.len().max(1) as f64;
    (points, share)
}
