//! The probabilistic chamfer distance (thesis ch. 5–6, DESIGN §2): coefficients, value
//! and exact gradient over existence probabilities `p ∈ [0, 1]^N`.
//!
//! `L(p) = w_prim · Σ_i p_i g_i + w_point · Σ_y E_y(p)` where
//!
//! * `g_i = Σ_{x∈σ_i} min_{y∈D} ‖x − y‖²` (thesis eq. 6.1), and
//! * `E_y` is the expected squared distance from `y` to the nearest existing sample
//!   (thesis eq. 5.14), with the tail cost `d_cap` when nothing exists:
//!   `E_y = Σ_k d_k q_k Π_{l<k}(1 − q_l) + Π_all(1 − q_l) · d_cap` over `y`'s sorted
//!   entries `(owner, d_k)`, `q_k = p_owner(k)`.
//!
//! Two point models decide what the entries are ([`PointModel`]); the approximations α
//! (samples kept per candidate) and β (candidates kept per point) of thesis §6.2 bound
//! their number. Coefficients are computed **once** ([`Coefficients::build`]): each
//! evaluation afterwards is pure arithmetic over flat arrays ([`Evaluator`]).
//!
//! Memory: one entry is a `u32` candidate id plus an `f64` squared distance, stored as
//! two flat arrays: **12 bytes per (point, candidate) entry**, plus 8 bytes per point
//! for the row offsets.

use std::ops::Range;

use nalgebra::Point3;
use rayon::prelude::*;

use crate::progress::Progress;
use crate::spatial::PointIndex;
use crate::{Error, Result};

/// What the loss needs to know about candidates: their finite sample sets σ_i.
///
/// Implemented by [`crate::lattice::CandidateSet`] (shared local templates) and by
/// [`SampleSets`] (explicit samples with owners).
pub trait CandidateGeometry: Sync {
    /// Number of candidates N.
    fn len(&self) -> usize;
    /// True when there are no candidates.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// M_i, the number of samples of candidate `i`.
    fn sample_count(&self, i: usize) -> usize;
    /// Candidate `i`'s samples in scene coordinates, written into `out` (cleared first).
    fn scene_samples(&self, i: usize, out: &mut Vec<Point3<f64>>);
    /// A ball `(centre, radius)` containing all samples of candidate `i` and, where
    /// [`CandidateGeometry::surface_distance`] knows a continuous surface, that surface.
    fn bounding_ball(&self, i: usize) -> (Point3<f64>, f64);
    /// `(sample index, squared distance)` of candidate `i`'s sample nearest to `y`.
    fn nearest_sample(&self, i: usize, y: &Point3<f64>) -> (u32, f64);
    /// Squared distance from `y` to candidate `i`'s continuous surface, when the geometry
    /// knows it (the limit of infinitely dense samples). Defaults to the nearest sample.
    fn surface_distance(&self, i: usize, y: &Point3<f64>) -> f64 {
        self.nearest_sample(i, y).1
    }
    /// The `k` samples of candidate `i` nearest to `y` (all when `k` is `None`), sorted by
    /// (squared distance, sample index), written into `out` (cleared first).
    fn nearest_samples(
        &self,
        i: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    );
}

/// How the point term models which samples exist (DESIGN §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PointModel {
    /// A candidate's samples exist together, with its probability (exact expectation of
    /// the binary chamfer under independent Bernoulli existences). One entry per
    /// (point, candidate): each candidate's nearest sample.
    #[default]
    Existence,
    /// Every sample is kept independently with its owner's probability (thesis eq. 5.14).
    /// Up to α entries per (point, candidate).
    Independent,
}

impl PointModel {
    /// Name used on the CLI and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            PointModel::Existence => "existence",
            PointModel::Independent => "independent",
        }
    }
    /// Parses `"existence"` or `"independent"`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "existence" => Ok(PointModel::Existence),
            "independent" => Ok(PointModel::Independent),
            other => Err(Error::invalid(format!(
                "unknown point model {other:?} (existence|independent)"
            ))),
        }
    }
}

