//! A guessed radius for k-nearest searches: the typical `k`-th neighbour distance of a
//! cloud, from which each search starts as a radius search
//! ([`PointIndex::nearest_n_guessed`]; the neighbours found are exact whatever the
//! radius). Used by the normals of detection and the local planes of the noise level
//! and the frame estimate.

use nalgebra::Point3;

use super::{PointIndex, strided_quantiles};

/// Points probed for the typical `k`-th neighbour distance of a cloud; a cloud of fewer
/// than [`KTH_DISTANCE_PROBE_STRIDE`] times as many points is searched without a guess
/// (on leftover pieces of a few hundred points the guess saved nothing, measured; from
/// about a thousand points the neighbour grid it sizes more than repays the probes).
const KTH_DISTANCE_PROBES: usize = 256;
const KTH_DISTANCE_PROBE_STRIDE: usize = 4;

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

/// Most neighbour grids of an uneven cloud ([`grid_radii`]): their radii span
/// `KTH_DISTANCE_MAX_SPREAD^(n−1)` = 64 in squared `k`-th distance, a density 64 times
/// lower in the sparsest grid than in the finest (on a surface, 8 times the distance
/// from a scanner); sparser points are searched in the kd-tree.
const MAX_NEIGHBOUR_GRIDS: usize = 4;

/// A squared radius that holds the `k` nearest neighbours of most of `points` (scene
/// units²), or `None` for a small cloud, an uneven one, or one whose points have no `k`
/// distinct neighbours.
pub(crate) fn kth_distance_guess(
    points: &[Point3<f64>],
    index: &PointIndex,
    k: usize,
) -> Option<f64> {
    let [low, high] = kth_distance_spread(points, index, k)?;
    (high <= KTH_DISTANCE_MAX_SPREAD * low).then(|| high * KTH_DISTANCE_MARGIN.powi(2))
}

/// The squared radii (ascending, scene units²) of the neighbour grids of `points`
/// ([`super::NeighbourSearch`]): on an even cloud the one radius of
/// [`kth_distance_guess`]; on an uneven one, radii [`KTH_DISTANCE_MAX_SPREAD`] times
/// apart from the dense parts' `k`-th distance up to the sparse parts', at most
/// [`MAX_NEIGHBOUR_GRIDS`] of them, so that each point finds its `k` nearest in a grid
/// whose cells hold about `k` points around it. Empty for a small cloud.
pub(crate) fn grid_radii(points: &[Point3<f64>], index: &PointIndex, k: usize) -> Vec<f64> {
    let Some([low, high]) = kth_distance_spread(points, index, k) else {
        return Vec::new();
    };
    let margin = KTH_DISTANCE_MARGIN.powi(2);
    if high <= KTH_DISTANCE_MAX_SPREAD * low {
        return vec![high * margin];
    }
    let mut radii = vec![low * margin];
    while radii.len() < MAX_NEIGHBOUR_GRIDS && radii[radii.len() - 1] < high * margin {
        radii.push(radii[radii.len() - 1] * KTH_DISTANCE_MAX_SPREAD);
    }
    radii
}

/// The [`KTH_DISTANCE_LOW_QUANTILE`] and [`KTH_DISTANCE_QUANTILE`] of the squared `k`-th
/// neighbour distances of [`KTH_DISTANCE_PROBES`] points spread over `points`; `None`
/// for a small cloud or one whose points have no `k` distinct neighbours.
fn kth_distance_spread(points: &[Point3<f64>], index: &PointIndex, k: usize) -> Option<[f64; 2]> {
    if points.len() < KTH_DISTANCE_PROBES * KTH_DISTANCE_PROBE_STRIDE {
        return None;
    }
    let kth = |i: usize| index.nearest_n(&points[i], k).last().map(|h| h.1);
    let quantiles = [KTH_DISTANCE_LOW_QUANTILE, KTH_DISTANCE_QUANTILE];
    strided_quantiles(points.len(), KTH_DISTANCE_PROBES, quantiles, kth)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

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
        let uneven_index = PointIndex::new(&uneven);
        assert_eq!(kth_distance_guess(&uneven, &uneven_index, 32), None);
        let small = &even[..1000];
        assert_eq!(kth_distance_guess(small, &PointIndex::new(small), 32), None);

        // The grids: the one guessed radius on the even cloud; on the uneven one, radii
        // four times apart from the dense patch's (32 nearest within about 4 mm, as
        // 6 400 points on 1 dm² put them) towards the sparse square's, at most four:
        // 64 times the dense patch's falls short of a density 100 times lower.
        assert_eq!(grid_radii(&even, &index, 32), vec![r2]);
        let radii = grid_radii(&uneven, &uneven_index, 32);
        assert_eq!(radii.len(), MAX_NEIGHBOUR_GRIDS, "{radii:?}");
        for pair in radii.windows(2) {
            assert_eq!(pair[1], pair[0] * KTH_DISTANCE_MAX_SPREAD);
        }
        let dense_area = std::f64::consts::PI * radii[0] / (0.1f64 / 80.0).powi(2);
        assert!(dense_area > 32.0 && dense_area < 80.0, "{dense_area}");
        assert!(
            radii[3] < r2 && radii[3] * KTH_DISTANCE_MAX_SPREAD > r2,
            "{radii:?}"
        );
        assert!(grid_radii(small, &PointIndex::new(small), 32).is_empty());
    }
}
