//! Range checks of options and arguments. Each returns [`Error::OutOfRange`] naming the
//! option by its library field name, so that `validate` methods read as a list of
//! rules: `check::positive("spacing", self.spacing)?`.

use std::fmt;

use crate::error::{Error, Result};

/// `v` is finite and `> 0` (a length, a rate, a scale).
pub fn positive(name: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::out_of_range(name, v, "positive and finite"))
    }
}

/// `v` is finite and `≥ 0` (a noise level, a weight, a tolerance).
pub fn non_negative(name: &str, v: f64) -> Result<()> {
    not_below(name, v, 0.0)
}

/// `v` is finite and `≥ min`.
pub fn not_below(name: &str, v: f64, min: f64) -> Result<()> {
    if v.is_finite() && v >= min {
        Ok(())
    } else {
        Err(Error::out_of_range(name, v, format!("finite and ≥ {min}")))
    }
}

/// Every coordinate of `v` (a point, a vector) is finite.
pub fn finite(name: &str, v: &[f64]) -> Result<()> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(Error::out_of_range(name, format!("{v:?}"), "finite"))
    }
}

/// `v` lies in `interval` (NaN lies in none).
pub fn in_interval(name: &str, v: f64, interval: Interval) -> Result<()> {
    if interval.contains(v) {
        Ok(())
    } else {
        Err(Error::out_of_range(name, v, format!("in {interval}")))
    }
}

/// There are as many `what` (`len`) as `per` (`expected`): one each.
pub fn same_len(what: &'static str, len: usize, per: &'static str, expected: usize) -> Result<()> {
    if len == expected {
        Ok(())
    } else {
        Err(Error::Mismatch {
            what,
            len,
            per,
            expected,
        })
    }
}

/// The count `v` is at least `min`.
pub fn at_least(name: &str, v: usize, min: usize) -> Result<()> {
    if v >= min {
        Ok(())
    } else {
        Err(Error::out_of_range(name, v, format!("at least {min}")))
    }
}

/// The count `v` is at most `max`.
pub fn at_most(name: &str, v: usize, max: usize) -> Result<()> {
    if v <= max {
        Ok(())
    } else {
        Err(Error::out_of_range(name, v, format!("at most {max}")))
    }
}

/// `(lo, hi)` is a range of positive finite values with `lo ≤ hi` (a scale range).
pub fn positive_range(name: &str, (lo, hi): (f64, f64)) -> Result<()> {
    if lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi {
        Ok(())
    } else {
        let expected = "a positive range (lo, hi) with lo ≤ hi";
        Err(Error::out_of_range(name, format!("({lo}, {hi})"), expected))
    }
}

/// `v` is a whole multiple of `step` (up to a relative 1e-9): a length that must fall
/// on a lattice whose spacing `step` is named `step_name`.
pub fn multiple_of(name: &str, v: f64, step: f64, step_name: &str) -> Result<()> {
    let cells = v / step;
    if (cells - cells.round()).abs() <= MULTIPLE_TOLERANCE {
        Ok(())
    } else {
        let expected = format!("a multiple of {step_name} = {step}");
        Err(Error::out_of_range(name, v, expected))
    }
}

/// The rotation of a quaternion `[w, x, y, z]` given in JSON or an option: finite and
/// not zero, normalised. The components are divided by the largest first, so that
/// `[1e308, 1e308, 0, 0]` is the rotation it names rather than an overflow to zero.
pub fn unit_quaternion(name: &str, q: [f64; 4]) -> Result<nalgebra::UnitQuaternion<f64>> {
    let largest = q.iter().fold(0.0_f64, |m, c| m.max(c.abs()));
    if !(q.iter().all(|c| c.is_finite()) && largest > 0.0) {
        let expected = "a finite, non-zero quaternion [w, x, y, z]";
        return Err(Error::out_of_range(name, format!("{q:?}"), expected));
    }
    let [w, i, j, k] = q;
    let plain = nalgebra::Quaternion::new(w, i, j, k);
    // Rescaled only when the norm itself over- or underflows, so that a unit quaternion
    // read back from JSON keeps its exact bits.
    let norm = plain.norm();
    if norm.is_finite() && norm >= QUATERNION_MIN_NORM {
        return Ok(nalgebra::UnitQuaternion::from_quaternion(plain));
    }
    let [w, i, j, k] = q.map(|c| c / largest);
    Ok(nalgebra::UnitQuaternion::from_quaternion(
        nalgebra::Quaternion::new(w, i, j, k),
    ))
}

