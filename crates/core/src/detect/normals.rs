//! Per-point normals and curvature of the sample points, with each point's nearest
//! neighbours kept for region growing ([`super::grow`]).
//!
//! For every point the `k` nearest neighbours (itself included) give a PCA plane
//! ([`crate::surface::pca_plane`]): the unit normal, the flatness ("curvature",
//! `λ0 / Σλ`, Pauly et al. 2002) and the residual `√λ0` (scene units). Points are
//! processed in parallel with rayon; each point's result depends on its neighbourhood
//! only, so the output is the same for any thread count.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::spatial::PointIndex;
use crate::surface::pca_plane;

/// The flatness given to a point whose neighbourhood is degenerate (all neighbours
/// coincide or are collinear): the isotropic value 1/3, so it never seeds or propagates
/// a region.
const DEGENERATE_FLATNESS: f64 = 1.0 / 3.0;

/// One point's neighbour ids, PCA plane (normal, flatness, residual) and radius.
type Row = (Vec<u32>, Option<(Vector3<f64>, f64, f64)>, f64);

/// Normals, curvature and neighbour lists of a set of points.
#[derive(Debug, Clone)]
pub struct Neighbourhoods {
    /// Neighbours per point (the point itself included).
    pub k: usize,
    /// Row `i` (entries `i·k .. (i+1)·k`): the `k` nearest points of point `i`, by
    /// increasing distance (ties: lower index); the first entry is the point itself.
    pub neighbours: Vec<u32>,
    /// Unit normal of each point, sign arbitrary; zero where the neighbourhood is
    /// degenerate.
    pub normals: Vec<Vector3<f64>>,
    /// `λ0 / (λ0 + λ1 + λ2)` ∈ [0, 1/3] of each point: 0 = flat.
    pub flatness: Vec<f64>,
    /// `√λ0` of each point: spread of its neighbours off their plane (scene units).
    pub residual: Vec<f64>,
    /// Distance from each point to its `k`-th neighbour (scene units).
    pub radius: Vec<f64>,
}

impl Neighbourhoods {
    /// Computes the neighbourhoods of every point of `points` (indexed by `index`, built
    /// over exactly these points) with `k` neighbours each.
    pub fn new(points: &[Point3<f64>], index: &PointIndex, k: usize) -> Self {
        let k = k.max(1).min(points.len().max(1));
        let rows: Vec<Row> = points
            .par_iter()
            .map(|p| {
                let hits = index.nearest_n(p, k);
                let local: Vec<Point3<f64>> =
                    hits.iter().map(|(i, _)| points[*i as usize]).collect();
                let radius = hits.last().map_or(0.0, |h| h.1.sqrt());
                let ids = hits.iter().map(|h| h.0).collect();
                (ids, pca_plane(&local), radius)
            })
            .collect();
        let mut out = Neighbourhoods {
            k,
            neighbours: Vec::with_capacity(points.len() * k),
            normals: Vec::with_capacity(points.len()),
            flatness: Vec::with_capacity(points.len()),
            residual: Vec::with_capacity(points.len()),
            radius: Vec::with_capacity(points.len()),
        };
        for (i, (mut ids, plane, radius)) in rows.into_iter().enumerate() {
            // Put the point itself first (a duplicate point may tie with it) and pad a
            // short row with the point itself.
            if let Some(pos) = ids.iter().position(|&j| j as usize == i) {
                ids[..=pos].rotate_right(1);
            }
            ids.resize(k, i as u32);
            out.neighbours.extend_from_slice(&ids);
            let (n, f, r) = plane.unwrap_or((Vector3::zeros(), DEGENERATE_FLATNESS, 0.0));
            out.normals.push(n);
            out.flatness.push(f);
            out.residual.push(r);
            out.radius.push(radius);
        }
        out
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.normals.len()
    }

    /// The `k` neighbours of point `i` (itself first).
    pub fn row(&self, i: usize) -> &[u32] {
        &self.neighbours[i * self.k..(i + 1) * self.k]
    }
}

/// The median of `values` (`None` when empty); `values` is reordered.
pub(super) fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    values.select_nth_unstable_by(mid, f64::total_cmp);
    Some(values[mid])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_of_a_plane_and_neighbour_rows() {
        let n = Vector3::new(0.2, -0.3, 1.0).normalize();
        let u = n.cross(&Vector3::x()).normalize();
        let v = n.cross(&u);
        let pts: Vec<Point3<f64>> = (0..30)
            .flat_map(|i| (0..30).map(move |j| (i, j)))
            .map(|(i, j)| Point3::from(u * (i as f64 * 0.01) + v * (j as f64 * 0.01)))
            .collect();
        let index = PointIndex::new(&pts);
        let nb = Neighbourhoods::new(&pts, &index, 16);
        assert_eq!(nb.len(), pts.len());
        for i in 0..pts.len() {
            assert_eq!(nb.row(i)[0] as usize, i);
            assert!(nb.normals[i].dot(&n).abs() > 1.0 - 1e-9);
            assert!(nb.flatness[i] < 1e-12 && nb.residual[i] < 1e-9);
            assert!(
                nb.radius[i] > 0.015 && nb.radius[i] < 0.05,
                "{}",
                nb.radius[i]
            );
        }
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let again = one_thread.install(|| Neighbourhoods::new(&pts, &index, 16));
        assert_eq!(again.neighbours, nb.neighbours);
        assert_eq!(again.normals, nb.normals);
    }
}
