//! The occupancy-aware factor of the `mcmc` prior: surface that no point observed costs
//! prior odds.
//!
//! The ray likelihood (eq. 4.10) only sees the parts of a candidate that rays reach.
//! A square half behind a wall explains the same points as the square on the wall, so
//! the posterior cannot tell them apart, and the sampler keeps invented surface (thesis
//! §4.3: "extra primitives fit in certain places"). This factor charges each candidate
//! for its **unobserved samples**: samples of its surface, `point_spacing` apart (about
//! one per point the surface would have given where seen), with no point within
//! `tolerance`. Each costs [`UNOBSERVED_SAMPLE_NATS`] of prior log-odds:
//!
//! ```text
//! logit p'(φ_i = 1) = logit p(φ_i = 1) − UNOBSERVED_SAMPLE_NATS · unobserved_i
//! ```
//!
//! This is the chamfer's primitive term (thesis eq. 6.1) counted instead of summed, as a
//! second factor of the posterior. An observed sample explains about one ray, worth
//! `ln(h / r)` ≈ 3–6 nats in eq. 4.10, so a candidate whose surface is mostly observed
//! still wins; between two candidates that explain the same rays, the one claiming less
//! unobserved surface wins.

use rayon::prelude::*;

use crate::spatial::PointIndex;
use crate::{Primitive, Result, check};

/// Prior log-odds (nats) charged per unobserved sample (module docs): half a nat, well below the
/// 3–6 nats a ray explained by a surface gains in eq. 4.10.
pub const UNOBSERVED_SAMPLE_NATS: f64 = 0.5;

/// Prior log-odds are kept above this, so the prior stays positive in `f64`.
const MIN_LOGIT: f64 = -700.0;

/// Samples of each candidate with no point of `points` (indexed by `index`) within
/// `tolerance`, the samples `spacing` apart (scene units). Deterministic, parallel.
pub fn unobserved_samples(
    index: &PointIndex,
    candidates: &[Primitive],
    spacing: f64,
    tolerance: f64,
) -> Result<Vec<usize>> {
    check::positive("spacing", spacing)?;
    check::non_negative("tolerance", tolerance)?;
    let t2 = tolerance * tolerance;
    Ok(candidates
        .par_iter()
        .map(|c| {
            c.sample_surface(spacing)
                .iter()
                .filter(|x| index.nearest(x).is_none_or(|(_, d2)| d2 > t2))
                .count()
        })
        .collect())
}

/// `prior` with each candidate's odds lowered by `nats_per_sample` per unobserved sample
/// (module docs: [`UNOBSERVED_SAMPLE_NATS`] when the samples are one point spacing
/// apart, scaled by the area a sample stands for otherwise); a prior of 0 stays 0.
pub fn occupancy_prior(
    prior: &[f64],
    unobserved: &[usize],
    nats_per_sample: f64,
) -> Result<Vec<f64>> {
    check::same_len("unobserved counts", unobserved.len(), "priors", prior.len())?;
    check::non_negative("nats_per_sample", nats_per_sample)?;
    Ok(prior
        .iter()
        .zip(unobserved)
        .map(|(&p, &u)| {
            if p <= 0.0 {
                return 0.0;
            }
            let logit = (p.ln() - (-p).ln_1p() - nats_per_sample * u as f64).max(MIN_LOGIT);
            1.0 / (1.0 + (-logit).exp())
        })
        .collect())
}
