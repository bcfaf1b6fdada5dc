//! One lattice pass: candidates → memory check → coefficients → solve → (refinement).

use std::time::Instant;

use super::work::check_work;
use super::{FitResult, FitStats, Settings};
use crate::atlas::Shape;
use crate::chamfer::{ChamferOptions, Coefficients, estimate_bytes};
use crate::error::Remedy;
use crate::lattice::CandidateSet;
use crate::progress::Progress;
use crate::ray::{FreeSpace, Rays};
use crate::refine::{RefineContext, Refined, refine};
use crate::solve::solve;
use crate::spatial::PointIndex;
use crate::{Error, PointCloud, Primitive, Result, StageTimes, budget, check};

/// What [`refine`] needs from a fit under `settings` (`shapes` = `settings.shapes()`).
pub(super) fn refine_context<'a>(
    cloud: &'a PointCloud,
    index: &'a PointIndex,
    settings: &'a Settings,
    shapes: &'a [Shape],
) -> RefineContext<'a> {
    RefineContext {
        points: &cloud.points,
        index,
        point_spacing: settings.point_spacing,
        sample_spacing: settings.sample_spacing,
        chamfer: &settings.chamfer,
        shapes,
        frame: settings.frame,
    }
}

/// The peak memory the coefficients of `candidates` over `points` points will need, and
/// the most samples of any template; an error when that is over the settings' budget.
pub(super) fn check_memory(
    points: usize,
    candidates: &CandidateSet,
    settings: &Settings,
) -> Result<(u64, usize)> {
    let max_samples = candidates
        .templates
        .iter()
        .map(|t| t.samples.len())
        .max()
        .unwrap_or(1);
    let need = estimate_bytes(points, candidates.len(), max_samples, &settings.chamfer);
    budget::check_memory(
        &describe_fit(points, candidates, settings),
        need,
        settings.memory_budget,
        vec![
            Remedy::Lower("beta"),
            Remedy::Raise("spacing"),
            Remedy::Subsample,
            Remedy::Raise("memory_budget"),
        ],
    )?;
    Ok((need, max_samples))
}

/// `a fit of P points × N candidates (β = B)`: what a refused budget names.
pub(super) fn describe_fit(
    points: usize,
    candidates: &CandidateSet,
    settings: &Settings,
) -> String {
    let beta = settings
        .chamfer
        .beta
        .map_or("inf".to_string(), |b| b.to_string());
    format!(
        "a fit of {points} points × {} candidates (β = {beta})",
        candidates.len()
    )
}

/// Adds the free-space cost of `candidates` under the rays of `cloud` (which has sensor
/// origins) to their primitive coefficients `g`: the loss gains `w_point · Σ_i p_i f_i`
/// ([`FreeSpace`]), entered as `g_i += w_point f_i / w_prim` like the compact model's
/// description lengths. Needs a positive primitive weight.
pub(super) fn charge_free_space(
    cloud: &PointCloud,
    candidates: &[Primitive],
    chamfer: &ChamferOptions,
    g: &mut [f64],
) -> Result<FreeSpace> {
    check::positive(
        "primitive_weight (with free space)",
        chamfer.primitive_weight,
    )?;
    let rays = Rays::from_cloud(cloud)?;
    let free = FreeSpace::build(&rays, candidates, chamfer.cap)?;
    let scale = chamfer.point_weight / chamfer.primitive_weight;
    for (g, f) in g.iter_mut().zip(&free.cost) {
        *g += scale * f;
    }
    Ok(free)
}

/// The lattice's candidates within reach of the data (an error if none): a candidate
/// with no point within the cap of its surface can only raise the loss (see
/// `CandidateSet::near_data`), so dropping it is exact in effect.
fn near_candidates(cloud: &PointCloud, settings: &Settings) -> Result<CandidateSet> {
    let mut candidates = CandidateSet::build(&settings.lattice(), cloud)?;
    // Before the filter below, whose own cost is every candidate's samples.
    check_work(cloud.len(), &candidates, settings)?;
    if settings.cap > 0.0 {
        let keep = candidates.near_data(&cloud.points, settings.cap + settings.sample_spacing);
        candidates.retain(&keep);
    }
    if candidates.is_empty() {
        return Err(Error::Missing {
            what: "a lattice candidate near the cloud".into(),
            needed_by: "the existence solve",
        });
    }
    Ok(candidates)
}

