//! Honest confidence of a found object: how much better its pose explains the cloud than
//! the outlier-only explanation does, and the calibrated probability that it is right.
//!
//! **Support test.** Around the posed surface, the points within the inlier distance δ
//! (the *near* shell, volume ≈ 2δA for area A) are compared with those in the
//! surrounding shell δ < d ≤ [`SHELL_FACTOR`]·δ (volume ≈ 2(F − 1)δA). Under the
//! outlier-only explanation the local clutter density is the same in both shells, so of
//! the `n` points in their union each lies in the near shell with probability
//! `p₀ = 1/F`, whatever the clutter's density (uniform noise, a plane, other objects
//! nearby all raise both counts alike). The object explanation piles its points into
//! the near shell. The margin is the signed root of the binomial log-likelihood ratio
//! (`z = ±√G`, `G = 2[k ln(k/(n p₀)) + s ln(s/(n(1 − p₀)))]`, k near and s shell
//! points): about N(0, 1) under clutter alone, large for a real object.
//!
//! **Calibration.** The existence is a logistic function of `z` and of its lead over
//! the best other symmetry try (an object that another pose explains nearly as well
//! is ambiguous), whose coefficients were fitted on benchmark scenes, right and wrong poses and scenes without the object
//! (`benches/registration_compare.py`, table in `benches/REGISTRATION.md`), capped at
//! [`MAX_EXISTENCE`]: no finite calibration set supports certainty.

use nalgebra::Point3;

use crate::Primitive;

/// Outer radius of the comparison shell, in inlier distances.
pub const SHELL_FACTOR: f64 = 4.0;
/// Logistic calibration of the existence: `p = σ(CALIBRATION_BIAS + CALIBRATION_MARGIN
/// · z + CALIBRATION_GAP · gap)`, `z` the margin over clutter and `gap = min(z − z₂,
/// GAP_CAP)` its lead over the best other symmetry try (`z₂` at least 0, the margin
/// of clutter alone). Fitted (L2-regularised logistic
/// regression, λ = 1) on 43 benchmark answers, 18 right and 25 wrong, seeds 100–103 of
/// whole-surface, partial-view and object-free scenes of the bunny and the procedural
/// object (docs/registration_confidence.md).
pub const CALIBRATION_BIAS: f64 = -8.9;
/// See [`CALIBRATION_BIAS`] (per unit of `z`).
pub const CALIBRATION_MARGIN: f64 = 0.415;
/// See [`CALIBRATION_BIAS`] (per unit of the gap).
pub const CALIBRATION_GAP: f64 = 1.54;
/// Largest lead over the runner-up that counts (a runner-up far behind is as good as
/// none).
pub const GAP_CAP: f64 = 10.0;
/// Largest existence reported: one wrong pose in a hundred confident ones is the
/// resolution of the calibration set.
pub const MAX_EXISTENCE: f64 = 0.99;

/// The points of a cloud around a posed surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Support {
    /// Points within the inlier distance δ of the surface.
    pub near: usize,
    /// Points at distances in (δ, [`SHELL_FACTOR`]·δ].
    pub shell: usize,
}

/// Counts the points of `cloud` near `object`'s surface and in the shell around it, for
/// the inlier distance `inlier` (scene units).
pub fn support(cloud: &[Point3<f64>], object: &Primitive, inlier: f64) -> Support {
    let reach = SHELL_FACTOR * inlier;
    let (centre, radius) = (object.center(), object.bounding_radius());
    let mut counts = Support { near: 0, shell: 0 };
    for y in cloud {
        if (y - centre).norm() > radius + reach {
            continue;
        }
        let d = object.distance(y);
        if d <= inlier {
            counts.near += 1;
        } else if d <= reach {
            counts.shell += 1;
        }
    }
    counts
}

/// The signed root of the binomial log-likelihood ratio of `support` against clutter
/// alone (module documentation): > 0 when the near shell holds more than its volume
/// share `1/`[`SHELL_FACTOR`] of the points; 0 without points.
pub fn margin(support: Support) -> f64 {
    let (k, s) = (support.near as f64, support.shell as f64);
    let n = k + s;
    if n == 0.0 {
        return 0.0;
    }
    let p0 = 1.0 / SHELL_FACTOR;
    let term = |x: f64, expected: f64| {
        if x > 0.0 {
            x * (x / expected).ln()
        } else {
            0.0
        }
    };
    let g = 2.0 * (term(k, n * p0) + term(s, n * (1.0 - p0)));
    g.max(0.0).sqrt() * (k - n * p0).signum()
}

/// The calibrated probability that an object with margin `z` over clutter, whose best
/// other symmetry try has margin `runner_up` (−∞: none), is really there at that pose
/// (module documentation), in `[0, MAX_EXISTENCE]`.
pub fn existence(z: f64, runner_up: f64) -> f64 {
    // Clutter alone gives a margin of about 0: no runner-up is worse than that.
    let gap = (z - runner_up.max(0.0)).clamp(0.0, GAP_CAP);
    let logit = CALIBRATION_BIAS + CALIBRATION_MARGIN * z + CALIBRATION_GAP * gap;
    (1.0 / (1.0 + (-logit).exp())).min(MAX_EXISTENCE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Pose, Shape};
    use nalgebra::Vector3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn uniform(n: usize, half: f64, rng: &mut ChaCha8Rng) -> Vec<Point3<f64>> {
        (0..n)
            .map(|_| {
                Point3::from(Vector3::from_fn(|_, _| {
                    (2.0 * rng.random::<f64>() - 1.0) * half
                }))
            })
            .collect()
    }

    #[test]
    fn clutter_alone_has_a_small_margin_and_an_object_a_large_one() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let sphere = Primitive::new(Shape::Sphere { diameter: 1.0 }, Pose::identity());
        let mut cloud = uniform(4000, 1.0, &mut rng);
        let clutter = margin(support(&cloud, &sphere, 0.01));
        assert!(clutter.abs() < 3.5, "{clutter}");
        assert!(existence(clutter, f64::NEG_INFINITY) < 0.1);
        // 100 points on the sphere.
        cloud.extend((0..100).map(|_| {
            let v = Vector3::from_fn(|_, _| rng.random::<f64>() - 0.5);
            Point3::from(v.normalize() * 0.5)
        }));
        let object = margin(support(&cloud, &sphere, 0.01));
        assert!(object > 10.0, "{object}");
        let p = existence(object, f64::NEG_INFINITY);
        assert!(p > 0.9 && p <= MAX_EXISTENCE);
        // A runner-up as good as the best halves the confidence at most to its share.
        assert!(existence(object, object) < p);
    }

    #[test]
    fn margin_matches_brute_force_likelihood_ratio() {
        // k = 30 of n = 60 with p0 = 1/4: G = 2 (30 ln 2 + 30 ln(30/45)).
        let z = margin(Support {
            near: 30,
            shell: 30,
        });
        let g = 2.0 * (30.0 * 2f64.ln() + 30.0 * (30.0f64 / 45.0).ln());
        assert!((z - g.sqrt()).abs() < 1e-12);
        assert!(margin(Support { near: 5, shell: 30 }) < 0.0);
        assert_eq!(margin(Support { near: 0, shell: 0 }), 0.0);
    }
}
