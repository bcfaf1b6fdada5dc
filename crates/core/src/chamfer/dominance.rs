//! Exact removal of candidates that cannot exist at any minimum of the loss.
//!
//! **Why it is exact.** `∂L/∂p_i = w_prim g_i + w_point Σ_y ∂E_y/∂p_i`, and an entry k of
//! row y owned by i contributes `Π_{l<k}(1 − q_l) · (d_k − ERD_k)` (thesis eq. 6.6), where
//! `ERD_k` is a convex combination of the later entries' distances and `d_cap`. So every
//! entry contributes at least `−(M_k − d_k)⁺` with `M_k = max(d_cap, d_{k+1}, …)`. With
//! `S_i = Σ_{entries k of i} (M_k − d_k)⁺` (the most existing can ever save), a candidate
//! with `w_prim g_i > w_point S_i` has `∂L/∂p_i > 0` everywhere in `[0, 1]^N`: lowering
//! `p_i` always lowers the loss, so `p_i = 0` at every minimum, and adding it to any
//! binary scene raises the loss. The argument needs no multilinearity, so it holds for
//! both point models and any α/β.
//!
//! Such a candidate is **dominated**: it is dropped with its entries. An entry with
//! `q = 0` changes neither `ERD` nor the survival products, so the reduced loss equals the
//! full loss at `p_i = 0` exactly. Dropping entries only lowers the other candidates'
//! `M_k`, so the test is repeated on the reduced rows until nothing more drops (each later
//! round is the same proof on the loss restricted to `p = 0` for the earlier drops).
//!
//! **Why it is cheap.** `g_i` is a sum of non-negative squared distances, so any partial
//! sum is a lower bound: samples are visited in an interleaved order (every 8th first)
//! and a candidate's sum stops as soon as it proves dominance. Most candidates of a
//! lattice lie beside the data rather than on it and are decided after a fraction of
//! their samples (the 20k-point pipe: 82 % of candidates dropped, 5.3× fewer
//! nearest-neighbour queries for the primitive term).

use nalgebra::Point3;
use rayon::prelude::*;

use super::{CandidateGeometry, ChamferOptions, Coefficients, PointRows, check_candidate_count};
use crate::Result;
use crate::progress::Progress;
use crate::spatial::{BoxTree, Hint};

/// Coefficients over the candidates that can exist, and which candidates those are.
#[derive(Debug, Clone)]
pub struct Reduced {
    /// Coefficients of the kept candidates, numbered `0..kept.len()`.
    pub coefficients: Coefficients,
    /// Original index of each kept candidate, ascending.
    pub kept: Vec<usize>,
}

impl Reduced {
    /// `keep[i]`: whether original candidate `i` (of `n`) was kept.
    pub fn keep_mask(&self, n: usize) -> Vec<bool> {
        let mut keep = vec![false; n];
        for &i in &self.kept {
            keep[i] = true;
        }
        keep
    }
}

