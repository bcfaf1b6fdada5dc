//! Smoothness-constrained region growing (Rabbani et al. 2006; PCL's `RegionGrowing`).
//!
//! Points are visited as **seeds** in order of increasing flatness (ties: lower index).
//! An unlabelled seed starts a region; the region grows breadth-first over each member's
//! nearest neighbours: an unlabelled neighbour whose normal makes an angle below the
//! threshold with the member's normal joins the region, and it **propagates** the growth
//! further only if its own neighbourhood is smooth (residual at most the propagation
//! limit). Points at creases thus join a face without carrying the region across the
//! crease onto the next face. Growing is sequential over a fixed order, so the regions
//! do not depend on the thread count.

use std::collections::VecDeque;

use super::normals::{FlatnessOrder, Neighbourhoods};

/// The thresholds of one run of [`grow_regions`], per point where the noise varies.
#[derive(Debug, Clone, PartialEq)]
pub struct GrowParams {
    /// Neighbours of a member examined for growth (the first ones of its row, itself
    /// excluded).
    pub neighbours: usize,
    /// Per point: `cos` of the largest angle between its normal and that of a neighbour
    /// it takes into its region (normals are unoriented: `|n_a · n_b|` is compared).
    pub cos_angle: Vec<f64>,
    /// Per point: it propagates growth only if its residual is at most this (scene units).
    pub max_residual: Vec<f64>,
}

/// Regions of the points of `nb` (lists of point indices, each ascending), in the order
/// they were started. Points with a zero normal (degenerate neighbourhoods) never seed
/// or join a region; every other point ends in exactly one region (possibly a region of
/// one point).
pub fn grow_regions(
    nb: &Neighbourhoods,
    flatness: &FlatnessOrder,
    params: &GrowParams,
) -> Vec<Vec<usize>> {
    let n = nb.len();
    let usable = |i: usize| nb.normals[i] != nalgebra::Vector3::zeros();
    let mut label = vec![false; n];
    let mut regions = Vec::new();
    let mut queue = VecDeque::new();
    let take = params.neighbours.min(nb.k.saturating_sub(1));
    for seed in flatness.order.iter().map(|&i| i as usize) {
        if label[seed] || !usable(seed) {
            continue;
        }
        label[seed] = true;
        let mut region = vec![seed];
        queue.clear();
        queue.push_back(seed);
        while let Some(cur) = queue.pop_front() {
            let normal = nb.normals[cur];
            let cos_angle = params.cos_angle[cur];
            for &j in &nb.row(cur)[1..=take] {
                let j = j as usize;
                if label[j] || !usable(j) || nb.normals[j].dot(&normal).abs() < cos_angle {
                    continue;
                }
                label[j] = true;
                region.push(j);
                if nb.residual[j] <= params.max_residual[j] {
                    queue.push_back(j);
                }
            }
        }
        region.sort_unstable();
        regions.push(region);
    }
    regions
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector3};

    use super::*;
    use crate::spatial::PointIndex;

    #[test]
    fn two_faces_of_a_crease_are_two_regions() {
        // An L: floor z = 0 (x ∈ [0, 0.3]) and wall x = 0 (z ∈ (0, 0.3]), 1 cm grid.
        let mut pts: Vec<Point3<f64>> = Vec::new();
        for i in 0..30 {
            for j in 0..30 {
                pts.push(Point3::new(i as f64 * 0.01, j as f64 * 0.01, 0.0));
                pts.push(Point3::new(0.0, j as f64 * 0.01, (i + 1) as f64 * 0.01));
            }
        }
        let index = PointIndex::new(&pts);
        let nb = Neighbourhoods::new(&pts, &index, 16);
        let params = GrowParams {
            neighbours: 8,
            cos_angle: vec![10f64.to_radians().cos(); pts.len()],
            max_residual: vec![1e-3; pts.len()],
        };
        let regions = grow_regions(&nb, &FlatnessOrder::new(&nb), &params);
        let big: Vec<&Vec<usize>> = regions.iter().filter(|r| r.len() > 100).collect();
        assert_eq!(
            big.len(),
            2,
            "{:?}",
            regions.iter().map(Vec::len).collect::<Vec<_>>()
        );
        for r in big {
            let n = nb.normals[r[r.len() / 2]];
            let flat = n.dot(&Vector3::z()).abs() > 0.99;
            for &i in r {
                // Every member lies on its face (crease points may join either).
                let on = if flat {
                    pts[i].z.abs() < 1e-9
                } else {
                    pts[i].x.abs() < 1e-9
                };
                assert!(on || pts[i].x.abs() + pts[i].z.abs() < 0.05);
            }
        }
        let total: usize = regions.iter().map(Vec::len).sum();
        assert_eq!(total, pts.len());
    }
}
