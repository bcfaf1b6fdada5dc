//! [`PointIndex`]: exact nearest-neighbour queries over 3-D points; [`PlaneIndex`]: radius
//! queries over 2-D points (the angles of [`crate::ray::RayTree`]); [`PrimitiveIndex`]:
//! exact nearest-surface queries over primitives (built on [`PointIndex`]);
//! `NeighbourSearch` (`neighbour_grid.rs`): the `k` nearest of every point of a cloud,
//! through a uniform grid, as [`PointIndex::nearest_n`] answers.
//!
//! The only module that imports kiddo; the rest of the crate sees plain
//! `(index, squared distance)` pairs. Distances returned by [`PointIndex`] and
//! [`PlaneIndex`] are **squared**; [`PrimitiveIndex`] returns plain surface distances.

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;
use rayon::prelude::*;

use crate::{Error, Primitive, Result};

mod box_tree;
mod kth_guess;
mod neighbour_grid;
pub(crate) use box_tree::{BoxTree, Hint};
pub(crate) use kth_guess::{grid_radii, kth_distance_guess};
pub(crate) use neighbour_grid::NeighbourSearch;

/// Squared distances to the nearest indexed point for runs of nearby queries: `hint`
/// carries where the last query's search ended (used by [`BoxTree`], ignored by
/// [`PointIndex`]); the distance never depends on it.
pub(crate) trait NearestDistance: Sync {
    /// Number of indexed points.
    fn len(&self) -> usize;
    /// Squared distance from `q` to the nearest point (infinite when there is none).
    fn nearest_distance(&self, q: &Point3<f64>, hint: &mut Hint) -> f64;
}

impl NearestDistance for PointIndex {
    fn len(&self) -> usize {
        self.len
    }
    fn nearest_distance(&self, q: &Point3<f64>, _: &mut Hint) -> f64 {
        self.nearest(q).map_or(f64::INFINITY, |r| r.1)
    }
}

impl NearestDistance for BoxTree {
    fn len(&self) -> usize {
        BoxTree::len(self)
    }
    fn nearest_distance(&self, q: &Point3<f64>, hint: &mut Hint) -> f64 {
        self.nearest(q, hint)
    }
}

/// The order of neighbours: squared distance, then index.
pub(crate) fn by_distance_then_index(a: &(u32, f64), b: &(u32, f64)) -> std::cmp::Ordering {
    a.1.total_cmp(&b.1).then(a.0.cmp(&b.0))
}

/// Keeps the `k` nearest of `found` (`(index, squared distance)` pairs: every point
/// within some radius, at least `k` of them), sorted by [`by_distance_then_index`].
/// False, with `found` reordered, when points tie across the `k`-th place: which of them
/// are kept is then the kd-tree's choice ([`PointIndex::nearest_n`]), so that every
/// neighbourhood of the crate is the tree's.
pub(crate) fn keep_k_nearest(found: &mut Vec<(u32, f64)>, k: usize) -> bool {
    if found.len() > k {
        found.select_nth_unstable_by(k - 1, by_distance_then_index);
        let kth = found[k - 1].1;
        if found[k..].iter().any(|h| h.1 == kth) {
            return false;
        }
        found.truncate(k);
    }
    found.sort_unstable_by(by_distance_then_index);
    true
}

/// A static KD-tree over points (kiddo's `ImmutableKdTree<f64, 3>`), tolerant of empty input.
pub struct PointIndex {
    tree: Option<ImmutableKdTree<f64, 3>>,
    len: usize,
}

impl std::fmt::Debug for PointIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PointIndex")
            .field("len", &self.len)
            .finish()
    }
}

pub(crate) fn as_array(p: &Point3<f64>) -> [f64; 3] {
    [p.x, p.y, p.z]
}

/// `dx² + dy² + dz²`, summed in the order kiddo's `SquaredEuclidean` sums it: every
/// exact nearest-point search of the crate (kd-tree, [`BoxTree`], a partial tube's
/// sample lattice) returns the same `f64` for the same pair of points.
#[inline]
pub(crate) fn squared_distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let (dx, dy, dz) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    dx * dx + dy * dy + dz * dz
}

