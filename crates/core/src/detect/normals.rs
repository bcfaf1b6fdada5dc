//! Per-point normals and curvature of the sample points, with each point's nearest
//! neighbours kept for region growing ([`super::grow`]).
//!
//! For every point the `k` nearest neighbours (itself included) give a PCA plane
//! ([`crate::surface::pca_plane`]): the unit normal, the flatness ("curvature",
//! `λ0 / Σλ`, Pauly et al. 2002) and the residual `√λ0` (scene units). Points are
//! processed in parallel with rayon; each point's result depends on its neighbourhood
//! only, so the output is the same for any thread count. On a cloud of about a thousand
//! points or more the neighbours come from grids sized by guessed radii (one on an even
//! cloud, a few on an uneven one), which find the same neighbours as the kd-tree faster
//! ([`crate::spatial::NeighbourSearch`]).

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::spatial::{NeighbourSearch, PointIndex, grid_radii};
use crate::surface::pca_plane;

/// The flatness given to a point whose neighbourhood is degenerate (all neighbours
/// coincide or are collinear): the isotropic value 1/3, so it never seeds or propagates
/// a region.
const DEGENERATE_FLATNESS: f64 = 1.0 / 3.0;

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
        let n = points.len();
        let mut out = Neighbourhoods {
            k,
            neighbours: vec![0; n * k],
            normals: vec![Vector3::zeros(); n],
            flatness: vec![DEGENERATE_FLATNESS; n],
            residual: vec![0.0; n],
            radius: vec![0.0; n],
        };
        let radii = grid_radii(points, index, k);
        let search = NeighbourSearch::new(points, index, k, &radii);
        (
            out.neighbours.par_chunks_mut(k),
            &mut out.normals,
            &mut out.flatness,
            &mut out.residual,
            &mut out.radius,
        )
            .into_par_iter()
            .enumerate()
            .for_each_init(
                || (Vec::new(), Vec::new()),
                |(local, scratch), (i, (row, normal, flatness, residual, radius))| {
                    let hits = search.nearest(i, scratch);
                    local.clear();
                    local.extend(hits.iter().map(|(j, _)| points[*j as usize]));
                    *radius = hits.last().map_or(0.0, |h| h.1.sqrt());
                    if let Some((nrm, f, r)) = pca_plane(local) {
                        (*normal, *flatness, *residual) = (nrm, f, r);
                    }
                    fill_row(row, hits, i as u32);
                },
            );
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

/// The points of a [`Neighbourhoods`] by increasing flatness (ties: lower index), the
/// order region growing seeds in and the split draws its candidate planes from; sorted
/// once, in parallel.
#[derive(Debug, Clone)]
pub struct FlatnessOrder {
    /// Point indices, flattest first.
    pub order: Vec<u32>,
    /// Each point's place in `order`.
    rank: Vec<u32>,
}

impl FlatnessOrder {
    /// The order of the points of `nb`.
    pub fn new(nb: &Neighbourhoods) -> Self {
        let mut order: Vec<u32> = (0..nb.len() as u32).collect();
        // Keys are distinct (index ties), so an unstable sort is the same on any thread
        // count.
        order.par_sort_unstable_by(|&a, &b| {
            nb.flatness[a as usize]
                .total_cmp(&nb.flatness[b as usize])
                .then(a.cmp(&b))
        });
        let mut rank = vec![0u32; order.len()];
        for (place, &i) in order.iter().enumerate() {
            rank[i as usize] = place as u32;
        }
        FlatnessOrder { order, rank }
    }

    /// Sorts `ids` (point indices) flattest first, as [`Self::order`] lists them.
    pub fn sort(&self, ids: &mut [usize]) {
        ids.sort_unstable_by_key(|&i| self.rank[i]);
    }
}

/// Writes point `me`'s neighbour row from its `hits` (sorted by distance): the point
/// itself first (a duplicate point may tie with it), a short row padded with itself.
fn fill_row(row: &mut [u32], hits: &[(u32, f64)], me: u32) {
    for (slot, hit) in row.iter_mut().zip(hits) {
        *slot = hit.0;
    }
    let filled = hits.len().min(row.len());
    if let Some(pos) = row[..filled].iter().position(|&j| j == me) {
        row[..=pos].rotate_right(1);
    }
    row[filled..].fill(me);
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
    fn a_row_starts_with_its_point_and_is_padded_with_it() {
        // Point 7 ties with its duplicate 3, which the index listed first.
        let hits = [(3, 0.0), (7, 0.0), (9, 0.5)];
        let mut row = [u32::MAX; 5];
        fill_row(&mut row, &hits, 7);
        assert_eq!(row, [7, 3, 9, 7, 7]);
        let mut row = [u32::MAX; 2];
        fill_row(&mut row, &hits[1..], 7);
        assert_eq!(row, [7, 9]);
    }

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
