//! Per-point normals and curvature of the sample points, with each point's nearest
//! neighbours kept for region growing ([`super::grow`]).
//!
//! For every point the `k` nearest neighbours (itself included) give a PCA plane
//! ([`crate::surface::pca_plane`]): the unit normal, the flatness ("curvature",
//! `λ0 / Σλ`, Pauly et al. 2002) and the residual `√λ0` (scene units). Points are
//! processed in parallel with rayon; each point's result depends on its neighbourhood
//! only, so the output is the same for any thread count. On clouds of a few thousand
//! points or more each search starts as a radius search of a guessed radius, which
//! finds the same neighbours faster ([`PointIndex::nearest_n_guessed`]).

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::spatial::{PointIndex, strided_quantiles};
use crate::surface::pca_plane;

/// The flatness given to a point whose neighbourhood is degenerate (all neighbours
/// coincide or are collinear): the isotropic value 1/3, so it never seeds or propagates
/// a region.
const DEGENERATE_FLATNESS: f64 = 1.0 / 3.0;

/// Points probed for the typical `k`-th neighbour distance of a cloud; a cloud of fewer
/// than [`KTH_DISTANCE_PROBE_STRIDE`] times as many points is searched without a guess
/// (on leftover pieces of a few hundred points the guess saved nothing, measured).
const KTH_DISTANCE_PROBES: usize = 256;
const KTH_DISTANCE_PROBE_STRIDE: usize = 16;

/// The quantile of the probed `k`-th neighbour distances, and the factor above it, that
/// each point's neighbour search starts from as a radius search (results are exact
/// whatever the radius; [`PointIndex::nearest_n_guessed`]). With 0.9 and 1.1, 4 % of
/// the searches of 20k points on planes and a cylinder fell back to a k-nearest search
/// and the 32-nearest searches took 35 % less time than k-nearest searches alone (best
/// of 0.5–0.9 × 1.0–1.25, measured).
const KTH_DISTANCE_QUANTILE: f64 = 0.9;
const KTH_DISTANCE_MARGIN: f64 = 1.1;

/// The guess is made only where the density is even: where the 90th percentile of the
/// probed squared `k`-th distances is at most this many times their 10th percentile.
/// A radius that fits the sparse parts of a cloud gathers about `k` × this ratio ×
/// the margin² points in its dense parts (a scanner's near range can be 100× denser
/// than its far range), so an uneven cloud is searched without a guess.
const KTH_DISTANCE_LOW_QUANTILE: f64 = 0.1;
const KTH_DISTANCE_MAX_SPREAD: f64 = 4.0;

/// A squared radius that holds the `k` nearest neighbours of most of `points` (scene
/// units²), or `None` for a small cloud, an uneven one, or one whose points have no `k`
/// distinct neighbours.
fn kth_distance_guess(points: &[Point3<f64>], index: &PointIndex, k: usize) -> Option<f64> {
    if points.len() < KTH_DISTANCE_PROBES * KTH_DISTANCE_PROBE_STRIDE {
        return None;
    }
    let kth = |i: usize| index.nearest_n(&points[i], k).last().map(|h| h.1);
    let quantiles = [KTH_DISTANCE_LOW_QUANTILE, KTH_DISTANCE_QUANTILE];
    let [low, high] = strided_quantiles(points.len(), KTH_DISTANCE_PROBES, quantiles, kth)?;
    (high <= KTH_DISTANCE_MAX_SPREAD * low).then(|| high * KTH_DISTANCE_MARGIN.powi(2))
}

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
        let guess = kth_distance_guess(points, index, k);
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
                Vec::new,
                |local, (i, (row, normal, flatness, residual, radius))| {
                    let hits = match guess {
                        Some(r2) => index.nearest_n_guessed(&points[i], k, r2),
                        None => index.nearest_n(&points[i], k),
                    };
                    local.clear();
                    local.extend(hits.iter().map(|(j, _)| points[*j as usize]));
                    *radius = hits.last().map_or(0.0, |h| h.1.sqrt());
                    if let Some((nrm, f, r)) = pca_plane(local) {
                        (*normal, *flatness, *residual) = (nrm, f, r);
                    }
                    fill_row(row, &hits, i as u32);
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
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

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
    fn the_search_radius_is_guessed_on_an_even_cloud_only() {
        // 6 400 points on a 1 m square (1.25 cm grid, jittered), and the same with as
        // many again on a 10 cm square, 100× denser: the radius that fits the sparse
        // part would gather thousands of points in the dense one.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut unit = || rng.random::<f64>();
        let even: Vec<Point3<f64>> = (0..6400)
            .map(|i| {
                let (x, y) = ((i % 80) as f64, (i / 80) as f64);
                Point3::new((x + unit() * 0.5) / 80.0, (y + unit() * 0.5) / 80.0, 0.0)
            })
            .collect();
        let index = PointIndex::new(&even);
        let r2 = kth_distance_guess(&even, &index, 32).expect("an even cloud");
        // The 32 nearest of a point fill a disc of about 32 spacings².
        let area = std::f64::consts::PI * r2 / (1.0 / 80.0f64).powi(2);
        assert!(area > 32.0 && area < 80.0, "{area}");
        let mut uneven = even.clone();
        uneven.extend((0..6400).map(|_| Point3::new(unit() * 0.1, unit() * 0.1, 0.0)));
        let index = PointIndex::new(&uneven);
        assert_eq!(kth_distance_guess(&uneven, &index, 32), None);
        let small = &even[..1000];
        assert_eq!(kth_distance_guess(small, &PointIndex::new(small), 32), None);
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
