//! The ray measurement model of thesis eq. 4.10, in log space.
//!
//! A point observed at range `z` (metres) along its ray, with the existing primitives
//! crossing that ray at depths `μ_i` with along-ray standard deviations `s_i`, has density
//!
//! ```text
//! p(z | P) = e^{−r z} · Π_i g(z; μ_i, s_i) · (r + Σ_i N(z; μ_i, s_i) / g(z; μ_i, s_i))
//! ```
//!
//! with `r` the noise rate (points per metre of ray), `N` the normal density and
//! `g = 1 − Φ` its upper tail (thesis eqs. 4.5, 4.8–4.10). We compute
//!
//! ```text
//! log p = −r z + Σ_i log g_i + ln(r + Σ_i h_i),   h_i = N_i / g_i   (the normal hazard)
//! ```
//!
//! where `log g` uses the Mills-ratio continued fraction in the far tail, so a point
//! thousands of standard deviations behind a primitive gives a large negative number,
//! never `−∞` or NaN, and `h` never overflows (it grows like `t / s`). The per-crossing
//! terms `(log g_i, h_i)` depend only on the point and the candidate, so the
//! [`crate::ray::RayTable`] computes them once; evaluating a scene is then sums and one
//! logarithm per ray.

use crate::Result;
use crate::check::{self, Interval};

/// `ln √(2π)`.
const LN_SQRT_2PI: f64 = 0.918_938_533_204_672_8;

/// Standardised distances beyond this use the continued fraction for the normal tail.
const TAIL_SWITCH: f64 = 5.0;

/// Terms of the backward continued fraction for the Mills ratio (converged to rounding
/// for `t ≥ TAIL_SWITCH`).
const MILLS_TERMS: u32 = 80;

/// Hazards are capped here (1/m), so sums of millions of them stay finite.
const H_CAP: f64 = 1e250;

/// Standardised distances are clamped to ±this, so squares stay finite (the log-tail at
/// the clamp is −5·10¹⁹⁹: finite, and still overwhelmingly unlikely).
const T_CLAMP: f64 = 1e100;

/// Parameters of the measurement model (thesis §4.2.1). Lengths in scene units (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayModel {
    /// Noise rate `r`: expected noise points per metre of ray (1/m, > 0).
    pub rate: f64,
    /// Standard deviation of a primitive's generated points along its surface normal (m, > 0).
    pub sigma: f64,
    /// Floor of `|cos θ|` (ray vs surface normal) when projecting `sigma` onto the ray:
    /// the along-ray deviation is `s = sigma / max(|cos θ|, min_cos)` (the thesis's
    /// "projected variance"). `1` means pure range noise, `s = sigma`. In `(0, 1]`.
    pub min_cos: f64,
}

impl Default for RayModel {
    fn default() -> Self {
        RayModel {
            rate: 0.05,
            sigma: 0.02,
            min_cos: 0.2,
        }
    }
}

impl RayModel {
    /// Checks `rate > 0`, `sigma > 0` (both finite) and `min_cos ∈ (0, 1]`.
    pub fn validate(&self) -> Result<()> {
        check::positive("rate", self.rate)?;
        check::positive("sigma", self.sigma)?;
        check::in_interval("min_cos", self.min_cos, Interval::open_closed(0.0, 1.0))
    }

    /// The along-ray standard deviation `s` for a crossing at incidence `|cos θ|` (m).
    #[inline]
    pub fn projected_sigma(&self, cos: f64) -> f64 {
        let c = if cos.is_nan() { 1.0 } else { cos.abs() };
        self.sigma / c.clamp(self.min_cos, 1.0)
    }

    /// `log p(z | ∅) = ln r − r z` (eq. 4.5): a point explained by noise alone.
    pub fn empty_log_likelihood(&self, z: f64) -> f64 {
        self.rate.ln() - self.rate * z
    }
}

/// `ln φ(t)` of the standard normal density.
#[inline]
fn log_phi(t: f64) -> f64 {
    -0.5 * t * t - LN_SQRT_2PI
}

