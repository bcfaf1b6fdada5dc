//! Value and exact gradient of the loss over precomputed [`Coefficients`].

use std::ops::Range;

use rayon::prelude::*;

use super::{Coefficients, LossValue};

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

/// Points per block aimed at: the block count is `J / POINTS_PER_BLOCK`, clamped to
/// `1..=MAX_BLOCKS` and by [`MAX_ACCUMULATOR_CELLS`]. The blocks fix the summation order,
/// so changing either constant changes the results' last bits.
const POINTS_PER_BLOCK: usize = 2048;

/// Most blocks, each one parallel task with its own gradient accumulator (see
/// [`POINTS_PER_BLOCK`]).
const MAX_BLOCKS: usize = 64;

/// Candidates per parallel task when the block gradients are summed.
const GRADIENT_CHUNK: usize = 4096;

impl<'c> Evaluator<'c> {
    /// Allocates the work buffers for `coeffs`.
    pub fn new(coeffs: &'c Coefficients) -> Self {
        let j = coeffs.points();
        let n = coeffs.candidates().max(1);
        let count = j
            .div_ceil(POINTS_PER_BLOCK)
            .clamp(1, MAX_BLOCKS)
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
    ///
    /// `L(p) = w_prim · Σ_i p_i g_i + w_point · Σ_y E_y(p)` (thesis eqs. 6.1 and 5.14), the
    /// point term row by row (`point_expectation`).
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
        grad.par_chunks_mut(GRADIENT_CHUNK)
            .enumerate()
            .for_each(|(k, out)| {
                let start = k * GRADIENT_CHUNK;
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
