//! The final choice among a registration's tries: each start pose (the filter's answer,
//! its symmetry flips, the point-pair hypotheses) settled by trimmed ICP against the
//! exact surface, measured by its margin over the outlier-only explanation
//! ([`confidence`](super::confidence)), the best kept with the calibrated existence of
//! its margin and of its lead over the best *other* answer.

use nalgebra::Point3;
use rayon::prelude::*;

use super::particle_filter::{Context, RoundStats};
use super::{FoundObject, confidence, icp};
use crate::atlas::MeshShape;
use crate::{PointCloud, Pose, Primitive};

/// The points no object found so far explains, with their sensor origins when the
/// cloud has them (for [`confidence::support`]'s visibility test): each new object's
/// margin is measured on them, so a second copy of a found object has no support.
pub(super) struct Unexplained {
    points: Vec<Point3<f64>>,
    sensors: Option<Vec<Point3<f64>>>,
}

impl Unexplained {
    /// Every point of `cloud`.
    pub fn all(cloud: &PointCloud) -> Self {
        Unexplained {
            points: cloud.points.clone(),
            sensors: cloud.sensors.clone(),
        }
    }

    /// Drops the points within `inlier` of `object`'s surface (scene units).
    pub fn remove_near(&mut self, object: &Primitive, inlier: f64) {
        let keep: Vec<bool> = self
            .points
            .iter()
            .map(|y| object.distance(y) > inlier)
            .collect();
        let mut flags = keep.iter();
        self.points
            .retain(|_| *flags.next().expect("one flag per point"));
        if let Some(sensors) = &mut self.sensors {
            let mut flags = keep.iter();
            sensors.retain(|_| *flags.next().expect("one flag per point"));
        }
    }
}

/// A start pose polished against the whole cloud: what a try is before it is measured.
/// It does not depend on which points are still unexplained, so the point-pair
/// hypotheses are polished once and measured again for each object searched for.
#[derive(Clone)]
pub(super) struct Polished {
    /// The pose it started from.
    pub start: Pose,
    /// Its ICP-refined pose, inliers and RMS.
    pub refined: icp::IcpResult,
}

/// One try of the final choice.
pub(super) struct Settled {
    /// The pose it started from.
    pub start: Pose,
    /// Its ICP-refined pose, inliers and RMS.
    pub refined: icp::IcpResult,
    /// Its margin over the outlier-only explanation of the unexplained points.
    pub margin: f64,
}

/// Each of `starts` (at `scale`) polished by ICP from the first kernel down to the last
/// ([`settle`]) and refined down to the inlier distance ([`refine_object`]), in
/// parallel, in order.
pub(super) fn polish_all(
    context: &Context,
    cloud: &PointCloud,
    mesh: &MeshShape,
    starts: &[Pose],
    scale: f64,
) -> Vec<Polished> {
    let kernel = context.options.kernel_end * context.size * scale;
    starts
        .par_iter()
        .map(|start| {
            let settled = settle(context, cloud, mesh, *start, scale);
            Polished {
                start: *start,
                refined: refine_object(context, cloud, mesh, settled, kernel, scale),
            }
        })
        .collect()
}

/// Each of `polished` measured on `unexplained` (its margin), in parallel, in order.
pub(super) fn measure_all(
    context: &Context,
    unexplained: &Unexplained,
    polished: &[Polished],
) -> Vec<Settled> {
    polished
        .par_iter()
        .map(|p| Settled {
            start: p.start,
            refined: p.refined.clone(),
            margin: margin_of(context, unexplained, &p.refined.pose),
        })
        .collect()
}

/// Each of `starts` polished ([`polish_all`]) and measured on `unexplained`
/// ([`measure_all`]).
pub(super) fn settle_all(
    context: &Context,
    cloud: &PointCloud,
    unexplained: &Unexplained,
    mesh: &MeshShape,
    starts: &[Pose],
    scale: f64,
) -> Vec<Settled> {
    let polished = polish_all(context, cloud, mesh, starts, scale);
    measure_all(context, unexplained, &polished)
}

/// The try chosen and how sure it is.
#[derive(Debug, Clone, Copy)]
pub(super) struct Answer {
    /// Index of the try with the largest margin (the first on ties).
    pub pick: usize,
    /// The largest margin among the tries that are not the same answer ([`same_pose`];
    /// −∞ when there is none).
    pub runner_up: f64,
    /// The calibrated existence of the pick ([`confidence::existence`]).
    pub existence: f64,
}

/// The best of `tries` (`None` when there are none), its existence under the
/// calibration of clouds with or without sensor origins, as `unexplained` has them.
pub(super) fn choose(
    context: &Context,
    unexplained: &Unexplained,
    tries: &[Settled],
) -> Option<Answer> {
    let calibration = match unexplained.sensors {
        Some(_) => &confidence::WITH_SENSORS,
        None => &confidence::WITHOUT_SENSORS,
    };
    let pick = (0..tries.len()).max_by(|&a, &b| {
        (tries[a].margin)
            .total_cmp(&tries[b].margin)
            .then(b.cmp(&a))
    })?;
    let chosen = &tries[pick].refined.pose;
    let runner_up = tries
        .iter()
        .filter(|t| !same_pose(context, chosen, &t.refined.pose))
        .map(|t| t.margin)
        .fold(f64::NEG_INFINITY, f64::max);
    Some(Answer {
        pick,
        runner_up,
        existence: confidence::existence(tries[pick].margin, runner_up, calibration),
    })
}

