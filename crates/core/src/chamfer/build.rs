//! Building [`Coefficients`] (thesis algorithms 4 and 6): the primitive term by nearest
//! input points, the point term row by row in parallel, then the rows put back in cloud
//! order.

use nalgebra::Point3;
use rayon::prelude::*;

use super::row_builder::{CellGrid, CentreIndex, RowBuilder};
use super::{CandidateGeometry, ChamferOptions, Coefficients, PointModel};
use crate::error::{Error, Result, Unit};
use crate::progress::Progress;
use crate::spatial::{BoxTree, Hint, NearestDistance, PointIndex};

/// Points per parallel work item when building coefficients.
const BUILD_CHUNK: usize = 1024;

/// Destination rows per parallel task when the rows are put back in cloud order.
const GATHER_BLOCK: usize = 4096;

/// Largest row length (entries) reserved for every point of a chunk up front; a larger
/// bound (β × α) is too large to reserve blindly, and rows then grow as needed.
const MAX_RESERVED_ROW: usize = 4096;

/// Points are visited in cubic cells of side `R_max / CELLS_PER_RADIUS` (`R_max` the
/// largest candidate bounding radius, dimensionless): cells small next to a candidate, so
/// that a cell's candidate list fits all its points closely.
const CELLS_PER_RADIUS: f64 = 4.0;

impl Coefficients {
    /// Computes g and the sorted point entries (thesis algorithms 4 and 6) in parallel.
    ///
    /// The primitive term's nearest points come from a [`BoxTree`] over `cloud`: candidate
    /// samples beside the data are settled after a few of its leaves.
    pub fn build(
        cloud: &[Point3<f64>],
        geometry: &impl CandidateGeometry,
        options: &ChamferOptions,
        progress: &dyn Progress,
    ) -> Result<Self> {
        Self::build_with(cloud, &BoxTree::new(cloud), geometry, options, progress)
    }

    /// [`Coefficients::build`] with `cloud_index`, a kd-tree over exactly `cloud`,
    /// already built: for candidates whose samples lie on the data (a fit's own
    /// primitives), where the kd-tree is as fast and no second tree is built.
    pub fn build_indexed(
        cloud: &[Point3<f64>],
        cloud_index: &PointIndex,
        geometry: &impl CandidateGeometry,
        options: &ChamferOptions,
        progress: &dyn Progress,
    ) -> Result<Self> {
        Self::build_with(cloud, cloud_index, geometry, options, progress)
    }

    /// [`Coefficients::build`] with `nearest`, a tree over exactly `cloud`, already built
    /// (the registration keeps a [`BoxTree`] for all its measurements).
    pub(crate) fn build_with(
        cloud: &[Point3<f64>],
        nearest: &impl NearestDistance,
        geometry: &impl CandidateGeometry,
        options: &ChamferOptions,
        progress: &dyn Progress,
    ) -> Result<Self> {
        options.validate()?;
        crate::check::same_len("indexed points", nearest.len(), "points", cloud.len())?;
        let n = geometry.len();
        check_candidate_count(n)?;
        progress.start("primitive term", n as u64);
        let g = primitive_coefficients(nearest, geometry, progress);
        progress.finish();
        let rows = PointRows::build(cloud, geometry, options, progress);
        Ok(rows.into_coefficients(g, options.clone()))
    }
}

/// Candidate ids are `u32` in the entries.
pub(super) fn check_candidate_count(n: usize) -> Result<()> {
    if n > u32::MAX as usize {
        return Err(Error::OverLimit {
            what: "the candidate set".into(),
            need: n as f64,
            limit: u32::MAX as f64,
            unit: Unit::Count("candidates"),
            remedies: Vec::new(),
        });
    }
    Ok(())
}

