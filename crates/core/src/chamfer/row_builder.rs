//! Each point's entries: its β nearest candidates (exactly, by cells and bounds on a
//! KD-tree of candidate centres), or their α nearest samples.

use nalgebra::Point3;

use super::{CandidateGeometry, ChamferOptions, PointModel};
use crate::spatial::PointIndex;

/// Bits of one axis's cell index in a [`CellGrid`] key (three axes packed in a `u64`).
const KEY_BITS: u32 = 21;

/// The largest cell index per axis; indices beyond it saturate.
const MAX_CELL_INDEX: u64 = (1 << KEY_BITS) - 1;

/// Cells per axis a [`CellGrid`] is coarsened to at most (2²⁰, within [`MAX_CELL_INDEX`]).
const MAX_CELLS_PER_AXIS: u32 = 1 << 20;

/// Smallest cell side (scene units), so that a cloud of coincident points still has cells.
const MIN_CELL_SIDE: f64 = 1e-12;

/// Relative margin (dimensionless) by which distance bounds are loosened against
/// rounding, so that a bound never exceeds the computed exact distance.
const ROUNDING_MARGIN: f64 = 1e-12;

/// Smallest search radius ρ (scene units), so that a zero start radius (`d_cap = 0`) can
/// still grow.
const MIN_SEARCH_RADIUS: f64 = 1e-9;

/// Least factor (dimensionless) by which ρ grows between two rounds of the bounded
/// search, so that every round looks farther.
const MIN_RADIUS_GROWTH: f64 = 1.000_001;

/// Factor (dimensionless) by which ρ grows when fewer than β candidates were found (no
/// β-th distance to grow to).
const BLIND_RADIUS_GROWTH: f64 = 2.0;

/// The next point's start radius is this times the last point's β-th distance
/// (dimensionless): neighbouring points need about the same radius, and the margin saves
/// most repeated searches. The result never depends on it.
const START_RADIUS_MARGIN: f64 = 1.25;

/// A grid of cubic cells over the cloud's bounding box, for visiting points cell by cell.
pub(super) struct CellGrid {
    origin: Point3<f64>,
    side: f64,
}

impl CellGrid {
    /// Cells of about `side` (coarser if the box would need more than 2²⁰ cells per axis).
    pub(super) fn new(cloud: &[Point3<f64>], side: f64) -> Self {
        let (lo, hi) =
            crate::cloud::bounds_of(cloud).unwrap_or((Point3::origin(), Point3::origin()));
        let extent = (hi - lo).max();
        let side = side
            .max(extent / f64::from(MAX_CELLS_PER_AXIS))
            .max(MIN_CELL_SIDE);
        CellGrid { origin: lo, side }
    }

    /// The cell of `y`: three [`KEY_BITS`]-bit cell indices packed into one key.
    pub(super) fn key(&self, y: &Point3<f64>) -> u64 {
        let index =
            |v: f64, o: f64| (((v - o) / self.side).floor().max(0.0) as u64).min(MAX_CELL_INDEX);
        (index(y.x, self.origin.x) << (2 * KEY_BITS))
            | (index(y.y, self.origin.y) << KEY_BITS)
            | index(y.z, self.origin.z)
    }

    /// Centre of the cell with `key`.
    fn centre(&self, key: u64) -> Point3<f64> {
        let mask = MAX_CELL_INDEX;
        let at = |k: u64, o: f64| o + (k as f64 + 0.5) * self.side;
        Point3::new(
            at(key >> (2 * KEY_BITS), self.origin.x),
            at((key >> KEY_BITS) & mask, self.origin.y),
            at(key & mask, self.origin.z),
        )
    }

    /// Half the diagonal of a cell: every point of a cell is this close to its centre.
    fn half_diagonal(&self) -> f64 {
        self.side * 3f64.sqrt() / 2.0
    }
}

/// A KD-tree over candidate bounding-ball centres, for finding the candidates near a point.
pub(super) struct CentreIndex {
    index: PointIndex,
    /// Bounding radius of each candidate (its samples and surface lie within it).
    radii: Vec<f64>,
    /// The largest bounding radius `R_max`.
    pub(super) max_radius: f64,
}

