//! The loss of a trial elbow at one junction (`elbows.rs`): a swap (`swap.rs`) of the
//! junction's two runs for the elbow and the runs cut to meet it, with the small
//! primitives lying wholly within the junction (patches that stood in for the bend) kept
//! or replaced.
//!
//! Only what a cut or an elbow can change is measured: the points within reach of the
//! corner, the part of each run between its shortest and longest cut (as rings of
//! samples, so that each bend radius tried costs a lookup), and the elbow.

use std::f64::consts::TAU;

use nalgebra::Point3;
use rayon::prelude::*;

use super::elbows::{Junction, Run, Scored};
use super::mdl::primitive_cost;
use super::swap::{NearTree, SwapLoss, strided};
use super::trim::{Cloud, Pricing};
use crate::Primitive;

/// The most near points whose distances a trial is measured by; more are taken with a
/// stride, each weighted by the points it stands for.
const MAX_NEAR_POINTS: usize = 20_000;

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
        let local = Local::new(self, &junction, hi, &near, &patches);
        let loss = |bend: f64| local.loss(self, &junction, bend);
        let bend = best_on_grid(lo, hi, &|b| loss(b).0);
        let (after, replace) = loss(bend);
        Some(Scored {
            gain: local.before - after,
            bend,
            replaced: if replace { patches } else { Vec::new() },
            junction,
        })
    }

    fn cost(&self, primitive: &Primitive) -> f64 {
        primitive_cost(primitive, self.pricing.noise, self.cloud.points.len())
    }
}

/// The loss terms near one junction that do not depend on the bend radius.
struct Local<'a> {
    tree: NearTree<'a>,
    swap: SwapLoss,
    /// Each run's primitive term where a cut can change it.
    rings: [Rings; 2],
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
        patches: &[usize],
    ) -> Self {
        let (prims, cap) = (judge.primitives, judge.pricing.cap);
        let tree = NearTree::of_near(near, judge.cloud.index, cap, judge.spacing);
        let stay: Vec<&Primitive> = (0..prims.len())
            .filter(|k| !junction.ids.contains(k) && !patches.contains(k))
            .map(|k| &prims[k])
            .collect();
        let patches: Vec<&Primitive> = patches.iter().map(|&k| &prims[k]).collect();
        let patch_price: f64 = (patches.iter())
            .map(|p| tree.sampled_term(p) + judge.cost(p))
            .sum();
        let (points, share) = strided(near, MAX_NEAR_POINTS);
        let swap = SwapLoss::new(points, share, &stay, &patches, patch_price, judge.pricing);
        // A cut leaves a run shorter than `reach − bend_hi` from its far end unchanged.
        let rings = [0, 1].map(|k| {
            let old = 2.0 * junction.runs[k].half;
            let from = old.min(junction.reach[k] - bend_hi).max(0.0);
            Rings::new(junction, k, from, &tree)
        });
        let run_terms: f64 = (0..2)
            .map(|k| rings[k].at(2.0 * junction.runs[k].half))
            .sum();
        let old_runs = junction.ids.map(|id| &prims[id]);
        Local {
            before: swap.point_cost(&old_runs).keep + run_terms,
            tree,
            swap,
            rings,
        }
    }

    /// The loss with the elbow of bend radius `bend` and the runs cut to meet it, the
    /// patches kept or replaced (whichever is lower), and whether they are replaced.
    fn loss(&self, judge: &Judge, junction: &Junction, bend: f64) -> (f64, bool) {
        let elbow = junction.elbow(bend);
        let runs = [0, 1].map(|k| junction.cut_run(k, bend));
        let (points, replace) = (self.swap).point_cost(&[&elbow, &runs[0], &runs[1]]).best();
        let run_terms: f64 = (0..2)
            .map(|k| self.rings[k].at(junction.reach[k] - bend))
            .sum();
        let fixed = run_terms + self.tree.sampled_term(&elbow) + judge.cost(&elbow);
        (fixed + points, replace)
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
fn best_on_grid(lo: f64, hi: f64, loss: &(impl Fn(f64) -> f64 + Sync)) -> f64 {
    let steps = ((hi / lo).ln() / BEND_GRID_RATIO.ln()).ceil().max(1.0) as usize;
    let grid: Vec<f64> = (0..=steps)
        .map(|i| lo * (hi / lo).powf(i as f64 / steps as f64))
        .collect();
    // The grid's values side by side: each is a short pass over the near points, too
    // short to share among threads on its own.
    let values: Vec<f64> = grid.par_iter().map(|&b| loss(b)).collect();
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
