//! The occupancy-aware factor of the `mcmc` prior: surface that no point observed costs
//! prior odds.
//!
//! The ray likelihood (eq. 4.10) only sees the parts of a candidate that rays reach.
//! A square half behind a wall explains the same points as the square on the wall, so
//! the posterior cannot tell them apart, and the sampler keeps invented surface (thesis
//! §4.3: "extra primitives fit in certain places"). This factor charges each candidate
//! for its **unobserved samples**: samples of its surface, `point_spacing` apart (about
//! one per point the surface would have given where seen), with no point within
//! `tolerance`. Each point's worth costs [`UNOBSERVED_POINT_NATS`] of prior log-odds:
//!
//! ```text
//! logit p'(φ_i = 1) = logit p(φ_i = 1) − UNOBSERVED_POINT_NATS · unobserved_i
//! ```
//!
//! This is the chamfer's primitive term (thesis eq. 6.1) counted instead of summed, as a
//! second factor of the posterior. An observed sample explains about one ray, worth
//! `ln(h / r)` ≈ 3–6 nats in eq. 4.10, so a candidate whose surface is mostly observed
//! still wins; between two candidates that explain the same rays, the one claiming less
//! unobserved surface wins.
//!
//! **Density.** A surface far from the sensor, or seen at a grazing angle, gets fewer
//! points: a room seen through a doorway has points several times sparser than the
//! corridor's walls. Counting its unobserved surface at the cloud's median density would
//! charge it for points it could never have given, and drop it with the points it
//! explains. So both tests follow the density of the points the candidate has:
//!
//! - a sample is observed when its nearest point `y` lies within `max(tolerance, s_y)`,
//!   `s_y` the distance from `y` to its own nearest neighbour (its local spacing);
//! - unobserved surface counts in points' worth at the candidate's own density: a
//!   candidate with `u` unobserved samples `h` apart, whose observed samples' points have
//!   median spacing `s`, claims `u · (h / s)²` unobserved points (`s` is the cloud's
//!   median spacing for a candidate with no observed sample).

use rayon::prelude::*;

use crate::na::Point3;
use crate::spatial::{PointIndex, strided_median};
use crate::{Primitive, Result, check};

/// Prior log-odds (nats) charged per unobserved point's worth of surface (module docs):
/// one nat, below the 3–6 nats a ray explained by a surface gains in eq. 4.10, so a
/// surface that is more than about a quarter observed keeps its points. Measured on
/// the ray-cast scenes at three resolutions (`docs/free_space.md`): 1 nat keeps all nine
/// within 1.25× the truth's model→point with coverage ≥ 99.3 %; 0.5 leaves one at
/// 1.62×, 2 drops coverage to 97 %.
pub const UNOBSERVED_POINT_NATS: f64 = 1.0;

/// Prior log-odds are kept above this, so the prior stays positive in `f64`.
const MIN_LOGIT: f64 = -700.0;

/// Each point's distance to its nearest other point of `points` (0 for a lone point
/// or an exact duplicate), the points indexed by `index`. Parallel.
pub fn local_spacings(index: &PointIndex, points: &[Point3<f64>]) -> Vec<f64> {
    points
        .par_iter()
        .map(|p| index.spacing_at(p).unwrap_or(0.0))
        .collect()
}

/// Unobserved surface of each candidate, in points' worth at its own point density
/// (module docs): samples `sample_spacing` apart; `spacings` are the points' local
/// spacings ([`local_spacings`]), `median_spacing` the cloud's. Deterministic, parallel.
pub fn unobserved_points(
    index: &PointIndex,
    spacings: &[f64],
    candidates: &[Primitive],
    sample_spacing: f64,
    tolerance: f64,
    median_spacing: f64,
) -> Result<Vec<f64>> {
    check::positive("sample_spacing", sample_spacing)?;
    check::positive("median_spacing", median_spacing)?;
    check::non_negative("tolerance", tolerance)?;
    check::same_len("spacings", spacings.len(), "point", index.len())?;
    Ok(candidates
        .par_iter()
        .map(|c| {
            let mut observed: Vec<f64> = Vec::new();
            let mut unobserved = 0usize;
            for x in c.sample_surface(sample_spacing) {
                match index.nearest(&x) {
                    Some((j, d2)) if d2.sqrt() <= tolerance.max(spacings[j as usize]) => {
                        observed.push(spacings[j as usize])
                    }
                    _ => unobserved += 1,
                }
            }
            let own = strided_median(observed.len(), observed.len(), |i| Some(observed[i]))
                .unwrap_or(median_spacing);
            unobserved as f64 * (sample_spacing / own).powi(2)
        })
        .collect())
}

