//! Voxel-grid subsampling: large clouds are reduced to at most a given number of evenly
//! spread **sample** points before normals and region growing, so detection time does not
//! grow with the scan's density. Each sample is an input point (the one nearest its
//! voxel's centre), so every result still names input points; the other points are
//! handed to the segment of their nearest sample afterwards ([`super::expand`]).

use std::collections::HashMap;

use nalgebra::Point3;

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
/// occupies about `A / v²` voxels of edge `v`. In each occupied voxel the point nearest
/// the voxel's centre is kept (ties: the lower index), so the result does not depend on
/// the thread count or on the order in which voxels are visited.
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
/// the point nearest its centre (ties: the lower index); indices ascending.
pub fn voxel_grid(points: &[Point3<f64>], edge: f64) -> Vec<usize> {
    let mut kept = occupied(points, edge);
    kept.sort_unstable();
    kept
}

/// For each voxel of edge `edge` that holds a point, the index of the point nearest the
/// voxel's centre (ties: the lower index), in no particular order.
fn occupied(points: &[Point3<f64>], edge: f64) -> Vec<usize> {
    let mut best: HashMap<[i64; 3], (usize, f64)> = HashMap::new();
    for (i, p) in points.iter().enumerate() {
        let cell = p.coords.map(|c| (c / edge).floor());
        let centre = (cell.add_scalar(0.5)) * edge;
        let d2 = (p.coords - centre).norm_squared();
        let key = [cell.x as i64, cell.y as i64, cell.z as i64];
        best.entry(key)
            .and_modify(|b| {
                if d2 < b.1 {
                    *b = (i, d2);
                }
            })
            .or_insert((i, d2));
    }
    best.into_values().map(|(i, _)| i).collect()
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
        // The same input in another order keeps the same points.
        let mut rev = pts.clone();
        rev.reverse();
        let (back, _) = voxel_subsample(&rev, 0.01, 10_000).unwrap();
        let mut back: Vec<usize> = back.iter().map(|i| pts.len() - 1 - i).collect();
        back.sort_unstable();
        assert_eq!(back.len(), kept.len());
    }
}
