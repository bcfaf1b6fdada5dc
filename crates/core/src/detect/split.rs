//! From grown regions to model parts: classify each region, and split the regions that
//! no model explains.
//!
//! Region growing follows normals, and normals estimated from `k` neighbours turn
//! gradually across a crease (over about one neighbourhood radius `R`); where the noise is
//! large against `R`, the crease's residual is not much above the noise either, so a
//! region can creep across it in small steps (a mug and the table it stands on). The
//! models then catch what growing let through: a region that no model explains is
//! **split** by peeling its dominant plane or cylinder, whichever holds more of it (a
//! table under the mug that grew onto it; a pipe run that grew into its bends, which
//! a plane could only peel in strips).
//!
//! 1. **Candidates.** Planes: the tangent planes (point, normal) of [`PLANE_CANDIDATES`]
//!    samples spread over the flatter half of the region (by rank of flatness).
//!    Cylinders: those fitted to the patches (two rings of neighbours) of
//!    [`CYLINDER_CANDIDATES`] samples spread over the region, none wider than the
//!    region's largest spread.
//! 2. **Dominant surface.** The candidate with most samples within `t σ` of it (a
//!    cylinder's with their normals within the growing angle of its own), refitted on
//!    those samples, twice; the plane or the cylinder, whichever has more.
//! 3. **Pieces.** The surface's inliers, cut into connected pieces over the growing
//!    neighbourhoods; pieces of at least the smallest segment become parts (each
//!    classified again). The other samples, cut into connected pieces as well, are
//!    classified or split in turn, down to [`MAX_SPLIT_DEPTH`].
//! 4. A region whose dominant surface has no piece of the smallest segment's size is
//!    **clutter**, as is what remains at the depth limit.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::classify::{Oriented, classify, spreads};
use super::cylinder::{CylinderFit, fit_cylinder, refit_cylinder};
use super::merge::Part;
use super::normals::{FlatnessOrder, Neighbourhoods, median};
use super::plane::Moments;
use crate::schedule::map_largest_first;

/// Tangent planes tried as the dominant plane of a region.
pub const PLANE_CANDIDATES: usize = 8;

/// Most nested splits of one region.
pub const MAX_SPLIT_DEPTH: usize = 6;

/// Least-squares refits of the dominant plane on its inliers.
const PLANE_REFITS: usize = 2;

/// Patches whose fitted cylinders are tried as the dominant cylinder of a region.
pub const CYLINDER_CANDIDATES: usize = 8;

/// Levenberg–Marquardt refits of the dominant cylinder on its inliers.
const CYLINDER_REFITS: usize = 2;

/// Everything the parts of one detection are judged by.
#[derive(Debug, Clone, Copy)]
pub struct Splitter<'a> {
    /// The samples.
    pub samples: &'a [Point3<f64>],
    /// Their neighbourhoods.
    pub nb: &'a Neighbourhoods,
    /// The samples by flatness.
    pub flatness: &'a FlatnessOrder,
    /// σ models are judged against, per sample (scene units).
    pub model_sigma: &'a [f64],
    /// Model tolerance `t`, in σ.
    pub tolerance: f64,
    /// Whether spheres are tried.
    pub spheres: bool,
    /// Smallest part, in samples.
    pub min_points: usize,
    /// Neighbours that connect samples (the growing neighbourhood).
    pub neighbours: usize,
    /// Each sample's residual off a height quadric in its neighbourhood
    /// ([`super::noise::quadric_residuals`], scene units): its noise without the
    /// curvature that inflates `nb.residual` on pipes and poles.
    pub quadric: &'a [f64],
    /// Per sample: `cos` of the growing angle (a normal within it of a surface's is the
    /// surface's).
    pub cos_angle: &'a [f64],
}

/// A candidate dominant plane: its inlier count, a point on it and its unit normal.
type CountedPlane = (usize, Point3<f64>, Vector3<f64>);

/// Marks a sample outside the ids of [`Splitter::components`].
const NOT_INSIDE: usize = usize::MAX;

