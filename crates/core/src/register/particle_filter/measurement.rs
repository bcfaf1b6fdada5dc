//! The filter's measurement: each particle's binary chamfer decrease next to the
//! background (outlier primitive and objects found), and on request the existence
//! probabilities of the polished chamfer solve.

use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::Context;
use crate::Pose;
use crate::Result;
use crate::chamfer::primitive_coefficients;
use crate::chamfer::{CandidateGeometry, Coefficients};
use crate::progress::Silent;
use crate::register::geometry::{Chain, OutlierBox, OutlierLevel, Particles};
use crate::solve::{Solution, SolverOptions, solve};

/// What [`Context::measure`] returns for each pose.
pub(crate) struct Measurement {
    /// Binary chamfer decrease when the pose alone joins the background (squared units).
    pub score: Vec<f64>,
    /// Existence probability in the polished chamfer solve: exactly 0 when the polished
    /// binary solution drops it, at least the threshold when it keeps it.
    pub existence: Vec<f64>,
}

impl Context<'_> {
    /// The measurement of every pose of `poses` (the filter's weights): the binary
    /// chamfer decrease when it alone is added to the outlier primitive (at the level of
    /// `kernel`) and the objects `found`, `Σ_y max(0, b(y) − d_i(y)) − w_prim g_i`, `b(y)`
    /// = the background's cost of `y`, with the primitive weight calibrated for `support`
    /// points ([`Context::price`]) unless
    /// [`RegisterOptions::primitive_weight`](super::RegisterOptions::primitive_weight) is
    /// set. Only the primitive term `g` of the chamfer is needed: the point term enters
    /// through the gains, over all points.
    pub fn scores(&self, found: &[Pose], poses: Vec<Pose>, kernel: f64, support: f64) -> Vec<f64> {
        let level = self.outlier_level(kernel);
        let particles = Particles::new(self.template(), self.grid.clone(), poses);
        let g = primitive_coefficients(&self.cloud_boxes, &particles, &Silent);
        let background = Particles::new(self.template(), self.grid.clone(), found.to_vec());
        self.scores_with(&level, &background, &particles, &g, support)
            .0
    }

    /// [`Context::scores`] and each pose's existence probability in the polished chamfer
    /// solve over the outlier primitive (its samples drawn from `rng`), the objects
    /// `found` (which come first in the candidate set and always exist) and `poses`.
    pub fn measure(
        &self,
        found: &[Pose],
        poses: Vec<Pose>,
        kernel: f64,
        support: f64,
        rng: &mut ChaCha8Rng,
    ) -> Result<Measurement> {
        let level = self.outlier_level(kernel);
        let outlier = OutlierBox::new(level, rng);
        let background = Particles::new(self.template(), self.grid.clone(), found.to_vec());
        let particles = Particles::new(self.template(), self.grid.clone(), poses);
        let fixed = Chain {
            a: &outlier,
            b: &background,
        };
        let all = Chain {
            a: &fixed,
            b: &particles,
        };
        let options = self.chamfer(kernel);
        let mut coeffs =
            Coefficients::build_with(self.cloud, &self.cloud_boxes, &all, &options, &Silent)?;
        let offset = fixed.len();
        let (score, weight) = self.scores_with(
            &level,
            &background,
            &particles,
            &coeffs.g[offset..],
            support,
        );
        coeffs.options.primitive_weight = weight;
        // The outlier primitive and the objects already found always exist: they pay no
        // primitive term, so the solve never trades them away.
        coeffs.g[..offset].iter_mut().for_each(|g| *g = 0.0);
        let solver = SolverOptions {
            polish: true,
            max_iterations: 100,
            initial: 1.0,
            ..Default::default()
        };
        let solution = solve(&coeffs, &solver, &Silent)?;
        Ok(Measurement {
            score,
            existence: self.polished_existence(&solution)[offset..].to_vec(),
        })
    }

    /// The outlier primitive at the level of `kernel` over the scene box.
    fn outlier_level(&self, kernel: f64) -> OutlierLevel {
        OutlierLevel::new(self.lo, self.hi, kernel, self.options.max_outlier_samples)
    }

    /// The scores of `particles` with primitive terms `g` (module docs of
    /// [`Context::scores`]) and the primitive weight they were priced with.
    fn scores_with(
        &self,
        level: &OutlierLevel,
        background: &Particles,
        particles: &Particles,
        g: &[f64],
        support: f64,
    ) -> (Vec<f64>, f64) {
        let kernel2 = level.expected_distance();
        let weight = match self.options.primitive_weight {
            Some(w) => w,
            None => self.price(kernel2, support) / median(g),
        };
        let cost = self.background_cost(level, background);
        let gain = self.point_gains(particles, &cost);
        // With a scale, clutter gains in proportion to the surface (scale²): each particle
        // is charged the clutter gain of its own area beyond that of the model at scale 1
        // (which the calibrated weight prices), or larger poses would win on clutter.
        let clutter = self.price(kernel2, 0.0);
        let score = (0..particles.len())
            .map(|i| {
                let s = particles.set.poses[i].scale;
                gain[i] - weight * g[i] - clutter * (s * s - 1.0)
            })
            .collect();
        (score, weight)
    }

    /// Each point's cost under the background (outlier primitive and found objects): its
    /// squared surface distance to the nearest of them (squared scene units).
    fn background_cost(&self, level: &OutlierLevel, background: &Particles) -> Vec<f64> {
        self.cloud
            .par_iter()
            .map(|y| {
                (0..background.len())
                    .map(|k| background.surface_distance(k, y))
                    .fold(level.cost(y), f64::min)
            })
            .collect()
    }

    /// Each particle's point-term gain over the background, `Σ_y max(0, b(y) − d_i(y)²)`
    /// with `b = cost`, over all points — not only over the β candidates each point keeps
    /// in the chamfer: in a concentrated population many particles pass near every object
    /// point and would crowd one another out of those lists.
    fn point_gains(&self, particles: &Particles, cost: &[f64]) -> Vec<f64> {
        // (A point farther than √b(y) from the particle's bounding box gains nothing.)
        particles
            .set
            .poses
            .par_iter()
            .enumerate()
            .map(|(i, pose)| {
                let (c, r) = particles.bounding_ball(i);
                self.cloud
                    .iter()
                    .zip(cost)
                    .filter_map(|(y, &b)| {
                        if (y - c).norm_squared() > (r + b.sqrt()).powi(2) {
                            return None;
                        }
                        let local = pose.to_local(y);
                        let reach = b.sqrt() / pose.scale;
                        if self.grid.box_distance(&local) >= reach {
                            return None;
                        }
                        let d = self.grid.distance(&local) * pose.scale;
                        Some((b - d * d).max(0.0))
                    })
                    .sum()
            })
            .collect()
    }

    /// The existence of every candidate after polish: exactly 0 where the polished binary
    /// solution drops it, at least
    /// [`RegisterOptions::threshold`](super::RegisterOptions::threshold) where it keeps it.
    fn polished_existence(&self, solution: &Solution) -> Vec<f64> {
        solution
            .exists
            .iter()
            .zip(&solution.probability)
            .map(|(&e, &p)| {
                if e {
                    p.max(self.options.threshold)
                } else {
                    p.min(0.0)
                }
            })
            .collect()
    }

    /// What an object must gain to exist: the point-term gain expected from uniform
    /// clutter around its surface plus that of `support` perfectly explained points.
    /// Clutter of density ρ = J / V (the scene box) gains `(4/3) ρ A δ³` on a surface of
    /// area `A` (the model's, at scale 1) for the kernel `δ² = kernel2`. The calibrated
    /// primitive weight makes a typical particle (median `g`) pay exactly this.
    fn price(&self, kernel2: f64, support: f64) -> f64 {
        let volume = (self.hi - self.lo)
            .iter()
            .map(|e| e.max(1e-12))
            .product::<f64>();
        let rho = self.cloud.len() as f64 / volume;
        let delta = kernel2.sqrt();
        let clutter = 4.0 / 3.0 * rho * self.area * delta * kernel2;
        clutter + support * kernel2
    }
}

/// The median of `values` (at least the smallest positive number; 1 when empty).
fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 1.0;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2].max(f64::MIN_POSITIVE)
}