/// Options of the probabilistic chamfer.
#[derive(Debug, Clone, PartialEq)]
pub struct ChamferOptions {
    /// Point-term model.
    pub model: PointModel,
    /// α: samples kept per (point, candidate) for [`PointModel::Independent`]; `None` = all.
    pub alpha: Option<usize>,
    /// β: candidates kept per point (those whose nearest sample is closest); `None` = all.
    pub beta: Option<usize>,
    /// `d_cap` (squared distance): cost of a point that no existing candidate explains.
    pub cap: f64,
    /// Measure `d_i(y)` of the `existence` model (and the β ranking) to the candidate's
    /// continuous surface instead of its nearest sample.
    ///
    /// With sample distances, a second candidate overlapping the same surface lowers the
    /// point term (its samples interleave with the first one's), so the loss rewards
    /// redundant copies; surface distances remove that artefact. The fitter turns this on;
    /// the default (off) is DESIGN §2's sample-based definition.
    pub surface_distance: bool,
    /// Weight of the primitive term.
    pub primitive_weight: f64,
    /// Weight of the point term.
    pub point_weight: f64,
}

impl Default for ChamferOptions {
    fn default() -> Self {
        ChamferOptions {
            model: PointModel::Existence,
            alpha: None,
            beta: None,
            cap: 0.0,
            surface_distance: false,
            primitive_weight: 1.0,
            point_weight: 1.0,
        }
    }
}

impl ChamferOptions {
    /// Checks ranges (α, β ≥ 1; cap, weights finite and ≥ 0).
    pub fn validate(&self) -> Result<()> {
        if self.alpha == Some(0) || self.beta == Some(0) {
            return Err(Error::invalid(
                "alpha and beta must be at least 1 (or unlimited)",
            ));
        }
        if !(self.cap.is_finite() && self.cap >= 0.0) {
            return Err(Error::invalid(format!(
                "cap must be finite and ≥ 0, got {}",
                self.cap
            )));
        }
        for (n, w) in [
            ("primitive", self.primitive_weight),
            ("point", self.point_weight),
        ] {
            if !(w.is_finite() && w >= 0.0) {
                return Err(Error::invalid(format!(
                    "{n} weight must be finite and ≥ 0, got {w}"
                )));
            }
        }
        Ok(())
    }
}

/// Precomputed coefficients of the probabilistic chamfer for one cloud and candidate set.
///
/// Row `j` (input point `y_j`) holds entries `offsets[j]..offsets[j+1]` of `cand`/`dist`,
/// sorted by ascending squared distance.
#[derive(Debug, Clone)]
pub struct Coefficients {
    /// Primitive-term coefficients g_i (eq. 6.1).
    pub g: Vec<f64>,
    /// Row offsets, length J + 1.
    pub offsets: Vec<usize>,
    /// Owner candidate of each entry.
    pub cand: Vec<u32>,
    /// Squared distance of each entry.
    pub dist: Vec<f64>,
    /// The options the coefficients were built with.
    pub options: ChamferOptions,
    /// Longest row.
    pub max_row: usize,
}

/// Points per parallel work item when building coefficients.
const BUILD_CHUNK: usize = 1024;

/// Destination rows per parallel task when the rows are put back in cloud order.
const GATHER_BLOCK: usize = 4096;

impl Coefficients {
    /// Computes g and the sorted point entries (thesis algorithms 4 and 6) in parallel.
    pub fn build(
        cloud: &[Point3<f64>],
        geometry: &impl CandidateGeometry,
        options: &ChamferOptions,
        progress: &dyn Progress,
    ) -> Result<Self> {
        options.validate()?;
        let n = geometry.len();
        check_candidate_count(n)?;
        let cloud_index = PointIndex::new(cloud);
        progress.start("primitive term", n as u64);
        let g = primitive_coefficients(&cloud_index, geometry, progress);
        progress.finish();
        let rows = PointRows::build(cloud, geometry, options, progress);
        Ok(rows.into_coefficients(g, options.clone()))
    }

    /// Number of candidates N.
    pub fn candidates(&self) -> usize {
        self.g.len()
    }
    /// Number of input points J.
    pub fn points(&self) -> usize {
        self.offsets.len() - 1
    }
    /// Number of (point, candidate[, sample]) entries.
    pub fn entries(&self) -> usize {
        self.cand.len()
    }
    /// Bytes per entry of the point term (candidate id + squared distance).
    pub const BYTES_PER_ENTRY: usize = std::mem::size_of::<u32>() + std::mem::size_of::<f64>();
    /// Heap bytes held by the coefficients.
    pub fn bytes(&self) -> usize {
        self.entries() * Self::BYTES_PER_ENTRY
            + self.offsets.len() * std::mem::size_of::<usize>()
            + self.g.len() * std::mem::size_of::<f64>()
    }
    /// Entry range of point `j`.
    #[inline]
    pub fn row(&self, j: usize) -> Range<usize> {
        self.offsets[j]..self.offsets[j + 1]
    }

