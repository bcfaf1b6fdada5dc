//! Rays from a cloud, the per-frame [`RayTree`] (thesis §4.2.2) and the ray ↔ candidate
//! [`RayTable`] with the full scene evaluation of Algorithm 2.
//!
//! A **frame** is the set of points that share one sensor origin, numbered in order of
//! first appearance in the cloud (the cloud's order is taken as time order). A RayTree
//! indexes a frame's rays by (azimuth, elevation) in a 2-D KD-tree whose azimuth seam
//! (±π) points **behind** the sensor, i.e. opposite the frame's mean viewing direction.
//! A candidate's angular bounds are the cone subtended by its bounding ball; a ball
//! search in angle space returns a superset of the rays in that cone (widened in azimuth
//! by `1/cos(elevation)`, and repeated across the seam when the cone reaches it, so even a
//! 360° scan is answered exactly), and an exact cone test and the ray's first crossing
//! ([`crate::Primitive::first_hit`]) finish the job.

use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::likelihood::{RayModel, crossing_terms, ray_log_likelihood_from_sums};
use crate::error::{Remedy, Unit};
use crate::spatial::PlaneIndex;
use crate::{Error, PointCloud, Primitive, Result, check};

/// Crossings more than this many along-ray deviations *beyond* the point are left out of
/// the table: their effect on `log p` is below 10⁻³⁰ (ln g ≥ −Q(12), h ≤ φ(12)/s).
pub const FAR_SIGMAS: f64 = 12.0;

/// A crossing within this many along-ray deviations of its point is positive evidence:
/// the candidate was **seen** in that point's frame (for the flip rates of the sampler).
pub const SEEN_SIGMAS: f64 = 3.0;

/// Every usable point of a cloud as a ray from its sensor origin.
#[derive(Debug, Clone, Default)]
pub struct Rays {
    /// Sensor origin of each frame, in order of first appearance.
    pub frames: Vec<Point3<f64>>,
    /// Frame of each ray.
    pub frame: Vec<u32>,
    /// Unit direction of each ray (scene frame).
    pub dirs: Vec<Vector3<f64>>,
    /// Range `z` of each ray's point from its sensor (scene units, > 0).
    pub ranges: Vec<f64>,
    /// Index in the cloud of each ray's point.
    pub point: Vec<u32>,
    /// Points left out: zero range (the point is its own sensor origin).
    pub skipped: usize,
}

impl Rays {
    /// Rays of `cloud`, which must have `sensors`. Points at their own sensor origin are
    /// skipped (counted in [`Rays::skipped`]); non-finite coordinates are an error.
    pub fn from_cloud(cloud: &PointCloud) -> Result<Rays> {
        let sensors = cloud.sensors.as_ref().ok_or_else(|| Error::Missing {
            what: "each point's sensor origin (PLY vertex properties sensor_x, sensor_y, \
                   sensor_z)"
                .into(),
            needed_by: "the ray likelihood",
        })?;
        check::same_len("sensor origins", sensors.len(), "points", cloud.len())?;
        if cloud.len() > u32::MAX as usize {
            return Err(Error::OverLimit {
                what: "the ray set".into(),
                need: cloud.len() as f64,
                limit: u32::MAX as f64,
                unit: Unit::Count("points"),
                remedies: vec![Remedy::Subsample],
            });
        }
        let mut rays = Rays::default();
        let mut frame_of: HashMap<[u64; 3], u32> = HashMap::new();
        for (j, (p, o)) in cloud.points.iter().zip(sensors).enumerate() {
            let v = p - o;
            if !v.iter().chain(o.coords.iter()).all(|c| c.is_finite()) {
                return Err(Error::NonFinite {
                    what: "sensor ray of point".into(),
                    index: j,
                });
            }
            let z = v.norm();
            if z == 0.0 || !z.is_finite() {
                rays.skipped += 1;
                continue;
            }
            let key = [o.x.to_bits(), o.y.to_bits(), o.z.to_bits()];
            let next = rays.frames.len() as u32;
            let f = *frame_of.entry(key).or_insert(next);
            if f == next {
                rays.frames.push(*o);
            }
            rays.frame.push(f);
            rays.dirs.push(v / z);
            rays.ranges.push(z);
            rays.point.push(j as u32);
        }
        Ok(rays)
    }

    /// Number of rays.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// True when there are no rays.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// Sensor origin of ray `j`.
    #[inline]
    pub fn origin(&self, j: usize) -> &Point3<f64> {
        &self.frames[self.frame[j] as usize]
    }

    /// The rays of each frame (ray ids, ascending).
    pub fn by_frame(&self) -> Vec<Vec<u32>> {
        let mut out = vec![Vec::new(); self.frames.len()];
        for (j, f) in self.frame.iter().enumerate() {
            out[*f as usize].push(j as u32);
        }
        out
    }
}

