//! The particle filter: one object's pose, searched with the probabilistic chamfer as the
//! measurement (thesis §6.3.3).

use std::sync::Arc;

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use rayon::prelude::*;

use super::RegisterOptions;
use super::geometry::{Chain, DistanceGrid, OutlierBox, Particles};
use super::icp::{Freedom, IcpOptions, refine};
use super::vote::{VoteIndex, refine_peak, vote_translation};
use crate::atlas::MeshShape;
use crate::chamfer::{CandidateGeometry, ChamferOptions, Coefficients, PointModel};
use crate::lattice::Template;
use crate::progress::{Progress, Silent};
use crate::solve::{SolverOptions, solve};
use crate::{Pose, Result};

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
    /// Largest existence probability of a particle in the chamfer solution.
    pub best_existence: f64,
    /// Effective sample size of the weights (particles).
    pub ess: f64,
}

/// Outcome of one filter run.
#[derive(Debug, Clone)]
pub struct FilterResult {
    /// Best pose of the last round.
    pub pose: Pose,
    /// Its measurement.
    pub score: f64,
    /// Kernel of the last round (scene units).
    pub kernel: f64,
    /// Per-round statistics.
    pub rounds: Vec<RoundStats>,
    /// For each approximate symmetry flip `f` of the model (index ≥ 1 of
    /// [`super::symmetry_flips`]), the best particle of the last round in the basin of
    /// `pose ∘ f`, if any.
    pub basins: Vec<Option<Pose>>,
}

/// What [`Context::measure`] returns for each pose.
pub(crate) struct Measurement {
    /// Binary chamfer decrease when the pose alone joins the background (squared units).
    pub score: Vec<f64>,
    /// Existence probability in the chamfer solve (with polish: exactly 0 when the
    /// polished binary solution drops it, at least the threshold when it keeps it).
    pub existence: Vec<f64>,
}