    /// About `target` of the rows (a deterministic pseudo-random choice of points), with
    /// the point weight scaled by `J / rows kept` so that the point term stays an unbiased
    /// estimate of the full one. Every row when `target ≥ J`.
    pub fn row_sample(&self, target: usize) -> Coefficients {
        let j_all = self.points();
        let every = j_all.div_ceil(target.max(1)).max(1) as u64;
        let chosen: Vec<usize> = (0..j_all)
            .filter(|&j| splitmix64(j as u64).is_multiple_of(every))
            .collect();
        let mut offsets = Vec::with_capacity(chosen.len() + 1);
        offsets.push(0);
        let total: usize = chosen.iter().map(|&j| self.row(j).len()).sum();
        let (mut cand, mut dist) = (Vec::with_capacity(total), Vec::with_capacity(total));
        let mut max_row = 0;
        for &j in &chosen {
            let r = self.row(j);
            max_row = max_row.max(r.len());
            cand.extend_from_slice(&self.cand[r.clone()]);
            dist.extend_from_slice(&self.dist[r]);
            offsets.push(cand.len());
        }
        let mut options = self.options.clone();
        options.point_weight *= j_all as f64 / chosen.len().max(1) as f64;
        Coefficients {
            g: self.g.clone(),
            offsets,
            cand,
            dist,
            options,
            max_row,
        }
    }
}

/// A 64-bit mix of `x` (SplitMix64's finaliser): a fixed, well-spread hash.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Candidate ids are `u32` in the entries.
fn check_candidate_count(n: usize) -> Result<()> {
    if n > u32::MAX as usize {
        return Err(Error::TooLarge(format!(
            "{n} candidates (at most {})",
            u32::MAX
        )));
    }
    Ok(())
}

/// g_i for every candidate: sum over its samples of the squared distance to the nearest
/// input point (thesis algorithm 4).
fn primitive_coefficients(
    cloud_index: &PointIndex,
    geometry: &impl CandidateGeometry,
    progress: &dyn Progress,
) -> Vec<f64> {
    (0..geometry.len())
        .into_par_iter()
        .map_init(Vec::new, |buf, i| {
            geometry.scene_samples(i, buf);
            let s = buf
                .iter()
                .map(|x| cloud_index.nearest(x).map_or(f64::INFINITY, |r| r.1))
                .sum();
            progress.advance(1);
            s
        })
        .collect()
}

/// The point term's sorted entries, row by row (thesis algorithm 6), before they are
/// packed into [`Coefficients`].
pub(crate) struct PointRows {
    /// Entries per row.
    pub lens: Vec<usize>,
    /// Owner candidate of each entry, rows concatenated.
    pub cand: Vec<u32>,
    /// Squared distance of each entry.
    pub dist: Vec<f64>,
}