/// One frame's rays in a KD-tree on (azimuth, elevation) angles (radians), the seam behind
/// the sensor (thesis §4.2.2).
#[derive(Debug)]
pub struct RayTree {
    origin: Point3<f64>,
    forward: Vector3<f64>,
    left: Vector3<f64>,
    up: Vector3<f64>,
    index: PlaneIndex,
    /// Global ray id of each tree item.
    ids: Vec<u32>,
    /// Unit direction of each tree item.
    dirs: Vec<Vector3<f64>>,
}

impl RayTree {
    /// MAKERAYTREE: indexes the rays `ids` of `rays`, all from sensor `origin`. The forward
    /// axis is their mean direction (the x axis if they cancel out); `up` is the scene z
    /// axis made orthogonal to it (or y when forward is vertical).
    pub fn new(origin: Point3<f64>, rays: &Rays, ids: Vec<u32>) -> RayTree {
        let dirs: Vec<Vector3<f64>> = ids.iter().map(|&j| rays.dirs[j as usize]).collect();
        let sum: Vector3<f64> = dirs.iter().sum();
        let forward = sum
            .try_normalize(1e-9 * dirs.len().max(1) as f64)
            .unwrap_or_else(Vector3::x);
        let up = [Vector3::z(), Vector3::y(), Vector3::x()]
            .iter()
            .find_map(|a| (a - forward * a.dot(&forward)).try_normalize(1e-3))
            .unwrap_or_else(Vector3::z);
        let left = up.cross(&forward);
        let mut tree = RayTree {
            origin,
            forward,
            left,
            up,
            index: PlaneIndex::new(&[]),
            ids,
            dirs,
        };
        let angles: Vec<[f64; 2]> = tree.dirs.iter().map(|d| tree.angles(d)).collect();
        tree.index = PlaneIndex::new(&angles);
        tree
    }

    /// The sensor origin.
    pub fn origin(&self) -> &Point3<f64> {
        &self.origin
    }

    /// Number of rays.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// True when the frame has no rays.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// `[azimuth, elevation]` (radians) of a unit direction: azimuth in `[−π, π]` about
    /// `up`, 0 straight ahead, ±π straight behind; elevation in `[−π/2, π/2]`.
    pub fn angles(&self, d: &Vector3<f64>) -> [f64; 2] {
        let az = d.dot(&self.left).atan2(d.dot(&self.forward));
        let el = d.dot(&self.up).clamp(-1.0, 1.0).asin();
        [az, el]
    }

    /// Global ids (ascending) of the rays within `half_angle` (radians) of the unit
    /// direction `axis`: a ball search in angle space, then an exact cone test.
    pub fn cone(&self, axis: &Vector3<f64>, half_angle: f64) -> Vec<u32> {
        if half_angle.is_nan() || self.is_empty() {
            return Vec::new();
        }
        if half_angle >= PI {
            let mut all = self.ids.clone();
            all.sort_unstable();
            return all;
        }
        let [az, el] = self.angles(axis);
        let dphi = azimuth_reach(el, half_angle);
        let radius = (half_angle * half_angle + dphi * dphi).sqrt() * (1.0 + 1e-9) + 1e-12;
        let mut centres = vec![az];
        if az - dphi < -PI {
            centres.push(az + TAU);
        }
        if az + dphi > PI {
            centres.push(az - TAU);
        }
        let min_cos = half_angle.cos() - 1e-12;
        let mut out: Vec<u32> = centres
            .iter()
            .flat_map(|c| self.index.within([*c, el], radius * radius))
            .filter(|&k| self.dirs[k as usize].dot(axis) >= min_cos)
            .map(|k| self.ids[k as usize])
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// COMPUTEPOLARBOUNDS + BALLSEARCH: ids (ascending) of the rays that may cross `prim`,
    /// i.e. those meeting its bounding ball (every ray when the sensor is inside it).
    pub fn candidate_rays(&self, prim: &Primitive) -> Vec<u32> {
        let to_centre = prim.center() - self.origin;
        let distance = to_centre.norm();
        let radius = prim.bounding_radius();
        if distance <= radius * (1.0 + 1e-9) {
            return self.cone(&self.forward, PI);
        }
        let half_angle = (radius / distance).asin() * (1.0 + 1e-9) + 1e-12;
        self.cone(&(to_centre / distance), half_angle)
    }
}

/// The largest azimuth difference (radians) between a direction at elevation `el` and any
/// direction within `half_angle` of it: from the haversine formula,
/// `sin(Δφ/2) ≤ sin(α/2) / min cos(elevation over the band)`; π when the band reaches a pole.
fn azimuth_reach(el: f64, half_angle: f64) -> f64 {
    let top = el.abs() + half_angle;
    if top >= FRAC_PI_2 {
        return PI;
    }
    let ratio = (half_angle / 2.0).sin() / top.cos();
    if ratio >= 1.0 { PI } else { 2.0 * ratio.asin() }
}

/// One (ray, candidate) crossing's precomputed terms of eq. 4.10.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry {
    /// The candidate (in the ray's list) or the ray (in the candidate's list).
    pub id: u32,
    /// `ln g(z; μ, s)` (nats, ≤ 0).
    pub log_g: f64,
    /// `h = N(z; μ, s) / g(z; μ, s)` (1/scene unit, ≥ 0).
    pub h: f64,
}