impl PointIndex {
    /// Builds the index (in parallel for large inputs). Item ids are positions in `points`.
    ///
    /// Points must be finite; at most `u32::MAX` points.
    pub fn new(points: &[Point3<f64>]) -> Self {
        let coords: Vec<[f64; 3]> = points.iter().map(as_array).collect();
        let tree = if coords.is_empty() {
            None
        } else if coords.len() > 50_000 {
            ImmutableKdTree::new_from_slice_parallel(&coords).ok()
        } else {
            ImmutableKdTree::new_from_slice(&coords).ok()
        };
        PointIndex {
            tree,
            len: points.len(),
        }
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when no points are indexed.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The nearest point: `(index, squared distance)`, or `None` when empty.
    #[inline]
    pub fn nearest(&self, q: &Point3<f64>) -> Option<(u32, f64)> {
        let tree = self.tree.as_ref()?;
        let r = tree
            .query(&as_array(q))
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        Some((r.item, r.distance))
    }

    /// The `k` nearest points sorted by (squared distance, index).
    pub fn nearest_n(&self, q: &Point3<f64>, k: usize) -> Vec<(u32, f64)> {
        let (Some(tree), Some(k)) = (self.tree.as_ref(), NonZeroUsize::new(k.min(self.len))) else {
            return Vec::new();
        };
        let mut out: Vec<(u32, f64)> = tree
            .query(&as_array(q))
            .nearest_n::<SquaredEuclidean<f64>>(k)
            .execute()
            .into_iter()
            .map(|r| (r.item, r.distance))
            .collect();
        out.sort_by(by_distance_then_index);
        out
    }

    /// The `k` nearest points, as [`Self::nearest_n`] returns them, searched first
    /// within the squared distance `guess` (scene units²; `None`: a plain
    /// [`Self::nearest_n`]). The answer does not depend on the guess; the search is
    /// fastest when the guess is a little above the `k`-th squared distance, where a
    /// radius search gathers the candidates for less than a k-nearest search (kiddo keeps
    /// its `k` best sorted as it goes).
    pub fn nearest_n_guessed(
        &self,
        q: &Point3<f64>,
        k: usize,
        guess: Option<f64>,
    ) -> Vec<(u32, f64)> {
        let Some(guess) = guess else {
            return self.nearest_n(q, k);
        };
        let k = k.min(self.len);
        let mut found = self.within(q, guess);
        if k == 0 || found.len() < k {
            return self.nearest_n(q, k);
        }
        if !keep_k_nearest(&mut found, k) {
            return self.nearest_n(q, k);
        }
        found
    }

    /// The distance from `q`, one of the indexed points, to the nearest other one
    /// (0 for an exact duplicate; `None` when fewer than two points are indexed): its
    /// local point spacing.
    pub fn spacing_at(&self, q: &Point3<f64>) -> Option<f64> {
        self.nearest_n(q, 2).get(1).map(|r| r.1.sqrt())
    }

    /// Every point with squared distance ≤ `r2`, unsorted.
    pub fn within(&self, q: &Point3<f64>, r2: f64) -> Vec<(u32, f64)> {
        let Some(tree) = self.tree.as_ref() else {
            return Vec::new();
        };
        tree.query(&as_array(q))
            .within::<SquaredEuclidean<f64>>(r2)
            .unsorted()
            .execute()
            .into_iter()
            .map(|r| (r.item, r.distance))
            .collect()
    }
    /// Median distance from a point to its nearest other point, estimated on at most
    /// `max_probe` evenly spaced points of `points` (the points this index was built
    /// over): the cloud's typical point spacing. `None` when fewer than two distinct
    /// points exist.
    ///
    /// ```
    /// use primfit_core::PointIndex;
    /// use primfit_core::na::Point3;
    ///
    /// let points: Vec<_> = (0..10).map(|i| Point3::new(0.5 * i as f64, 0.0, 0.0)).collect();
    /// let index = PointIndex::new(&points);
    /// assert_eq!(index.median_spacing(&points, 100), Some(0.5));
    /// ```
    pub fn median_spacing(&self, points: &[Point3<f64>], max_probe: usize) -> Option<f64> {
        if points.len() < 2 {
            return None;
        }
        strided_median(points.len(), max_probe, |i| self.spacing_at(&points[i]))
    }
}

/// The median of the positive values of `distance(i)` over up to `max_probe` evenly
/// strided `i` in `0..n` (`None` where it has none): the probe of a median spacing.
pub(crate) fn strided_median(
    n: usize,
    max_probe: usize,
    distance: impl Fn(usize) -> Option<f64> + Sync + Send,
) -> Option<f64> {
    strided_quantiles(n, max_probe, [0.5], distance).map(|[median]| median)
}

/// The `quantiles` (each in [0, 1]; 0.5: the median) of the positive values of
/// `distance(i)` over up to `max_probe` evenly strided `i` in `0..n` (`None` where it
/// has none).
pub(crate) fn strided_quantiles<const N: usize>(
    n: usize,
    max_probe: usize,
    quantiles: [f64; N],
    distance: impl Fn(usize) -> Option<f64> + Sync + Send,
) -> Option<[f64; N]> {
    let stride = (n / max_probe.max(1)).max(1);
    // In parallel; a quantile of the collected values does not depend on their order.
    let mut d: Vec<f64> = (0..n)
        .into_par_iter()
        .step_by(stride)
        .filter_map(distance)
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return None;
    }
    let last = d.len() - 1;
    Some(quantiles.map(|q| {
        let at = ((d.len() as f64 * q.clamp(0.0, 1.0)) as usize).min(last);
        *d.select_nth_unstable_by(at, f64::total_cmp).1
    }))
}

