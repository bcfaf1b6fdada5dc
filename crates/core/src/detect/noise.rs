//! The local noise level: σ as a function of position, at two scales.
//!
//! **Position.** Real sensors do not have one noise level: stereo and structured-light
//! depth noise grows with the square of the range, so a table 2 m away is several times
//! noisier than one 0.8 m away in the same frame (the shared table scan: 0.25 mm near,
//! 0.9 mm far, measured). One global σ then splits the far surfaces and merges the near
//! ones. A [`NoiseMap`] cuts space into cubic cells of [`CELL_RADII`] neighbourhood
//! radii, fixed to the cloud's lowest corner (so that moving a scan moves its cells with
//! it, [`super::sample::voxel_of`]); a cell's σ is the floored estimate of
//! [`crate::surface::noise_sigma`] (the median residual of the flattest half of its
//! neighbourhoods, at least `s/√12`) over the points in it, if it holds at least
//! [`MIN_CELL_SAMPLES`] of them; thinner cells take the global value. Taking the
//! flattest half keeps creases and clutter in a cell from inflating its σ.
//!
//! **Scale.** Stereo matching windows make the depth noise spatially correlated: a
//! neighbourhood of a few spacings moves with the noise and sees only part of it. On the
//! shared table scan the residual of flat neighbourhoods grows with their radius — 0.17,
//! 0.25, 0.46, 0.59, 0.73 mm at 4, 7, 17, 37, 81 mm (measured) — so a plane fitted to
//! the whole table (0.8 mm RMS) is not explained within 2.5 σ of the finest scale,
//! although it is exactly as flat as the sensor allows. Models are therefore judged
//! against the larger of the fine σ and the σ of neighbourhoods [`COARSE_FACTOR`] times
//! wider (a coarser voxel grid, same `k`). On white noise the two agree and nothing
//! changes; the fine σ alone sets the growing angle (normals are estimated at the fine
//! scale).

use std::collections::HashMap;

use nalgebra::{Point3, SMatrix, SVector, Vector3};
use rayon::prelude::*;

use super::normals::Neighbourhoods;
use super::sample::{grid_anchor, voxel_of};
use crate::surface::{LocalPlane, noise_sigma};

/// Cell edge of the noise map, in median neighbourhood radii: large enough that a cell
/// holds hundreds of samples and its flattest half is real surface, small enough to
/// follow a range-dependent noise across a room.
pub const CELL_RADII: f64 = 8.0;

/// A cell needs at least this many points for its own σ.
pub const MIN_CELL_SAMPLES: usize = 64;

/// The coarse noise scale, in fine neighbourhood radii (the voxel edge of the coarse grid
/// is this many times the fine sample pitch).
pub const COARSE_FACTOR: f64 = 4.0;

/// Parameters of the local height quadric `h = a + b u + c v + d u² + e uv + f v²`.
const QUADRIC_PARAMS: usize = 6;

/// The residual of each neighbourhood of `nb` (over `points`) after a least-squares
/// height quadric in its PCA frame, with the degrees of freedom restored
/// (`√(Σr² / (k − 6))`), scene units; the PCA residual where the fit is singular. On a
/// curved surface the plane residual contains the sagitta (`R²/(8ρ)` for radius `ρ`);
/// the quadric removes it and leaves the noise at the scale of the neighbourhood.
pub fn quadric_residuals(points: &[Point3<f64>], nb: &Neighbourhoods) -> Vec<f64> {
    (0..points.len())
        .into_par_iter()
        .map(|i| {
            let n = nb.normals[i];
            let row = nb.row(i);
            if n == Vector3::zeros() || row.len() <= QUADRIC_PARAMS {
                return nb.residual[i];
            }
            let (u, v) = super::cylinder::perpendicular_basis(&n);
            let o = points[i];
            let mut ata = SMatrix::<f64, QUADRIC_PARAMS, QUADRIC_PARAMS>::zeros();
            let mut atb = SVector::<f64, QUADRIC_PARAMS>::zeros();
            let local: Vec<(SVector<f64, QUADRIC_PARAMS>, f64)> = row
                .iter()
                .map(|&j| {
                    let d = points[j as usize] - o;
                    let (x, y) = (d.dot(&u), d.dot(&v));
                    (SVector::from([1.0, x, y, x * x, x * y, y * y]), d.dot(&n))
                })
                .collect();
            for (a, h) in &local {
                ata += a * a.transpose();
                atb += a * *h;
            }
            let Some(c) = ata.cholesky() else {
                return nb.residual[i];
            };
            let coef = c.solve(&atb);
            let ss: f64 = local.iter().map(|(a, h)| (h - a.dot(&coef)).powi(2)).sum();
            (ss / (local.len() - QUADRIC_PARAMS) as f64).sqrt()
        })
        .collect()
}