/// The RayMap of Algorithm 2 for **all** candidates, built once: for every ray the
/// candidates that cross it (with their eq. 4.10 terms), and for every candidate the rays
/// it crosses. A scene Φ ⊆ candidates is then evaluated by [`RayTable::log_likelihood`]
/// without any geometry.
#[derive(Debug, Clone)]
pub struct RayTable {
    model: RayModel,
    ranges: Vec<f64>,
    frame_of_ray: Vec<u32>,
    frames: usize,
    ray_start: Vec<usize>,
    ray_entries: Vec<Entry>,
    cand_start: Vec<usize>,
    cand_rays: Vec<u32>,
    last_seen: Vec<Option<u32>>,
}

/// A candidate's crossings: `(ray, ln g, h)` ascending by ray, and the last frame seen.
type CandidateCrossings = (Vec<(u32, f64, f64)>, Option<u32>);

impl RayTable {
    /// Builds the trees (one per frame), runs the ball search for every candidate and
    /// computes each crossing's terms (in parallel over candidates; the result does not
    /// depend on the thread count).
    pub fn build(rays: &Rays, candidates: &[Primitive], model: RayModel) -> Result<RayTable> {
        model.validate()?;
        if candidates.len() >= u32::MAX as usize {
            return Err(Error::OverLimit {
                what: "the candidate set".into(),
                need: candidates.len() as f64,
                limit: (u32::MAX - 1) as f64,
                unit: Unit::Count("candidates"),
                remedies: Vec::new(),
            });
        }
        for (i, c) in candidates.iter().enumerate() {
            c.shape.validate().map_err(|e| e.in_item("candidate", i))?;
        }
        let trees: Vec<RayTree> = rays
            .by_frame()
            .into_iter()
            .enumerate()
            .map(|(f, ids)| RayTree::new(rays.frames[f], rays, ids))
            .collect();
        let per_candidate: Vec<CandidateCrossings> = candidates
            .par_iter()
            .map(|c| candidate_crossings(c, &trees, rays, &model))
            .collect();
        Ok(Self::assemble(rays, model, per_candidate))
    }

    /// Lays the per-candidate crossings out as the two CSR tables.
    fn assemble(rays: &Rays, model: RayModel, per_candidate: Vec<CandidateCrossings>) -> RayTable {
        let n_rays = rays.len();
        let mut count = vec![0usize; n_rays + 1];
        let mut cand_start = Vec::with_capacity(per_candidate.len() + 1);
        let mut cand_rays = Vec::new();
        cand_start.push(0);
        for (list, _) in &per_candidate {
            for (j, _, _) in list {
                count[*j as usize + 1] += 1;
                cand_rays.push(*j);
            }
            cand_start.push(cand_rays.len());
        }
        for j in 0..n_rays {
            count[j + 1] += count[j];
        }
        let ray_start = count.clone();
        let blank = Entry {
            id: 0,
            log_g: 0.0,
            h: 0.0,
        };
        let mut ray_entries = vec![blank; cand_rays.len()];
        let mut fill = count;
        for (i, (list, _)) in per_candidate.iter().enumerate() {
            for &(j, log_g, h) in list {
                let slot = &mut fill[j as usize];
                ray_entries[*slot] = Entry {
                    id: i as u32,
                    log_g,
                    h,
                };
                *slot += 1;
            }
        }
        RayTable {
            model,
            ranges: rays.ranges.clone(),
            frame_of_ray: rays.frame.clone(),
            frames: rays.frames.len(),
            ray_start,
            ray_entries,
            cand_start,
            cand_rays,
            last_seen: per_candidate.into_iter().map(|(_, s)| s).collect(),
        }
    }

    /// The measurement model.
    pub fn model(&self) -> &RayModel {
        &self.model
    }

    /// Number of rays.
    pub fn rays(&self) -> usize {
        self.ranges.len()
    }

