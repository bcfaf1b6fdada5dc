//! The `k` nearest neighbours of every point of a cloud, through a uniform grid: the
//! neighbourhoods of detection's normals ([`crate::detect`]).
//!
//! The grid's cells are a hair wider than a radius `r` that holds the `k` nearest of
//! most points ([`super::grid_radii`]), so every point within `r` of a point lies in
//! the 3 × 3 × 3 cells around its own. A cloud of uneven density (a scanner's near range
//! against its far range) gets a few grids, each radius twice the last: a point is
//! searched in the finest grid whose radius holds `k` points around it. The points are
//! sorted by cell, so that the
//! cells of one row along x are one contiguous run: a search measures nine runs of
//! coordinates in straight loops, with no tree walk and no sorted best-`k` list kept as
//! it goes (a kd-tree's k-nearest search keeps one). Where at least `k` points lie
//! within `r` they are the exact `k` nearest; the few points where fewer do in every
//! grid are searched in the kd-tree.
//!
//! The answer is [`PointIndex::nearest_n`]'s, whatever the radius, the grid or the
//! thread count: the exact `k` nearest by (squared distance, index), and where points
//! tie across the `k`-th place, the tree's choice among them (the grid hands those
//! points to the tree).

use nalgebra::Point3;
use rayon::prelude::*;

use super::{PointIndex, as_array, keep_k_nearest, squared_distance};

/// Cells per axis at most (2^20 each, so that a cell's key fits 60 bits); a cloud whose
/// extent spans more cells than this at the guessed radius is searched in the tree.
const MAX_CELLS_PER_AXIS: u64 = 1 << 20;

/// Relative margin of the cell edge over the radius.
const CELL_MARGIN: f64 = 1e-9;

/// The `k` nearest neighbours of each point of a cloud, as [`PointIndex::nearest_n`]
/// finds them: through the grid where the guessed radius allows, through the kd-tree
/// elsewhere.
pub(crate) struct NeighbourSearch<'a> {
    points: &'a [Point3<f64>],
    index: &'a PointIndex,
    k: usize,
    /// Finest first.
    grids: Vec<Grid>,
}

/// What one grid says of a point's `k` nearest.
enum GridAnswer {
    /// Written out: at least `k` points lie within the radius, with no tie across the
    /// `k`-th place.
    Exact,
    /// Fewer than `k` points within the radius: a coarser grid or the tree.
    TooFew,
    /// Points tie across the `k`-th place: the tree chooses among them.
    Ties,
}

impl<'a> NeighbourSearch<'a> {
    /// The search for the `k` nearest of every point of `points` (indexed by `index`,
    /// built over exactly these points), through grids of cells `√r2` wide for each `r2`
    /// of `radii` (ascending squared radii, scene units², each holding the `k` nearest of
    /// some of the points). A radius that is not positive, or a grid too fine for the
    /// cloud's extent, is skipped; without any grid every point is searched in `index`.
    pub fn new(points: &'a [Point3<f64>], index: &'a PointIndex, k: usize, radii: &[f64]) -> Self {
        let k = k.min(points.len());
        let grids = if k == 0 {
            Vec::new()
        } else {
            radii
                .iter()
                .filter_map(|&r2| Grid::new(points, r2))
                .collect()
        };
        NeighbourSearch {
            points,
            index,
            k,
            grids,
        }
    }

    /// The `k` nearest points of point `i` (itself included, as any other point at
    /// distance 0) as [`PointIndex::nearest_n`] answers: `(index, squared distance)` by
    /// increasing (squared distance, index). `scratch` is reused across calls.
    pub fn nearest<'s>(&self, i: usize, scratch: &'s mut Vec<(u32, f64)>) -> &'s [(u32, f64)] {
        let q = as_array(&self.points[i]);
        // The finest grid with `k` points within its radius answers, unless they tie.
        let mut answer = GridAnswer::TooFew;
        for grid in &self.grids {
            answer = grid.nearest(i, &q, self.k, scratch);
            if !matches!(answer, GridAnswer::TooFew) {
                break;
            }
        }
        if !matches!(answer, GridAnswer::Exact) {
            *scratch = self.index.nearest_n(&self.points[i], self.k);
        }
        &scratch[..self.k.min(scratch.len())]
    }
}

/// The points sorted by grid cell, and for each occupied cell where the points of the
/// cells around it lie.
struct Grid {
    /// The squared radius searched (scene units²); cells are a hair wider than its root.
    r2: f64,
    /// Point indices sorted by (cell key, index), and their coordinates in that order.
    order: Vec<u32>,
    coords: Vec<[f64; 3]>,
    /// Each point's occupied cell (a place in `around_starts`).
    cell_of: Vec<u32>,
    /// The ranges of `order` holding the points of the cells around each occupied cell:
    /// those of cell `c` are `around[around_starts[c]..around_starts[c + 1]]`.
    around: Vec<(u32, u32)>,
    around_starts: Vec<u32>,
}

