//! The precomputed coefficients of the loss: the primitive term g and the point term's
//! sorted (candidate, squared distance) entries, row by row, in flat arrays.

use std::ops::Range;

use super::ChamferOptions;

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

impl Coefficients {
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
