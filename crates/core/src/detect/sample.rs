//! Voxel-grid subsampling: large clouds are reduced to at most a given number of evenly
//! spread **sample** points before normals and region growing, so detection time does not
//! grow with the scan's density. Each sample is an input point (the one nearest its
//! voxel's centre), so every result still names input points; the other points are
//! handed to the segment of their nearest sample afterwards ([`super::expand`]).
//!
//! The voxels are fixed to the cloud (a corner at its bounding box's lowest corner), not
//! to the origin: a scan moved by any offset is cut into the same voxels, so its
//! detection does not depend on where it lies (docs/compact.md).

use nalgebra::Point3;
use rayon::prelude::*;

/// The voxel edge grows by this factor beyond the ratio that the area scaling predicts,
/// so the loop of [`voxel_subsample`] ends after one or two passes.
const VOXEL_GROWTH_MARGIN: f64 = 1.05;

/// At most this many resizing passes: the area scaling converges in one or two.
const MAX_VOXEL_PASSES: usize = 12;

/// The sample points of `points` (indices, ascending) and the voxel edge used (scene
/// units), or `None` when `points` has at most `cap` points (all of them are samples).
///
/// The voxel edge starts at `spacing` (the median nearest-neighbour distance) and grows
/// by `√(count / cap)` until at most `cap` voxels are occupied: a surface of area `A`
/// occupies about `A / v²` voxels of edge `v`. In each occupied voxel the point of lowest
/// index is kept: not the one nearest the voxel's centre, which would select points by
/// their noise (the offset along the normal decides which point is nearest) and bias
/// the noise estimate of the samples. The result does not depend on the thread count.
pub fn voxel_subsample(
    points: &[Point3<f64>],
    spacing: f64,
    cap: usize,
) -> Option<(Vec<usize>, f64)> {
    if points.len() <= cap {
        return None;
    }
    let cap = cap.max(1);
    let mut edge = spacing.max(f64::MIN_POSITIVE);
    let mut kept = occupied(points, edge);
    for _ in 0..MAX_VOXEL_PASSES {
        if kept.len() <= cap {
            break;
        }
        edge *= (kept.len() as f64 / cap as f64).sqrt() * VOXEL_GROWTH_MARGIN;
        kept = occupied(points, edge);
    }
    kept.sort_unstable();
    Some((kept, edge))
}

/// The points of a voxel grid of edge `edge` (scene units, > 0): in each occupied voxel
/// the point of lowest index; indices ascending.
pub fn voxel_grid(points: &[Point3<f64>], edge: f64) -> Vec<usize> {
    let mut kept = occupied(points, edge);
    kept.sort_unstable();
    kept
}

/// For each voxel of edge `edge` that holds a point, the lowest index of its points, in
/// no particular order. A parallel sort of (voxel, index) pairs: 32 bytes a point, and
/// the same answer on any number of threads.
fn occupied(points: &[Point3<f64>], edge: f64) -> Vec<usize> {
    let anchor = grid_anchor(points);
    let mut cells: Vec<([i64; 3], usize)> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| (voxel_of(p, &anchor, edge), i))
        .collect();
    cells.par_sort_unstable();
    cells
        .chunk_by(|a, b| a.0 == b.0)
        .map(|run| run[0].1)
        .collect()
}

/// The corner the detection's grids are fixed to: the lowest corner of `points`' bounding
/// box (the origin for no points), so that moving the cloud moves its voxels with it.
pub(crate) fn grid_anchor(points: &[Point3<f64>]) -> Point3<f64> {
    crate::cloud::bounds_of(points).map_or(Point3::origin(), |b| b.0)
}

/// The voxel of edge `edge` holding `p`, in a grid with a corner at `anchor` (the cloud's
/// lowest corner: a grid fixed to the cloud, so that moving the cloud moves its voxels).
pub(crate) fn voxel_of(p: &Point3<f64>, anchor: &Point3<f64>, edge: f64) -> [i64; 3] {
    let c = (p - anchor).map(|c| (c / edge).floor() as i64);
    [c.x, c.y, c.z]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dense_grid_is_reduced_to_the_cap_evenly() {
        let pts: Vec<Point3<f64>> = (0..200)
            .flat_map(|i| (0..200).map(move |j| Point3::new(i as f64 * 0.01, j as f64 * 0.01, 0.0)))
            .collect();
        assert!(voxel_subsample(&pts, 0.01, 40_000).is_none());
        let (kept, edge) = voxel_subsample(&pts, 0.01, 10_000).unwrap();
        assert!(kept.len() <= 10_000 && kept.len() > 5_000, "{}", kept.len());
        assert!(edge > 0.015 && edge < 0.03, "{edge}");
        assert!(kept.windows(2).all(|w| w[0] < w[1]));
        // One point per voxel: no two kept points share a voxel.
        let cells: std::collections::HashSet<[i64; 2]> = kept
            .iter()
            .map(|&i| {
                [
                    (pts[i].x / edge).floor() as i64,
                    (pts[i].y / edge).floor() as i64,
                ]
            })
            .collect();
        assert_eq!(cells.len(), kept.len());
    }
}
