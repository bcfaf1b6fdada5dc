//! From segments of the samples to segments of every input point.
//!
//! 1. **Fragments.** A sample left out of every segment (its region was smaller than
//!    the smallest segment) joins the segment of one of its growing neighbours whose
//!    model lies within `t σ` of it (the nearest such model). Each pass reads the labels
//!    as they were before it, so the result does not depend on the visiting order;
//!    passes repeat while samples join.
//! 2. **Points.** Every other input point takes the segment of its nearest sample if it
//!    lies within `t σ` of that segment's model (clutter: unconditionally); otherwise the
//!    segment of one of its few nearest samples whose model it lies within `t σ` of (at
//!    a junction the nearest sample may be the other surface's); otherwise it is
//!    unassigned.
//! 3. **Final models.** Each segment's model is refitted on all its points (planes by
//!    moments, cylinders by LM from the sample fit, spheres afresh) and its RMS taken over
//!    all of them.

use nalgebra::Point3;
use rayon::prelude::*;

use super::cylinder::{CylinderFit, refit_cylinder};
use super::merge::Part;
use super::normals::Neighbourhoods;
use super::plane::Moments;
use super::sphere::fit_sphere;
use super::{Detection, Segment, SurfaceModel};
use crate::spatial::PointIndex;

/// Marks a point that is not a sample / a sample in no segment.
const NONE: u32 = u32::MAX;

/// Samples around a point that its nearest sample's segment does not explain, among
/// which a segment that does is looked for ([`fitting_neighbour`]).
const CREASE_SAMPLES: usize = 8;

/// Most passes of fragment absorption: each reaches one neighbour further, so a segment
/// reaches at most this many growing steps into fragments.
const MAX_ABSORB_PASSES: usize = 32;

/// The samples of a detection: their points, where they come from, their index and
/// neighbourhoods.
#[derive(Debug, Clone, Copy)]
pub struct Samples<'a> {
    /// The sample points: `points[s] = input[ids[s]]`.
    pub points: &'a [Point3<f64>],
    /// The input index of each sample.
    pub ids: &'a [usize],
    /// An index over `points`.
    pub index: &'a PointIndex,
    /// Their neighbourhoods.
    pub nb: &'a Neighbourhoods,
}

/// A segment's points with its refitted model and RMS (`None`: clutter).
type Finished = (Vec<usize>, Option<(SurfaceModel, f64)>);

/// Builds the [`Detection`] (without its scalar fields) from the merged `parts` of the
/// `samples` of the input `points`; fragments look at their first `grow_neighbours`
/// neighbours.
pub fn expand(
    points: &[Point3<f64>],
    samples: &Samples,
    mut parts: Vec<Part>,
    grow_neighbours: usize,
    tolerance: f64,
) -> Detection {
    let mut label = vec![NONE; samples.points.len()];
    for (k, part) in parts.iter().enumerate() {
        for &s in &part.ids {
            label[s] = k as u32;
        }
    }
    absorb_fragments(
        samples.points,
        samples.nb,
        &mut parts,
        &mut label,
        grow_neighbours,
        tolerance,
    );
    let point_label = point_labels(points, samples, &parts, &label, tolerance);
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); parts.len()];
    let mut unassigned = Vec::new();
    for (i, &l) in point_label.iter().enumerate() {
        match l {
            NONE => unassigned.push(i),
            l => members[l as usize].push(i),
        }
    }
    let finished: Vec<Finished> = members
        .into_par_iter()
        .zip(parts.par_iter())
        .map(|(ids, part)| {
            let model = part.model.map(|m| refit(points, &ids, &m));
            (ids, model)
        })
        .collect();
    let mut segments = Vec::new();
    let mut clutter = Vec::new();
    for (ids, model) in finished {
        match model {
            Some((model, rms)) => segments.push(Segment {
                points: ids,
                model,
                rms,
            }),
            None if !ids.is_empty() => clutter.push(ids),
            None => {}
        }
    }
    segments.sort_by(|a, b| {
        b.points
            .len()
            .cmp(&a.points.len())
            .then(a.points.first().cmp(&b.points.first()))
    });
    clutter.sort_by(|a, b| b.len().cmp(&a.len()).then(a.first().cmp(&b.first())));
    Detection {
        segments,
        clutter,
        unassigned,
        noise: 0.0,
        model_noise: 0.0,
        spacing: 0.0,
        angle: 0.0,
        voxel: None,
        samples: 0,
    }
}