/// Below this norm a quaternion is rescaled before it is normalised ([`unit_quaternion`]):
/// its squared components would lose precision in subnormals.
const QUATERNION_MIN_NORM: f64 = 1e-150;

/// How far (in steps) from a whole multiple [`multiple_of`] accepts.
const MULTIPLE_TOLERANCE: f64 = 1e-9;

/// An interval of the real line whose ends are each open or closed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interval {
    lo: f64,
    hi: f64,
    lo_closed: bool,
    hi_closed: bool,
}

impl Interval {
    /// `[0, 1]`: probabilities, shares.
    pub const UNIT: Interval = Interval::closed(0.0, 1.0);

    /// `[lo, hi]`.
    pub const fn closed(lo: f64, hi: f64) -> Self {
        Interval {
            lo,
            hi,
            lo_closed: true,
            hi_closed: true,
        }
    }
    /// `(lo, hi)`.
    pub const fn open(lo: f64, hi: f64) -> Self {
        Interval {
            lo,
            hi,
            lo_closed: false,
            hi_closed: false,
        }
    }
    /// `(lo, hi]`.
    pub const fn open_closed(lo: f64, hi: f64) -> Self {
        Interval {
            lo,
            hi,
            lo_closed: false,
            hi_closed: true,
        }
    }
    /// `[lo, hi)`.
    pub const fn closed_open(lo: f64, hi: f64) -> Self {
        Interval {
            lo,
            hi,
            lo_closed: true,
            hi_closed: false,
        }
    }
    /// Whether `v` lies in the interval (false for NaN).
    pub fn contains(&self, v: f64) -> bool {
        let above = if self.lo_closed {
            v >= self.lo
        } else {
            v > self.lo
        };
        let below = if self.hi_closed {
            v <= self.hi
        } else {
            v < self.hi
        };
        above && below
    }
}

impl fmt::Display for Interval {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let open = if self.lo_closed { '[' } else { '(' };
        let close = if self.hi_closed { ']' } else { ')' };
        write!(f, "{open}{}, {}{close}", self.lo, self.hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_pass_in_range_and_name_the_option_outside() {
        assert!(positive("size", 1.0).is_ok());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = positive("size", bad).expect_err("out of range");
            assert!(
                matches!(&e, Error::OutOfRange { name, .. } if name == "size"),
                "{e}"
            );
        }
        assert!(non_negative("cap", 0.0).is_ok());
        assert_eq!(
            non_negative("cap", -1.0).expect_err("negative").to_string(),
            "cap must be finite and ≥ 0, got -1"
        );
        assert!(finite("origin", &[0.0, 1.0, 2.0]).is_ok());
        assert!(finite("origin", &[0.0, f64::NAN, 2.0]).is_err());
        assert!(at_least("beta", 1, 1).is_ok());
        assert_eq!(
            at_least("beta", 0, 1).expect_err("zero").to_string(),
            "beta must be at least 1, got 0"
        );
        assert!(same_len("normals", 3, "points", 3).is_ok());
        assert_eq!(
            same_len("normals", 2, "points", 3)
                .expect_err("short")
                .to_string(),
            "length mismatch: 2 normals for 3 points (one each expected)"
        );
        assert!(at_most("segments", 1000, 1000).is_ok());
        assert!(at_most("segments", 1001, 1000).is_err());
        assert!(positive_range("scale", (0.5, 2.0)).is_ok());
        assert!(positive_range("scale", (2.0, 0.5)).is_err());
        assert!(positive_range("scale", (0.0, 1.0)).is_err());
        assert!(multiple_of("width", 0.3, 0.1, "side / 2").is_ok());
        assert_eq!(
            multiple_of("width", 0.25, 0.1, "side / 2")
                .expect_err("not a multiple")
                .to_string(),
            "width must be a multiple of side / 2 = 0.1, got 0.25"
        );
    }

    #[test]
    fn intervals_honour_open_and_closed_ends() {
        let half_open = Interval::open_closed(0.0, 1.0);
        assert!(!half_open.contains(0.0) && half_open.contains(1.0));
        assert!(!half_open.contains(f64::NAN));
        assert!(Interval::closed_open(0.0, 1.0).contains(0.0));
        assert!(!Interval::open(0.0, 1.0).contains(1.0));
        assert!(Interval::UNIT.contains(0.0) && Interval::UNIT.contains(1.0));
        assert_eq!(
            in_interval("ess", 0.0, half_open)
                .expect_err("open end")
                .to_string(),
            "ess must be in (0, 1], got 0"
        );
    }
}