impl PointRows {
    /// Each point's entries (its β nearest candidates, or their α nearest samples), in
    /// parallel over chunks of points.
    pub fn build(
        cloud: &[Point3<f64>],
        geometry: &impl CandidateGeometry,
        options: &ChamferOptions,
        progress: &dyn Progress,
    ) -> Self {
        let n = geometry.len();
        progress.start("point term", cloud.len() as u64);
        let centres = CentreIndex::new(geometry);
        // Entries per row when β bounds them (β candidates × at most α samples); 0 = unknown
        // or too large to reserve blindly.
        let row_bound = options.beta.map_or(0, |b| {
            b.min(n).saturating_mul(match options.model {
                PointModel::Existence => 1,
                PointModel::Independent => options.alpha.unwrap_or(0),
            })
        });
        let row_bound = if row_bound <= 4096 { row_bound } else { 0 };
        // Points are visited cell by cell (cells of side `cell`, in key order) so that each
        // cell's candidate list is fetched from the tree once and shared by its points;
        // the rows are put back in cloud order at the end.
        let cell = CellGrid::new(cloud, centres.max_radius / 4.0);
        let mut order: Vec<(u64, u32)> = cloud
            .par_iter()
            .enumerate()
            .map(|(j, y)| (cell.key(y), j as u32))
            .collect();
        order.par_sort_unstable();
        let chunks: Vec<(Vec<usize>, Vec<u32>, Vec<f64>)> = order
            .par_chunks(BUILD_CHUNK)
            .map(|chunk| {
                let mut builder = RowBuilder::new(geometry, &centres, options);
                let mut lens = Vec::with_capacity(chunk.len());
                // Reserving the bound up front avoids up to 2× growth slack per chunk: the
                // chunks coexist with the final arrays while they are copied (the build's
                // peak; 11 GB measured at 10M hallway points without this).
                let reserve = chunk.len() * row_bound;
                let (mut c, mut d) = (Vec::with_capacity(reserve), Vec::with_capacity(reserve));
                for &(key, j) in chunk {
                    if builder.cell_key != Some(key) {
                        builder.load_cell(key, &cell);
                    }
                    let before = c.len();
                    builder.push_row(&cloud[j as usize], &mut c, &mut d);
                    lens.push(c.len() - before);
                }
                progress.advance(chunk.len() as u64);
                (lens, c, d)
            })
            .collect();
        progress.finish();

        // Back to cloud order: where each point's row lies among the chunks, then a gather
        // in parallel over blocks of destination rows (each block writes its rows in order;
        // a scatter in chunk order wrote them at random and took 16 s at 10M points).
        let mut lens = vec![0usize; cloud.len()];
        let mut from = vec![(0u32, 0usize); cloud.len()];
        for (k, ((chunk_lens, _, _), points)) in
            chunks.iter().zip(order.chunks(BUILD_CHUNK)).enumerate()
        {
            let mut at = 0;
            for (&l, &(_, j)) in chunk_lens.iter().zip(points) {
                lens[j as usize] = l;
                from[j as usize] = (k as u32, at);
                at += l;
            }
        }
        drop(order);
        let total: usize = lens.iter().sum();
        let mut cand = vec![0u32; total];
        let mut dist = vec![0.0f64; total];
        let mut blocks = Vec::with_capacity(cloud.len().div_ceil(GATHER_BLOCK));
        let (mut cand_rest, mut dist_rest) = (&mut cand[..], &mut dist[..]);
        for first in (0..cloud.len()).step_by(GATHER_BLOCK) {
            let points = first..(first + GATHER_BLOCK).min(cloud.len());
            let len: usize = lens[points.clone()].iter().sum();
            let (c, c_tail) = std::mem::take(&mut cand_rest).split_at_mut(len);
            let (d, d_tail) = std::mem::take(&mut dist_rest).split_at_mut(len);
            (cand_rest, dist_rest) = (c_tail, d_tail);
            blocks.push((points, c, d));
        }
        blocks.into_par_iter().for_each(|(points, c_out, d_out)| {
            let mut at = 0;
            for j in points {
                let (l, (k, offset)) = (lens[j], from[j]);
                let (_, c, d) = &chunks[k as usize];
                c_out[at..at + l].copy_from_slice(&c[offset..offset + l]);
                d_out[at..at + l].copy_from_slice(&d[offset..offset + l]);
                at += l;
            }
        });
        PointRows { lens, cand, dist }
    }

    /// Packs the rows with the primitive term `g` into [`Coefficients`].
    pub fn into_coefficients(self, g: Vec<f64>, options: ChamferOptions) -> Coefficients {
        let mut offsets = Vec::with_capacity(self.lens.len() + 1);
        offsets.push(0);
        let mut max_row = 0;
        for &l in &self.lens {
            max_row = max_row.max(l);
            offsets.push(offsets.last().copied().unwrap_or(0) + l);
        }
        Coefficients {
            g,
            offsets,
            cand: self.cand,
            dist: self.dist,
            options,
            max_row,
        }
    }
}

/// A grid of cubic cells over the cloud's bounding box, for visiting points cell by cell.
struct CellGrid {
    origin: Point3<f64>,
    side: f64,
}

