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
//! **Visibility.** With each point's sensor origin, a point near the posed surface that
//! the posed object itself hides from its sensor (a point on its far side, or in a fold
//! its near side covers) cannot have been seen there: it counts in the shell. A partial
//! view is explained by the model's seen side only, and a wrong pose that explains the
//! points by its unseen side is not rewarded for it; the model's unseen side is never
//! punished for having no points.
//!
//! **Calibration.** The existence is a logistic function of `z` and of its lead over
//! the best other answer of the final choice (an object that another pose explains
//! nearly as well is ambiguous): [`WITH_SENSORS`] for clouds with sensor origins,
//! [`WITHOUT_SENSORS`] for clouds without (no visibility test: margins run higher),
//! each fitted on benchmark scenes, right and wrong poses and scenes without the object
//! (`benches/calibrate_confidence.py`, answers and reliability tables in
//! `docs/registration_confidence.md`), capped at [`MAX_EXISTENCE`]: no finite
//! calibration set supports certainty.

use nalgebra::Point3;

use crate::Primitive;

/// Outer radius of the comparison shell, in inlier distances.
pub const SHELL_FACTOR: f64 = 4.0;
/// Logistic calibration of the existence: `p = σ(bias + margin · z + gap · lead)`, `z`
/// the margin over clutter and `lead = min(z − z₂, `[`GAP_CAP`]`)` its lead over the best
/// other answer (`z₂` at least 0, the margin of clutter alone).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Log-odds at `z = 0` and no lead.
    pub bias: f64,
    /// Log-odds per unit of `z`.
    pub margin: f64,
    /// Log-odds per unit of the lead.
    pub gap: f64,
}

/// The calibration for clouds with sensor origins (the visibility test on). Fitted
/// (L2-regularised logistic regression, λ = 1) on 40 benchmark answers, 27 right and
/// 13 wrong: seeds 100–103 of the partial-view scenes (the ones with sensor origins),
/// plain, cluttered and object-free, of the bunny and the procedural object
/// (`benches/calibrate_confidence.py --sensors-only`, docs/registration_confidence.md).
pub const WITH_SENSORS: Calibration = Calibration {
    bias: -3.50,
    margin: 0.353,
    gap: 0.038,
};

/// The calibration for clouds without sensor origins (most real scans as they arrive:
/// no visibility test, so margins run higher for right and wrong poses alike). Fitted
/// as [`WITH_SENSORS`] on 56 answers (38 right): the same seeds of every scene kind,
/// whole-surface ones included, with the sensor origins dropped.
pub const WITHOUT_SENSORS: Calibration = Calibration {
    bias: -5.45,
    margin: 0.317,
    gap: 0.842,
};
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
/// the inlier distance `inlier` (scene units). With `sensors` (each point's sensor
/// origin, parallel to `cloud`), a point near the surface that the posed object itself
/// hides from its sensor — the ray from the sensor meets the object more than
/// [`SHELL_FACTOR`] inlier distances before the point: a point on the far side, or in a
/// fold the near side covers — cannot have been seen there and counts in the shell.
/// Under clutter alone this only lowers the near count (a conservative null); a right
/// pose keeps its points, a wrong one that explains them by its unseen side loses them.
pub fn support(
    cloud: &[Point3<f64>],
    sensors: Option<&[Point3<f64>]>,
    object: &Primitive,
    inlier: f64,
) -> Support {
    let reach = SHELL_FACTOR * inlier;
    let (centre, radius) = (object.center(), object.bounding_radius());
    let mut counts = Support { near: 0, shell: 0 };
    for (i, y) in cloud.iter().enumerate() {
        if (y - centre).norm() > radius + reach {
            continue;
        }
        let d = object.distance(y);
        if d <= inlier && !sensors.is_some_and(|s| hidden(object, &s[i], y, reach)) {
            counts.near += 1;
        } else if d <= reach {
            counts.shell += 1;
        }
    }
    counts
}

/// Whether the posed `object` blocks the ray from `sensor` to `point` more than
/// `tolerance` before the point (scene units).
fn hidden(object: &Primitive, sensor: &Point3<f64>, point: &Point3<f64>, tolerance: f64) -> bool {
    let ray = point - sensor;
    let range = ray.norm();
    if range <= tolerance {
        return false;
    }
    object
        .first_hit(sensor, &(ray / range))
        .is_some_and(|hit| hit.depth < range - tolerance)
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
/// other answer has margin `runner_up` (−∞: none), is really there at that pose
/// (module documentation), under `calibration`, in `[0, MAX_EXISTENCE]`.
pub fn existence(z: f64, runner_up: f64, calibration: &Calibration) -> f64 {
    // Clutter alone gives a margin of about 0: no runner-up is worse than that.
    let lead = (z - runner_up.max(0.0)).clamp(0.0, GAP_CAP);
    let logit = calibration.bias + calibration.margin * z + calibration.gap * lead;
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
        // No sensor origins: the calibration for clouds without them.
        let calibration = &WITHOUT_SENSORS;
        let clutter = margin(support(&cloud, None, &sphere, 0.01));
        assert!(clutter.abs() < 3.5, "{clutter}");
        assert!(existence(clutter, f64::NEG_INFINITY, calibration) < 0.1);
        // 100 points on the sphere.
        cloud.extend((0..100).map(|_| {
            let v = Vector3::from_fn(|_, _| rng.random::<f64>() - 0.5);
            Point3::from(v.normalize() * 0.5)
        }));
        let object = margin(support(&cloud, None, &sphere, 0.01));
        assert!(object > 10.0, "{object}");
        let p = existence(object, f64::NEG_INFINITY, calibration);
        assert!(p > 0.9 && p <= MAX_EXISTENCE, "{p}");
        // A runner-up as good as the best lowers the confidence.
        assert!(existence(object, object, calibration) < p);
    }

    #[test]
    fn both_calibrations_rise_with_the_margin_and_the_lead_and_stay_capped() {
        for calibration in [&WITH_SENSORS, &WITHOUT_SENSORS] {
            let none = f64::NEG_INFINITY;
            assert!(existence(0.0, none, calibration) < 0.1);
            assert!(existence(5.0, none, calibration) < existence(15.0, none, calibration));
            assert!(existence(15.0, 15.0, calibration) < existence(15.0, 5.0, calibration));
            assert_eq!(existence(1e6, none, calibration), MAX_EXISTENCE);
        }
    }

    #[test]
    fn points_the_object_hides_from_their_sensor_do_not_support_it() {
        // A sphere of radius 0.5 seen from +z: 50 points on its near cap and 50 on its
        // far cap, all within the inlier distance of the surface.
        let sphere = Primitive::new(Shape::Sphere { diameter: 1.0 }, Pose::identity());
        let eye = Point3::new(0.0, 0.0, 5.0);
        let cap = |sign: f64, k: usize| {
            let a = k as f64 * 0.12;
            Point3::new(0.3 * a.cos(), 0.3 * a.sin(), sign * 0.4)
        };
        let cloud: Vec<Point3<f64>> = (0..50)
            .map(|k| cap(1.0, k))
            .chain((0..50).map(|k| cap(-1.0, k)))
            .collect();
        let sensors = vec![eye; cloud.len()];
        let blind = support(&cloud, None, &sphere, 0.01);
        assert_eq!(
            blind,
            Support {
                near: 100,
                shell: 0
            }
        );
        let seen = support(&cloud, Some(&sensors), &sphere, 0.01);
        assert_eq!(
            seen,
            Support {
                near: 50,
                shell: 50
            }
        );
        assert!(margin(seen) < margin(blind));
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
