//! Merging: removing a primitive that is only partly redundant.
//!
//! A primitive that its neighbours could cover (a third cylinder overlapping two that
//! tile a run, a cylinder reaching into an elbow) survives the existence re-check,
//! because its neighbours were refined with its points taken. So each primitive, fewest
//! points first, is tried for removal *with* its neighbours (the primitives that would
//! own its points) re-refined on the points they would then own; the removal is kept
//! when the local chamfer ([`Merger::local_cost`]: the points of the primitive and of its
//! neighbours, each at `min(d², d_cap)`, plus the squared distances to the cloud of the
//! samples of all primitives involved, with the refinement's balance but no dead zone)
//! does not increase. Without the dead zone a neighbour grown over the removed
//! primitive's points pays for its larger area, so a merge must lower the chamfer
//! (`docs/refine.md`, *Merging*).

use nalgebra::Point3;
use rayon::prelude::*;

use super::RefineContext;
use super::lm::{Fitter, Weights};
use super::ownership::{owners, owners_of};
use crate::spatial::PrimitiveIndex;
use crate::{Primitive, Result};

/// Assignment rounds when neighbours are re-refined in a merge trial.
const MERGE_ROUNDS: usize = 3;

/// A neighbour re-refined in a merge trial gets this many times the refinement's LM
/// iterations per round: it has to grow over the removed primitive's points, a larger
/// move than a refinement round's.
const MERGE_ITERATION_FACTOR: usize = 2;

/// A model as `(index in the merge input, primitive)` pairs, and the region (point
/// indices) whose owners a merge changed.
type Alive = (Vec<(usize, Primitive)>, Vec<usize>);

/// The merge pass of the module docs.
pub(super) struct Merger<'a> {
    pub(super) ctx: &'a RefineContext<'a>,
    pub(super) weights: &'a Weights,
    /// Trim distance of the ownership rule (scene units).
    pub(super) trim: f64,
    /// LM iterations per refinement round.
    pub(super) iterations: usize,
}