/// The Mills ratio `Q(t) / φ(t)` for `t ≥ TAIL_SWITCH`, by the continued fraction
/// `1 / (t + 1/(t + 2/(t + 3/(t + …))))` evaluated backwards.
fn mills_ratio(t: f64) -> f64 {
    let mut f = t;
    for k in (1..=MILLS_TERMS).rev() {
        f = t + k as f64 / f;
    }
    1.0 / f
}

/// `ln Q(t) = ln(1 − Φ(t))`, the log upper tail of the standard normal, accurate to a few
/// ulps of `Q` and finite for every finite `t` (NaN gives NaN).
pub fn log_upper_tail(t: f64) -> f64 {
    let t = t.clamp(-T_CLAMP, T_CLAMP);
    if t >= TAIL_SWITCH {
        log_phi(t) + mills_ratio(t).ln()
    } else if t >= 0.0 {
        (0.5 * libm::erfc(t * std::f64::consts::FRAC_1_SQRT_2)).ln()
    } else {
        // Q(t) = 1 − Q(−t): ln_1p keeps the tiny deficit instead of rounding to ln 1.
        (-0.5 * libm::erfc(-t * std::f64::consts::FRAC_1_SQRT_2)).ln_1p()
    }
}

/// `(ln g, h)` of one crossing (eq. 4.10): `g = 1 − Φ((z − μ)/s)` is the probability that
/// the primitive generated no point in front of `z`; `h = N(z; μ, s) / g` (1/m) the
/// hazard, capped at 10²⁵⁰. `z`, `mu` in metres, `s > 0` in metres. Both are finite for
/// finite input.
pub fn crossing_terms(z: f64, mu: f64, s: f64) -> (f64, f64) {
    let t = ((z - mu) / s).clamp(-T_CLAMP, T_CLAMP);
    let log_g = log_upper_tail(t);
    let h = if t >= TAIL_SWITCH {
        1.0 / (s * mills_ratio(t))
    } else {
        (log_phi(t) - log_g).exp() / s
    };
    (log_g, h.min(H_CAP))
}

/// `log p(z | P)` of eq. 4.10 for one ray from its crossings' precomputed terms:
/// `−r z + Σ ln g_i + ln(r + Σ h_i)`. `sum_log_g` and `sum_h` are the sums over the
/// existing primitives that cross the ray.
#[inline]
pub fn ray_log_likelihood_from_sums(model: &RayModel, z: f64, sum_log_g: f64, sum_h: f64) -> f64 {
    -model.rate * z + sum_log_g + (model.rate + sum_h).ln()
}