/// σ by position (scene units).
#[derive(Debug, Clone)]
pub struct NoiseMap {
    /// Cell edge (scene units).
    edge: f64,
    /// A corner of the grid of cells: the lowest corner of the cloud's bounding box.
    anchor: Point3<f64>,
    /// σ of each cell with enough points.
    cells: HashMap<[i64; 3], f64>,
    /// σ over all points: the value of every other cell.
    global: f64,
}

impl NoiseMap {
    /// The map of the neighbourhoods `nb` of `points`, floored at the input's point
    /// `spacing` (scene units), with cells of [`CELL_RADII`] × the median neighbourhood
    /// `radius`.
    pub fn new(points: &[Point3<f64>], nb: &Neighbourhoods, spacing: f64, radius: f64) -> Self {
        let plane = |i: usize| LocalPlane {
            point: points[i],
            normal: nb.normals[i],
            flatness: nb.flatness[i],
            residual: nb.residual[i],
        };
        let usable: Vec<usize> = (0..points.len())
            .into_par_iter()
            .filter(|&i| nb.normals[i] != Vector3::zeros())
            .collect();
        let edge = CELL_RADII * radius;
        let anchor = grid_anchor(points);
        // The global level and the cells' levels are independent: computed side by side.
        let (global, cells) = rayon::join(
            || {
                let all: Vec<LocalPlane> = usable.par_iter().map(|&i| plane(i)).collect();
                noise_sigma(&all, spacing)
            },
            || cell_levels(points, &usable, (&anchor, edge), spacing, plane),
        );
        NoiseMap {
            edge,
            anchor,
            cells,
            global,
        }
    }

    /// The same σ everywhere.
    pub fn uniform(sigma: f64) -> Self {
        NoiseMap {
            edge: f64::INFINITY,
            anchor: Point3::origin(),
            cells: HashMap::new(),
            global: sigma,
        }
    }

    /// The cell of `p`.
    fn cell(&self, p: &Point3<f64>) -> [i64; 3] {
        voxel_of(p, &self.anchor, self.edge)
    }

    /// σ at `p` (scene units).
    pub fn at(&self, p: &Point3<f64>) -> f64 {
        if self.cells.is_empty() {
            return self.global;
        }
        self.cells
            .get(&self.cell(p))
            .copied()
            .unwrap_or(self.global)
    }

    /// σ over the whole cloud (scene units).
    pub fn global(&self) -> f64 {
        self.global
    }
}

/// The σ of each cell of the grid `(anchor, edge)` (a corner, scene units) that holds at
/// least [`MIN_CELL_SAMPLES`] of the `usable` points, from their local planes
/// (`plane(i)`); none when the edge is not a positive finite length.
fn cell_levels(
    points: &[Point3<f64>],
    usable: &[usize],
    (anchor, edge): (&Point3<f64>, f64),
    spacing: f64,
    plane: impl Fn(usize) -> LocalPlane + Sync,
) -> HashMap<[i64; 3], f64> {
    if !(edge.is_finite() && edge > 0.0) {
        return HashMap::new();
    }
    let cell = |p: &Point3<f64>| voxel_of(p, anchor, edge);
    // The usable points by (cell, index), sorted in parallel: each cell's points are
    // one run, in increasing index.
    let mut members: Vec<([i64; 3], usize)> =
        usable.par_iter().map(|&i| (cell(&points[i]), i)).collect();
    members.par_sort_unstable();
    let runs: Vec<&[([i64; 3], usize)]> = members.chunk_by(|a, b| a.0 == b.0).collect();
    // Each cell's σ is its own: computed in parallel, the same map on any thread count.
    runs.into_par_iter()
        .filter(|run| run.len() >= MIN_CELL_SAMPLES)
        .map(|run| {
            let planes: Vec<LocalPlane> = run.iter().map(|&(_, i)| plane(i)).collect();
            (run[0].0, noise_sigma(&planes, spacing))
        })
        .collect()
}