/// A static KD-tree over 2-D points (kiddo's `ImmutableKdTree<f64, 2>`), tolerant of
/// empty input. Used for the (azimuth, elevation) coordinates of rays.
pub struct PlaneIndex {
    tree: Option<ImmutableKdTree<f64, 2>>,
    len: usize,
}

impl std::fmt::Debug for PlaneIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PlaneIndex")
            .field("len", &self.len)
            .finish()
    }
}

impl PlaneIndex {
    /// Builds the index. Item ids are positions in `points`; points must be finite; at
    /// most `u32::MAX` points.
    pub fn new(points: &[[f64; 2]]) -> Self {
        let tree = if points.is_empty() {
            None
        } else if points.len() > 50_000 {
            ImmutableKdTree::new_from_slice_parallel(points).ok()
        } else {
            ImmutableKdTree::new_from_slice(points).ok()
        };
        PlaneIndex {
            tree,
            len: points.len(),
        }
    }

    /// Ids of every point with squared distance ≤ `r2` from `q`, unsorted.
    pub fn within(&self, q: [f64; 2], r2: f64) -> Vec<u32> {
        let Some(tree) = self.tree.as_ref() else {
            return Vec::new();
        };
        tree.query(&q)
            .within::<SquaredEuclidean<f64>>(r2)
            .unsorted()
            .execute()
            .into_iter()
            .map(|r| r.item)
            .collect()
    }
}

/// Primitives of one bounding-radius class with a kd-tree over their centres.
struct RadiusClass {
    /// kd-tree over the centres; item `k` is `ids[k]`.
    tree: PointIndex,
    /// Indices into the primitive slice.
    ids: Vec<usize>,
    /// Largest bounding radius in the class.
    max_radius: f64,
}

/// An exact nearest-surface index over a set of primitives.
///
/// Primitives are grouped by bounding radius (classes a factor 2 apart) so one huge
/// primitive does not widen every search. A query first takes, in each class, the
/// primitive with the nearest centre (an upper bound `b` on the answer), then examines
/// every primitive whose centre lies within `b + max_radius` of the point and whose
/// bounding ball is nearer than the best distance so far, and measures a flat one only
/// when its plane is nearer too ([`Primitive::distance_within`]). The result is exact,
/// since `distance(p, surface) ≥ |p − centre| − bounding_radius`, and a flat surface's
/// ≥ the distance to its plane.
pub struct PrimitiveIndex<'a> {
    prims: &'a [Primitive],
    classes: Vec<RadiusClass>,
}

