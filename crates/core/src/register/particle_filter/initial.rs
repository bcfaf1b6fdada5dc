//! The first population: prior draws (screened by a cheap proxy of the measurement) or,
//! with translation search, prior rotations with the translations their votes pick.

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

use super::Context;
use crate::Pose;
use crate::register::vote::{VoteIndex, refine_peak, vote_translation};

impl Context<'_> {
    /// A particle drawn from the prior: Haar-uniform rotation; log-uniform scale; with
    /// translation search, the model centre uniform in the positions where the rotated,
    /// scaled model lies inside the scene box ([`Context::translation_prior`]).
    fn prior(&self, rng: &mut ChaCha8Rng) -> Pose {
        let o = self.options;
        let rotation = random_rotation(rng);
        let scale = match o.scale {
            Some((a, b)) => (a.ln() + (b.ln() - a.ln()) * rng.random::<f64>()).exp(),
            None => 1.0,
        };
        if o.translation {
            let (lo, hi) = self.translation_prior(&rotation, scale);
            let c = lo + (hi - lo).map(|e| e * rng.random::<f64>());
            Pose::anchored(rotation, scale, &self.centre, &c)
        } else {
            Pose {
                rotation,
                translation: o.fixed_translation,
                scale,
            }
        }
    }

    /// The box of model-centre positions (scene units) for which the model's samples,
    /// rotated by `rotation` and scaled, lie inside the scene box (an object lies inside
    /// the scan), each extent first multiplied by
    /// [`RegisterOptions::prior_margin`](super::RegisterOptions::prior_margin); along an
    /// axis where the model does not fit, the box's midpoint.
    pub fn translation_prior(
        &self,
        rotation: &UnitQuaternion<f64>,
        scale: f64,
    ) -> (Point3<f64>, Point3<f64>) {
        let (mut neg, mut pos) = (Vector3::zeros(), Vector3::zeros());
        for v in &self.hull {
            let w = rotation * (v * scale);
            neg = neg.inf(&w);
            pos = pos.sup(&w);
        }
        let m = self.options.prior_margin;
        let (mut lo, mut hi) = (self.lo, self.hi);
        for a in 0..3 {
            let (l, h) = (self.lo[a] - m * neg[a], self.hi[a] - m * pos[a]);
            if l <= h {
                (lo[a], hi[a]) = (l, h);
            } else {
                let mid = 0.5 * (l + h);
                (lo[a], hi[a]) = (mid, mid);
            }
        }
        (lo, hi)
    }

    /// The first population: `initial_particles` prior draws, or with screening
    /// ([`RegisterOptions::screen`](super::RegisterOptions::screen)) the best
    /// `initial_particles` of that many draws by a cheap proxy of the measurement, the
    /// point-term gain `Σ_y max(0, δ² − d_i(y)²)` at the first kernel δ over a stride
    /// subsample of about
    /// [`RegisterOptions::screen_points`](super::RegisterOptions::screen_points) cloud
    /// points.
    pub(super) fn initial(&self, rng: &mut ChaCha8Rng) -> Vec<Pose> {
        let o = self.options;
        if let Some(index) = self.vote_index.as_ref().filter(|_| o.vote_peaks > 0) {
            return self.initial_by_vote(index, rng);
        }
        let draws = o.screen_draws().max(o.initial_particles);
        let poses: Vec<Pose> = (0..draws).map(|_| self.prior(rng)).collect();
        if draws == o.initial_particles {
            return poses;
        }
        let stride = self.cloud.len().div_ceil(o.screen_points.max(1)).max(1);
        let points: Vec<Point3<f64>> = self.cloud.iter().step_by(stride).copied().collect();
        let k2 = (o.kernel_start * self.size).powi(2);
        let gain: Vec<f64> = poses
            .par_iter()
            .map(|p| {
                points
                    .iter()
                    .map(|y| {
                        let d = self.grid.distance(&p.to_local(y)) * p.scale;
                        (k2 * p.scale * p.scale - d * d).max(0.0)
                    })
                    .sum()
            })
            .collect();
        let mut order: Vec<usize> = (0..draws).collect();
        order.sort_by(|&a, &b| gain[b].total_cmp(&gain[a]).then(a.cmp(&b)));
        order
            .iter()
            .take(o.initial_particles)
            .map(|&k| poses[k])
            .collect()
    }

    /// The first population with translation votes:
    /// [`RegisterOptions::screen_draws`](super::RegisterOptions::screen_draws) prior
    /// rotations (with a scale range, each at stratified scales across the range, at most a
    /// factor 1.25 apart), each with the translations of its
    /// [`RegisterOptions::vote_peaks`](super::RegisterOptions::vote_peaks) best vote peaks
    /// over the translation prior ([`Context::vote`], one grid cell precise); the
    /// [`RegisterOptions::vote_keep`](super::RegisterOptions::vote_keep) candidates with
    /// the most votes above clutter per unit model area, each translation refined at point
    /// level ([`refine_peak`]).
    fn initial_by_vote(&self, index: &VoteIndex, rng: &mut ChaCha8Rng) -> Vec<Pose> {
        let o = self.options;
        let draws = o.screen_draws().max(1);
        let seeds: Vec<Pose> = (0..draws).map(|_| self.prior(rng)).collect();
        // With a scale range, every rotation votes at stratified scales (ratio ≤ 1.25
        // apart: a scale that far off still piles the object's votes within one cell).
        let levels = match o.scale {
            Some((lo, hi)) if hi > lo => ((hi / lo).ln() / 1.25f64.ln()).ceil().max(1.0) as usize,
            _ => 1,
        };
        let jitter: Vec<f64> = (0..draws).map(|_| rng.random::<f64>()).collect();
        let tries: Vec<Pose> = seeds
            .iter()
            .zip(&jitter)
            .flat_map(|(p, u)| {
                (0..levels).map(move |k| match o.scale {
                    Some((lo, hi)) if levels > 1 => Pose {
                        scale: lo * (hi / lo).powf((k as f64 + u) / levels as f64),
                        ..*p
                    },
                    _ => *p,
                })
            })
            .collect();
        // Votes above what uniform clutter would give a peak window (samples × cloud
        // density × window volume), per unit of model area (× scale²): a small model
        // over the object's dense points gathers as many raw votes as the right one.
        let volume = (self.hi - self.lo)
            .iter()
            .map(|e| e.max(1e-12))
            .product::<f64>();
        let clutter = self.vote_samples.len() as f64 * self.cloud.len() as f64 / volume
            * (3.0 * index.cell()).powi(3);
        let mut voted: Vec<(Pose, f64)> = tries
            .par_iter()
            .map(|p| {
                self.vote(index, p, o.vote_peaks)
                    .into_iter()
                    .map(|(q, v)| (q, (v - clutter) * q.scale * q.scale))
                    .collect::<Vec<_>>()
            })
            .collect::<Vec<_>>()
            .concat();
        if voted.is_empty() {
            return seeds.into_iter().take(o.vote_keep).collect();
        }
        // Stable: ties keep the draw order.
        voted.sort_by(|a, b| b.1.total_cmp(&a.1));
        voted.truncate(o.vote_keep);
        voted
            .par_iter()
            .map(|(p, _)| Pose {
                translation: refine_peak(index, &self.vote_offsets(p), p.translation, 2),
                ..*p
            })
            .collect()
    }

    /// The model samples that vote, rotated and scaled by `pose` (scene units).
    fn vote_offsets(&self, pose: &Pose) -> Vec<Vector3<f64>> {
        self.vote_samples
            .iter()
            .map(|m| pose.rotation * (m * pose.scale))
            .collect()
    }

    /// `pose`'s rotation and scale with the translations of the `peaks` best vote peaks
    /// over its translation prior (the model inside the scene box; votes within a cell of
    /// it count), cells of [`RegisterOptions::vote_bin`](super::RegisterOptions::vote_bin)
    /// × the model size; with the votes of each peak.
    pub fn vote(&self, index: &VoteIndex, pose: &Pose, peaks: usize) -> Vec<(Pose, f64)> {
        let (clo, chi) = self.translation_prior(&pose.rotation, pose.scale);
        let shift = pose.rotation * (self.centre.coords * pose.scale);
        let (lo, hi) = (clo - shift, chi - shift);
        vote_translation(index, &self.vote_offsets(pose), &lo, &hi, peaks, 0)
            .into_iter()
            .map(|p| {
                (
                    Pose {
                        translation: p.translation,
                        ..*pose
                    },
                    p.votes,
                )
            })
            .collect()
    }
}

/// A Haar-uniform random rotation (a uniform unit quaternion: normalised 4-D Gaussian).
pub fn random_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    loop {
        let q = nalgebra::Quaternion::new(
            StandardNormal.sample(rng),
            StandardNormal.sample(rng),
            StandardNormal.sample(rng),
            StandardNormal.sample(rng),
        );
        if q.norm() > 1e-9 {
            return UnitQuaternion::from_quaternion(q);
        }
    }
}
