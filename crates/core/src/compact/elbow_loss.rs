//! The loss of a trial elbow at one junction (`elbows.rs`), in the existence decision's
//! own units (`model.rs`, `mdl.rs`): each point near the corner costs its capped squared
//! distance to the model, each sample of a changed primitive (one per sample spacing)
//! its capped squared distance to the cloud, and a primitive its description length.
//!
//! Only what a cut or an elbow can change is measured: the points within reach of the
//! corner, the part of each run between its shortest and longest cut, the elbow, and the
//! small primitives lying wholly within the junction (patches that stood in for the
//! bend), which are either kept or replaced by the elbow, whichever costs less.

use std::f64::consts::TAU;

use nalgebra::Point3;
use rayon::prelude::*;

use super::elbows::{Junction, Run, Scored};
use super::mdl::primitive_cost;
use super::trim::{Cloud, Pricing};
use crate::Primitive;
use crate::spatial::{BoxTree, Hint, PointIndex};

/// The most samples a trial elbow's or a patch's primitive term is estimated from (each
/// weighted by the area it stands for, as `model.rs`'s `PRIMITIVE_TERM_SAMPLES`): a
/// bend radius is tried some forty times per junction.
const MAX_TERM_SAMPLES: f64 = 256.0;

/// The most near points whose distances a trial is measured by; more are taken with a
/// stride, each weighted by the points it stands for.
const MAX_NEAR_POINTS: usize = 20_000;

/// The most near points a junction's own box tree holds; beyond it the cloud's kd-tree
/// answers (a dense scan's junction would otherwise copy much of the cloud per thread).
const MAX_TREE_POINTS: usize = 200_000;

/// Ratio between neighbouring bend radii of the coarse grid.
const BEND_GRID_RATIO: f64 = 1.1;

/// Golden-section steps refining the best bend radius of the grid (each shrinks the
/// bracket by 0.618: 12 steps to 0.3 % of it).
const BEND_REFINE_STEPS: usize = 12;

/// What a junction's loss is measured against.
pub(super) struct Judge<'a> {
    pub cloud: Cloud<'a>,
    pub primitives: &'a [Primitive],
    pub pricing: Pricing,
    /// The sample spacing of the primitive term (scene units).
    pub spacing: f64,
}

impl Judge<'_> {
    /// The best elbow of `junction` with its gain and the patches it replaces; `None`
    /// where no bend radius fits.
    pub(super) fn best_elbow(&self, junction: Junction) -> Option<Scored> {
        let (lo, hi) = junction.bend_range()?;
        let ball = junction.reach_of_changes(hi);
        let patches: Vec<usize> = (0..self.primitives.len())
            .filter(|k| !junction.ids.contains(k))
            .filter(|&k| {
                let p = &self.primitives[k];
                (p.center() - junction.corner).norm() + p.bounding_radius() <= ball
            })
            .collect();
        let near: Vec<Point3<f64>> = (self.cloud.index)
            .within(&junction.corner, (ball + self.pricing.cap).powi(2))
            .iter()
            .map(|&(j, _)| self.cloud.points[j as usize])
            .collect();
        let local = Local::new(self, &junction, hi, &near, patches);
        let loss = |bend: f64| local.loss(self, &junction, bend);
        let bend = best_on_grid(lo, hi, &|b| loss(b).0);
        let (after, replace) = loss(bend);
        Some(Scored {
            gain: local.before - after,
            bend,
            replaced: if replace { local.patches } else { Vec::new() },
            junction,
        })
    }

    fn cost(&self, primitive: &Primitive) -> f64 {
        primitive_cost(primitive, self.pricing.noise, self.cloud.points.len())
    }
}

/// Nearest-point distances for samples within a junction's ball: a box tree of the near
/// points (a trial elbow's samples beside the data are settled after a few tight boxes,
/// where a kd-tree query opens many leaves, `spatial/box_tree.rs`), or the cloud's
/// kd-tree where the near points are too many to copy.
struct NearTree<'a> {
    tree: Option<BoxTree>,
    index: &'a PointIndex,
    cap: f64,
    spacing: f64,
}