impl CentreIndex {
    pub(super) fn new(geometry: &impl CandidateGeometry) -> Self {
        let balls: Vec<(Point3<f64>, f64)> = (0..geometry.len())
            .map(|i| geometry.bounding_ball(i))
            .collect();
        let centres: Vec<Point3<f64>> = balls.iter().map(|b| b.0).collect();
        let radii: Vec<f64> = balls.iter().map(|b| b.1).collect();
        let max_radius = radii.iter().copied().fold(0.0, f64::max);
        CentreIndex {
            index: PointIndex::new(&centres),
            radii,
            max_radius,
        }
    }

    /// A lower bound on the squared distance from a point to candidate `i`, given the
    /// point's squared distance to the candidate's centre: `(‖y − c‖ − R_i)₊²`, shrunk by
    /// a rounding margin so that it never exceeds the computed exact distance.
    #[inline]
    fn lower_bound(&self, i: usize, centre_d2: f64) -> f64 {
        let lb = (centre_d2.sqrt() * (1.0 - ROUNDING_MARGIN)
            - self.radii[i] * (1.0 + ROUNDING_MARGIN))
            .max(0.0);
        lb * lb
    }
}

/// Builds the sorted entries of one point at a time, reusing its buffers.
pub(super) struct RowBuilder<'a, G: CandidateGeometry> {
    geometry: &'a G,
    centres: &'a CentreIndex,
    options: &'a ChamferOptions,
    near: Vec<(u32, f64)>,
    bounds: Vec<(f64, u32)>,
    samples: Vec<(u32, f64)>,
    entries: Vec<(f64, u32, u32)>,
    /// Search radius to start the next point with: the last point's β-th distance.
    /// Consecutive points are usually neighbours; the result never depends on it.
    start_radius: f64,
    /// The current cell, its centre `m`, and the candidates whose centre lies within
    /// `cell_radius + R_max` of every point of it as `(d_i(m), id)` (distance, not
    /// squared), ascending.
    cell_key: Option<u64>,
    cell_centre: Point3<f64>,
    cell_sorted: Vec<(f64, u32)>,
    cell_radius: f64,
    /// The β best so far of the cell scan: a max-heap on `(squared distance, id)`.
    best: std::collections::BinaryHeap<Best>,
    /// Whether a point of the current cell needed a search beyond the cell's list: the
    /// list is then fetched again with the start radius that point left.
    cell_too_small: bool,
}

/// A measured candidate in [`RowBuilder::scan_cell`]'s heap, ordered by (squared distance,
/// id): the order of the rows (ties to the lower index).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Best(f64, u32);

impl Eq for Best {}

impl PartialOrd for Best {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Best {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
    }
}

impl<'a, G: CandidateGeometry> RowBuilder<'a, G> {
    pub(super) fn new(
        geometry: &'a G,
        centres: &'a CentreIndex,
        options: &'a ChamferOptions,
    ) -> Self {
        RowBuilder {
            geometry,
            centres,
            options,
            near: Vec::new(),
            bounds: Vec::new(),
            samples: Vec::new(),
            entries: Vec::new(),
            start_radius: options.cap.sqrt(),
            cell_key: None,
            cell_centre: Point3::origin(),
            cell_sorted: Vec::new(),
            cell_radius: 0.0,
            best: std::collections::BinaryHeap::new(),
            cell_too_small: false,
        }
    }

    /// Whether the next point, in cell `key`, needs [`RowBuilder::load_cell`] first: a
    /// new cell, or one whose list a point had to search beyond. A new builder starts
    /// from ρ = √d_cap, far under the β-th distance of a scene with few candidates, and
    /// every later point of the cell (thousands on a dense scan) would otherwise search
    /// the tree again.
    pub(super) fn needs_cell(&self, key: u64) -> bool {
        self.cell_key != Some(key) || self.cell_too_small
    }

