//! The next population: tempered weights, systematic resampling and random moves.

use nalgebra::{UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::Context;
use crate::Pose;

impl Context<'_> {
    /// A random move of `pose`: rotation by the exponential map of a Gaussian axis-angle
    /// vector (σ = `spread / lever` rad) about the model centre (about the origin when the
    /// translation is fixed); Gaussian translation (σ = `spread`); log-normal scale (σ =
    /// `spread / lever`), clamped to
    /// [`RegisterOptions::scale`](super::RegisterOptions::scale).
    pub(super) fn perturb(&self, pose: &Pose, spread: f64, rng: &mut ChaCha8Rng) -> Pose {
        let o = self.options;
        let sigma = spread / (self.lever * pose.scale);
        let omega = gaussian3(rng) * sigma;
        let rotation = UnitQuaternion::from_scaled_axis(omega) * pose.rotation;
        let scale = match o.scale {
            Some((lo, hi)) => {
                let z: f64 = StandardNormal.sample(rng);
                (pose.scale * (sigma * z).exp()).clamp(lo, hi)
            }
            None => pose.scale,
        };
        if o.translation {
            // The centre stays where it was, then moves by Gaussian noise.
            let centre = pose.to_scene(&self.centre);
            let mut moved = Pose::anchored(rotation, scale, &self.centre, &centre);
            moved.translation += gaussian3(rng) * (spread * o.translation_spread);
            moved
        } else {
            Pose {
                rotation,
                scale,
                ..*pose
            }
        }
    }
}

/// Weights `∝ exp((s_i − max s) / T)` with the temperature `T` chosen (bisection on
/// log T) so that the effective sample size is `ess` × the particle count.
pub fn tempered_weights(score: &[f64], ess: f64) -> Vec<f64> {
    let n = score.len();
    let max = score.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = score.iter().copied().fold(f64::INFINITY, f64::min);
    let range = max - min;
    if n == 0 || range.is_nan() || range <= 0.0 || !range.is_finite() {
        return vec![1.0 / n.max(1) as f64; n];
    }
    let weights = |t: f64| {
        let mut w: Vec<f64> = score.iter().map(|s| ((s - max) / t).exp()).collect();
        let sum: f64 = w.iter().sum();
        w.iter_mut().for_each(|x| *x /= sum);
        w
    };
    let ess_of = |w: &[f64]| 1.0 / w.iter().map(|x| x * x).sum::<f64>() / n as f64;
    let (mut lo, mut hi) = ((range * 1e-6).ln(), (range * 1e3).ln());
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if ess_of(&weights(mid.exp())) < ess {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    weights(hi.exp())
}

/// Systematic resampling: `count` indices drawn with probabilities `weights` (summing to 1)
/// from one uniform offset.
pub fn systematic(weights: &[f64], count: usize, rng: &mut ChaCha8Rng) -> Vec<usize> {
    let u0: f64 = rng.random::<f64>() / count as f64;
    let mut out = Vec::with_capacity(count);
    let (mut k, mut cum) = (0, weights.first().copied().unwrap_or(1.0));
    for m in 0..count {
        let u = u0 + m as f64 / count as f64;
        while u > cum && k + 1 < weights.len() {
            k += 1;
            cum += weights[k];
        }
        out.push(k);
    }
    out
}

fn gaussian3(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::from_fn(|_, _| StandardNormal.sample(rng))
}