/// Step 2 of the module docs: the part of every input point (`NONE`: unassigned), from
/// the sample `label`s.
fn point_labels(
    points: &[Point3<f64>],
    samples: &Samples,
    parts: &[Part],
    label: &[u32],
    tolerance: f64,
) -> Vec<u32> {
    let mut sample_of = vec![NONE; points.len()];
    for (s, &i) in samples.ids.iter().enumerate() {
        sample_of[i] = s as u32;
    }
    (0..points.len())
        .into_par_iter()
        .map(|i| {
            if sample_of[i] != NONE {
                return label[sample_of[i] as usize];
            }
            let Some((s, _)) = samples.index.nearest(&points[i]) else {
                return NONE;
            };
            let l = label[s as usize];
            if l == NONE {
                return NONE;
            }
            let part = &parts[l as usize];
            match part.model {
                Some(m) if m.distance(&points[i]) > tolerance * part.sigma => {
                    fitting_neighbour(&points[i], samples, parts, label, tolerance)
                }
                _ => l,
            }
        })
        .collect()
}

/// The segment of one of the [`CREASE_SAMPLES`] samples nearest `p` whose model lies
/// within `t σ` of it (the nearest in σ; ties to the lower label), or [`NONE`]: near a
/// crease or a junction the nearest sample may belong to the other surface, and the
/// point would be left out of its own, opening a gap a voxel wide along every junction.
fn fitting_neighbour(
    p: &Point3<f64>,
    samples: &Samples,
    parts: &[Part],
    label: &[u32],
    tolerance: f64,
) -> u32 {
    let mut best: Option<(f64, u32)> = None;
    for (s, _) in samples.index.nearest_n(p, CREASE_SAMPLES) {
        let l = label[s as usize];
        let Some(part) = parts.get(l as usize) else {
            continue;
        };
        let Some(m) = part.model else {
            continue;
        };
        let r = m.distance(p) / part.sigma.max(f64::MIN_POSITIVE);
        if r <= tolerance && best.is_none_or(|(b, bl)| r < b || (r == b && l < bl)) {
            best = Some((r, l));
        }
    }
    best.map_or(NONE, |(_, l)| l)
}

/// Step 1 of the module docs: fragments join a neighbouring segment whose model fits,
/// pass after pass (each from the labels the previous one left), so a segment reaches
/// along a chain of fragments, for at most [`MAX_ABSORB_PASSES`] passes.
fn absorb_fragments(
    samples: &[Point3<f64>],
    nb: &Neighbourhoods,
    parts: &mut [Part],
    label: &mut [u32],
    grow_neighbours: usize,
    tolerance: f64,
) {
    let take = grow_neighbours.min(nb.k.saturating_sub(1));
    let mut open: Vec<usize> = (0..samples.len()).filter(|&s| label[s] == NONE).collect();
    for _ in 0..MAX_ABSORB_PASSES {
        let joins: Vec<(usize, u32)> = open
            .par_iter()
            .filter_map(|&s| {
                let mut best: Option<(f64, u32)> = None;
                for &j in &nb.row(s)[1..=take] {
                    let l = label[j as usize];
                    if l == NONE {
                        continue;
                    }
                    let part = &parts[l as usize];
                    let Some(model) = part.model else { continue };
                    let d = model.distance(&samples[s]);
                    let better = best.is_none_or(|(bd, bl)| d < bd || (d == bd && l < bl));
                    if d <= tolerance * part.sigma && better {
                        best = Some((d, l));
                    }
                }
                best.map(|(_, l)| (s, l))
            })
            .collect();
        if joins.is_empty() {
            break;
        }
        for (s, l) in joins {
            label[s] = l;
            let part = &mut parts[l as usize];
            part.ids.push(s);
            part.moments.add(&samples[s]);
        }
        open.retain(|&s| label[s] == NONE);
    }
    for part in parts.iter_mut() {
        part.ids.sort_unstable();
    }
}

/// The model of `m`'s type refitted on `points[ids]`, with the RMS over them.
fn refit(points: &[Point3<f64>], ids: &[usize], m: &SurfaceModel) -> (SurfaceModel, f64) {
    let pts: Vec<Point3<f64>> = ids.iter().map(|&i| points[i]).collect();
    let model = match *m {
        SurfaceModel::Plane { .. } => {
            Moments::of(points, ids)
                .plane()
                .map(|f| SurfaceModel::Plane {
                    point: f.point,
                    normal: f.normal,
                })
        }
        SurfaceModel::Cylinder {
            point,
            axis,
            radius,
            length,
        } => {
            let start = CylinderFit {
                point,
                axis,
                radius,
                length,
                rms: 0.0,
            };
            refit_cylinder(&pts, &start).map(|c| SurfaceModel::Cylinder {
                point: c.point,
                axis: c.axis,
                radius: c.radius,
                length: c.length,
            })
        }
        SurfaceModel::Sphere { .. } => fit_sphere(&pts).map(|s| SurfaceModel::Sphere {
            centre: s.centre,
            radius: s.radius,
        }),
    }
    .unwrap_or(*m);
    let ss: f64 = pts.iter().map(|p| model.distance(p).powi(2)).sum();
    (model, (ss / pts.len().max(1) as f64).sqrt())
}
