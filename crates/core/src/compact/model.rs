//! The compact model: detect → propose → decide existence → join runs by elbows → merge
//! collinear pieces → trim.

use std::borrow::Cow;

use nalgebra::Point3;
use rayon::prelude::*;

use super::candidates::{
    CandidateSamples, Proposal, judged_samples, planned_samples, propose, sparse_surface_scale,
};
use super::collinear::merge_collinear;
use super::elbows::join_runs;
use super::existence::{ExistenceOptions, decide_existence};
use super::mdl::primitive_cost;
use super::trim::{Cloud, Kept, Pricing, trim_overlaps};
use crate::chamfer::ChamferOptions;
use crate::detect::{DetectOptions, Detection, detect_timed};
use crate::error::{Remedy, Unit};
use crate::progress::Progress;
use crate::ray::{FreeSpace, Rays};
use crate::solve::{Solution, SolverOptions};
use crate::spatial::PointIndex;
use crate::{Error, Primitive, Result, StageTimes, Stopwatch};

/// The distance (in noise σ) within which a point counts as explained by a surface:
/// `cap = max(CAP_SIGMAS σ, CAP_SPACINGS s)`, with `d_cap = cap²` the cost of an
/// unexplained point. Five σ holds 99.99994 % of Gaussian noise.
pub const CAP_SIGMAS: f64 = 5.0;

/// See [`CAP_SIGMAS`]: a point within three point spacings of a surface is explained
/// even on a scan whose noise is below its sampling.
pub const CAP_SPACINGS: f64 = 3.0;

/// Candidate sample spacing in point spacings `s`: at one sample per spacing, the
/// primitive term of a surface covered by points is about `(s/2)²` per sample, well
/// under the cap, and a candidate has about as many samples as it explains points.
pub const SAMPLE_SPACINGS: f64 = 1.0;

/// β of the existence decision: candidates kept per point. Proposed candidates are
/// disjoint surfaces, so a point lies near a handful at most.
pub const EXISTENCE_BETA: usize = 8;

/// The most samples a plane's or sphere's primitive term is estimated from: a larger
/// surface is sampled more coarsely, each sample weighted by the area it stands for
/// (`candidates::judged_samples`). 20 000 samples estimate the area mean of the squared
/// distance to well under 1 % (its standard error shrinks as 1/√n), while the
/// nearest-point queries of a wall of a 10M-point scan drop from millions to this.
pub const PRIMITIVE_TERM_SAMPLES: f64 = 20_000.0;

/// The most candidate samples a compact model may plan (about 12 bytes of coefficients
/// and 24 of samples each): 20 million, a few hundred MiB.
pub const MAX_CANDIDATE_SAMPLES: f64 = 2e7;

/// Options of [`compact_model`]; every `None` is derived from the data.
#[derive(Debug, Clone, Default)]
pub struct CompactOptions {
    /// Shape detection.
    pub detect: DetectOptions,
    /// The distance within which a point counts as explained (scene units); default
    /// `max(5σ, 3s)` ([`CAP_SIGMAS`], [`CAP_SPACINGS`]).
    pub cap: Option<f64>,
    /// Spacing of candidate samples (scene units); default the point spacing `s`.
    pub sample_spacing: Option<f64>,
    /// Weights of the primitive and the point term (`None`: 1 and 1).
    pub weights: Option<[f64; 2]>,
    /// The solver of the existence decision.
    pub solver: SolverOptions,
    /// The scan's rays, when candidates are to pay for the rays that cross them in front
    /// of their points ([`FreeSpace`]); `None`: no free-space cost.
    pub free_space: Option<Rays>,
}

/// What [`compact_model`] returns.
#[derive(Debug, Clone)]
pub struct CompactModel {
    /// The primitives that exist.
    pub primitives: Vec<Primitive>,
    /// The continuous existence probability of each.
    pub existence: Vec<f64>,
    /// The detected segments (point lists, models, noise, spacing).
    pub detection: Detection,
    /// Candidates proposed from the segments.
    pub proposed: usize,
    /// The existence solver's output over the proposed candidates.
    pub solution: Solution,
    /// The cap used (scene units).
    pub cap: f64,
    /// The sample spacing used (scene units).
    pub sample_spacing: f64,
    /// Seconds spent detecting.
    pub detect_seconds: f64,
    /// Seconds spent proposing candidates and deciding their existence.
    pub existence_seconds: f64,
    /// Wall time of every step: `detect.*` ([`crate::detect::detect_timed`]),
    /// `propose`, `free_space`, `samples`, `existence.*` (coefficients, solve),
    /// `elbows`, `collinear`, `trim`.
    pub times: StageTimes,
}

