//! Existence over candidates proposed from the data: the probabilistic chamfer (thesis
//! ch. 6) with each candidate's description length added to its primitive term.
//!
//! The loss minimised is `L(p) + Σ_i p_i c_i` with `c_i` the description length of
//! candidate `i` ([`super::mdl`]): linear in `p` like the primitive term, so it enters as
//! `g_i ← g_i + c_i / w_prim` and the L-BFGS, thresholding and polish of [`crate::solve`]
//! run unchanged. The primitive term is summed over each candidate's *supported* samples
//! (the caller's choice: of a tube, the sectors its points lie in), the point term over
//! the candidates' exact surfaces. Proposed candidates are few, so no dominance pruning.

use nalgebra::Point3;

use super::candidates::CandidateSamples;
use super::geometry::Supported;
use crate::chamfer::LossValue;
use crate::chamfer::{ChamferOptions, Coefficients};
use crate::lattice::CandidateSet;
use crate::progress::Progress;
use crate::solve::{Solution, SolverOptions, solve};
use crate::{PointIndex, Primitive, Result, StageTimes, Stopwatch, check};

/// What [`decide_existence`] found for each candidate, in the candidates' order.
#[derive(Debug, Clone)]
pub struct Existence {
    /// Decided existence (after thresholding and polish).
    pub exists: Vec<bool>,
    /// The continuous existence probability at the end of L-BFGS (0 for a candidate
    /// the dominance test removed).
    pub probability: Vec<f64>,
    /// The solver's output, over all candidates (a dominated candidate: probability 0,
    /// absent); `solution.binary.total` is the binary loss of the decided scene,
    /// description lengths included.
    pub solution: Solution,
    /// Wall time of `coefficients` and `solve`.
    pub times: StageTimes,
}

/// How [`decide_existence`] scores candidates.
#[derive(Debug, Clone)]
pub struct ExistenceOptions {
    /// Spacing of each candidate's surface samples σ_i (scene units).
    pub sample_spacing: f64,
    /// The loss.
    pub chamfer: ChamferOptions,
    /// The solver.
    pub solver: SolverOptions,
}

/// Decides which candidates exist for `points` (indexed by `index`, a kd-tree over
/// exactly them): candidate `i` is judged by `samples[i]` (its primitive term: at least
/// one sample, each weighted; a partial surface's point term too) and charged its
/// description length `cost[i]` (squared scene units).
pub fn decide_existence(
    points: &[Point3<f64>],
    index: &PointIndex,
    candidates: &[Primitive],
    samples: &[CandidateSamples],
    cost: &[f64],
    options: &ExistenceOptions,
    progress: &dyn Progress,
) -> Result<Existence> {
    check::same_len("costs", cost.len(), "candidates", candidates.len())?;
    check::same_len("sample sets", samples.len(), "candidates", candidates.len())?;
    let chamfer = &options.chamfer;
    let n = samples.len();
    let point = points.len() as f64 * chamfer.cap;
    let nothing = LossValue {
        primitive: 0.0,
        point,
        total: point * chamfer.point_weight,
    };
    if n == 0 {
        return Ok(Existence {
            exists: Vec::new(),
            probability: Vec::new(),
            solution: Solution::nothing(0, nothing),
            times: StageTimes::new(),
        });
    }
    // A candidate whose samples are a part of its surface is judged by them for both
    // terms; every other by its exact surface (`geometry.rs`).
    // The exact shapes serve their surface distances and bounding balls only, which do
    // not depend on the template's samples: sampled no finer than the coarsest candidate.
    let coarsest = samples.iter().map(|s| s.weight.sqrt()).fold(1.0, f64::max);
    let set = CandidateSet::from_primitives(candidates, options.sample_spacing * coarsest)?;
    let geometry = Supported::new(set, samples)?;
    let mut clock = Stopwatch::start();
    let mut coefficients =
        Coefficients::build_indexed(points, index, &geometry, chamfer, progress)?;
    clock.lap("coefficients");
    for ((g, c), s) in coefficients.g.iter_mut().zip(cost).zip(samples) {
        *g = *g * s.weight * s.sparse_scale + c / chamfer.primitive_weight;
    }
    let kept: Vec<usize> = (0..n).collect();
    let mut exists = vec![false; n];
    let mut probability = vec![0.0; n];
    let mut solution = solve(&coefficients, &options.solver, progress)?;
    clock.lap("solve");
    for (k, &i) in kept.iter().enumerate() {
        exists[i] = solution.exists[k];
        probability[i] = solution.probability[k];
    }
    solution.exists.clone_from(&exists);
    solution.probability.clone_from(&probability);
    Ok(Existence {
        exists,
        probability,
        solution,
        times: clock.times,
    })
}

#[cfg(test)]
mod tests {
    use nalgebra::{UnitQuaternion, Vector3};

    use super::*;

    use crate::chamfer::Evaluator;
    use crate::compact::mdl::primitive_cost;
    use crate::lattice::CandidateSet;
    use crate::progress::Silent;
    use crate::{Pose, Primitive, Shape};

