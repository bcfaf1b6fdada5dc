//! `fit_mcmc`: the whole thesis-chapter-4 pipeline behind `primfit fit --method mcmc`
//! ([`super::fit`] with [`super::MethodOptions::Mcmc`]).
//!
//! cloud (with sensor origins) → lattice candidates ([`CandidateSet::build`]) → the
//! §4.2.1 prior keeps the supported ones → [`RayTable`] → Metropolis–Hastings → the best
//! visited scene, as a [`FitResult`] (so JSON, mesh and metrics output are shared with
//! the chamfer method).
//!
//! Defaults (scene units, metres for the bundled data; the fixed ones are
//! [`super::McmcFitOptions::default`]):
//!
//! | setting | default |
//! |---|---|
//! | `rate` | `1 / diagonal` of the cloud's bounding box: about one noise return per scene-length of ray |
//! | `sigma` | `spacing / 10` |
//! | `min_cos` | 0.2 (the along-ray deviation is at most 5 σ) |
//! | `prior` | 0.1 (thesis) |
//! | `steps` | `max(1000, 20 N)` for N supported candidates; `burn_in` = `steps / 5` |
//! | `flips_per_step` | 1; `decay` 0.9 per frame |

use std::time::Instant;

use super::{FitOptions, FitResult, FitStats, McmcSettings, MethodSettings, Settings};
use crate::chamfer::LossValue;
use crate::lattice::CandidateSet;
use crate::na::Point3;
use crate::progress::Progress;
use crate::ray::{
    Entry, McmcOptions, PriorOptions, RayModel, RayTable, Rays, SEEN_SIGMAS, UNOBSERVED_POINT_NATS,
    existence_prior, flip_rates, local_spacings, occupancy_prior, sample, unobserved_points,
};
use crate::solve::{Solution, StopReason};
use crate::spatial::PointIndex;
use crate::{Error, PointCloud, Primitive, Result};

/// Default proposals after burn-in are `max(MIN_STEPS, STEPS_PER_CANDIDATE · N)` for N
/// supported candidates.
const MIN_STEPS: usize = 1000;
/// See [`MIN_STEPS`].
const STEPS_PER_CANDIDATE: usize = 20;
/// The default burn-in is the proposals after it divided by this.
const STEPS_PER_BURN_IN: usize = 5;

/// Who needs what the errors of this module name as missing.
const METHOD: &str = "the mcmc method";

/// What the `mcmc` sampler did (written to `result.json` under `settings.mcmc`).
#[derive(Debug, Clone, PartialEq)]
pub struct McmcRun {
    /// Proposals after burn-in.
    pub steps: usize,
    /// Proposals before the existence frequencies counted.
    pub burn_in: usize,
    /// Accepted proposals.
    pub accepted: usize,
    /// Single flips of the final climb from the best visited scene.
    pub polish_flips: usize,
    /// Log-likelihood of the chosen scene.
    pub log_likelihood: f64,
    /// Log-posterior of the chosen scene.
    pub log_posterior: f64,
    /// Sensor frames of the rays.
    pub frames: usize,
    /// Points skipped as rays (coinciding with their sensor origin).
    pub skipped_points: usize,
}