impl NearTree<'_> {
    /// `weight` × Σ over `samples` of `min(d², cap²)`, `d` the distance to the cloud:
    /// the primitive term of samples within the junction's ball, where every point
    /// within `cap` of them is near.
    fn term(&self, samples: impl Iterator<Item = Point3<f64>>, weight: f64) -> f64 {
        let mut hint = Hint::default();
        let cap2 = self.cap * self.cap;
        let mut d2 = |x: &Point3<f64>| match &self.tree {
            Some(tree) => tree.nearest(x, &mut hint),
            None => self.index.nearest(x).map_or(cap2, |(_, d2)| d2),
        };
        weight * samples.map(|x| d2(&x).min(cap2)).sum::<f64>()
    }

    /// The primitive term of `primitive` (within the junction's ball), from at most
    /// [`MAX_TERM_SAMPLES`] samples each weighted by the area it stands for.
    fn primitive_term(&self, primitive: &Primitive) -> f64 {
        let coarse = (self.spacing).max((primitive.area() / MAX_TERM_SAMPLES).sqrt());
        let weight = (coarse / self.spacing).powi(2);
        self.term(primitive.sample_surface(coarse).into_iter(), weight)
    }
}

/// The loss terms near one junction that do not depend on the bend radius.
struct Local<'a> {
    tree: NearTree<'a>,
    /// The near points the point term is measured on, each standing for `point_share`
    /// near points.
    points: Vec<Point3<f64>>,
    point_share: f64,
    /// Each measured point's distance (capped) to the primitives other than the runs
    /// and the patches, and to the patches.
    other: Vec<f64>,
    patch: Vec<f64>,
    patches: Vec<usize>,
    /// Each run's primitive term where a cut can change it.
    rings: [Rings; 2],
    /// The patches' primitive terms and description lengths.
    patch_price: f64,
    /// The loss before any change.
    before: f64,
}

impl<'a> Local<'a> {
    /// The terms of `junction` for bend radii up to `bend_hi`, measured over the `near`
    /// points, with `patches` (model indices) to keep or replace.
    fn new(
        judge: &Judge<'a>,
        junction: &Junction,
        bend_hi: f64,
        near: &[Point3<f64>],
        patches: Vec<usize>,
    ) -> Self {
        let cap = judge.pricing.cap;
        let prims = judge.primitives;
        let stride = near.len().div_ceil(MAX_NEAR_POINTS).max(1);
        let points: Vec<Point3<f64>> = near.iter().step_by(stride).copied().collect();
        let point_share = near.len() as f64 / points.len().max(1) as f64;
        let nearest = |ids: &[usize], y: &Point3<f64>| {
            (ids.iter().map(|&k| prims[k].distance(y))).fold(cap, f64::min)
        };
        let rest: Vec<usize> = (0..prims.len())
            .filter(|k| !junction.ids.contains(k) && !patches.contains(k))
            .collect();
        let (other, patch): (Vec<f64>, Vec<f64>) = (points.par_iter())
            .map(|y| (nearest(&rest, y), nearest(&patches, y)))
            .unzip();
        let tree = NearTree {
            tree: (near.len() <= MAX_TREE_POINTS).then(|| BoxTree::new(near)),
            index: judge.cloud.index,
            cap,
            spacing: judge.spacing,
        };
        // A cut leaves a run shorter than `reach − bend_hi` from its far end unchanged.
        let rings = [0, 1].map(|k| {
            let old = 2.0 * junction.runs[k].half;
            let from = old.min(junction.reach[k] - bend_hi).max(0.0);
            Rings::new(junction, k, from, &tree)
        });
        let patch_price: f64 = (patches.iter())
            .map(|&k| tree.primitive_term(&prims[k]) + judge.cost(&prims[k]))
            .sum();
        let old_runs = junction.ids.map(|id| &prims[id]);
        let point_term: f64 = (points.iter().zip(other.iter().zip(&patch)))
            .map(|(y, (&o, &p))| {
                let d = (old_runs.iter().map(|r| r.distance(y))).fold(o.min(p), f64::min);
                d * d
            })
            .sum();
        let run_terms: f64 = (0..2)
            .map(|k| rings[k].at(2.0 * junction.runs[k].half))
            .sum();
        let w = judge.pricing.point_weight * point_share;
        Local {
            before: w * point_term + run_terms + patch_price,
            tree,
            points,
            point_share,
            other,
            patch,
            patches,
            rings,
            patch_price,
        }
    }

    /// The loss with the elbow of bend radius `bend` and the runs cut to meet it, the
    /// patches kept or replaced (whichever is lower), and whether they are replaced.
    fn loss(&self, judge: &Judge, junction: &Junction, bend: f64) -> (f64, bool) {
        let elbow = junction.elbow(bend);
        let runs = [0, 1].map(|k| junction.cut_run(k, bend));
        // Per point in parallel, summed in order: the same loss on any number of threads.
        let terms: Vec<(f64, f64)> = (self.points.par_iter())
            .zip(self.other.par_iter().zip(&self.patch))
            .map(|(y, (&o, &p))| {
                let to_elbow = elbow.distance(y).min(o);
                let d = (runs.iter().map(|r| r.distance(y))).fold(to_elbow, f64::min);
                (d.min(p).powi(2), d * d)
            })
            .collect();
        let (kept, replaced) = terms.iter().fold((0.0, 0.0), |s, t| (s.0 + t.0, s.1 + t.1));
        let run_terms: f64 = (0..2)
            .map(|k| self.rings[k].at(junction.reach[k] - bend))
            .sum();
        let fixed = run_terms + self.tree.primitive_term(&elbow) + judge.cost(&elbow);
        let w = judge.pricing.point_weight * self.point_share;
        let (keep, replace) = (w * kept + self.patch_price, w * replaced);
        (fixed + keep.min(replace), replace < keep)
    }
}

