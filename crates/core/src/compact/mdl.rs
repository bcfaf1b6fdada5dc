//! The description length of a primitive, in the loss's own units.
//!
//! The chamfer loss sums squared distances. Under Gaussian noise of deviation σ along
//! the surface normal, a point at distance `d` costs `d² / (2σ²)` nats of code length
//! (the negative log-likelihood up to a constant), so **one nat is `2σ²` of loss**.
//! The two-part code of minimum description length (Rissanen; the BIC is its
//! large-sample form) charges `½ ln J` nats per real parameter estimated from `J`
//! points. A primitive with `k` parameters therefore costs
//!
//! ```text
//! c = k · ½ ln J · 2σ² = k σ² ln J      (squared scene units)
//! ```
//!
//! and it is worth adding only when it lowers the point and primitive terms by more
//! than `c`. Two small primitives that explain the same points as one large one lose to
//! it by the cost of the second, which is what makes the model compact; a primitive
//! that explains a handful of points within the noise is not worth its parameters.

use crate::Primitive;

/// The description length `k σ² ln J` of a primitive with `parameters` parameters, fitted
/// to a cloud of `points` points with noise deviation `noise` (scene units); squared
/// scene units, like the loss. Zero for `points ≤ 1` or `noise = 0`.
pub fn description_length(parameters: usize, noise: f64, points: usize) -> f64 {
    if points <= 1 {
        return 0.0;
    }
    parameters as f64 * noise * noise * (points as f64).ln()
}

/// The description length of `primitive` ([`description_length`] of its parameter
/// count: the pose's 7 plus its sizes, [`Primitive::parameter_count`]).
pub fn primitive_cost(primitive: &Primitive, noise: f64, points: usize) -> f64 {
    description_length(primitive.parameter_count(), noise, points)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cost_is_k_sigma_squared_ln_j() {
        let c = description_length(7, 0.01, 1000);
        assert!((c - 7.0 * 1e-4 * 1000f64.ln()).abs() < 1e-15);
        assert_eq!(description_length(7, 0.01, 1), 0.0);
        assert_eq!(description_length(7, 0.0, 1000), 0.0);
        // Twice the parameters, twice the cost; cost grows with the log of the points.
        assert!((description_length(14, 0.01, 1000) - 2.0 * c).abs() < 1e-15);
        assert!(description_length(7, 0.01, 10_000) > c);
    }
}