impl Grid {
    /// The grid of `points` with cells `√r2` wide, or `None` when the radius is not
    /// positive and finite or the cloud spans too many cells.
    fn new(points: &[Point3<f64>], r2: f64) -> Option<Self> {
        // A hair wider than the radius: two points within it are never two cells apart
        // along an axis, whatever the rounding of their cell coordinates.
        let edge = r2.sqrt() * (1.0 + CELL_MARGIN);
        if !(edge.is_finite() && edge > 0.0) {
            return None;
        }
        let (lo, hi) = crate::bounds_of(points)?;
        let cells = |axis: usize| ((hi[axis] - lo[axis]) / edge).floor() + 1.0;
        let counts = [cells(0), cells(1), cells(2)];
        if counts
            .iter()
            .any(|c| c.is_nan() || *c > MAX_CELLS_PER_AXIS as f64)
        {
            return None;
        }
        let dims = counts.map(|c| c as u64);
        let key_of = |p: &Point3<f64>| {
            let cell = |axis: usize| (((p[axis] - lo[axis]) / edge) as u64).min(dims[axis] - 1);
            cell(0) + dims[0] * (cell(1) + dims[1] * cell(2))
        };
        let mut keyed: Vec<(u64, u32)> = points
            .par_iter()
            .enumerate()
            .map(|(i, p)| (key_of(p), i as u32))
            .collect();
        // Keys are distinct pairs: the unstable sort gives one order on any thread count.
        keyed.par_sort_unstable();
        let mut keys = Vec::new();
        let mut starts = Vec::new();
        let mut cell_of = vec![0u32; points.len()];
        for (place, &(key, i)) in keyed.iter().enumerate() {
            if keys.last() != Some(&key) {
                keys.push(key);
                starts.push(place as u32);
            }
            cell_of[i as usize] = (keys.len() - 1) as u32;
        }
        starts.push(keyed.len() as u32);
        let around_of: Vec<Vec<(u32, u32)>> = (0..keys.len())
            .into_par_iter()
            .map(|c| cells_around(&keys, &starts, keys[c], dims))
            .collect();
        let mut around_starts = Vec::with_capacity(keys.len() + 1);
        around_starts.push(0);
        let mut around = Vec::new();
        for ranges in around_of {
            around.extend(ranges);
            around_starts.push(around.len() as u32);
        }
        let order: Vec<u32> = keyed.par_iter().map(|&(_, i)| i).collect();
        let coords = order
            .par_iter()
            .map(|&i| as_array(&points[i as usize]))
            .collect();
        Some(Grid {
            r2,
            order,
            coords,
            cell_of,
            around,
            around_starts,
        })
    }

    /// Writes the `k` nearest of point `i` into `out` (sorted) when at least `k` points
    /// lie within the radius (they are then its exact `k` nearest) and none ties across
    /// the `k`-th place.
    fn nearest(&self, i: usize, q: &[f64; 3], k: usize, out: &mut Vec<(u32, f64)>) -> GridAnswer {
        let c = self.cell_of[i] as usize;
        let ranges =
            &self.around[self.around_starts[c] as usize..self.around_starts[c + 1] as usize];
        let scanned: usize = ranges.iter().map(|&(from, to)| (to - from) as usize).sum();
        // Every scanned point is written and the length moves past those within the
        // radius only: no branch to mispredict on about half of them.
        out.clear();
        out.resize(scanned, (0, 0.0));
        let mut len = 0;
        for &(from, to) in ranges {
            let (from, to) = (from as usize, to as usize);
            for (&id, p) in self.order[from..to].iter().zip(&self.coords[from..to]) {
                let d = squared_distance(q, p);
                out[len] = (id, d);
                len += usize::from(d <= self.r2);
            }
        }
        out.truncate(len);
        if out.len() < k {
            GridAnswer::TooFew
        } else if keep_k_nearest(out, k) {
            GridAnswer::Exact
        } else {
            GridAnswer::Ties
        }
    }
}