impl Merger<'_> {
    /// Tries every primitive once, fewest points first; returns the survivors and their
    /// indices in `prims`.
    pub(super) fn run(
        &self,
        prims: Vec<Primitive>,
        limits: Vec<Vec<(f64, f64)>>,
    ) -> Result<(Vec<Primitive>, Vec<usize>)> {
        let mut owner = owners(self.ctx.points, &prims, self.trim, self.ctx.point_spacing)?;
        let mut count = vec![0usize; prims.len()];
        for o in owner.iter().flatten() {
            count[*o] += 1;
        }
        let mut order: Vec<usize> = (0..prims.len()).collect();
        order.sort_by_key(|&i| (count[i], i));
        let mut alive: Vec<(usize, Primitive)> = prims.into_iter().enumerate().collect();
        for id in order {
            let Some(pos) = alive.iter().position(|a| a.0 == id) else {
                continue;
            };
            if let Some((next, region)) = self.try_remove(&alive, &owner, pos, &limits)? {
                alive = next;
                self.update_owners(&mut owner, pos, &alive, &region)?;
            }
        }
        Ok(alive.into_iter().map(|(k, p)| (p, k)).unzip())
    }

    /// After `alive[pos]` was removed: only the region's owners change (up to points of
    /// third primitives that a moved neighbour now passes closer to); the rest shift
    /// their index.
    fn update_owners(
        &self,
        owner: &mut [Option<usize>],
        pos: usize,
        alive: &[(usize, Primitive)],
        region: &[usize],
    ) -> Result<()> {
        for o in owner.iter_mut().flatten() {
            if *o > pos {
                *o -= 1;
            }
        }
        let model: Vec<Primitive> = alive.iter().map(|a| a.1.clone()).collect();
        let fresh = owners_of(
            self.ctx.points,
            region,
            &model,
            self.trim,
            self.ctx.point_spacing,
        )?;
        for (&j, o) in region.iter().zip(fresh) {
            owner[j] = o;
        }
        Ok(())
    }

    /// The model without `alive[pos]` and with its neighbours re-refined, if that does not
    /// raise the local chamfer.
    fn try_remove(
        &self,
        alive: &[(usize, Primitive)],
        owners: &[Option<usize>],
        pos: usize,
        limits: &[Vec<(f64, f64)>],
    ) -> Result<Option<Alive>> {
        let model: Vec<Primitive> = alive.iter().map(|a| a.1.clone()).collect();
        let mut rest: Vec<(usize, Primitive)> = alive.to_vec();
        rest.remove(pos);
        let (neighbours, region) = self.neighbourhood(&rest, owners, pos)?;
        let before = self.local_cost(
            &region,
            &model,
            std::iter::once(pos)
                .chain(neighbours.iter().map(|&k| if k >= pos { k + 1 } else { k })),
        )?;
        let trial = self.refit_neighbours(rest, &neighbours, &region, limits)?;
        let trial_model: Vec<Primitive> = trial.iter().map(|a| a.1.clone()).collect();
        let after = self.local_cost(&region, &trial_model, neighbours.iter().copied())?;
        Ok((after <= before).then_some((trial, region)))
    }

    /// The neighbours of `alive[pos]` (indices in `rest`, the model without it: the
    /// primitives that would own its points) and the region (the removed primitive's
    /// points and its neighbours' points, sorted).
    fn neighbourhood(
        &self,
        rest: &[(usize, Primitive)],
        owners: &[Option<usize>],
        pos: usize,
    ) -> Result<(Vec<usize>, Vec<usize>)> {
        let mine: Vec<usize> = (0..owners.len())
            .filter(|&j| owners[j] == Some(pos))
            .collect();
        let rest_model: Vec<Primitive> = rest.iter().map(|a| a.1.clone()).collect();
        let heirs = owners_of(
            self.ctx.points,
            &mine,
            &rest_model,
            self.trim,
            self.ctx.point_spacing,
        )?;
        let mut neighbours: Vec<usize> = heirs.iter().flatten().copied().collect();
        neighbours.sort_unstable();
        neighbours.dedup();
        let region = region_of(mine, owners, pos, &neighbours);
        Ok((neighbours, region))
    }

    /// Re-refines the `neighbours` in `trial` on the region points each owns without the
    /// removed primitive, re-assigning the region between rounds.
    fn refit_neighbours(
        &self,
        mut trial: Vec<(usize, Primitive)>,
        neighbours: &[usize],
        region: &[usize],
        limits: &[Vec<(f64, f64)>],
    ) -> Result<Vec<(usize, Primitive)>> {
        for _ in 0..MERGE_ROUNDS {
            let model: Vec<Primitive> = trial.iter().map(|a| a.1.clone()).collect();
            let region_owner = owners_of(
                self.ctx.points,
                region,
                &model,
                self.trim,
                self.ctx.point_spacing,
            )?;
            let refitted: Vec<Primitive> = neighbours
                .par_iter()
                .map(|&k| {
                    let pts: Vec<Point3<f64>> = region
                        .iter()
                        .zip(&region_owner)
                        .filter(|(_, o)| **o == Some(k))
                        .map(|(&j, _)| self.ctx.points[j])
                        .collect();
                    let lim = &limits[trial[k].0];
                    Fitter::new(self.ctx, self.weights, &pts, lim)
                        .run(trial[k].1.clone(), MERGE_ITERATION_FACTOR * self.iterations)
                })
                .collect();
            for (&k, p) in neighbours.iter().zip(refitted) {
                trial[k].1 = p;
            }
        }
        Ok(trial)
    }

    /// `w_point Σ_{j ∈ region} min(d(y_j, model)², d_cap) + w_s Σ_{i ∈ sampled} Σ_x d(x, D)²`
    /// (`w_s` of [`Weights`], no dead zone: see the module docs).
    fn local_cost(
        &self,
        region: &[usize],
        model: &[Primitive],
        sampled: impl Iterator<Item = usize>,
    ) -> Result<f64> {
        let chamfer = self.ctx.chamfer;
        let mut cost = 0.0;
        if !model.is_empty() {
            let index = PrimitiveIndex::new(model)?;
            cost += chamfer.point_weight
                * region
                    .par_iter()
                    .map(|&j| {
                        let d = index
                            .nearest(&self.ctx.points[j])
                            .map_or(f64::INFINITY, |r| r.1);
                        (d * d).min(chamfer.cap)
                    })
                    .sum::<f64>();
        } else {
            cost += chamfer.point_weight * chamfer.cap * region.len() as f64;
        }
        for i in sampled {
            let p = &model[i];
            cost += self.weights.sample
                * p.sample_surface(self.ctx.sample_spacing)
                    .iter()
                    .filter_map(|x| self.ctx.index.nearest(x))
                    .map(|(_, d2)| d2)
                    .sum::<f64>();
        }
        Ok(cost)
    }
}

/// The removed primitive's points `mine` followed by the points whose owner (index in
/// the model with `pos`) is one of the `neighbours` (indices in the model without it),
/// sorted.
fn region_of(
    mine: Vec<usize>,
    owners: &[Option<usize>],
    pos: usize,
    neighbours: &[usize],
) -> Vec<usize> {
    let mut region = mine;
    for (j, o) in owners.iter().enumerate() {
        if let Some(o) = o {
            let k = if *o > pos {
                o - 1
            } else if *o == pos {
                continue;
            } else {
                *o
            };
            if neighbours.binary_search(&k).is_ok() {
                region.push(j);
            }
        }
    }
    region.sort_unstable();
    region
}
