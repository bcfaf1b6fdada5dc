//! The particle filter: one object's pose, searched with the probabilistic chamfer as the
//! measurement (thesis §6.3.3).

mod initial;
mod measurement;
mod resampling;

use std::sync::Arc;

use nalgebra::{Point3, Vector3};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::RegisterOptions;
use super::geometry::DistanceGrid;
use super::icp::{Freedom, IcpOptions, refine};
use super::vote::VoteIndex;
use crate::atlas::MeshShape;
use crate::chamfer::{ChamferOptions, PointModel};
use crate::lattice::Template;
use crate::progress::Progress;
use crate::spatial::{BoxTree, PointIndex};
use crate::{Pose, Result};

#[cfg(test)]
pub(crate) use initial::random_rotation;
pub use resampling::{systematic, tempered_weights};

/// What one round of the filter saw.
#[derive(Debug, Clone, PartialEq)]
pub struct RoundStats {
    /// Kernel width of the round: the outlier primitive's expected nearest-sample
    /// distance (scene units).
    pub kernel: f64,
    /// Particles in the round.
    pub particles: usize,
    /// Best measurement (loss decrease when the best particle is added to the
    /// background; squared scene units).
    pub best_score: f64,
    /// Effective sample size of the weights (particles).
    pub ess: f64,
}

/// Outcome of one filter run.
#[derive(Debug, Clone)]
pub struct FilterResult {
    /// Best pose of the last round.
    pub pose: Pose,
    /// Per-round statistics.
    pub rounds: Vec<RoundStats>,
    /// For each approximate symmetry flip `f` of the model (index ≥ 1 of
    /// [`super::symmetry_flips`]), the best particle of the last round in the basin of
    /// `pose ∘ f`, if any.
    pub basins: Vec<Option<Pose>>,
}

/// Fixed context of a search: cloud, model, scene box, objects already found.
pub(crate) struct Context<'a> {
    pub cloud: &'a [Point3<f64>],
    /// A kd-tree over `cloud`.
    pub cloud_index: PointIndex,
    /// A box tree over `cloud`: the primitive terms of the measurements.
    pub cloud_boxes: BoxTree,
    pub grid: Arc<DistanceGrid>,
    pub mesh: MeshShape,
    pub template_spacing: f64,
    pub shape: crate::Shape,
    pub lo: Point3<f64>,
    pub hi: Point3<f64>,
    /// The model's surface samples relative to its centre (local units).
    pub hull: Vec<Vector3<f64>>,
    /// Mesh surface area (local units²).
    pub area: f64,
    /// Model size: diagonal of the mesh's bounding box (local units).
    pub size: f64,
    /// Centre of the mesh's bounding box (local frame).
    pub centre: Point3<f64>,
    /// RMS distance of the mesh's samples from the rotation centre (local units).
    pub lever: f64,
    /// The cloud bucketed for translation votes (with translation search).
    pub vote_index: Option<VoteIndex>,
    /// The model samples that vote (local frame, local units).
    pub vote_samples: Vec<Vector3<f64>>,
    /// The identity and the model's approximate symmetry flips (poses to compose on the
    /// right).
    pub flips: Vec<Pose>,
    pub options: &'a RegisterOptions,
}

