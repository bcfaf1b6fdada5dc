//! Free space as evidence for the chamfer fit: a candidate that rays cross in front of
//! their measured points pays for every such ray.
//!
//! A ray from sensor `o` to its point `y` at range `z` says that nothing lies between
//! `o` and `y`. A candidate `S_i` whose first crossing with the ray is at depth `μ < z`
//! would have hidden `y`; the ray then charges it
//!
//! ```text
//! c_ij = min(d(y_j, S_i)², d_cap)
//! ```
//!
//! the squared distance from the point to the crossed surface, capped at the chamfer's
//! cost of an unexplained point. A point on (or within noise of) the surface it sits
//! behind costs nothing; a point far behind a surface costs as much as a point that
//! nothing explains. The term of the loss is
//!
//! ```text
//! F(p) = Σ_i p_i f_i,   f_i = Σ_j c_ij,   ∂F/∂p_i = f_i
//! ```
//!
//! the expected free-space cost under independent existences: linear in `p`, like the
//! chamfer's primitive term (thesis eq. 6.1), so it is added to the primitive
//! coefficients and the solver, the polish and the dominance test run unchanged (a
//! dominated candidate stays dominated: `f_i ≥ 0` only raises its cost). Each crossing
//! counts once per candidate, so two surfaces in front of one point are both charged.
//!
//! The crossings are found with the per-frame [`RayTree`]s of the ray likelihood. Above
//! [`MAX_FREE_SPACE_RAYS`] rays, an even stride of them is used and the costs scaled by
//! `rays / used`. Units: lengths in scene units, costs in squared scene units.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::raytree::{RayTree, Rays};
use crate::{Primitive, Result, check};

/// Rays used at most to build the free-space costs (an even stride of larger scans, the
/// costs scaled up to all rays): each costs one bounding-cone test and one exact crossing
/// per nearby candidate.
pub const MAX_FREE_SPACE_RAYS: usize = 200_000;

/// The free-space cost of every candidate: `f_i = Σ_j min(d(y_j, S_i)², d_cap)` over the
/// rays `j` that cross `S_i` before their point (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct FreeSpace {
    /// `f_i` of each candidate (squared scene units, ≥ 0), in the candidates' order.
    pub cost: Vec<f64>,
    /// The number of rays that cross each candidate in front of their points (of the
    /// rays used, unscaled).
    pub crossings: Vec<usize>,
    /// Rays used (after the stride).
    pub rays_used: usize,
    /// `rays / rays_used`: the factor already applied to `cost`.
    pub scale: f64,
}

impl FreeSpace {
    /// The costs of `candidates` under the rays of `rays`; `d_cap` is the chamfer's cost
    /// of an unexplained point (squared scene units, ≥ 0). Deterministic whatever the
    /// thread count: each candidate's sum runs over its rays in ascending order.
    pub fn build(rays: &Rays, candidates: &[Primitive], d_cap: f64) -> Result<FreeSpace> {
        check::non_negative("cap", d_cap)?;
        for (i, c) in candidates.iter().enumerate() {
            c.shape.validate().map_err(|e| e.in_item("candidate", i))?;
        }
        let stride = rays.len().div_ceil(MAX_FREE_SPACE_RAYS).max(1);
        let trees: Vec<RayTree> = rays
            .by_frame()
            .into_iter()
            .enumerate()
            .map(|(f, ids)| {
                let used = ids
                    .into_iter()
                    .filter(|j| (*j as usize).is_multiple_of(stride));
                RayTree::new(rays.frames[f], rays, used.collect())
            })
            .collect();
        let rays_used = rays.len().div_ceil(stride);
        let scale = rays.len() as f64 / rays_used.max(1) as f64;
        let (cost, crossings): (Vec<f64>, Vec<usize>) = candidates
            .par_iter()
            .map(|c| candidate_cost(c, &trees, rays, d_cap))
            .map(|(f, k)| (f * scale, k))
            .unzip();
        Ok(FreeSpace {
            cost,
            crossings,
            rays_used,
            scale,
        })
    }