impl Splitter<'_> {
    /// The parts of the region `ids` (ascending sample indices): one classified part, or
    /// the pieces of its splits (module docs).
    pub fn parts(&self, ids: Vec<usize>) -> Vec<Part> {
        let mut out = Vec::new();
        self.split(ids, 0, &mut out);
        out
    }

    /// The part of `ids` with its model (`None`: clutter).
    fn part(&self, ids: Vec<usize>) -> Part {
        let (sigma, fine) = self.noise(&ids);
        let surface = Oriented {
            points: self.samples,
            normals: &self.nb.normals,
            cos_angle: self.cos_angle,
        };
        let c = classify(surface, &ids, (sigma, fine), self.tolerance, self.spheres);
        let moments = Moments::of(self.samples, &ids);
        Part {
            ids,
            model: c.model,
            rms: c.rms,
            sigma,
            moments,
        }
    }

    /// Step 1–4 of the module docs on `ids` at nesting `depth`, parts pushed to `out`.
    fn split(&self, ids: Vec<usize>, depth: usize, out: &mut Vec<Part>) {
        let part = self.part(ids);
        if part.model.is_some() || depth >= MAX_SPLIT_DEPTH || part.ids.len() < 2 * self.min_points
        {
            out.push(part);
            return;
        }
        let limit = self.tolerance * part.sigma;
        // Peel whichever dominant surface holds more of the region: a plane (a table
        // under a mug), or a cylinder (a pipe run that grew into its bends).
        let plane = self.dominant_plane(&part.ids, limit);
        let cylinder = self.dominant_cylinder(&part.ids, limit);
        let peeled = match (plane, cylinder) {
            (Some(p), Some(c)) if c.len() > p.len() => Some(c),
            (Some(p), _) => Some(p),
            (None, c) => c,
        };
        let Some(on) = peeled else {
            out.push(part);
            return;
        };
        let mut inlier = vec![false; self.samples.len()];
        for &i in &on {
            inlier[i] = true;
        }
        let off: Vec<usize> = part.ids.iter().copied().filter(|&i| !inlier[i]).collect();
        let pieces: Vec<Vec<usize>> = self
            .components(&on)
            .into_iter()
            .filter(|c| c.len() >= self.min_points)
            .collect();
        if pieces.is_empty() {
            out.push(part);
            return;
        }
        let mut taken = vec![false; self.samples.len()];
        for &i in pieces.iter().flatten() {
            taken[i] = true;
        }
        let mut rest: Vec<usize> = on.into_iter().chain(off).filter(|&i| !taken[i]).collect();
        rest.sort_unstable();
        let rest = self
            .components(&rest)
            .into_iter()
            .filter(|c| c.len() >= self.min_points);
        // The pieces are disjoint: split in parallel, kept in order (deterministic).
        let pieces: Vec<Vec<usize>> = pieces.into_iter().chain(rest).collect();
        let split = map_largest_first(pieces, Vec::len, |piece| {
            let mut parts = Vec::new();
            self.split(piece, depth + 1, &mut parts);
            parts
        });
        out.extend(split.into_iter().flatten());
    }

    /// The inliers (ascending) of the dominant plane of `ids` within `limit` (scene
    /// units), or `None` when no candidate plane exists.
    fn dominant_plane(&self, ids: &[usize], limit: f64) -> Option<Vec<usize>> {
        let mut by_flatness: Vec<usize> = ids.to_vec();
        self.flatness.sort(&mut by_flatness);
        let half = by_flatness.len().div_ceil(2);
        let is_inlier = |i: usize, point: &Point3<f64>, normal: &Vector3<f64>| {
            (self.samples[i] - point).dot(normal).abs() <= limit
        };
        let within = |point: &Point3<f64>, normal: &Vector3<f64>| -> Vec<usize> {
            ids.iter()
                .copied()
                .filter(|&i| is_inlier(i, point, normal))
                .collect()
        };
        // The candidates' inliers are counted in parallel; the first with most wins, and
        // only its inliers are listed.
        let counted: Vec<Option<CountedPlane>> = (0..PLANE_CANDIDATES)
            .into_par_iter()
            .map(|c| {
                let seed = by_flatness[c * half / PLANE_CANDIDATES];
                let (point, normal) = (self.samples[seed], self.nb.normals[seed]);
                (normal != Vector3::zeros()).then(|| {
                    let count = ids
                        .iter()
                        .filter(|&&i| is_inlier(i, &point, &normal))
                        .count();
                    (count, point, normal)
                })
            })
            .collect();
        let mut best: Option<CountedPlane> = None;
        for candidate in counted.into_iter().flatten() {
            if best.is_none_or(|b| candidate.0 > b.0) {
                best = Some(candidate);
            }
        }
        let (_, point, normal) = best?;
        let mut inliers = within(&point, &normal);
        for _ in 0..PLANE_REFITS {
            let Some(fit) = Moments::of(self.samples, &inliers).plane() else {
                break;
            };
            inliers = within(&fit.point, &fit.normal);
        }
        Some(inliers)
    }

    /// The inliers (ascending) of the dominant cylinder of `ids` within `limit` (scene
    /// units), or `None` when no candidate cylinder exists: the cylinders fitted to the
    /// patches (two rings of neighbours) around [`CYLINDER_CANDIDATES`] samples spread
    /// over the region, the one with most inliers refitted (Levenberg–Marquardt) on them,
    /// twice. An inlier lies within `limit` of the surface with its normal within the
    /// growing angle of the surface's. A cylinder wider than the region's largest spread
    /// is a plane in disguise and is not tried.
    fn dominant_cylinder(&self, ids: &[usize], limit: f64) -> Option<Vec<usize>> {
        let pts: Vec<Point3<f64>> = ids.iter().map(|&i| self.samples[i]).collect();
        let widest = spreads(&pts)[0];
        let mut inside = vec![false; self.samples.len()];
        for &i in ids {
            inside[i] = true;
        }
        // Within `limit` of the surface, and the normal within the growing angle of the
        // surface's (a bend's start lies near its run's cylinder, tilted).
        let within = |fit: &CylinderFit| -> Vec<usize> {
            ids.iter()
                .copied()
                .filter(|&i| {
                    let off_axis = fit.off_axis(&self.samples[i]);
                    let r = off_axis.norm();
                    (r - fit.radius).abs() <= limit
                        && self.nb.normals[i].dot(&off_axis).abs() >= self.cos_angle[i] * r
                })
                .collect()
        };
        // The candidates are fitted and counted in parallel; the first with most wins.
        let counted: Vec<Option<(usize, CylinderFit)>> = (0..CYLINDER_CANDIDATES)
            .into_par_iter()
            .map(|c| {
                let seed = ids[c * ids.len() / CYLINDER_CANDIDATES];
                let patch = self.patch(seed, &inside);
                let ps: Vec<Point3<f64>> = patch.iter().map(|&i| self.samples[i]).collect();
                let ns: Vec<Vector3<f64>> = patch.iter().map(|&i| self.nb.normals[i]).collect();
                let fit = fit_cylinder(&ps, &ns).filter(|f| f.radius <= widest)?;
                Some((within(&fit).len(), fit))
            })
            .collect();
        let mut best: Option<(usize, CylinderFit)> = None;
        for candidate in counted.into_iter().flatten() {
            if best.is_none_or(|b| candidate.0 > b.0) {
                best = Some(candidate);
            }
        }
        let (_, mut fit) = best?;
        let mut inliers = within(&fit);
        for _ in 0..CYLINDER_REFITS {
            let on: Vec<Point3<f64>> = inliers.iter().map(|&i| self.samples[i]).collect();
            let Some(refit) = refit_cylinder(&on, &fit).filter(|f| f.radius <= widest) else {
                break;
            };
            fit = refit;
            inliers = within(&fit);
        }
        Some(inliers)
    }

    /// The samples of `inside` among the neighbours of `seed`'s neighbours (ascending).
    fn patch(&self, seed: usize, inside: &[bool]) -> Vec<usize> {
        let mut patch: Vec<usize> = (self.nb.row(seed).iter())
            .flat_map(|&j| self.nb.row(j as usize))
            .map(|&i| i as usize)
            .filter(|&i| inside[i])
            .collect();
        patch.sort_unstable();
        patch.dedup();
        patch
    }

    /// The connected pieces of `ids` (ascending) over the growing neighbourhoods, each
    /// ascending, in order of their lowest sample.
    fn components(&self, ids: &[usize]) -> Vec<Vec<usize>> {
        // Each sample's position in `ids` (`NOT_INSIDE` elsewhere): a dense table, one
        // read per neighbour, where a hash map spent most of this function hashing.
        let mut inside = vec![NOT_INSIDE; self.samples.len()];
        for (k, &i) in ids.iter().enumerate() {
            inside[i] = k;
        }
        let mut seen = vec![false; ids.len()];
        let take = self.neighbours.min(self.nb.k.saturating_sub(1));
        let mut pieces = Vec::new();
        let mut stack = Vec::new();
        for start in 0..ids.len() {
            if seen[start] {
                continue;
            }
            seen[start] = true;
            stack.push(ids[start]);
            let mut piece = Vec::new();
            while let Some(i) = stack.pop() {
                piece.push(i);
                for &j in &self.nb.row(i)[1..=take] {
                    let k = inside[j as usize];
                    if k != NOT_INSIDE && !seen[k] {
                        seen[k] = true;
                        stack.push(j as usize);
                    }
                }
            }
            piece.sort_unstable();
            pieces.push(piece);
        }
        pieces
    }

    /// A part's noise: the median of the model σ over its samples, or the median quadric
    /// residual of its samples where that is larger; and that median residual (the
    /// finest scale, without the surface's curvature).
    fn noise(&self, ids: &[usize]) -> (f64, f64) {
        let mut s: Vec<f64> = ids.iter().map(|&i| self.model_sigma[i]).collect();
        let mut r: Vec<f64> = ids.iter().map(|&i| self.quadric[i]).collect();
        let local = median(&mut s).unwrap_or(0.0);
        let fine = median(&mut r).unwrap_or(0.0);
        (fine.max(local), fine)
    }
}