/// Fits primitives to a cloud with sensor origins by the ray likelihood and MCMC
/// (thesis ch. 4): [`super::fit`] with [`MethodOptions::Mcmc`]. Errors when the cloud has
/// no sensor origins.
pub(super) fn fit_mcmc(
    cloud: &PointCloud,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<FitResult> {
    let rays = check_cloud(cloud)?;
    let index = PointIndex::new(&cloud.points);
    let settings = Settings::resolve(cloud, &index, options)?;
    let MethodSettings::Mcmc(mcmc) = settings.method.clone() else {
        return Err(Error::Unknown {
            what: "method of an mcmc fit",
            value: settings.method.name().into(),
            expected: "mcmc",
        });
    };
    let model = mcmc.ray;

    let t0 = Instant::now();
    let (candidates, prior) = supported_candidates(cloud, &settings, mcmc.prior)?;
    let prior = observed_surface_prior(
        &index,
        &cloud.points,
        &candidates,
        &prior,
        &settings,
        &model,
    )?;
    let lattice_seconds = t0.elapsed().as_secs_f64();
    progress.message(&format!(
        "{} candidates supported by the prior",
        candidates.len()
    ));

    let t1 = Instant::now();
    let table = RayTable::build(&rays, &candidates, model)?;
    let table_seconds = t1.elapsed().as_secs_f64();
    progress.message(&format!(
        "{} rays in {} frames, {} crossings",
        table.rays(),
        table.frames(),
        table.entries()
    ));

    let steps = mcmc
        .steps
        .unwrap_or((STEPS_PER_CANDIDATE * candidates.len()).max(MIN_STEPS));
    let sampler = McmcOptions {
        steps,
        burn_in: mcmc.burn_in.unwrap_or(steps / STEPS_PER_BURN_IN),
        flips_per_step: mcmc.flips_per_step,
        decay: mcmc.decay,
        seed: settings.seed,
        polish: true,
    };
    // The sampler's length, known now that the candidates are, is part of the settings used.
    let settings = settings.with_method(MethodSettings::Mcmc(McmcSettings {
        steps: Some(sampler.steps),
        burn_in: Some(sampler.burn_in),
        ..mcmc
    }));
    let t2 = Instant::now();
    let rates = flip_rates(&table, &prior, &sampler)?;
    let run = sample(&table, &prior, &rates, &sampler, progress)?;
    let solve_seconds = t2.elapsed().as_secs_f64();

    let record = McmcRun {
        steps: sampler.steps,
        burn_in: sampler.burn_in,
        accepted: run.accepted,
        polish_flips: run.polish_flips,
        log_likelihood: run.best_log_likelihood,
        log_posterior: run.best_log_posterior,
        frames: rays.frames.len(),
        skipped_points: rays.skipped,
    };
    let chosen: Vec<usize> = (0..candidates.len()).filter(|&i| run.best[i]).collect();
    let stats = FitStats {
        points: cloud.len(),
        candidates: candidates.len(),
        entries: table.entries(),
        bytes_per_entry: std::mem::size_of::<Entry>(),
        coefficient_bytes: table.bytes(),
        estimated_bytes: table.bytes() as u64,
        lattice_seconds,
        coefficient_seconds: table_seconds,
        solve_seconds,
        ..Default::default()
    };
    let solution = Solution {
        probability: run.frequency.clone(),
        exists: run.best.clone(),
        history: run.trace.iter().map(|v| -v).collect(),
        iterations: run.proposals,
        evaluations: run.proposals,
        stop: StopReason::Iterations,
        thresholded: LossValue::default(),
        binary: LossValue::default(),
        flips: run.accepted,
    };
    Ok(FitResult {
        primitives: chosen.iter().map(|&i| candidates[i].clone()).collect(),
        existence: chosen.iter().map(|&i| run.frequency[i]).collect(),
        settings,
        solution,
        stats,
        mcmc: Some(record),
    })
}

/// The rays of a non-empty, finite cloud with sensor origins.
fn check_cloud(cloud: &PointCloud) -> Result<Rays> {
    if cloud.is_empty() {
        return Err(Error::EmptyCloud);
    }
    if cloud.sensors.is_none() {
        return Err(Error::Missing {
            what: "each point's sensor origin (the PLY vertex properties sensor_x, sensor_y, \
                   sensor_z)"
                .into(),
            needed_by: METHOD,
        });
    }
    let rays = Rays::from_cloud(cloud)?;
    if rays.is_empty() {
        return Err(Error::Missing {
            what: "a ray: a point apart from its sensor origin".into(),
            needed_by: METHOD,
        });
    }
    Ok(rays)
}

/// `prior` times the occupancy factor of `crate::ray` (`unseen.rs`): each candidate's
/// odds drop by [`UNOBSERVED_POINT_NATS`] per point's worth of its surface (at its own
/// point density) with no point within `max(SEEN_SIGMAS σ, local spacing)`. Samples are
/// `max(sample_spacing, point_spacing)` apart.
fn observed_surface_prior(
    index: &PointIndex,
    points: &[Point3<f64>],
    candidates: &[Primitive],
    prior: &[f64],
    settings: &Settings,
    model: &RayModel,
) -> Result<Vec<f64>> {
    let spacing = settings.sample_spacing.max(settings.point_spacing);
    let tolerance = SEEN_SIGMAS * model.sigma;
    let spacings = local_spacings(index, points);
    let unobserved = unobserved_points(
        index,
        &spacings,
        candidates,
        spacing,
        tolerance,
        settings.point_spacing,
    )?;
    occupancy_prior(prior, &unobserved, UNOBSERVED_POINT_NATS)
}

/// Lattice candidates whose §4.2.1 prior is positive, with that prior.
fn supported_candidates(
    cloud: &PointCloud,
    settings: &Settings,
    probability: f64,
) -> Result<(Vec<Primitive>, Vec<f64>)> {
    let spec = settings.lattice();
    let set = CandidateSet::build(&spec, cloud)?;
    let all: Vec<Primitive> = (0..set.len()).map(|i| set.primitive(i)).collect();
    let options = PriorOptions {
        probability,
        spacing: spec.spacing,
        origin: spec.origin,
        frame: spec.frame,
        up: nalgebra::Vector3::z(),
    };
    let prior = existence_prior(cloud, &all, &options)?;
    let (kept, prior): (Vec<Primitive>, Vec<f64>) =
        all.into_iter().zip(prior).filter(|(_, p)| *p > 0.0).unzip();
    if kept.is_empty() {
        return Err(Error::Missing {
            what: "a candidate supported by the prior (points near a lattice node with a \
                   matching label or normal)"
                .into(),
            needed_by: METHOD,
        });
    }
    Ok((kept, prior))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{McmcFitOptions, MethodOptions};
    use crate::progress::Silent;
    use crate::ray::tests::room;

    #[test]
    fn fit_mcmc_recovers_a_scanned_room_on_the_lattice() {
        let (cloud, truth, _) = room();
        let options = FitOptions {
            size: Some(1.0),
            spacing: Some(0.5),
            seed: 1,
            method: MethodOptions::Mcmc(McmcFitOptions {
                sigma: Some(0.02),
                ..Default::default()
            }),
            ..FitOptions::lattice()
        };
        let result = super::super::fit(&cloud, &options, &Silent).unwrap();
        assert!(!result.primitives.is_empty());
        for p in &result.primitives {
            let c = p.center();
            let on_truth = truth.iter().any(|t| t.distance(&c) < 1e-9);
            assert!(on_truth, "stray square at {c:?}");
        }
        let covered = cloud
            .points
            .iter()
            .filter(|y| result.primitives.iter().any(|p| p.distance(y) < 0.05))
            .count();
        assert!(
            covered as f64 > 0.9 * cloud.len() as f64,
            "{covered} / {}",
            cloud.len()
        );
        let json = result.to_json(serde_json::json!({}));
        assert_eq!(json["settings"]["method"], "mcmc");
        assert!(json["settings"].get("beta").is_none());
        assert!(json["settings"]["mcmc"]["accepted"].as_u64().unwrap() > 0);
        let measures = crate::metrics::MetricsOptions::default();
        let m = crate::metrics::evaluate(&cloud.points, &result.primitives, None, &measures);
        let doc = result.to_json(m.unwrap().to_json());
        let (back, m) = FitResult::from_json(&doc, &|_| unreachable!("no meshes")).unwrap();
        assert_eq!(back.mcmc, result.mcmc);
        assert_eq!(back.settings.method, result.settings.method);
        assert_eq!(back.to_json(m.to_json()), doc);
        // Without sensor origins it says so.
        let bare = PointCloud::from_points(cloud.points.clone());
        let err = super::super::fit(&bare, &options, &Silent)
            .unwrap_err()
            .to_string();
        assert!(err.contains("sensor"), "{err}");
    }
}