/// g_i for every candidate: sum over its samples of the squared distance to the nearest
/// input point (thesis algorithm 4; squared scene units), in parallel over candidates.
/// Each sample's search starts from the previous sample's nearest point.
pub(crate) fn primitive_coefficients(
    cloud: &impl NearestDistance,
    geometry: &impl CandidateGeometry,
    progress: &dyn Progress,
) -> Vec<f64> {
    (0..geometry.len())
        .into_par_iter()
        .map_init(Vec::new, |buf, i| {
            geometry.scene_samples(i, buf);
            let mut hint = Hint::default();
            let s = buf
                .iter()
                .map(|x| cloud.nearest_distance(x, &mut hint))
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
    ///
    /// Points are visited cell by cell (cells of side `R_max / CELLS_PER_RADIUS`, in key
    /// order) so that each cell's candidate list is fetched from the tree once and shared
    /// by its points; the rows are put back in cloud order at the end.
    pub fn build(
        cloud: &[Point3<f64>],
        geometry: &impl CandidateGeometry,
        options: &ChamferOptions,
        progress: &dyn Progress,
    ) -> Self {
        progress.start("point term", cloud.len() as u64);
        let centres = CentreIndex::new(geometry);
        let row_bound = reserved_row_len(geometry.len(), options);
        let cell = CellGrid::new(cloud, centres.max_radius / CELLS_PER_RADIUS);
        let mut order: Vec<(u64, u32)> = cloud
            .par_iter()
            .enumerate()
            .map(|(j, y)| (cell.key(y), j as u32))
            .collect();
        order.par_sort_unstable();
        let new_builder = || RowBuilder::new(geometry, &centres, options);
        let chunks = rows_in_cell_order(cloud, &order, &cell, row_bound, new_builder, progress);
        progress.finish();
        gather_in_cloud_order(chunks, order)
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

/// Entries per row when β bounds them (β candidates × at most α samples); 0 = unknown or
/// above [`MAX_RESERVED_ROW`].
fn reserved_row_len(n: usize, options: &ChamferOptions) -> usize {
    let row_bound = options.beta.map_or(0, |b| {
        b.min(n).saturating_mul(match options.model {
            PointModel::Existence => 1,
            PointModel::Independent => options.alpha.unwrap_or(0),
        })
    });
    if row_bound <= MAX_RESERVED_ROW {
        row_bound
    } else {
        0
    }
}

/// The rows of the points in `order` (cell key, point index), in that order, one
/// [`PointRows`] per chunk of [`BUILD_CHUNK`] points, built in parallel.
fn rows_in_cell_order<'a, G: CandidateGeometry + 'a>(
    cloud: &[Point3<f64>],
    order: &[(u64, u32)],
    cell: &CellGrid,
    row_bound: usize,
    new_builder: impl Fn() -> RowBuilder<'a, G> + Sync,
    progress: &dyn Progress,
) -> Vec<PointRows> {
    order
        .par_chunks(BUILD_CHUNK)
        .map(|chunk| {
            let mut builder = new_builder();
            let mut lens = Vec::with_capacity(chunk.len());
            // Reserving the bound up front avoids up to 2× growth slack per chunk: the
            // chunks coexist with the final arrays while they are copied (the build's
            // peak; 11 GB measured at 10M hallway points without this).
            let reserve = chunk.len() * row_bound;
            let (mut c, mut d) = (Vec::with_capacity(reserve), Vec::with_capacity(reserve));
            for &(key, j) in chunk {
                if builder.needs_cell(key) {
                    builder.load_cell(key, cell);
                }
                let before = c.len();
                builder.push_row(&cloud[j as usize], &mut c, &mut d);
                lens.push(c.len() - before);
            }
            progress.advance(chunk.len() as u64);
            PointRows {
                lens,
                cand: c,
                dist: d,
            }
        })
        .collect()
}

/// The rows of `chunks` (built in the point order `order`) back in cloud order: where each
/// point's row lies among the chunks, then a gather in parallel over blocks of
/// destination rows (each block writes its rows in order; a scatter in chunk order wrote
/// them at random and took 16 s at 10M points).
fn gather_in_cloud_order(chunks: Vec<PointRows>, order: Vec<(u64, u32)>) -> PointRows {
    let points = order.len();
    let mut lens = vec![0usize; points];
    let mut from = vec![(0u32, 0usize); points];
    for (k, (chunk, chunk_points)) in chunks.iter().zip(order.chunks(BUILD_CHUNK)).enumerate() {
        let mut at = 0;
        for (&l, &(_, j)) in chunk.lens.iter().zip(chunk_points) {
            lens[j as usize] = l;
            from[j as usize] = (k as u32, at);
            at += l;
        }
    }
    drop(order);
    let total: usize = lens.iter().sum();
    let mut cand = vec![0u32; total];
    let mut dist = vec![0.0f64; total];
    let mut blocks = Vec::with_capacity(points.div_ceil(GATHER_BLOCK));
    let (mut cand_rest, mut dist_rest) = (&mut cand[..], &mut dist[..]);
    for first in (0..points).step_by(GATHER_BLOCK) {
        let rows = first..(first + GATHER_BLOCK).min(points);
        let len: usize = lens[rows.clone()].iter().sum();
        let (c, c_tail) = std::mem::take(&mut cand_rest).split_at_mut(len);
        let (d, d_tail) = std::mem::take(&mut dist_rest).split_at_mut(len);
        (cand_rest, dist_rest) = (c_tail, d_tail);
        blocks.push((rows, c, d));
    }
    blocks.into_par_iter().for_each(|(rows, c_out, d_out)| {
        let mut at = 0;
        for j in rows {
            let (l, (k, offset)) = (lens[j], from[j]);
            let chunk = &chunks[k as usize];
            c_out[at..at + l].copy_from_slice(&chunk.cand[offset..offset + l]);
            d_out[at..at + l].copy_from_slice(&chunk.dist[offset..offset + l]);
            at += l;
        }
    });
    PointRows { lens, cand, dist }
}