/// `prior` with each candidate's odds lowered by `nats_per_point` per unobserved point's
/// worth of surface (module docs: [`UNOBSERVED_POINT_NATS`]); a prior of 0 stays 0.
pub fn occupancy_prior(prior: &[f64], unobserved: &[f64], nats_per_point: f64) -> Result<Vec<f64>> {
    check::same_len("unobserved counts", unobserved.len(), "priors", prior.len())?;
    check::non_negative("nats_per_point", nats_per_point)?;
    Ok(prior
        .iter()
        .zip(unobserved)
        .map(|(&p, &u)| {
            if p <= 0.0 {
                return 0.0;
            }
            let logit = (p.ln() - (-p).ln_1p() - nats_per_point * u).max(MIN_LOGIT);
            1.0 / (1.0 + (-logit).exp())
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::na::{UnitQuaternion, Vector3};
    use crate::{Pose, Shape};

    /// Points on the grid `step` apart over `[x0, x1] × [0, 1]`, z = 0.
    fn grid(x0: f64, x1: f64, step: f64) -> Vec<Point3<f64>> {
        let nx = ((x1 - x0) / step).round() as usize;
        let ny = (1.0 / step).round() as usize;
        (0..=nx)
            .flat_map(|i| {
                (0..=ny).map(move |j| Point3::new(x0 + i as f64 * step, j as f64 * step, 0.0))
            })
            .collect()
    }

    /// The unit square on z = 0 with its corner at the origin.
    fn unit_square() -> Primitive {
        let centre = Vector3::new(0.5, 0.5, 0.0);
        Primitive::new(
            Shape::Square { side: 1.0 },
            Pose::new(UnitQuaternion::identity(), centre),
        )
    }

    fn unobserved(points: &[Point3<f64>], square: &Primitive, sample: f64, median: f64) -> f64 {
        let index = PointIndex::new(points);
        let spacings = local_spacings(&index, points);
        unobserved_points(
            &index,
            &spacings,
            std::slice::from_ref(square),
            sample,
            0.003,
            median,
        )
        .unwrap()[0]
    }

    #[test]
    fn local_spacings_are_each_points_nearest_neighbour_distance() {
        let points = [
            Point3::origin(),
            Point3::new(0.1, 0.0, 0.0),
            Point3::new(0.5, 0.0, 0.0),
        ];
        let index = PointIndex::new(&points);
        let s = local_spacings(&index, &points);
        assert!(
            (s[0] - 0.1).abs() < 1e-12 && (s[1] - 0.1).abs() < 1e-12 && (s[2] - 0.4).abs() < 1e-12
        );
    }

    #[test]
    fn a_sparsely_but_fully_seen_surface_claims_no_unobserved_surface() {
        // Points 8 cm apart (a far wall) while the samples, at the cloud's 2 cm, are dense.
        let square = unit_square();
        assert_eq!(unobserved(&grid(0.0, 1.0, 0.08), &square, 0.02, 0.02), 0.0);
    }

    #[test]
    fn half_seen_surface_claims_its_unseen_half_at_its_own_density() {
        let square = unit_square();
        for step in [0.05, 0.1] {
            // Points over x ≤ 0.5 only. Samples within one point spacing of the last
            // column count as seen; the rest, x in (0.5 + step, 1], is (0.5 − step) of
            // area: (0.5 − step) / step² points of this density.
            let u = unobserved(&grid(0.0, 0.5, step), &square, 0.02, 0.02);
            let expected = (0.5 - step) / (step * step);
            assert!(
                (u - expected).abs() < 0.1 * expected,
                "step {step}: {u} vs {expected}"
            );
        }
    }

    #[test]
    fn an_unseen_surface_counts_at_the_clouds_median_density() {
        let square = unit_square();
        let far = [Point3::new(10.0, 10.0, 10.0), Point3::new(10.0, 10.1, 10.0)];
        let u = unobserved(&far, &square, 0.05, 0.1);
        let samples = square.sample_surface(0.05).len() as f64;
        assert!(
            (u - samples * 0.25).abs() < 1e-9,
            "{u} vs {}",
            samples * 0.25
        );
    }

    #[test]
    fn the_prior_falls_with_unobserved_surface_and_zero_stays_zero() {
        let p = occupancy_prior(&[0.5, 0.5, 0.0], &[0.0, 2.0, 5.0], 1.0).unwrap();
        assert_eq!(p[0], 0.5);
        assert!((p[1] - 1.0 / (1.0 + 2f64.exp())).abs() < 1e-12);
        assert_eq!(p[2], 0.0);
        assert!(occupancy_prior(&[0.5], &[1.0, 2.0], 1.0).is_err());
    }
}