    /// Number of candidates N.
    pub fn candidates(&self) -> usize {
        self.cand_start.len() - 1
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Number of (ray, candidate) crossings stored.
    pub fn entries(&self) -> usize {
        self.ray_entries.len()
    }

    /// Bytes held by the tables.
    pub fn bytes(&self) -> usize {
        self.ray_entries.len() * std::mem::size_of::<Entry>()
            + self.cand_rays.len() * 4
            + (self.ray_start.len() + self.cand_start.len()) * std::mem::size_of::<usize>()
            + self.ranges.len() * 12
    }

    /// The candidates crossing ray `j` (ascending), with their terms.
    pub fn ray_crossings(&self, j: usize) -> &[Entry] {
        &self.ray_entries[self.ray_start[j]..self.ray_start[j + 1]]
    }

    /// The rays candidate `i` crosses (ascending).
    pub fn candidate_rays(&self, i: usize) -> &[u32] {
        &self.cand_rays[self.cand_start[i]..self.cand_start[i + 1]]
    }

    /// The last frame in which candidate `i` had a point within [`SEEN_SIGMAS`] of its
    /// crossing, if any.
    pub fn last_seen(&self, i: usize) -> Option<u32> {
        self.last_seen[i]
    }

    /// Frame of ray `j`.
    pub fn frame_of_ray(&self, j: usize) -> u32 {
        self.frame_of_ray[j]
    }

    /// COMPUTELOGLIKELIHOOD of ray `j` under the existence vector `exists` (length N,
    /// not checked): eq. 4.10 in log space (nats).
    #[inline]
    pub(crate) fn ray_log_likelihood(&self, j: usize, exists: &[bool]) -> f64 {
        let (mut sum_log_g, mut sum_h) = (0.0, 0.0);
        for e in self.ray_crossings(j) {
            if exists[e.id as usize] {
                sum_log_g += e.log_g;
                sum_h += e.h;
            }
        }
        ray_log_likelihood_from_sums(&self.model, self.ranges[j], sum_log_g, sum_h)
    }

    /// Algorithm 2: `log p(D | Φ)` (nats) = Σ over rays of eq. 4.10, for the scene whose
    /// existing candidates are `exists[i] == true`.
    pub fn log_likelihood(&self, exists: &[bool]) -> Result<f64> {
        self.check(exists)?;
        Ok((0..self.rays())
            .map(|j| self.ray_log_likelihood(j, exists))
            .sum())
    }

    /// The per-ray log-likelihoods of a scene (nats).
    pub fn ray_log_likelihoods(&self, exists: &[bool]) -> Result<Vec<f64>> {
        self.check(exists)?;
        Ok((0..self.rays())
            .map(|j| self.ray_log_likelihood(j, exists))
            .collect())
    }

    fn check(&self, exists: &[bool]) -> Result<()> {
        check::same_len(
            "existence values",
            exists.len(),
            "candidates",
            self.candidates(),
        )
    }
}

/// One candidate's crossings over every frame.
fn candidate_crossings(
    prim: &Primitive,
    trees: &[RayTree],
    rays: &Rays,
    model: &RayModel,
) -> CandidateCrossings {
    let mut out = Vec::new();
    let mut seen = None;
    for (f, tree) in trees.iter().enumerate() {
        for j in tree.candidate_rays(prim) {
            let (dir, z) = (&rays.dirs[j as usize], rays.ranges[j as usize]);
            let Some(hit) = prim.first_hit(tree.origin(), dir) else {
                continue;
            };
            let s = model.projected_sigma(hit.incidence(dir));
            if (hit.depth - z) / s > FAR_SIGMAS {
                continue;
            }
            if ((hit.depth - z) / s).abs() <= SEEN_SIGMAS {
                seen = Some(f as u32);
            }
            let (log_g, h) = crossing_terms(z, hit.depth, s);
            out.push((j, log_g, h));
        }
    }
    out.sort_unstable_by_key(|e| e.0);
    (out, seen)
}

/// Algorithm 1 (the naïve reference): for every ray, test every existing candidate for a
/// crossing and sum eq. 4.10 (nats). No ray tree, no far-crossing cut-off: for tests.
pub fn naive_log_likelihood(
    rays: &Rays,
    candidates: &[Primitive],
    exists: &[bool],
    model: &RayModel,
) -> Result<f64> {
    model.validate()?;
    check::same_len(
        "existence values",
        exists.len(),
        "candidates",
        candidates.len(),
    )?;
    let mut total = 0.0;
    for j in 0..rays.len() {
        let (o, d, z) = (rays.origin(j), &rays.dirs[j], rays.ranges[j]);
        let crossings: Vec<(f64, f64)> = candidates
            .iter()
            .zip(exists)
            .filter(|(_, e)| **e)
            .filter_map(|(c, _)| c.first_hit(o, d))
            .map(|hit| (hit.depth, model.projected_sigma(hit.incidence(d))))
            .collect();
        total += super::likelihood::ray_log_likelihood(model, z, &crossings);
    }
    Ok(total)
}