impl<'a> PrimitiveIndex<'a> {
    /// Builds the index; errs when a primitive has a non-finite centre or radius.
    pub fn new(prims: &'a [Primitive]) -> Result<Self> {
        let mut by_class: Vec<(i32, Vec<usize>)> = Vec::new();
        for (i, p) in prims.iter().enumerate() {
            let (c, r) = (p.center(), p.bounding_radius());
            if !(c.coords.iter().all(|v| v.is_finite()) && r.is_finite() && r >= 0.0) {
                return Err(Error::NonFinite {
                    what: "the bounding sphere of primitive".into(),
                    index: i,
                });
            }
            let class = if r > 0.0 {
                r.log2().floor() as i32
            } else {
                i32::MIN
            };
            match by_class.iter_mut().find(|(k, _)| *k == class) {
                Some((_, ids)) => ids.push(i),
                None => by_class.push((class, vec![i])),
            }
        }
        let classes = by_class
            .into_iter()
            .map(|(_, ids)| {
                let centres: Vec<Point3<f64>> = ids.iter().map(|&i| prims[i].center()).collect();
                let tree = PointIndex::new(&centres);
                let max_radius = ids
                    .iter()
                    .map(|&i| prims[i].bounding_radius())
                    .fold(0.0, f64::max);
                Ok(RadiusClass {
                    tree,
                    ids,
                    max_radius,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(PrimitiveIndex { prims, classes })
    }

    /// The nearest primitive surface to `p`: `(index, distance)`, or `None` for an
    /// empty index. Ties go to the lower index.
    pub fn nearest(&self, p: &Point3<f64>) -> Option<(usize, f64)> {
        self.nearest_from(p, None)
    }

    /// [`Self::nearest`], measuring primitive `hint` first (a neighbouring point's
    /// answer, which it shares more often than not): its distance bounds the search from
    /// the start, in place of one nearest-centre query per radius class. The answer does
    /// not depend on the hint.
    pub fn nearest_from(&self, p: &Point3<f64>, hint: Option<usize>) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        let consider = |i: usize, best: &mut Option<(usize, f64)>| {
            let bound = best.map_or(f64::INFINITY, |(_, bd)| bd);
            let Some(d) = self.prims[i].distance_within(p, bound) else {
                return;
            };
            if best.is_none_or(|(bi, bd)| d < bd || (d == bd && i < bi)) {
                *best = Some((i, d));
            }
        };
        match hint.filter(|&h| h < self.prims.len()) {
            Some(h) => consider(h, &mut best),
            None => {
                for class in &self.classes {
                    if let Some((k, _)) = class.tree.nearest(p) {
                        consider(class.ids[k as usize], &mut best);
                    }
                }
            }
        }
        for class in &self.classes {
            let bound = best.map_or(f64::INFINITY, |(_, d)| d) + class.max_radius;
            for (k, d2) in class.tree.within(p, bound * bound) {
                let i = class.ids[k as usize];
                let lower = d2.sqrt() - self.prims[i].bounding_radius();
                if Some(i) != hint && best.is_none_or(|(_, bd)| lower <= bd) {
                    consider(i, &mut best);
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn grid() -> Vec<Point3<f64>> {
        (0..5)
            .flat_map(|i| (0..5).map(move |j| Point3::new(i as f64, j as f64, 0.0)))
            .collect()
    }

    #[test]
    fn queries_match_brute_force() {
        let pts = grid();
        let idx = PointIndex::new(&pts);
        let q = Point3::new(1.2, 3.4, 0.5);
        let mut brute: Vec<(u32, f64)> = pts
            .iter()
            .enumerate()
            .map(|(i, p)| (i as u32, (p - q).norm_squared()))
            .collect();
        brute.sort_by(by_distance_then_index);
        assert_eq!(idx.nearest(&q).unwrap().0, brute[0].0);
        assert_eq!(idx.nearest_n(&q, 4), brute[..4].to_vec());
        let mut w: Vec<u32> = idx.within(&q, 1.5).into_iter().map(|r| r.0).collect();
        w.sort();
        let mut bw: Vec<u32> = brute.iter().filter(|r| r.1 <= 1.5).map(|r| r.0).collect();
        bw.sort();
        assert_eq!(w, bw);
    }

    #[test]
    fn a_guessed_search_answers_as_the_k_nearest_search_whatever_the_guess() {
        // Jittered points (no ties) and the grid (ties across the k-th place at every
        // lattice query), guesses from far below to far above the k-th distance.
        let mut jittered = Vec::new();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut unit = || rng.random::<f64>();
        for _ in 0..300 {
            jittered.push(Point3::new(unit() * 4.0, unit() * 4.0, 0.1 * unit()));
        }
        // Many copies of the axis points at distance 1 from the origin, interleaved: the
        // k-nearest search's choice among them is not the lowest indices.
        let axes: Vec<Point3<f64>> = (0..200)
            .map(|i| [Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, -1.0, 0.0)][i % 2])
            .chain([Point3::origin()])
            .collect();
        for pts in [jittered, grid(), axes] {
            let idx = PointIndex::new(&pts);
            let queries = pts
                .iter()
                .copied()
                .chain([Point3::new(2.0, 2.0, 0.0), Point3::new(9.0, 9.0, 1.0)]);
            for q in queries {
                for k in [1, 4, 9, 25, 40] {
                    let exact = idx.nearest_n(&q, k);
                    for guess in [0.0, 0.3, 1.0, 2.0, 5.0, 100.0] {
                        assert_eq!(
                            idx.nearest_n_guessed(&q, k, Some(guess)),
                            exact,
                            "{q} {k} {guess}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn empty_index_answers_nothing() {
        let idx = PointIndex::new(&[]);
        assert!(idx.nearest(&Point3::origin()).is_none());
        assert!(idx.nearest_n(&Point3::origin(), 3).is_empty());
        assert!(idx.within(&Point3::origin(), 1.0).is_empty());
    }

    #[test]
    fn plane_index_ball_matches_brute_force() {
        let pts: Vec<[f64; 2]> = (0..200)
            .map(|i| [(i as f64 * 0.37).sin() * 3.0, (i as f64 * 0.91).cos() * 2.0])
            .collect();
        let idx = PlaneIndex::new(&pts);
        let q = [0.4, -0.3];
        let mut got = idx.within(q, 0.8);
        got.sort();
        let want: Vec<u32> = (0..pts.len() as u32)
            .filter(|&i| {
                let p = pts[i as usize];
                (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) <= 0.8
            })
            .collect();
        assert_eq!(got, want);
        assert!(PlaneIndex::new(&[]).within(q, 1.0).is_empty());
    }

    #[test]
    fn primitive_index_is_exact_across_radius_classes() {
        use crate::{Pose, Shape};
        let at = |shape: Shape, x: f64| {
            Primitive::new(
                shape,
                Pose::new(Default::default(), Vector3::new(x, 0.0, 0.0)),
            )
        };
        // One huge sphere among small squares: its class must not hide a nearer square.
        let mut prims: Vec<Primitive> = (0..10)
            .map(|i| at(Shape::Square { side: 0.2 }, i as f64))
            .collect();
        prims.push(at(Shape::Sphere { diameter: 40.0 }, 30.0));
        let index = PrimitiveIndex::new(&prims).unwrap();
        for q in [
            [3.1, 0.05, 0.3],
            [-2.0, 1.0, 0.0],
            [11.5, 0.0, 0.0],
            [30.0, 0.0, 0.0],
        ] {
            let q = Point3::new(q[0], q[1], q[2]);
            let (i, d) = index.nearest(&q).unwrap();
            let brute = prims
                .iter()
                .map(|p| p.distance(&q))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(d, brute, "{q}");
            assert_eq!(prims[i].distance(&q), d);
            // Any hint, near or far (or out of range), gives the same answer.
            for hint in [0, 3, 9, 10, 11] {
                assert_eq!(
                    index.nearest_from(&q, Some(hint)),
                    Some((i, d)),
                    "{q} from {hint}"
                );
            }
        }
        // Two squares at the same distance: the lower index, whatever the hint.
        let q = Point3::new(4.5, 0.0, 0.0);
        for hint in [None, Some(4), Some(5)] {
            assert_eq!(index.nearest_from(&q, hint).unwrap().0, 4, "from {hint:?}");
        }
        assert!(
            PrimitiveIndex::new(&[])
                .unwrap()
                .nearest(&Point3::origin())
                .is_none()
        );
        let bad = [at(Shape::Square { side: 0.2 }, f64::NAN)];
        assert!(PrimitiveIndex::new(&bad).is_err());
    }

    #[test]
    fn median_spacing_of_unit_grid_is_one() {
        let pts = grid();
        let idx = PointIndex::new(&pts);
        assert!((idx.median_spacing(&pts, 100).unwrap() - 1.0).abs() < 1e-12);
    }
}