/// The compact model of `points` (indexed by `index`): shapes detected from the data
/// ([`crate::detect`]), proposed as bounded candidates, kept by the probabilistic
/// chamfer with a description length per primitive (`mdl.rs`).
pub fn compact_model(
    points: &[Point3<f64>],
    index: &PointIndex,
    options: &CompactOptions,
    progress: &dyn Progress,
) -> Result<CompactModel> {
    let mut clock = Stopwatch::start();
    let (detection, detect_times) = detect_timed(points, index, &options.detect)?;
    let detect_seconds = clock.lap("detect");
    clock.nest("detect", &detect_times);
    progress.checkpoint()?;
    progress.message(&format!(
        "detected {} segments ({} clutter, {} points unassigned), σ = {:.5}, spacing {:.5}, {:.2} s",
        detection.segments.len(),
        detection.clutter.len(),
        detection.unassigned.len(),
        detection.model_noise,
        detection.spacing,
        detect_seconds
    ));
    let proposals: Vec<Proposal> = propose(points, index, &detection);
    clock.lap("propose");
    let (noise, spacing) = (detection.model_noise, detection.spacing);
    let cap = options
        .cap
        .unwrap_or((CAP_SIGMAS * noise).max(CAP_SPACINGS * spacing));
    let sample_spacing = options.sample_spacing.unwrap_or(SAMPLE_SPACINGS * spacing);
    let candidates: Vec<Primitive> = proposals.iter().map(|p| p.primitive.clone()).collect();
    check_sample_budget(&candidates, sample_spacing)?;
    let mut cost: Vec<f64> = candidates
        .iter()
        .map(|p| primitive_cost(p, noise, points.len()))
        .collect();
    if let Some(rays) = &options.free_space {
        // The loss gains `w_point · Σ_i p_i f_i`; `cost` enters it unweighted.
        let free = FreeSpace::build(rays, &candidates, cap * cap)?;
        let point_weight = options.weights.map_or(1.0, |w| w[1]);
        for (c, f) in cost.iter_mut().zip(&free.cost) {
            *c += point_weight * f;
        }
        clock.lap("free_space");
    }
    let existence_options = existence_options(options, cap, sample_spacing)?;
    let samples: Vec<CandidateSamples> = proposals
        .par_iter()
        .map(|p| {
            let segment = &detection.segments[p.segment].points;
            let mut judged = judged_samples(
                &p.primitive,
                segment,
                points,
                sample_spacing,
                PRIMITIVE_TERM_SAMPLES,
            );
            judged.sparse_scale = sparse_surface_scale(points, index, segment, spacing);
            judged
        })
        .collect();
    clock.lap("samples");
    let decision = decide_existence(
        points,
        index,
        &candidates,
        &samples,
        &cost,
        &existence_options,
        progress,
    )?;
    clock.nest("existence", &decision.times);
    let cloud = Cloud {
        points,
        index,
        spacing,
    };
    let pricing = Pricing {
        cap,
        noise,
        point_weight: options.weights.map_or(1.0, |w| w[1]),
    };
    let (kept, existence) = kept_with_members(
        points,
        &detection,
        &proposals,
        &decision.exists,
        &decision.probability,
    );
    let (kept, existence) = join_runs(cloud, kept, existence, pricing, sample_spacing);
    clock.lap("elbows");
    let (kept, existence) = merge_collinear(cloud, kept, existence, pricing, sample_spacing);
    clock.lap("collinear");
    let (primitives, existence) = trimmed(cloud, &kept, &existence, pricing);
    clock.lap("trim");
    let existence_seconds: f64 = (clock.times.iter())
        .filter(|(stage, _)| !stage.starts_with("detect"))
        .map(|(_, t)| t)
        .sum();
    progress.checkpoint()?;
    progress.message(&format!(
        "{} of {} proposed primitives exist, {:.2} s",
        primitives.len(),
        proposals.len(),
        existence_seconds
    ));
    Ok(CompactModel {
        primitives,
        existence,
        detection,
        proposed: proposals.len(),
        solution: decision.solution,
        cap,
        sample_spacing,
        detect_seconds,
        existence_seconds,
        times: clock.times,
    })
}