impl CellGrid {
    /// Cells of about `side` (coarser if the box would need more than 2²⁰ cells per axis).
    fn new(cloud: &[Point3<f64>], side: f64) -> Self {
        let (lo, hi) =
            crate::cloud::bounds_of(cloud).unwrap_or((Point3::origin(), Point3::origin()));
        let extent = (hi - lo).max();
        let side = side.max(extent / f64::from(1u32 << 20)).max(1e-12);
        CellGrid { origin: lo, side }
    }

    /// The cell of `y`: three 21-bit cell indices packed into one key.
    fn key(&self, y: &Point3<f64>) -> u64 {
        let index =
            |v: f64, o: f64| (((v - o) / self.side).floor().max(0.0) as u64).min((1 << 21) - 1);
        (index(y.x, self.origin.x) << 42)
            | (index(y.y, self.origin.y) << 21)
            | index(y.z, self.origin.z)
    }

    /// Centre of the cell with `key`.
    fn centre(&self, key: u64) -> Point3<f64> {
        let mask = (1u64 << 21) - 1;
        let at = |k: u64, o: f64| o + (k as f64 + 0.5) * self.side;
        Point3::new(
            at(key >> 42, self.origin.x),
            at((key >> 21) & mask, self.origin.y),
            at(key & mask, self.origin.z),
        )
    }

    /// Half the diagonal of a cell: every point of a cell is this close to its centre.
    fn half_diagonal(&self) -> f64 {
        self.side * 3f64.sqrt() / 2.0
    }
}

/// A KD-tree over candidate bounding-ball centres, for finding the candidates near a point.
struct CentreIndex {
    index: PointIndex,
    /// Bounding radius of each candidate (its samples and surface lie within it).
    radii: Vec<f64>,
    max_radius: f64,
}

impl CentreIndex {
    fn new(geometry: &impl CandidateGeometry) -> Self {
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
        let lb = (centre_d2.sqrt() * (1.0 - 1e-12) - self.radii[i] * (1.0 + 1e-12)).max(0.0);
        lb * lb
    }
}