impl Coefficients {
    /// Like [`Coefficients::build`], then drops the dominated candidates (module docs):
    /// the minimisers of the reduced loss, padded with `p = 0` for the dropped candidates,
    /// are exactly the minimisers of the full loss.
    ///
    /// The primitive term's nearest points come from a [`BoxTree`] over `cloud`, built
    /// here and dropped after: most samples of a lattice lie beside the data, where its
    /// tight boxes settle a query after a few leaves (same sums as the kd-tree's;
    /// measured in docs/performance.md).
    pub fn build_reduced(
        cloud: &[Point3<f64>],
        geometry: &impl CandidateGeometry,
        options: &ChamferOptions,
        progress: &dyn Progress,
    ) -> Result<Reduced> {
        options.validate()?;
        let n = geometry.len();
        check_candidate_count(n)?;
        let mut rows = PointRows::build(cloud, geometry, options, progress);
        let (wp, wq) = (options.primitive_weight, options.point_weight);

        let savings = savings_bounds(&rows, n, options.cap);
        progress.start("primitive term", n as u64);
        let boxes = BoxTree::new(cloud);
        let bounded: Vec<Bounded> = (0..n)
            .into_par_iter()
            .map_init(Vec::new, |buf, i| {
                geometry.scene_samples(i, buf);
                let b = bounded_primitive_term(&boxes, buf, |g| wp * g > wq * savings[i]);
                progress.advance(1);
                b
            })
            .collect();
        progress.finish();

        let mut alive: Vec<bool> = bounded.iter().map(|b| b.exact).collect();
        let g: Vec<f64> = bounded.iter().map(|b| b.sum).collect();
        loop {
            rows.retain_candidates(&alive);
            let savings = savings_bounds(&rows, n, options.cap);
            let mut changed = false;
            for i in 0..n {
                if alive[i] && wp * g[i] > wq * savings[i] {
                    alive[i] = false;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }

        let kept: Vec<usize> = (0..n).filter(|&i| alive[i]).collect();
        let mut new_id = vec![u32::MAX; n];
        for (k, &i) in kept.iter().enumerate() {
            new_id[i] = k as u32;
        }
        rows.cand
            .par_iter_mut()
            .for_each(|c| *c = new_id[*c as usize]);
        let g = kept.iter().map(|&i| g[i]).collect();
        Ok(Reduced {
            coefficients: rows.into_coefficients(g, options.clone()),
            kept,
        })
    }
}

/// `S_i` of the module docs for every candidate: the largest decrease of the point term
/// that `p_i` can ever bring, per unit of `w_point`.
///
/// Summed over [`SAVINGS_BLOCKS`] fixed blocks of rows in parallel, then block by block
/// in order, so the sums do not depend on the thread count.
fn savings_bounds(rows: &PointRows, n: usize, cap: f64) -> Vec<f64> {
    let points = rows.lens.len();
    let per_block = points.div_ceil(SAVINGS_BLOCKS).max(1);
    let mut blocks = Vec::new();
    let mut entry = 0;
    for first in (0..points).step_by(per_block) {
        let last = (first + per_block).min(points);
        blocks.push((first..last, entry));
        entry += rows.lens[first..last].iter().sum::<usize>();
    }
    let partial: Vec<Vec<f64>> = blocks
        .into_par_iter()
        .map(|(block, mut start)| {
            let mut savings = vec![0.0; n];
            for &len in &rows.lens[block] {
                let cand = &rows.cand[start..start + len];
                let dist = &rows.dist[start..start + len];
                // M_k = max(d_cap, distances after k), walking the row backwards.
                let mut later_max = cap;
                for (&i, &d) in cand.iter().zip(dist).rev() {
                    savings[i as usize] += (later_max - d).max(0.0);
                    later_max = later_max.max(d);
                }
                start += len;
            }
            savings
        })
        .collect();
    let mut savings = vec![0.0; n];
    for block in partial {
        for (total, s) in savings.iter_mut().zip(block) {
            *total += s;
        }
    }
    savings
}

/// Blocks of rows summed in parallel by [`savings_bounds`] (a constant, so results do
/// not depend on the machine).
const SAVINGS_BLOCKS: usize = 16;

/// A primitive-term sum that may have stopped early.
#[derive(Debug, Clone, Copy)]
struct Bounded {
    /// The sum over the samples visited: `g_i` when `exact`, a lower bound otherwise.
    sum: f64,
    /// Whether every sample was visited.
    exact: bool,
}

/// Interleaving of the samples: every 8th sample from offset 0, then 4, 2, 6, …, so that
/// each prefix of the visit covers the whole candidate.
const VISIT_OFFSETS: [usize; 8] = [0, 4, 2, 6, 1, 5, 3, 7];

/// `Σ_{x∈samples} min_y ‖x − y‖²`, stopping (inexact) as soon as `dominated(partial sum)`.
fn bounded_primitive_term(
    cloud: &BoxTree,
    samples: &[Point3<f64>],
    dominated: impl Fn(f64) -> bool,
) -> Bounded {
    let mut sum = 0.0;
    let mut hint = Hint::default();
    for offset in VISIT_OFFSETS {
        for x in samples.iter().skip(offset).step_by(VISIT_OFFSETS.len()) {
            sum += cloud.nearest(x, &mut hint);
            if dominated(sum) {
                return Bounded { sum, exact: false };
            }
        }
    }
    Bounded { sum, exact: true }
}

impl PointRows {
    /// Removes the entries of candidates with `alive[i] == false` (ids unchanged).
    fn retain_candidates(&mut self, alive: &[bool]) {
        let mut write = 0;
        let mut read = 0;
        for len in &mut self.lens {
            let mut kept = 0;
            for k in read..read + *len {
                if alive[self.cand[k] as usize] {
                    self.cand[write] = self.cand[k];
                    self.dist[write] = self.dist[k];
                    write += 1;
                    kept += 1;
                }
            }
            read += *len;
            *len = kept;
        }
        self.cand.truncate(write);
        self.dist.truncate(write);
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::chamfer::{Evaluator, PointModel, SampleSets};
    use crate::progress::Silent;

    /// Points on a few "true" candidates' samples (plus noise) and decoy candidates at
    /// random places, some overlapping the data and some far from it.
    struct Problem {
        cloud: Vec<Point3<f64>>,
        samples: Vec<Point3<f64>>,
        owner: Vec<usize>,
        n: usize,
    }

    fn problem(seed: u64, n: usize) -> Problem {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut pt = |scale: f64| {
            Point3::new(
                rng.random_range(-scale..scale),
                rng.random_range(-scale..scale),
                rng.random_range(-scale..scale),
            )
        };
        let mut samples = Vec::new();
        let mut owner = Vec::new();
        let mut cloud = Vec::new();
        for i in 0..n {
            let centre = pt(2.0);
            for _ in 0..6 {
                let s = centre + pt(0.3).coords;
                samples.push(s);
                owner.push(i);
                if i % 3 == 0 {
                    cloud.push(s + pt(0.02).coords);
                }
            }
        }
        Problem {
            cloud,
            samples,
            owner,
            n,
        }
    }

    fn options(model: PointModel, beta: Option<usize>) -> ChamferOptions {
        ChamferOptions {
            model,
            beta,
            alpha: Some(2),
            cap: 0.3,
            ..Default::default()
        }
    }

    fn build(pr: &Problem, o: &ChamferOptions) -> (Coefficients, Reduced) {
        let sets = SampleSets::new(&pr.samples, &pr.owner, pr.n).unwrap();
        let full = Coefficients::build(&pr.cloud, &sets, o, &Silent).unwrap();
        let reduced = Coefficients::build_reduced(&pr.cloud, &sets, o, &Silent).unwrap();
        (full, reduced)
    }

    fn value(c: &Coefficients, p: &[f64]) -> (f64, Vec<f64>) {
        let mut g = vec![0.0; p.len()];
        let v = Evaluator::new(c).evaluate(p, &mut g).total;
        (v, g)
    }

    #[test]
    fn the_reduced_loss_is_the_full_loss_with_dropped_candidates_absent() {
        let mut dropped_any = false;
        for seed in 0..20 {
            for model in [PointModel::Existence, PointModel::Independent] {
                for beta in [None, Some(3)] {
                    let pr = problem(seed, 12);
                    let (full, reduced) = build(&pr, &options(model, beta));
                    assert!(!reduced.kept.is_empty());
                    dropped_any |= reduced.kept.len() < pr.n;
                    for &i in &reduced.kept {
                        let k = reduced.kept.binary_search(&i).unwrap();
                        assert!((reduced.coefficients.g[k] - full.g[i]).abs() <= 1e-12 * full.g[i]);
                    }
                    let mut rng = ChaCha8Rng::seed_from_u64(seed + 100);
                    for _ in 0..5 {
                        let q: Vec<f64> = reduced
                            .kept
                            .iter()
                            .map(|_| rng.random_range(0.0..1.0))
                            .collect();
                        let mut p = vec![0.0; pr.n];
                        for (&i, &qi) in reduced.kept.iter().zip(&q) {
                            p[i] = qi;
                        }
                        let (vf, gf) = value(&full, &p);
                        let (vr, gr) = value(&reduced.coefficients, &q);
                        assert!((vf - vr).abs() <= 1e-10 * vf.abs(), "{vf} vs {vr}");
                        for (&i, &g) in reduced.kept.iter().zip(&gr) {
                            assert!((gf[i] - g).abs() <= 1e-9 * (1.0 + gf[i].abs()));
                        }
                    }
                }
            }
        }
        assert!(
            dropped_any,
            "no problem had a dominated candidate: the test proves nothing"
        );
    }

    #[test]
    fn dropped_candidates_always_raise_the_loss_and_miss_every_binary_optimum() {
        let mut dropped = 0;
        for seed in 0..30 {
            for model in [PointModel::Existence, PointModel::Independent] {
                let n = 9;
                let pr = problem(seed, n);
                let (full, reduced) = build(&pr, &options(model, Some(4)));
                let keep = reduced.keep_mask(n);
                dropped += keep.iter().filter(|k| !**k).count();
                // A dropped candidate's gradient is positive at random points of the box
                // where the other dropped candidates are absent (later rounds of the test
                // are proved on the loss reduced by the earlier ones).
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                for i in (0..n).filter(|&i| !keep[i]) {
                    for _ in 0..20 {
                        let p: Vec<f64> = (0..n)
                            .map(|k| {
                                let r = rng.random_range(0.0..1.0);
                                if keep[k] || k == i { r } else { 0.0 }
                            })
                            .collect();
                        let (_, g) = value(&full, &p);
                        assert!(g[i] > 0.0, "seed {seed}: ∂L/∂p_{i} = {}", g[i]);
                    }
                }
                // Brute force over all 2^n binary scenes: no minimiser uses a dropped one.
                let scenes: Vec<(f64, u32)> = (0..1u32 << n)
                    .map(|mask| {
                        let p: Vec<f64> = (0..n).map(|i| f64::from((mask >> i) & 1)).collect();
                        (value(&full, &p).0, mask)
                    })
                    .collect();
                let best = scenes.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
                for &(v, mask) in &scenes {
                    if v <= best {
                        for i in (0..n).filter(|&i| !keep[i]) {
                            assert_eq!((mask >> i) & 1, 0, "seed {seed}: optimum uses {i}");
                        }
                    }
                }
            }
        }
        assert!(dropped > 0, "nothing was dropped: the test proves nothing");
    }
}