impl Context<'_> {
    /// Which pose parameters are estimated.
    pub fn freedom(&self) -> Freedom {
        Freedom {
            translation: self.options.translation,
            scale: self.options.scale.is_some(),
        }
    }

    fn template(&self) -> Template {
        Template::new(self.shape.clone(), self.template_spacing)
    }

    /// The chamfer options of a round with kernel `kernel`.
    fn chamfer(&self, kernel: f64) -> ChamferOptions {
        ChamferOptions {
            model: PointModel::Existence,
            alpha: None,
            beta: Some(self.options.beta),
            cap: 4.0 * kernel * kernel,
            surface_distance: true,
            primitive_weight: 1.0, // replaced once g is known
            point_weight: 1.0,
        }
    }

    /// The basin of `pose` relative to `best`: the index of the flip `f` (0 = identity)
    /// for which the rotation of `best ∘ f` is nearest `pose`'s.
    fn basin(&self, best: &Pose, pose: &Pose) -> usize {
        self.flips
            .iter()
            .map(|f| pose.rotation.angle_to(&(best.rotation * f.rotation)))
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            .map_or(0, |(k, _)| k)
    }

    /// Runs the filter for one more object, given those already `found`.
    pub fn run(
        &self,
        found: &[Pose],
        rng: &mut ChaCha8Rng,
        progress: &dyn Progress,
    ) -> Result<FilterResult> {
        let o = self.options;
        let mut poses = self.initial(rng);
        let mut rounds = Vec::new();
        let mut best = Pose::identity();
        let mut stable = 0;
        let mut unpaid = 0;
        let mut basins = vec![None; self.flips.len().saturating_sub(1)];
        for round in 0..o.max_rounds {
            let kernel =
                self.size * (o.kernel_start * o.kernel_shrink.powi(round as i32)).max(o.kernel_end);
            let score = self.scores(found, poses.clone(), kernel, o.search_support);
            let (ib, &sb) = score
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))
                .expect("at least one particle");
            let previous = best;
            best = poses[ib];
            let weights = tempered_weights(&score, o.ess);
            let ess = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
            let ranking = self.rank(&poses, &score, ib);
            basins = ranking
                .leading
                .iter()
                .skip(1)
                .map(|k| k.map(|k| poses[k]))
                .collect();
            rounds.push(RoundStats {
                kernel,
                particles: poses.len(),
                best_score: sb,
                ess,
            });
            progress.advance(1);
            // No particle has paid for itself for a while: nothing (more) to find here.
            unpaid = if sb > 0.0 { 0 } else { unpaid + 1 };
            if o.give_up_rounds > 0 && unpaid == o.give_up_rounds {
                break;
            }
            let at_end = kernel <= o.kernel_end * self.size * (1.0 + 1e-9);
            if at_end {
                let settled = self.settled(&previous, &best, &rounds, kernel);
                stable = if settled { stable + 1 } else { 0 };
                if stable >= o.settle_rounds {
                    break;
                }
            }
            if round + 1 == o.max_rounds {
                break;
            }
            poses = self.next_population(&poses, &score, &weights, &ranking, kernel, rng);
        }
        Ok(FilterResult {
            pose: best,
            rounds,
            basins,
        })
    }

    /// The particles `poses` ranked by `score` and sorted into the basins of the symmetry
    /// flips of the best, `poses[best]`.
    fn rank(&self, poses: &[Pose], score: &[f64], best: usize) -> Ranking {
        let mut order: Vec<usize> = (0..poses.len()).collect();
        order.sort_by(|&a, &b| score[b].total_cmp(&score[a]).then(a.cmp(&b)));
        // Each particle's basin: the flip f for which best ∘ f is nearest in rotation.
        let labels: Vec<usize> = poses.iter().map(|p| self.basin(&poses[best], p)).collect();
        let mut leading = vec![None; self.flips.len()];
        for &k in &order {
            leading[labels[k]].get_or_insert(k);
        }
        Ranking {
            best,
            order,
            labels,
            leading,
        }
    }

    /// Whether the best pose has settled at the last kernel: it moved (rotation and scale
    /// changes weighted by the lever arm) less than half the kernel since the previous
    /// round's best, or the best score (the last of `rounds`) gained at most 0.5 %.
    fn settled(&self, previous: &Pose, best: &Pose, rounds: &[RoundStats], kernel: f64) -> bool {
        let moved = self.lever * previous.rotation.angle_to(&best.rotation)
            + (previous.translation - best.translation).norm()
            + self.lever * (previous.scale - best.scale).abs();
        let sb = rounds[rounds.len() - 1].best_score;
        let gained = sb - rounds[rounds.len().saturating_sub(2)].best_score;
        moved < 0.5 * kernel || gained <= 5e-3 * sb.abs()
    }

    /// The next round's particles: the best unchanged, the leaders moved
    /// downhill (a few trimmed-ICP steps at the kernel width: the local optimum of the
    /// measurement for a fixed inlier set), the rest resampled ([`Context::resample`]) and
    /// moved at random.
    fn next_population(
        &self,
        poses: &[Pose],
        score: &[f64],
        weights: &[f64],
        ranking: &Ranking,
        kernel: f64,
        rng: &mut ChaCha8Rng,
    ) -> Vec<Pose> {
        let o = self.options;
        let mut next = Vec::with_capacity(o.particles);
        next.push(poses[ranking.best]);
        let icp = IcpOptions {
            start_distance: kernel,
            min_distance: kernel,
            shrink: 1.0,
            max_iterations: o.local_steps,
            tolerance: 0.0,
            scale_range: o.scale,
        };
        next.extend(
            self.leaders(poses, ranking)
                .par_iter()
                .map(|p| refine(&self.mesh, &self.grid, self.cloud, *p, self.freedom(), &icp).pose)
                .collect::<Vec<_>>(),
        );
        let spread = o.spread * kernel;
        let picks = self.resample(score, weights, &ranking.labels, next.len(), rng);
        next.extend(picks.iter().map(|&k| self.perturb(&poses[k], spread, rng)));
        next
    }

    /// The particles moved downhill: the leaders, the best of every other basin, and the
    /// symmetry jumps of the leaders (turned by π about the model's principal axes), so
    /// many that with the best they stay under [`RegisterOptions::particles`].
    fn leaders(&self, poses: &[Pose], ranking: &Ranking) -> Vec<Pose> {
        let o = self.options;
        let order = &ranking.order;
        let mut leaders: Vec<Pose> = order
            .iter()
            .take(o.local_moves.min(o.particles.saturating_sub(1)))
            .map(|&k| poses[k])
            .collect();
        for k in ranking.leading.iter().skip(1).flatten() {
            if leaders.len() + 1 < o.particles
                && order[..o.local_moves.min(order.len())]
                    .iter()
                    .all(|j| j != k)
            {
                leaders.push(poses[*k]);
            }
        }
        for &k in order.iter().take(o.flip_moves) {
            for f in self.flips.iter().skip(1) {
                if leaders.len() + 1 < o.particles {
                    leaders.push(poses[k].compose(f));
                }
            }
        }
        leaders
    }

    /// Indices of the particles resampled (systematic) to fill the population after
    /// `kept` particles: every other basin keeps its quota
    /// ([`RegisterOptions::basin_share`]), resampled by its own weights, so that a basin
    /// the coarse kernels disfavour is still explored when the fine ones can tell the
    /// basins apart; the rest is resampled from all by `weights`.
    fn resample(
        &self,
        score: &[f64],
        weights: &[f64],
        labels: &[usize],
        kept: usize,
        rng: &mut ChaCha8Rng,
    ) -> Vec<usize> {
        let o = self.options;
        let quota = (o.basin_share * o.particles as f64).round() as usize;
        let mut picks = Vec::new();
        for l in 1..self.flips.len() {
            let members: Vec<usize> = (0..labels.len()).filter(|&i| labels[i] == l).collect();
            let room = o.particles.saturating_sub(kept + picks.len());
            if members.is_empty() || room == 0 {
                continue;
            }
            let member_scores: Vec<f64> = members.iter().map(|&i| score[i]).collect();
            let w = tempered_weights(&member_scores, o.ess);
            picks.extend(
                systematic(&w, quota.min(room), rng)
                    .into_iter()
                    .map(|k| members[k]),
            );
        }
        let room = o.particles.saturating_sub(kept + picks.len());
        picks.extend(systematic(weights, room, rng));
        picks
    }
}

/// One round's particles ranked by their measurement, with their basins.
struct Ranking {
    /// The best particle (ties: the lowest index).
    best: usize,
    /// Particle indices, best score first (ties: lowest index first).
    order: Vec<usize>,
    /// Each particle's basin: the index of the flip `f` of the best particle `best` for
    /// which `best ∘ f` is nearest in rotation (0 = the best's own basin).
    labels: Vec<usize>,
    /// For each basin, its best particle, if any.
    leading: Vec<Option<usize>>,
}