/// The primitive term of one run of a junction over the part of it that a cut can
/// change: rings of samples, one a sample spacing, from `from` (length from the far end)
/// to one tube radius past the corner, as prefix sums. What lies before `from` is the
/// same before and after a cut, and is left out of both.
struct Rings {
    from: f64,
    spacing: f64,
    /// `prefix[i]`: the term of the first `i` rings.
    prefix: Vec<f64>,
}

impl Rings {
    /// The rings of run `k` of `junction` from `from`, measured in `tree`.
    fn new(junction: &Junction, k: usize, from: f64, tree: &NearTree) -> Self {
        let (run, s): (&Run, f64) = (&junction.runs[k], tree.spacing);
        let towards = run.axis * junction.ends[k];
        let far = run.centre - towards * run.half;
        let (u, v) = crate::detect::perpendicular_basis(&towards);
        let around = ((TAU * run.radius / s).round() as usize).max(3);
        let rings = ((junction.reach[k] + run.radius - from) / s)
            .ceil()
            .max(1.0) as usize;
        let ring: Vec<_> = (0..around)
            .map(|m| {
                let phi = TAU * m as f64 / around as f64;
                (u * phi.cos() + v * phi.sin()) * run.radius
            })
            .collect();
        let terms: Vec<f64> = (0..rings)
            .into_par_iter()
            .map(|i| {
                let c = far + towards * (from + (i as f64 + 0.5) * s);
                tree.term(ring.iter().map(|x| c + x), 1.0)
            })
            .collect();
        let mut prefix = Vec::with_capacity(rings + 1);
        prefix.push(0.0);
        for t in terms {
            prefix.push(prefix.last().copied().unwrap_or(0.0) + t);
        }
        Rings {
            from,
            spacing: s,
            prefix,
        }
    }

    /// The term of the run when it is `length` long from its far end (interpolated
    /// within a ring).
    fn at(&self, length: f64) -> f64 {
        let p = &self.prefix;
        let x = ((length - self.from) / self.spacing).clamp(0.0, (p.len() - 1) as f64);
        let i = (x.floor() as usize).min(p.len() - 2);
        p[i] + (x - i as f64) * (p[i + 1] - p[i])
    }
}

/// The minimiser of `loss` over a geometric grid on `[lo, hi]` ([`BEND_GRID_RATIO`]),
/// refined by golden section between the best point's neighbours.
fn best_on_grid(lo: f64, hi: f64, loss: &impl Fn(f64) -> f64) -> f64 {
    let steps = ((hi / lo).ln() / BEND_GRID_RATIO.ln()).ceil().max(1.0) as usize;
    let grid: Vec<f64> = (0..=steps)
        .map(|i| lo * (hi / lo).powf(i as f64 / steps as f64))
        .collect();
    let values: Vec<f64> = grid.iter().map(|&b| loss(b)).collect();
    let best = (0..grid.len())
        .min_by(|&a, &b| values[a].total_cmp(&values[b]))
        .unwrap_or(0);
    let (mut a, mut b) = (grid[best.saturating_sub(1)], grid[(best + 1).min(steps)]);
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (b - phi * (b - a), a + phi * (b - a));
    let (mut f1, mut f2) = (loss(x1), loss(x2));
    let (mut best_x, mut best_f) = (grid[best], values[best]);
    for _ in 0..BEND_REFINE_STEPS {
        for (x, f) in [(x1, f1), (x2, f2)] {
            if f < best_f {
                (best_x, best_f) = (x, f);
            }
        }
        // Keep the bracket around the lower of the two; one new evaluation a step.
        if f1 < f2 {
            (b, x2, f2) = (x2, x1, f1);
            x1 = b - phi * (b - a);
            f1 = loss(x1);
        } else {
            (a, x1, f1) = (x1, x2, f2);
            x2 = a + phi * (b - a);
            f2 = loss(x2);
        }
    }
    for (x, f) in [(x1, f1), (x2, f2)] {
        if f < best_f {
            best_x = x;
            best_f = f;
        }
    }
    best_x
}