    /// Fetches the candidates near cell `key`: those a search of radius ρ (the current
    /// start radius) from any point of the cell can reach, with their distances from the
    /// cell's centre, sorted.
    pub(super) fn load_cell(&mut self, key: u64, grid: &CellGrid) {
        let c = self.centres;
        self.cell_key = Some(key);
        self.cell_too_small = false;
        self.cell_radius = self.start_radius.max(MIN_SEARCH_RADIUS);
        self.cell_centre = grid.centre(key);
        let reach = self.cell_radius + c.max_radius + grid.half_diagonal();
        self.cell_sorted.clear();
        for (i, _) in c.index.within(&self.cell_centre, reach * reach) {
            let d2 = candidate_distance(self.geometry, self.options, i as usize, &self.cell_centre);
            self.cell_sorted.push((d2.sqrt(), i));
        }
        self.cell_sorted
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    }

    /// Appends the entries of point `y` to `cand`/`dist`.
    pub(super) fn push_row(&mut self, y: &Point3<f64>, cand: &mut Vec<u32>, dist: &mut Vec<f64>) {
        self.select_candidates(y);
        self.entries.clear();
        match self.options.model {
            PointModel::Existence => {
                self.entries
                    .extend(self.near.iter().map(|&(i, d)| (d, i, 0)));
            }
            PointModel::Independent => {
                for &(i, _) in &self.near {
                    self.geometry.nearest_samples(
                        i as usize,
                        y,
                        self.options.alpha,
                        &mut self.samples,
                    );
                    self.entries
                        .extend(self.samples.iter().map(|&(s, d)| (d, i, s)));
                }
            }
        }
        // (distance, candidate, sample): ties never change the value (DESIGN §2) but a
        // total order keeps the arrays deterministic.
        self.entries
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        for &(d, i, _) in &self.entries {
            cand.push(i);
            dist.push(d);
        }
    }

    /// Fills `self.near` with the β candidates whose nearest sample (or surface) is
    /// closest to `y`, as `(candidate, squared distance)`, ties to the lower index.
    fn select_candidates(&mut self, y: &Point3<f64>) {
        let n = self.geometry.len();
        let beta = self.options.beta.unwrap_or(usize::MAX);
        self.near.clear();
        if beta >= n {
            self.near.extend((0..n).map(|i| {
                (
                    i as u32,
                    candidate_distance(self.geometry, self.options, i, y),
                )
            }));
        } else {
            self.bounded_search(y, beta);
        }
    }

    /// The β best candidates: first from the current cell ([`RowBuilder::scan_cell`]),
    /// then, if that cannot be proved exact, by a growing search radius ρ and lower bounds.
    ///
    /// The cell's list holds every candidate whose centre is within ρ + R_max of every
    /// point of the cell, so when its β-th distance is within ρ² no candidate outside it
    /// can be closer (its distance exceeds ρ). Otherwise candidates whose centre is within
    /// ρ + R_max of `y` are gathered from the tree with their lower bounds
    /// `(‖y − c_i‖ − R_i)₊²` and measured by [`RowBuilder::measure_bounded`]; once β are
    /// found and the β-th is within ρ², the β are exact; otherwise ρ grows to the β-th
    /// distance (or doubles) and the search repeats.
    fn bounded_search(&mut self, y: &Point3<f64>, beta: usize) {
        let c = self.centres;
        let n = self.geometry.len();
        let mut rho = self.cell_radius;
        let mut worst = f64::INFINITY;
        let mut grow = false;
        if self.cell_key.is_some() {
            worst = self.scan_cell(y, beta);
            if worst <= rho * rho || self.cell_sorted.len() == n {
                self.remember(worst);
                return;
            }
            grow = true;
            self.cell_too_small = true;
        }
        loop {
            if grow {
                rho = if worst.is_finite() {
                    // Every candidate within the β-th distance has its centre within reach.
                    worst.sqrt().max(rho * MIN_RADIUS_GROWTH)
                } else {
                    rho.max(MIN_SEARCH_RADIUS) * BLIND_RADIUS_GROWTH
                };
            }
            grow = true;
            let reach = rho + c.max_radius;
            self.bounds.clear();
            for (i, d2) in c.index.within(y, reach * reach) {
                self.bounds.push((c.lower_bound(i as usize, d2), i));
            }
            worst = self.measure_bounded(y, beta);
            if worst <= rho * rho || self.bounds.len() == n {
                self.remember(worst);
                return;
            }
        }
    }