/// The ranges of the sorted points (`starts`: where each occupied cell of `keys` starts)
/// that hold the points of the 3 × 3 × 3 cells around the cell of `key`, on a grid of
/// `dims` cells: one range per row of three cells along x, since the occupied cells of a
/// row are consecutive in `keys`.
fn cells_around(keys: &[u64], starts: &[u32], key: u64, dims: [u64; 3]) -> Vec<(u32, u32)> {
    let [nx, ny, nz] = dims;
    let (x, y, z) = (key % nx, (key / nx) % ny, key / (nx * ny));
    let mut ranges = Vec::with_capacity(9);
    for zz in z.saturating_sub(1)..=(z + 1).min(nz - 1) {
        for yy in y.saturating_sub(1)..=(y + 1).min(ny - 1) {
            let row = nx * (yy + ny * zz);
            let (from, to) = (row + x.saturating_sub(1), row + (x + 1).min(nx - 1));
            let first = keys.partition_point(|&k| k < from);
            let last = keys.partition_point(|&k| k <= to);
            if first < last {
                ranges.push((starts[first], starts[last]));
            }
        }
    }
    ranges
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::by_distance_then_index;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The `k` nearest of every point by brute force, by (squared distance, index).
    fn brute_force(points: &[Point3<f64>], k: usize) -> Vec<(u32, f64)> {
        let mut out = Vec::new();
        for q in points {
            let mut all: Vec<(u32, f64)> = points
                .iter()
                .enumerate()
                .map(|(j, p)| (j as u32, squared_distance(&as_array(q), &as_array(p))))
                .collect();
            all.sort_by(by_distance_then_index);
            out.extend_from_slice(&all[..k.min(points.len())]);
        }
        out
    }

    /// A wall, a floor strip, a dense blob and a few far outliers; with `ties`, exact
    /// duplicates and points on a coarse lattice too (ties at the k-th place).
    fn uneven_cloud(seed: u64, ties: bool) -> Vec<Point3<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut pts = Vec::new();
        for _ in 0..600 {
            pts.push(Point3::new(
                rng.random::<f64>() * 2.0,
                0.0,
                rng.random::<f64>(),
            ));
        }
        for _ in 0..300 {
            pts.push(Point3::new(
                rng.random::<f64>() * 2.0,
                rng.random::<f64>() * 0.5,
                0.0,
            ));
        }
        for _ in 0..200 {
            let u = Point3::new(
                rng.random::<f64>(),
                rng.random::<f64>(),
                rng.random::<f64>(),
            );
            pts.push(Point3::new(1.0, 0.2, 0.5) + u.coords * 0.02);
        }
        if ties {
            for i in 0..100 {
                pts.push(Point3::new(
                    (i % 10) as f64 * 0.05,
                    1.0,
                    (i / 10) as f64 * 0.05,
                ));
            }
            for i in 0..40 {
                pts.push(pts[i * 7]);
            }
        }
        pts.push(Point3::new(30.0, -4.0, 9.0));
        pts.push(Point3::new(-20.0, 5.0, 1.0));
        pts
    }

    /// Every row of a search, one after the other.
    fn neighbour_table(
        pts: &[Point3<f64>],
        index: &PointIndex,
        k: usize,
        radii: &[f64],
    ) -> Vec<(u32, f64)> {
        let search = NeighbourSearch::new(pts, index, k, radii);
        let mut scratch = Vec::new();
        (0..pts.len())
            .flat_map(|i| search.nearest(i, &mut scratch).to_vec())
            .collect()
    }

    /// Each point's row as the kd-tree answers it.
    fn tree_table(pts: &[Point3<f64>], index: &PointIndex, k: usize) -> Vec<(u32, f64)> {
        pts.iter().flat_map(|q| index.nearest_n(q, k)).collect()
    }

    /// No radius (the tree alone), radii far too small, about right, and larger than the
    /// cloud, alone and as the grids of an uneven cloud.
    const RADII: [&[f64]; 7] = [
        &[],
        &[1e-6],
        &[0.003],
        &[0.02],
        &[1e4],
        &[1e-6, 0.003, 0.02],
        &[0.0005, 0.002, 0.008, 0.032],
    ];

    /// Asserts that the search gives `truth(k)` for every `k` and radius.
    fn assert_every_radius(
        pts: &[Point3<f64>],
        truth: impl Fn(&PointIndex, usize) -> Vec<(u32, f64)>,
    ) {
        let index = PointIndex::new(pts);
        for k in [1, 8, 32] {
            let expected = truth(&index, k);
            for radii in RADII {
                let rows = neighbour_table(pts, &index, k, radii);
                assert_eq!(rows, expected, "k {k}, radii {radii:?}");
            }
        }
    }

    #[test]
    fn the_search_is_the_brute_force_answer_for_any_radius() {
        let pts = uneven_cloud(3, false);
        assert_every_radius(&pts, |_, k| brute_force(&pts, k));
    }

    #[test]
    fn with_ties_the_search_answers_as_the_tree() {
        // Duplicates and lattice points tie across the k-th place; the grid leaves those
        // points to the tree, whose choice among tied points is its own.
        let pts = uneven_cloud(3, true);
        assert_every_radius(&pts, |index, k| tree_table(&pts, index, k));
    }

    #[test]
    fn the_search_is_the_same_on_any_thread_count() {
        let pts = uneven_cloud(5, true);
        let index = PointIndex::new(&pts);
        let all = neighbour_table(&pts, &index, 16, &[0.004]);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let one = pool.install(|| neighbour_table(&pts, &index, 16, &[0.004]));
        assert_eq!(all, one);
    }

    #[test]
    fn small_and_degenerate_clouds() {
        let one = vec![Point3::new(1.0, 2.0, 3.0)];
        let index = PointIndex::new(&one);
        let rows = neighbour_table(&one, &index, 32, &[0.01]);
        assert_eq!(rows, vec![(0, 0.0)]);
        // All points coincide: a grid of one cell, every distance 0, all tied.
        let same = vec![Point3::new(0.5, 0.5, 0.5); 5];
        let index = PointIndex::new(&same);
        let rows = neighbour_table(&same, &index, 3, &[0.01]);
        assert_eq!(rows, tree_table(&same, &index, 3));
        let empty: Vec<Point3<f64>> = Vec::new();
        assert!(neighbour_table(&empty, &PointIndex::new(&empty), 8, &[1.0]).is_empty());
    }
}