/// Builds the sorted entries of one point at a time, reusing its buffers.
struct RowBuilder<'a, G: CandidateGeometry> {
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
    fn new(geometry: &'a G, centres: &'a CentreIndex, options: &'a ChamferOptions) -> Self {
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
        }
    }

    /// Fetches the candidates near cell `key`: those a search of radius ρ (the current
    /// start radius) from any point of the cell can reach, with their distances from the
    /// cell's centre, sorted.
    fn load_cell(&mut self, key: u64, grid: &CellGrid) {
        let c = self.centres;
        self.cell_key = Some(key);
        self.cell_radius = self.start_radius.max(1e-9);
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
    fn push_row(&mut self, y: &Point3<f64>, cand: &mut Vec<u32>, dist: &mut Vec<f64>) {
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
        }
        loop {
            if grow {
                rho = if worst.is_finite() {
                    // Every candidate within the β-th distance has its centre within reach.
                    worst.sqrt().max(rho * 1.000_001)
                } else {
                    rho.max(1e-9) * 2.0
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

    /// Neighbouring points need about the same radius; a margin saves most repeated
    /// searches. The result never depends on it.
    fn remember(&mut self, worst: f64) {
        if worst.is_finite() {
            self.start_radius = 1.25 * worst.sqrt();
        }
    }

    /// The β best of the current cell's candidates into `self.near`; returns the β-th
    /// squared distance (∞ if the cell has fewer than β).
    ///
    /// A distance to a set is 1-Lipschitz, so `d_i(y) ≥ d_i(m) − ‖y − m‖` for the cell's
    /// centre `m`: with the candidates sorted by `d_i(m)`, the scan stops at the first one
    /// whose bound exceeds the β-th distance found so far, and every one after it is
    /// farther still. The bound is loosened by a relative 1e-12 against rounding.
    fn scan_cell(&mut self, y: &Point3<f64>, beta: usize) -> f64 {
        let delta = (y - self.cell_centre).norm();
        self.best.clear();
        let mut w = f64::INFINITY;
        for &(dm, i) in &self.cell_sorted {
            if dm * (1.0 - 1e-12) - delta * (1.0 + 1e-12) > w * (1.0 + 1e-12) {
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

/// The two terms of the loss and their weighted total.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LossValue {
    /// Σ_i p_i g_i (unweighted).
    pub primitive: f64,
    /// Σ_y E_y (unweighted).
    pub point: f64,
    /// `w_prim · primitive + w_point · point`.
    pub total: f64,
}

/// Evaluates the loss and its gradient over precomputed [`Coefficients`] without allocating.
///
/// Points are split into a fixed number of blocks (a function of the problem size only,
/// never of the thread count), each with its own gradient accumulator; blocks are summed in
/// a fixed order, so results are bit-identical whatever the number of rayon threads.
pub struct Evaluator<'c> {
    coeffs: &'c Coefficients,
    blocks: Vec<Range<usize>>,
    block_grad: Vec<Vec<f64>>,
    block_value: Vec<f64>,
    scratch: Vec<Vec<f64>>,
}

/// Upper bound on the f64 cells of all block gradient accumulators together (256 MiB).
const MAX_ACCUMULATOR_CELLS: usize = 1 << 25;

impl<'c> Evaluator<'c> {
    /// Allocates the work buffers for `coeffs`.
    pub fn new(coeffs: &'c Coefficients) -> Self {
        let j = coeffs.points();
        let n = coeffs.candidates().max(1);
        let count = j
            .div_ceil(2048)
            .clamp(1, 64)
            .min((MAX_ACCUMULATOR_CELLS / n).max(1));
        let per = j.div_ceil(count).max(1);
        let blocks: Vec<Range<usize>> = (0..count)
            .map(|b| (b * per).min(j)..((b + 1) * per).min(j))
            .collect();
        Evaluator {
            coeffs,
            block_grad: vec![vec![0.0; coeffs.candidates()]; blocks.len()],
            block_value: vec![0.0; blocks.len()],
            scratch: vec![vec![0.0; coeffs.max_row]; blocks.len()],
            blocks,
        }
    }

    /// The coefficients evaluated.
    pub fn coefficients(&self) -> &Coefficients {
        self.coeffs
    }

    /// Loss at `p` (length N, values in [0, 1]); writes ∂total/∂p into `grad` (length N).
    pub fn evaluate(&mut self, p: &[f64], grad: &mut [f64]) -> LossValue {
        let c = self.coeffs;
        debug_assert_eq!(p.len(), c.candidates());
        debug_assert_eq!(grad.len(), c.candidates());
        let cap = c.options.cap;
        self.blocks
            .par_iter()
            .zip(self.block_grad.par_iter_mut())
            .zip(self.block_value.par_iter_mut())
            .zip(self.scratch.par_iter_mut())
            .for_each(|(((range, bg), bv), erd)| {
                bg.iter_mut().for_each(|g| *g = 0.0);
                let mut value = 0.0;
                for j in range.clone() {
                    let r = c.row(j);
                    value += point_expectation(&c.cand[r.clone()], &c.dist[r], p, cap, erd, bg);
                }
                *bv = value;
            });
        let point: f64 = self.block_value.iter().sum();
        let primitive: f64 = c.g.iter().zip(p).map(|(g, p)| g * p).sum();
        let (wp, wq) = (c.options.primitive_weight, c.options.point_weight);
        let block_grad = &self.block_grad;
        grad.par_chunks_mut(4096).enumerate().for_each(|(k, out)| {
            let start = k * 4096;
            for (o, (i, gi)) in out.iter_mut().zip(c.g[start..].iter().enumerate()) {
                let mut s = 0.0;
                for bg in block_grad {
                    s += bg[start + i];
                }
                *o = wp * gi + wq * s;
            }
        });
        LossValue {
            primitive,
            point,
            total: wp * primitive + wq * point,
        }
    }

    /// The loss at a binary scene (`exists[i]` = candidate i exists): the exact binary
    /// chamfer under the same entries and cap.
    pub fn binary_value(&mut self, exists: &[bool]) -> LossValue {
        let p: Vec<f64> = exists.iter().map(|&e| if e { 1.0 } else { 0.0 }).collect();
        let mut grad = vec![0.0; p.len()];
        self.evaluate(&p, &mut grad)
    }
}

/// `E_y` for one point's sorted entries, adding `∂E_y/∂p_i` into `grad`.
///
/// Backward pass: `ERD_K = d_cap`, `ERD_{k-1} = q_k d_k + (1 − q_k) ERD_k` (thesis eq. 6.6);
/// forward pass: `∂E_y/∂q_k = Π_{l<k}(1 − q_l) · (d_k − ERD_k)`, summed per owner.
#[inline]
fn point_expectation(
    cand: &[u32],
    dist: &[f64],
    p: &[f64],
    cap: f64,
    erd: &mut [f64],
    grad: &mut [f64],
) -> f64 {
    let k = cand.len();
    let mut r = cap;
    for m in (0..k).rev() {
        erd[m] = r; // ERD after entry m
        let q = p[cand[m] as usize];
        r = q * dist[m] + (1.0 - q) * r;
    }
    let mut survive = 1.0;
    for m in 0..k {
        let i = cand[m] as usize;
        grad[i] += survive * (dist[m] - erd[m]);
        survive *= 1.0 - p[i];
        if survive == 0.0 {
            break;
        }
    }
    r
}

/// Explicit candidate sample sets: samples `(K, 3)` with an owner candidate each, as the
/// Python API takes them. Samples keep their input order within a candidate (the α
/// tie-break is the lower sample index).
#[derive(Debug)]
pub struct SampleSets {
    samples: Vec<Point3<f64>>,
    ranges: Vec<Range<usize>>,
    indexes: Vec<PointIndex>,
    balls: Vec<(Point3<f64>, f64)>,
}

impl SampleSets {
    /// Groups `samples` by `owner` (each in `0..n`). Every candidate needs ≥ 1 sample.
    pub fn new(samples: &[Point3<f64>], owner: &[usize], n: usize) -> Result<Self> {
        if samples.len() != owner.len() {
            return Err(Error::Shape(format!(
                "{} samples but {} owners",
                samples.len(),
                owner.len()
            )));
        }
        let mut counts = vec![0usize; n];
        for (k, &o) in owner.iter().enumerate() {
            if o >= n {
                return Err(Error::invalid(format!(
                    "owner[{k}] = {o} is not a candidate index (N = {n})"
                )));
            }
            counts[o] += 1;
        }
        if let Some(empty) = counts.iter().position(|&c| c == 0) {
            return Err(Error::invalid(format!("candidate {empty} has no samples")));
        }
        let mut order: Vec<usize> = (0..samples.len()).collect();
        order.sort_by_key(|&k| owner[k]); // stable: input order within a candidate
        let sorted: Vec<Point3<f64>> = order.iter().map(|&k| samples[k]).collect();
        let mut ranges = Vec::with_capacity(n);
        let mut start = 0;
        for c in counts {
            ranges.push(start..start + c);
            start += c;
        }
        let indexes = ranges
            .par_iter()
            .map(|r| PointIndex::new(&sorted[r.clone()]))
            .collect();
        let balls = ranges
            .iter()
            .map(|r| {
                let s = &sorted[r.clone()];
                let centre = Point3::from(
                    s.iter().map(|p| p.coords).sum::<nalgebra::Vector3<f64>>() / s.len() as f64,
                );
                (
                    centre,
                    s.iter().map(|p| (p - centre).norm()).fold(0.0, f64::max),
                )
            })
            .collect();
        Ok(SampleSets {
            samples: sorted,
            ranges,
            indexes,
            balls,
        })
    }
}

impl CandidateGeometry for SampleSets {
    fn len(&self) -> usize {
        self.ranges.len()
    }
    fn sample_count(&self, i: usize) -> usize {
        self.ranges[i].len()
    }
    fn scene_samples(&self, i: usize, out: &mut Vec<Point3<f64>>) {
        out.clear();
        out.extend_from_slice(&self.samples[self.ranges[i].clone()]);
    }
    fn bounding_ball(&self, i: usize) -> (Point3<f64>, f64) {
        self.balls[i]
    }
    fn nearest_sample(&self, i: usize, y: &Point3<f64>) -> (u32, f64) {
        self.indexes[i].nearest(y).unwrap_or((0, f64::INFINITY))
    }
    fn nearest_samples(
        &self,
        i: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    ) {
        out.clear();
        let s = &self.samples[self.ranges[i].clone()];
        match k {
            Some(k) if k < s.len() => out.extend(self.indexes[i].nearest_n(y, k)),
            _ => {
                out.extend(
                    s.iter()
                        .enumerate()
                        .map(|(j, x)| (j as u32, (x - y).norm_squared())),
                );
                out.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            }
        }
    }
}

mod dominance;
pub use dominance::Reduced;

#[cfg(test)]
mod tests;