/// The object `answer` picks from `tries`, reporting `search_pose` (the search's pose
/// before ICP) and the search's `rounds`.
pub(super) fn found_object(
    cloud: &PointCloud,
    tries: Vec<Settled>,
    answer: Answer,
    search_pose: Pose,
    rounds: Vec<RoundStats>,
    context: &Context,
) -> FoundObject {
    let chosen = tries
        .into_iter()
        .nth(answer.pick)
        .expect("the pick is a try");
    FoundObject {
        primitive: Primitive::new(context.shape.clone(), chosen.refined.pose),
        existence: answer.existence,
        margin: chosen.margin,
        runner_up_margin: answer.runner_up,
        inlier_share: chosen.refined.inliers.len() as f64 / cloud.len() as f64,
        rms: chosen.refined.rms,
        filter_pose: search_pose,
        rounds,
    }
}

/// Whether two poses are the same answer: the model's surface samples move between them
/// by less than [`SAME_ANSWER_DISPLACEMENT`] × the model size (RMS). Tries that ICP
/// left a few degrees apart in one basin are one answer polished twice, not a rival.
fn same_pose(context: &Context, a: &Pose, b: &Pose) -> bool {
    let hull = &context.hull;
    let squared: f64 = hull
        .iter()
        .map(|h| {
            let x = context.centre + h;
            (a.to_scene(&x) - b.to_scene(&x)).norm_squared()
        })
        .sum();
    let rms = (squared / hull.len().max(1) as f64).sqrt();
    rms < SAME_ANSWER_DISPLACEMENT * context.size * a.scale
}

/// RMS displacement of the model's surface (fraction of the model size) under which two
/// poses are one answer (see [`same_pose`]): five inlier distances, about a 10° turn of
/// a compact object about its centre, well inside ICP's capture range.
const SAME_ANSWER_DISPLACEMENT: f64 = 0.05;

/// The margin of the mesh at `pose` over the outlier-only explanation of the points
/// `unexplained` ([`confidence::margin`]) at the inlier distance.
fn margin_of(context: &Context, unexplained: &Unexplained, pose: &Pose) -> f64 {
    let primitive = Primitive::new(context.shape.clone(), *pose);
    let inlier = context.options.inlier_distance * context.size * pose.scale;
    // Points the distance grid puts surely beyond the shell count neither way: left out
    // before the exact test (most of a cluttered cloud).
    let reach = confidence::SHELL_FACTOR * inlier / pose.scale;
    let maybe: Vec<usize> = (0..unexplained.points.len())
        .filter(|&i| {
            !context
                .grid
                .surely_beyond(&pose.to_local(&unexplained.points[i]), reach)
        })
        .collect();
    let points: Vec<Point3<f64>> = maybe.iter().map(|&i| unexplained.points[i]).collect();
    let sensors: Option<Vec<Point3<f64>>> = unexplained
        .sensors
        .as_ref()
        .map(|s| maybe.iter().map(|&i| s[i]).collect());
    confidence::margin(confidence::support(
        &points,
        sensors.as_deref(),
        &primitive,
        inlier,
    ))
}

/// `pose` polished by ICP from the first kernel down to the last (at `scale`), with
/// [`RegisterOptions::icp`](super::RegisterOptions::icp); as given otherwise.
fn settle(context: &Context, cloud: &PointCloud, mesh: &MeshShape, pose: Pose, scale: f64) -> Pose {
    let options = context.options;
    if !options.icp {
        return pose;
    }
    let size = context.size;
    let settle = icp::IcpOptions {
        start_distance: options.kernel_start * size * scale,
        min_distance: options.kernel_end * size * scale,
        shrink: 0.8,
        max_iterations: 15,
        tolerance: 1e-6 * size * scale,
        scale_range: options.scale,
    };
    let freedom = context.freedom();
    icp::refine(mesh, &context.grid, &cloud.points, pose, freedom, &settle).pose
}
/// `chosen` refined by trimmed ICP against the exact mesh surface, from the kernel
/// `kernel` down to the inlier distance (at the pose's `scale`); without
/// [`RegisterOptions::icp`], no steps: only its inliers and RMS.
fn refine_object(
    context: &Context,
    cloud: &PointCloud,
    mesh: &MeshShape,
    chosen: Pose,
    kernel: f64,
    scale: f64,
) -> icp::IcpResult {
    let options = context.options;
    let size = context.size;
    let largest_scale = options.scale.map_or(1.0, |s| s.1);
    let inlier_distance = options.inlier_distance * size;
    icp::refine(
        mesh,
        &context.grid,
        &cloud.points,
        chosen,
        if options.icp {
            context.freedom()
        } else {
            icp::Freedom {
                translation: false,
                scale: false,
            }
        },
        &icp::IcpOptions {
            start_distance: kernel,
            min_distance: inlier_distance * scale,
            shrink: 0.8,
            max_iterations: if options.icp { 60 } else { 0 },
            tolerance: 1e-6 * size * largest_scale,
            scale_range: options.scale,
        },
    )
}