/// Fixed context of a search: cloud, model, scene box, objects already found.
pub(crate) struct Context<'a> {
    pub cloud: &'a [Point3<f64>],
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

    /// Existence probabilities of `poses` next to `found` and the outlier primitive (which
    /// come first in the candidate set), and the measurement of every pose: the binary chamfer decrease when it alone is
    /// added to the outlier primitive and `found`,
    /// `Σ_y max(0, b(y) − d_i(y)) − w_prim g_i`, `b(y)` = the background's cost of `y`,
    /// with the primitive weight calibrated for `support` points ([`Context::price`])
    /// unless [`RegisterOptions::primitive_weight`] is set.
    pub fn measure(
        &self,
        found: &[Pose],
        poses: Vec<Pose>,
        kernel: f64,
        support: f64,
        polish: bool,
        rng: &mut ChaCha8Rng,
    ) -> Result<Measurement> {
        let outlier = OutlierBox::new(
            self.lo,
            self.hi,
            kernel,
            self.options.max_outlier_samples,
            rng,
        );
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
        let mut coeffs = Coefficients::build(self.cloud, &all, &options, &Silent)?;
        let offset = fixed.len();
        let n = particles.len();
        let kernel2 = outlier.expected_distance();
        let price = self.price(kernel2, support);
        let weight = match self.options.primitive_weight {
            Some(w) => w,
            None => price / median(&coeffs.g[offset..]),
        };
        coeffs.options.primitive_weight = weight;
        // The outlier primitive and the objects already found always exist: they pay no
        // primitive term, so the solve never trades them away.
        coeffs.g[..offset].iter_mut().for_each(|g| *g = 0.0);
        let solver = SolverOptions {
            polish,
            max_iterations: 100,
            initial: 1.0,
            ..Default::default()
        };
        let solution = solve(&coeffs, &solver, &Silent)?;
        // Each point's cost under the background (outlier primitive and found objects),
        // and each particle's gain over all points — not only over the β candidates each
        // point keeps in the chamfer: in a concentrated population many particles pass
        // near every object point and would crowd one another out of those lists.
        let cost: Vec<f64> = self
            .cloud
            .par_iter()
            .map(|y| {
                (0..background.len())
                    .map(|k| background.surface_distance(k, y))
                    .fold(outlier.surface_distance(0, y), f64::min)
            })
            .collect();
        // (A point farther than √b(y) from the particle's bounding box gains nothing.)
        let gain: Vec<f64> = particles
            .set
            .poses
            .par_iter()
            .enumerate()
            .map(|(i, pose)| {
                let (c, r) = particles.bounding_ball(i);
                self.cloud
                    .iter()
                    .zip(&cost)
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
            .collect();
        // With a scale, clutter gains in proportion to the surface (scale²): each particle
        // is charged the clutter gain of its own area beyond that of the model at scale 1
        // (which the calibrated weight prices), or larger poses would win on clutter.
        let clutter = self.price(kernel2, 0.0);
        let score = (0..n)
            .map(|i| {
                let s = particles.set.poses[i].scale;
                gain[i] - weight * coeffs.g[offset + i] - clutter * (s * s - 1.0)
            })
            .collect();
        let existence = if polish {
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
                .collect::<Vec<f64>>()
        } else {
            solution.probability
        };
        Ok(Measurement {
            score,
            existence: existence[offset..].to_vec(),
        })
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
    /// the scan), each extent first multiplied by [`RegisterOptions::prior_margin`];
    /// along an axis where the model does not fit, the box's midpoint.
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

    /// A random move of `pose`: rotation by the exponential map of a Gaussian axis-angle
    /// vector (σ = `spread / lever` rad) about the model centre (about the origin when
    /// the translation is fixed); Gaussian translation (σ = `spread`); log-normal scale
    /// (σ = `spread / lever`), clamped to [`RegisterOptions::scale`].
    fn perturb(&self, pose: &Pose, spread: f64, rng: &mut ChaCha8Rng) -> Pose {
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

    /// The first population: `initial_particles` prior draws, or with screening
    /// ([`RegisterOptions::screen`]) the best `initial_particles` of that many draws by a
    /// cheap proxy of the measurement, the point-term gain `Σ_y max(0, δ² − d_i(y)²)` at
    /// the first kernel δ over a stride subsample of about
    /// [`RegisterOptions::screen_points`] cloud points.
    fn initial(&self, rng: &mut ChaCha8Rng) -> Vec<Pose> {
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

    /// The first population with translation votes: [`RegisterOptions::screen_draws`]
    /// prior rotations (with a scale range, each at stratified scales across the range,
    /// at most a factor 1.25 apart), each with the translations of its
    /// [`RegisterOptions::vote_peaks`] best vote peaks over the translation prior
    /// ([`Context::vote`], one grid cell precise); the [`RegisterOptions::vote_keep`]
    /// candidates with the most votes above clutter per unit model area, each
    /// translation refined at point level ([`refine_peak`]).
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

    /// `pose`'s rotation and scale with the translations of the `peaks` best vote peaks
    /// over its translation prior (the model inside the scene box; votes within a cell
    /// of it count), cells of [`RegisterOptions::vote_bin`] × the model size; with the
    /// votes of each peak.
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
        let mut best = (Pose::identity(), f64::NEG_INFINITY);
        let mut stable = 0;
        let mut kernel = o.kernel_start * self.size;
        let mut basins = vec![None; self.flips.len().saturating_sub(1)];
        for round in 0..o.max_rounds {
            kernel =
                self.size * (o.kernel_start * o.kernel_shrink.powi(round as i32)).max(o.kernel_end);
            let Measurement { score, existence } =
                self.measure(found, poses.clone(), kernel, o.search_support, false, rng)?;
            let (ib, &sb) = score
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))
                .expect("at least one particle");
            let previous = best.0;
            best = (poses[ib], sb);
            let weights = tempered_weights(&score, o.ess);
            let ess = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
            let mut order: Vec<usize> = (0..poses.len()).collect();
            order.sort_by(|&a, &b| score[b].total_cmp(&score[a]).then(a.cmp(&b)));
            // Each particle's basin: the flip f for which best ∘ f is nearest in rotation.
            let labels: Vec<usize> = poses.iter().map(|p| self.basin(&best.0, p)).collect();
            let mut leading = vec![None; self.flips.len()];
            for &k in &order {
                leading[labels[k]].get_or_insert(k);
            }
            basins = leading
                .iter()
                .skip(1)
                .map(|k| k.map(|k| poses[k]))
                .collect();
            rounds.push(RoundStats {
                kernel,
                particles: poses.len(),
                best_score: sb,
                best_existence: existence.iter().copied().fold(0.0, f64::max),
                ess,
            });
            progress.advance(1);
            let at_end = kernel <= o.kernel_end * self.size * (1.0 + 1e-9);
            if at_end {
                let moved = self.lever * previous.rotation.angle_to(&best.0.rotation)
                    + (previous.translation - best.0.translation).norm()
                    + self.lever * (previous.scale - best.0.scale).abs();
                let gained = sb - rounds[rounds.len().saturating_sub(2)].best_score;
                let settled = moved < 0.5 * kernel || gained <= 5e-3 * sb.abs();
                stable = if settled { stable + 1 } else { 0 };
                if stable >= o.settle_rounds {
                    break;
                }
            }
            if round + 1 == o.max_rounds {
                break;
            }
            // Keep the best unchanged, move the leaders downhill (a few trimmed-ICP steps at
            // the kernel width: the local optimum of the measurement for a fixed inlier
            // set), resample the rest (systematic) and move them at random.
            let mut next = Vec::with_capacity(o.particles);
            next.push(poses[ib]);
            let icp = IcpOptions {
                start_distance: kernel,
                min_distance: kernel,
                shrink: 1.0,
                max_iterations: o.local_steps,
                tolerance: 0.0,
                scale_range: o.scale,
            };
            // The leaders, the best of every other basin, and the symmetry jumps of the
            // leaders (turned by π about the model's principal axes), each moved downhill.
            let mut leaders: Vec<Pose> = order
                .iter()
                .take(o.local_moves.min(o.particles.saturating_sub(1)))
                .map(|&k| poses[k])
                .collect();
            for k in leading.iter().skip(1).flatten() {
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
            next.extend(
                leaders
                    .par_iter()
                    .map(|p| {
                        refine(&self.mesh, &self.grid, self.cloud, *p, self.freedom(), &icp).pose
                    })
                    .collect::<Vec<_>>(),
            );
            let spread = o.spread * kernel;
            // Every other basin keeps its quota (resampled by its own weights), so that
            // a basin the coarse kernels disfavour is still explored when the fine ones
            // can tell the basins apart; the rest is resampled from all.
            let quota = (o.basin_share * o.particles as f64).round() as usize;
            let mut picks = Vec::new();
            for l in 1..self.flips.len() {
                let members: Vec<usize> = (0..poses.len()).filter(|&i| labels[i] == l).collect();
                let room = o.particles.saturating_sub(next.len() + picks.len());
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
            let room = o.particles.saturating_sub(next.len() + picks.len());
            picks.extend(systematic(&weights, room, rng));
            next.extend(picks.iter().map(|&k| self.perturb(&poses[k], spread, rng)));
            poses = next;
        }
        Ok(FilterResult {
            pose: best.0,
            score: best.1,
            kernel,
            rounds,
            basins,
        })
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

/// The median of `values` (at least the smallest positive number; 1 when empty).
fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 1.0;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2].max(f64::MIN_POSITIVE)
}