    /// `F(p) = Σ_i p_i f_i` (squared scene units), summed in candidate order.
    pub fn value(&self, p: &[f64]) -> Result<f64> {
        check::same_len("probabilities", p.len(), "candidates", self.cost.len())?;
        Ok(self.cost.iter().zip(p).map(|(f, p)| f * p).sum())
    }

    /// `F` of a binary scene (`exists[i]`: candidate `i` exists).
    pub fn binary_value(&self, exists: &[bool]) -> Result<f64> {
        let p: Vec<f64> = exists.iter().map(|&e| f64::from(u8::from(e))).collect();
        self.value(&p)
    }

    /// `∂F/∂p` (constant: `f`), written into `grad`.
    pub fn gradient(&self, grad: &mut [f64]) -> Result<()> {
        check::same_len("gradient", grad.len(), "candidates", self.cost.len())?;
        grad.copy_from_slice(&self.cost);
        Ok(())
    }
}

/// `c_ij = min(d(y, S)², d_cap)` of one ray whose point `y` lies `z` along it and which
/// first crosses `S` at depth `depth`; 0 when the crossing is not in front of the point.
#[inline]
pub fn crossing_cost(prim: &Primitive, y: &Point3<f64>, z: f64, depth: f64, d_cap: f64) -> f64 {
    if depth >= z {
        return 0.0;
    }
    let d = prim.distance(y);
    (d * d).min(d_cap)
}

/// One candidate's `(f_i, crossings)` over the rays of every tree (unscaled).
fn candidate_cost(prim: &Primitive, trees: &[RayTree], rays: &Rays, d_cap: f64) -> (f64, usize) {
    let (mut sum, mut count) = (0.0, 0usize);
    for tree in trees {
        for j in tree.candidate_rays(prim) {
            let (dir, z) = (&rays.dirs[j as usize], rays.ranges[j as usize]);
            let Some(hit) = prim.first_hit(tree.origin(), dir) else {
                continue;
            };
            if hit.depth >= z {
                continue;
            }
            let y = tree.origin() + dir * z;
            sum += crossing_cost(prim, &y, z, hit.depth, d_cap);
            count += 1;
        }
    }
    (sum, count)
}

/// The most sphere-tracing steps of one ray in [`marched_free_space`].
const MAX_MARCH_STEPS: usize = 100_000;

/// Whether the segment from `o` along unit `dir` up to depth `z` meets `prim`, by sphere
/// tracing on the unsigned distance: step by the distance to the surface until it falls
/// below `tolerance` (a crossing) or the depth reaches `z` (none). Needs no ray–surface
/// algebra: the reference the closed form is tested against.
pub fn marches_into(
    prim: &Primitive,
    o: &Point3<f64>,
    dir: &Vector3<f64>,
    z: f64,
    tolerance: f64,
) -> bool {
    let mut t = 0.0;
    for _ in 0..MAX_MARCH_STEPS {
        if t >= z {
            return false;
        }
        let d = prim.distance(&(o + dir * t));
        if d < tolerance {
            return true;
        }
        t += d;
    }
    false
}

/// `F` of a binary scene by brute force (tests and small scenes): every ray is marched
/// against every existing candidate ([`marches_into`], stopping `tolerance` short of the
/// point) and charged `min(d(y, S)², d_cap)`. All rays, no stride.
pub fn marched_free_space(
    rays: &Rays,
    candidates: &[Primitive],
    exists: &[bool],
    d_cap: f64,
    tolerance: f64,
) -> Result<f64> {
    check::same_len(
        "existence values",
        exists.len(),
        "candidates",
        candidates.len(),
    )?;
    check::positive("tolerance", tolerance)?;
    let mut total = 0.0;
    for (c, _) in candidates.iter().zip(exists).filter(|(_, e)| **e) {
        for j in 0..rays.len() {
            let (o, dir, z) = (rays.origin(j), &rays.dirs[j], rays.ranges[j]);
            if marches_into(c, o, dir, z - tolerance, tolerance) {
                let d = c.distance(&(o + dir * z));
                total += (d * d).min(d_cap);
            }
        }
    }
    Ok(total)
}