/// The candidates that exist (`exists`), each with the points it was built from, and
/// the existence `probability` of each.
fn kept_with_members<'a>(
    points: &[Point3<f64>],
    detection: &'a Detection,
    proposals: &[Proposal],
    exists: &[bool],
    probability: &[f64],
) -> (Vec<Kept<'a>>, Vec<f64>) {
    let mut members = kept_members(points, detection, proposals, exists);
    (0..proposals.len())
        .filter(|&i| exists[i])
        .map(|i| {
            let kept = Kept {
                primitive: proposals[i].primitive.clone(),
                members: std::mem::take(&mut members[i]),
            };
            (kept, probability[i])
        })
        .unzip()
}

/// `kept` trimmed where a larger one covers them (`trim.rs`): the model's primitives and
/// the existence of each (a trimmed plane's parts share its `existence`).
fn trimmed(
    cloud: Cloud,
    kept: &[Kept],
    existence: &[f64],
    pricing: Pricing,
) -> (Vec<Primitive>, Vec<f64>) {
    let (mut primitives, mut probability) = (Vec::new(), Vec::new());
    for (parts, &p) in trim_overlaps(cloud, kept, pricing)
        .into_iter()
        .zip(existence)
    {
        probability.extend(parts.iter().map(|_| p));
        primitives.extend(parts);
    }
    (primitives, probability)
}

/// The points each proposal that `exists` was built from (empty for the others): its
/// segment's, or, where the segment proposed several primitives, those nearer to it
/// than to its siblings (ties: the first).
fn kept_members<'a>(
    points: &[Point3<f64>],
    detection: &'a Detection,
    proposals: &[Proposal],
    exists: &[bool],
) -> Vec<Cow<'a, [usize]>> {
    let mut siblings: Vec<Vec<usize>> = vec![Vec::new(); detection.segments.len()];
    for (i, p) in proposals.iter().enumerate() {
        siblings[p.segment].push(i);
    }
    let mut members: Vec<Cow<[usize]>> = vec![Cow::Borrowed(&[]); proposals.len()];
    for (segment, ids) in detection.segments.iter().zip(&siblings) {
        if !ids.iter().any(|&i| exists[i]) {
            continue;
        }
        if let [only] = ids[..] {
            members[only] = Cow::Borrowed(&segment.points);
            continue;
        }
        let nearest: Vec<usize> = (segment.points.par_iter())
            .map(|&j| {
                let d = |&&k: &&usize| proposals[k].primitive.distance(&points[j]);
                let by_distance = |a: &&usize, b: &&usize| d(a).total_cmp(&d(b));
                *ids.iter()
                    .min_by(by_distance)
                    .expect("a segment's own proposal")
            })
            .collect();
        for (&j, &k) in segment.points.iter().zip(&nearest) {
            if exists[k] {
                members[k].to_mut().push(j);
            }
        }
    }
    members
}

/// Refuses candidates whose samples at `sample_spacing` would exceed
/// [`MAX_CANDIDATE_SAMPLES`], naming the remedies.
fn check_sample_budget(candidates: &[Primitive], sample_spacing: f64) -> Result<()> {
    let planned: f64 = (candidates.iter())
        .map(|c| planned_samples(c, sample_spacing, PRIMITIVE_TERM_SAMPLES))
        .sum();
    if planned > MAX_CANDIDATE_SAMPLES {
        return Err(Error::OverLimit {
            what: format!("the candidates' samples at spacing {sample_spacing}"),
            need: planned,
            limit: MAX_CANDIDATE_SAMPLES,
            unit: Unit::Count("samples"),
            remedies: vec![Remedy::Raise("sample_spacing"), Remedy::Subsample],
        });
    }
    Ok(())
}

/// The existence decision's options: the chamfer with cap `cap` (scene units) on surface
/// distances and β = [`EXISTENCE_BETA`], the weights and solver of `options`; checked.
fn existence_options(
    options: &CompactOptions,
    cap: f64,
    sample_spacing: f64,
) -> Result<ExistenceOptions> {
    let existence = ExistenceOptions {
        sample_spacing,
        chamfer: ChamferOptions {
            cap: cap * cap,
            surface_distance: true,
            beta: Some(EXISTENCE_BETA),
            primitive_weight: options.weights.map_or(1.0, |w| w[0]),
            point_weight: options.weights.map_or(1.0, |w| w[1]),
            ..Default::default()
        },
        solver: options.solver.clone(),
    };
    existence.chamfer.validate()?;
    Ok(existence)
}