/// One lattice fit under `settings`, refined when `settings.refine` is set.
pub(super) fn fit_pass(
    cloud: &PointCloud,
    index: &PointIndex,
    settings: Settings,
    progress: &dyn Progress,
) -> Result<FitResult> {
    let t0 = Instant::now();
    let mut candidates = near_candidates(cloud, &settings)?;
    let lattice_seconds = t0.elapsed().as_secs_f64();
    let (need, max_samples) = check_memory(cloud.len(), &candidates, &settings)?;
    progress.checkpoint()?;
    progress.message(&format!(
        "{} candidates, {} samples per template at most",
        candidates.len(),
        max_samples
    ));

    let t1 = Instant::now();
    // Exact: a dominated candidate has p = 0 at every minimum (`chamfer::dominance`).
    let reduced =
        Coefficients::build_reduced(&cloud.points, &candidates, &settings.chamfer, progress)?;
    let lattice_candidates = candidates.len();
    candidates.retain(&reduced.keep_mask(lattice_candidates));
    let mut coeffs = reduced.coefficients;
    if settings.free_space && cloud.sensors.is_some() {
        let prims: Vec<Primitive> = (0..candidates.len())
            .map(|i| candidates.primitive(i))
            .collect();
        let free = charge_free_space(cloud, &prims, &settings.chamfer, &mut coeffs.g)?;
        progress.message(&format!(
            "free space: {} rays cross candidates in front of their points",
            free.crossings.iter().sum::<usize>()
        ));
    }
    let coefficient_seconds = t1.elapsed().as_secs_f64();
    progress.checkpoint()?;
    progress.message(&format!(
        "{} of {lattice_candidates} candidates can exist (the rest are dominated); \
         {} entries ({} bytes each, {:.1} MiB in all)",
        candidates.len(),
        coeffs.entries(),
        Coefficients::BYTES_PER_ENTRY,
        coeffs.bytes() as f64 / (1 << 20) as f64
    ));

    let t2 = Instant::now();
    let solution = solve(&coeffs, &settings.solver, progress)?;
    let solve_seconds = t2.elapsed().as_secs_f64();

    let chosen: Vec<usize> = (0..candidates.len())
        .filter(|&i| solution.exists[i])
        .collect();
    let mut primitives: Vec<Primitive> = chosen.iter().map(|&i| candidates.primitive(i)).collect();
    let mut existence: Vec<f64> = chosen.iter().map(|&i| solution.probability[i]).collect();
    let mut refined = None;
    if let Some(options) = &settings.refine {
        let shapes = settings.shapes();
        let ctx = refine_context(cloud, index, &settings, &shapes);
        let r: Refined = refine(&ctx, &primitives, options)?;
        progress.checkpoint()?;
        progress.message(&format!(
            "refinement: binary chamfer {:.6} → {:.6}, {} primitives dropped, {:.2} s",
            r.loss_before, r.loss_after, r.dropped, r.seconds
        ));
        existence = r.source.iter().map(|&i| existence[i]).collect();
        primitives = r.primitives.clone();
        refined = Some(r);
    }
    let refine_seconds = refined.as_ref().map_or(0.0, |r| r.seconds);
    let mut stages = StageTimes::new();
    for (stage, seconds) in [
        ("lattice", lattice_seconds),
        ("coefficients", coefficient_seconds),
        ("solve", solve_seconds),
        ("refine", refine_seconds),
    ] {
        stages.add(stage, seconds);
    }
    let stats = FitStats {
        points: cloud.len(),
        lattice_candidates,
        candidates: candidates.len(),
        entries: coeffs.entries(),
        bytes_per_entry: Coefficients::BYTES_PER_ENTRY,
        coefficient_bytes: coeffs.bytes(),
        estimated_bytes: need,
        lattice_seconds,
        coefficient_seconds,
        solve_seconds,
        refine_seconds,
        refine_dropped: refined.as_ref().map_or(0, |r| r.dropped),
        passes: 1,
        filled: 0,
        stages,
    };
    Ok(FitResult {
        settings,
        primitives,
        existence,
        solution,
        stats,
        mcmc: None,
    })
}