    fn samples_of(cands: &[Primitive], spacing: f64) -> Vec<CandidateSamples> {
        (cands.iter())
            .map(|p| CandidateSamples {
                points: p.sample_surface(spacing),
                weight: 1.0,
                sparse_scale: 1.0,
                partial: false,
                tube: None,
            })
            .collect()
    }

    fn square(side: f64, x: f64, y: f64) -> Primitive {
        let pose = Pose::new(UnitQuaternion::identity(), Vector3::new(x, y, 0.0));
        Primitive::new(Shape::Square { side }, pose)
    }

    /// A 1 m square of points (2.5 cm grid) with a deterministic ±2 mm ripple.
    fn unit_square_points() -> Vec<Point3<f64>> {
        let n = 40;
        let mut out = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                let z = 0.002 * ((7 * i + 3 * j) % 5) as f64 / 4.0 - 0.001;
                out.push(Point3::new(u - 0.5, v - 0.5, z));
            }
        }
        out
    }

    fn options() -> ExistenceOptions {
        ExistenceOptions {
            sample_spacing: 0.025,
            chamfer: ChamferOptions {
                cap: 0.1 * 0.1,
                surface_distance: true,
                ..Default::default()
            },
            solver: SolverOptions::default(),
        }
    }

    /// One whole square, its four quarters, and one square with no points near it.
    fn candidates() -> Vec<Primitive> {
        let mut c = vec![square(1.0, 0.0, 0.0)];
        for (x, y) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
            c.push(square(0.5, x, y));
        }
        c.push(square(1.0, 3.0, 0.0));
        c
    }

    #[test]
    fn one_large_primitive_beats_its_four_quarters_and_is_the_brute_force_minimum() {
        let points = unit_square_points();

        let cands = candidates();
        let noise = 0.001;
        let cost: Vec<f64> = cands
            .iter()
            .map(|p| primitive_cost(p, noise, points.len()))
            .collect();
        let o = options();
        let samples = samples_of(&cands, o.sample_spacing);
        let e = decide_existence(
            &points,
            &PointIndex::new(&points),
            &cands,
            &samples,
            &cost,
            &o,
            &Silent,
        )
        .unwrap();
        assert_eq!(e.exists, [true, false, false, false, false, false]);

        // Brute force over all 2^6 scenes of the loss with the description lengths.
        // The point term from the candidates' surfaces; the primitive term summed by
        // brute force over every (sample, point) pair.
        let set = CandidateSet::from_primitives(&cands, o.sample_spacing).unwrap();
        let mut coefficients = Coefficients::build(&points, &set, &o.chamfer, &Silent).unwrap();
        for ((g, c), s) in coefficients.g.iter_mut().zip(&cost).zip(&samples) {
            let nearest = |x: &Point3<f64>| {
                points
                    .iter()
                    .map(|y| (x - y).norm_squared())
                    .fold(f64::INFINITY, f64::min)
            };
            *g = s.points.iter().map(nearest).sum::<f64>() + c;
        }
        let mut eval = Evaluator::new(&coefficients);
        let values: Vec<f64> = (0..1u32 << cands.len())
            .map(|mask| {
                let scene: Vec<bool> = (0..cands.len()).map(|i| mask >> i & 1 == 1).collect();
                eval.binary_value(&scene).total
            })
            .collect();
        let best = (0..values.len())
            .min_by(|&a, &b| values[a].total_cmp(&values[b]))
            .unwrap();
        assert_eq!(best, 1, "brute force picks the whole square alone");
        let loss = e.solution.binary.total;
        assert!((values[best] - loss).abs() <= 1e-9 * loss.max(1.0));
    }

    #[test]
    fn without_the_description_length_the_quarters_are_not_penalised() {
        // The same scene at zero cost: the whole square and its quarters tie up to
        // sampling, so the decision rests on the description length alone.
        let points = unit_square_points();

        let cands = candidates();
        let zero = vec![0.0; cands.len()];
        let samples = samples_of(&cands, options().sample_spacing);
        let e = decide_existence(
            &points,
            &PointIndex::new(&points),
            &cands,
            &samples,
            &zero,
            &options(),
            &Silent,
        )
        .unwrap();
        assert!(!e.exists[5], "a square with no points near never exists");
        let whole = e.exists[0] as usize;
        let quarters = e.exists[1..5].iter().filter(|&&x| x).count();
        assert!(whole == 1 || quarters == 4, "{:?}", e.exists);
    }

    #[test]
    fn no_candidates_costs_the_cap_per_point() {
        let points = unit_square_points();

        let e = decide_existence(
            &points,
            &PointIndex::new(&points),
            &[],
            &[],
            &[],
            &options(),
            &Silent,
        )
        .unwrap();
        assert!(e.exists.is_empty());
        assert!((e.solution.binary.total - points.len() as f64 * 0.01).abs() < 1e-9);
    }
}