/// `log p(z | P)` of eq. 4.10 for a point at range `z` whose ray crosses existing primitives
/// at `(μ_i, s_i)` (metres). Finite for finite input and a valid model.
pub fn ray_log_likelihood(model: &RayModel, z: f64, crossings: &[(f64, f64)]) -> f64 {
    let (mut sum_log_g, mut sum_h) = (0.0, 0.0);
    for &(mu, s) in crossings {
        let (lg, h) = crossing_terms(z, mu, s);
        sum_log_g += lg;
        sum_h += h;
    }
    ray_log_likelihood_from_sums(model, z, sum_log_g, sum_h)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq. 4.10 evaluated literally, in linear space (underflows far from the primitives).
    fn direct(model: &RayModel, z: f64, crossings: &[(f64, f64)]) -> f64 {
        let mut prod_g = 1.0;
        let mut sum = model.rate;
        for &(mu, s) in crossings {
            let t = (z - mu) / s;
            let g = 0.5 * libm::erfc(t / std::f64::consts::SQRT_2);
            let n = (-0.5 * t * t).exp() / (s * (2.0 * std::f64::consts::PI).sqrt());
            prod_g *= g;
            sum += n / g;
        }
        (-model.rate * z).exp() * prod_g * sum
    }

    #[test]
    fn log_tail_is_continuous_at_the_switch_and_matches_erfc() {
        for t in [5.0, 5.5, 6.0, 7.5, 9.0, 12.0, 20.0] {
            let want = (0.5 * libm::erfc(t / std::f64::consts::SQRT_2)).ln();
            let got = log_upper_tail(t);
            assert!(
                (got - want).abs() < 1e-12 * want.abs(),
                "t={t}: {got} vs {want}"
            );
        }
        let below = log_upper_tail(TAIL_SWITCH - 1e-12);
        let above = log_upper_tail(TAIL_SWITCH);
        assert!((below - above).abs() < 1e-10);
        assert!((log_upper_tail(0.0) - 0.5f64.ln()).abs() < 1e-15);
        // Deep negative: ln(1 − Q(8)) ≈ −Q(8) = −6.22e−16, not 0.
        let q8 = 0.5 * libm::erfc(8.0 / std::f64::consts::SQRT_2);
        assert!((log_upper_tail(-8.0) + q8).abs() < 1e-28);
    }

    #[test]
    fn matches_direct_evaluation_where_it_does_not_underflow() {
        let model = RayModel {
            rate: 0.1,
            sigma: 0.05,
            min_cos: 1.0,
        };
        let cases: [(f64, Vec<(f64, f64)>); 6] = [
            (4.0, vec![]),
            (4.0, vec![(4.0, 0.1)]),
            (3.7, vec![(4.0, 0.1), (5.0, 0.2)]),
            (4.35, vec![(4.0, 0.1), (5.0, 0.2)]),
            (5.0, vec![(4.0, 0.3), (5.0, 0.3), (5.2, 0.05)]),
            (1.0, vec![(9.0, 0.5)]),
        ];
        for (z, c) in &cases {
            let want = direct(&model, *z, c).ln();
            let got = ray_log_likelihood(&model, *z, c);
            assert!(
                (got - want).abs() < 1e-12 * want.abs().max(1.0),
                "z={z} {c:?}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn figure_4_2_a_primitive_at_the_point_can_lower_its_likelihood() {
        // Thesis fig. 4-2: with a primitive at μ = 4, a point at z = 5 becomes less likely
        // when a second primitive at μ = 5 is added (occlusion by the one at 4).
        let model = RayModel {
            rate: 0.1,
            sigma: 0.3,
            min_cos: 1.0,
        };
        let one = ray_log_likelihood(&model, 5.0, &[(4.0, 0.3)]);
        let two = ray_log_likelihood(&model, 5.0, &[(4.0, 0.3), (5.0, 0.3)]);
        assert!(two < one, "{two} !< {one}");
    }

    #[test]
    fn extreme_geometry_is_finite() {
        let model = RayModel {
            rate: 1e-9,
            sigma: 1e-9,
            min_cos: 1e-6,
        };
        for (z, mu, s) in [
            (1e6, 0.0, 1e-9),
            (0.0, 1e6, 1e-9),
            (1e300, 0.0, 1e-300),
            (0.0, 1e300, 1e-300),
            (5.0, 5.0, 1e-300),
            (1.0, 1.0 + 1e-12, 1e3),
        ] {
            let (lg, h) = crossing_terms(z, mu, s);
            assert!(lg.is_finite() && lg <= 0.0, "{z} {mu} {s}: ln g = {lg}");
            assert!(h.is_finite() && h >= 0.0, "{z} {mu} {s}: h = {h}");
            let ll = ray_log_likelihood(&model, z.min(1e200), &[(mu, s), (mu, s)]);
            assert!(ll.is_finite(), "{z} {mu} {s}: {ll}");
        }
        // Far behind: ln g ≈ −t²/2.
        let (lg, _) = crossing_terms(1e3, 0.0, 1.0);
        assert!((lg + 0.5e6).abs() / 0.5e6 < 1e-4);
    }

    #[test]
    fn bad_models_are_errors() {
        for m in [
            RayModel {
                rate: 0.0,
                ..Default::default()
            },
            RayModel {
                sigma: f64::NAN,
                ..Default::default()
            },
            RayModel {
                min_cos: 0.0,
                ..Default::default()
            },
            RayModel {
                min_cos: 1.5,
                ..Default::default()
            },
        ] {
            assert!(m.validate().is_err(), "{m:?}");
        }
        assert!(RayModel::default().validate().is_ok());
    }
}