    /// Starts the next point's search from this point's β-th squared distance `worst`,
    /// with [`START_RADIUS_MARGIN`].
    fn remember(&mut self, worst: f64) {
        if worst.is_finite() {
            self.start_radius = START_RADIUS_MARGIN * worst.sqrt();
        }
    }

    /// The β best of the current cell's candidates into `self.near`; returns the β-th
    /// squared distance (∞ if the cell has fewer than β).
    ///
    /// A distance to a set is 1-Lipschitz, so `d_i(y) ≥ d_i(m) − ‖y − m‖` for the cell's
    /// centre `m`: with the candidates sorted by `d_i(m)`, the scan stops at the first one
    /// whose bound exceeds the β-th distance found so far, and every one after it is
    /// farther still. The bound is loosened by [`ROUNDING_MARGIN`] against rounding.
    fn scan_cell(&mut self, y: &Point3<f64>, beta: usize) -> f64 {
        let delta = (y - self.cell_centre).norm();
        self.best.clear();
        let mut w = f64::INFINITY;
        for &(dm, i) in &self.cell_sorted {
            if dm * (1.0 - ROUNDING_MARGIN) - delta * (1.0 + ROUNDING_MARGIN)
                > w * (1.0 + ROUNDING_MARGIN)
            {
                break;
            }
            let d = candidate_distance(self.geometry, self.options, i as usize, y);
            let entry = Best(d, i);
            if self.best.len() < beta {
                self.best.push(entry);
            } else if self.best.peek().is_some_and(|top| entry < *top) {
                self.best.pop();
                self.best.push(entry);
            } else {
                continue;
            }
            if self.best.len() == beta {
                w = self.best.peek().map_or(f64::INFINITY, |top| top.0.sqrt());
            }
        }
        self.near.clear();
        self.near.extend(self.best.iter().map(|b| (b.1, b.0)));
        if self.near.len() == beta {
            self.best.peek().map_or(f64::INFINITY, |top| top.0)
        } else {
            f64::INFINITY
        }
    }

    /// The β best of `self.bounds` into `self.near`; returns the β-th distance (∞ if
    /// fewer than β). The β smallest bounds are measured exactly; their largest distance
    /// W bounds the β-th best, so of the rest only those with a bound ≤ W are measured.
    fn measure_bounded(&mut self, y: &Point3<f64>, beta: usize) -> f64 {
        let by_bound = |a: &(f64, u32), b: &(f64, u32)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
        let by_distance = |a: &(u32, f64), b: &(u32, f64)| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0));
        let first = beta.min(self.bounds.len());
        if self.bounds.len() > beta {
            self.bounds.select_nth_unstable_by(beta - 1, by_bound);
        }
        self.near.clear();
        for &(_, i) in &self.bounds[..first] {
            let d = candidate_distance(self.geometry, self.options, i as usize, y);
            self.near.push((i, d));
        }
        let w = if first == beta {
            self.near.iter().map(|e| e.1).fold(0.0, f64::max)
        } else {
            f64::INFINITY
        };
        for &(lb, i) in &self.bounds[first..] {
            if lb <= w {
                let d = candidate_distance(self.geometry, self.options, i as usize, y);
                self.near.push((i, d));
            }
        }
        if self.near.len() > beta {
            self.near.select_nth_unstable_by(beta - 1, by_distance);
            self.near.truncate(beta);
        }
        if self.near.len() == beta {
            self.near.iter().map(|e| e.1).fold(0.0, f64::max)
        } else {
            f64::INFINITY
        }
    }
}

/// `d_i(y)` of the point term: squared distance from `y` to candidate `i`'s nearest sample,
/// or to its surface with [`ChamferOptions::surface_distance`].
#[inline]
fn candidate_distance(
    geometry: &impl CandidateGeometry,
    options: &ChamferOptions,
    i: usize,
    y: &Point3<f64>,
) -> f64 {
    if options.surface_distance {
        geometry.surface_distance(i, y)
    } else {
        geometry.nearest_sample(i, y).1
    }
}
