//! Point-pair-feature pose hypotheses (Drost, Ulrich, Navab & Ilic 2010, "Model
//! globally, match locally"): on a partial view the particle filter's search over
//! rotations can settle in a wrong basin whose surface also lies along the seen side;
//! here each seen surface patch votes directly for the poses that put a model patch on
//! it, and the poses with the most votes join the final choice (`choice.rs`).
//!
//! **Model.** The mesh is sampled every [`SAMPLE_STEP`] × its size, each sample with the
//! normal of a PCA plane over a fine sample within [`NORMAL_RADIUS`] × size, turned
//! outward (the faces' winding, checked by the signed volume). Every ordered pair of
//! samples (m₁, m₂) gets the feature `F = (‖d‖, ∠(n₁, d), ∠(n₂, d), ∠(n₁, n₂))`,
//! `d = m₂ − m₁`, quantised (distance in steps of [`SAMPLE_STEP`] × size, angles in
//! [`ANGLE_BINS`] bins over [0, π]), and is filed under it with `α_m`, the angle about
//! +x of `R_m (m₂ − m₁)`, where `R_m` turns `n₁` onto +x.
//!
//! **Scene.** Normals come from a trimmed PCA of each point's [`NORMAL_NEIGHBOURS`]
//! nearest, turned towards the point's sensor: the seen side of a surface faces its
//! sensor as the model's outward normals face out. A cloud without sensor origins is
//! tried with normals turned towards the origin of coordinates (a range scan in its
//! sensor's frame) and with them turned away (an object seen all round, the origin
//! inside it). Every [`REFERENCE_STRIDE`]-th point is a reference `s_r`; each point
//! within the model's size of it looks up the model pairs with its feature, and each
//! votes for (model sample m₁, θ = α_s − α_m). A right pose maps the model pair onto
//! the scene pair, so `R_s R R_m⁻¹` turns about +x by θ: the accumulator's peak is the
//! pose `R = R_s⁻¹ R_x(θ) R_m`, `t = s_r − R m₁`.
//!
//! **Hypotheses.** The references' poses, most votes first, are clustered (rotations
//! within [`CLUSTER_DEG`], translations within [`CLUSTER_SIZE`] × size); the clusters
//! with the most votes, each as its best-voted pose, are the hypotheses. Each reference
//! votes on its own, in parallel, so the result does not depend on the thread count.

use std::f64::consts::PI;

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::Pose;
use crate::atlas::MeshShape;
use crate::spatial::PointIndex;
use crate::surface::pca_plane;

/// Model sample spacing and distance quantisation step, fraction of the model size.
pub const SAMPLE_STEP: f64 = 0.04;
/// Radius of the model's normal estimate, fraction of the model size.
pub const NORMAL_RADIUS: f64 = 0.06;
/// Scene points per PCA normal.
pub const NORMAL_NEIGHBOURS: usize = 12;
/// Share of a scene neighbourhood kept (nearest its first plane) for the normal's refit.
const NORMAL_TRIM: f64 = 0.7;
/// Angle bins of the feature over [0, π] (12° each).
pub const ANGLE_BINS: u32 = 15;
/// Bins of the rotation θ about the normal over [−π, π) (12° each).
pub const THETA_BINS: usize = 30;
/// Every this-many-th scene point is a reference.
pub const REFERENCE_STRIDE: usize = 4;
/// Poses of one cluster: rotations within this many degrees...
pub const CLUSTER_DEG: f64 = 15.0;
/// ... and translations within this fraction of the model size.
pub const CLUSTER_SIZE: f64 = 0.1;
/// Fine samples per model sample for the model normals.
const FINE_PER_SAMPLE: f64 = 16.0;
/// Seed of the model's fine sampling (the model does not depend on the search's seed).
const MODEL_SEED: u64 = 0x5050_4621;

/// The model's feature table.
pub(super) struct PpfModel {
    /// Model samples (local frame).
    points: Vec<Point3<f64>>,
    /// `R_m` of each sample: turns its outward normal onto +x.
    frames: Vec<UnitQuaternion<f64>>,
    /// (sample m₁, α_m) of every model pair, sorted by feature key.
    table: Vec<(u32, f32)>,
    /// Where each feature key's pairs start in `table` (one past the last key: its
    /// length), so a lookup is two reads.
    starts: Vec<u32>,
    /// Distance quantisation step (model units).
    step: f64,
    /// Model size (diagonal of the bounding box).
    size: f64,
}

/// A scene point's oriented normal, or `None` where its neighbourhood is degenerate.
type Normal = Option<Vector3<f64>>;

impl PpfModel {
    /// The feature table of `mesh` (model size `size`, mesh units).
    pub(super) fn new(mesh: &MeshShape, size: f64) -> PpfModel {
        let step = SAMPLE_STEP * size;
        let (points, normals) = model_samples(mesh, step, NORMAL_RADIUS * size);
        let frames: Vec<_> = normals.iter().map(to_x_axis).collect();
        // Every ordered pair, the rows of m₁ in parallel; the votes count pairs, so the
        // order of equal keys in the table does not matter.
        let mut table: Vec<(u32, u32, f32)> = points
            .par_iter()
            .zip(&normals)
            .enumerate()
            .flat_map_iter(|(i, (p, n))| {
                let frame = frames[i];
                points
                    .iter()
                    .zip(&normals)
                    .enumerate()
                    .filter(move |(j, _)| *j != i)
                    .filter_map(move |(_, (q, m))| {
                        let key = feature_key(&(q - p), n, m, step, size)?;
                        Some((key, i as u32, angle_about_x(&(frame * (q - p))) as f32))
                    })
            })
            .collect();
        table.par_sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
        let keys = table.last().map_or(0, |e| e.0 as usize + 1);
        let mut starts = vec![0u32; keys + 1];
        for e in &table {
            starts[e.0 as usize + 1] += 1;
        }
        for k in 0..keys {
            starts[k + 1] += starts[k];
        }
        PpfModel {
            points,
            frames,
            table: table.into_iter().map(|(_, m, alpha)| (m, alpha)).collect(),
            starts,
            step,
            size,
        }
    }

    /// The model pairs filed under `key`: (m₁, α_m).
    fn pairs(&self, key: u32) -> &[(u32, f32)] {
        let k = key as usize;
        match (self.starts.get(k), self.starts.get(k + 1)) {
            (Some(&lo), Some(&hi)) => &self.table[lo as usize..hi as usize],
            _ => &[],
        }
    }

    /// At most `count` pose hypotheses for the object in `cloud` (module docs), best
    /// first; `index` is a kd-tree over exactly `cloud`.
    pub(super) fn hypotheses(
        &self,
        cloud: &[Point3<f64>],
        index: &PointIndex,
        sensors: Option<&[Point3<f64>]>,
        count: usize,
    ) -> Vec<Pose> {
        if cloud.len() < 3 || count == 0 || self.points.is_empty() {
            return Vec::new();
        }
        let normals = scene_normals(cloud, index);
        let orientations: Vec<Vec<Normal>> = match sensors {
            Some(s) => vec![oriented(cloud, &normals, |i| s[i], 1.0)],
            None => [1.0, -1.0]
                .iter()
                .map(|&sign| oriented(cloud, &normals, |_| Point3::origin(), sign))
                .collect(),
        };
        let mut votes: Vec<(u32, usize, Pose)> = orientations
            .iter()
            .flat_map(|normals| self.vote(cloud, index, normals))
            .collect();
        // Most votes first; ties: the earlier reference (then the first orientation).
        votes.sort_by_key(|v| std::cmp::Reverse(v.0));
        cluster(&votes, self.size, count)
    }

    /// Each reference's best pose and its votes: (votes, reference, pose).
    fn vote(
        &self,
        cloud: &[Point3<f64>],
        index: &PointIndex,
        normals: &[Normal],
    ) -> Vec<(u32, usize, Pose)> {
        let reach2 = self.size * self.size;
        let cells = self.points.len() * THETA_BINS;
        let references: Vec<usize> = (0..cloud.len())
            .step_by(REFERENCE_STRIDE)
            .filter(|&r| normals[r].is_some())
            .collect();
        references
            .par_iter()
            .map_init(
                || vec![0u32; cells],
                |acc, &r| {
                    acc.fill(0);
                    let (s_r, n_r) = (cloud[r], normals[r].expect("filtered"));
                    let frame = to_x_axis(&n_r);
                    for (i, _) in index.within(&s_r, reach2) {
                        let i = i as usize;
                        let Some(n_i) = normals[i].filter(|_| i != r) else {
                            continue;
                        };
                        let d = cloud[i] - s_r;
                        let Some(key) = feature_key(&d, &n_r, &n_i, self.step, self.size) else {
                            continue;
                        };
                        let alpha_s = angle_about_x(&(frame * d));
                        for &(m, alpha_m) in self.pairs(key) {
                            let bin = theta_bin(alpha_s - alpha_m as f64);
                            acc[m as usize * THETA_BINS + bin] += 1;
                        }
                    }
                    let (cell, &best) = acc
                        .iter()
                        .enumerate()
                        .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0)))
                        .expect("cells");
                    let (m, bin) = (cell / THETA_BINS, cell % THETA_BINS);
                    let theta = (bin as f64 + 0.5) * 2.0 * PI / THETA_BINS as f64 - PI;
                    let turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), theta);
                    let rotation = frame.inverse() * turn * self.frames[m];
                    let translation = s_r.coords - rotation * self.points[m].coords;
                    (best, r, Pose::new(rotation, translation))
                },
            )
            .collect()
    }
}

/// Greedy clustering of `votes` (most first): each pose joins the first cluster whose
/// leading pose is within [`CLUSTER_DEG`] and [`CLUSTER_SIZE`] × `size`; the leading
/// poses of the `count` clusters with the most votes (ties: the earlier cluster).
fn cluster(votes: &[(u32, usize, Pose)], size: f64, count: usize) -> Vec<Pose> {
    let mut clusters: Vec<(u64, Pose)> = Vec::new();
    for (v, _, pose) in votes {
        let near = clusters.iter_mut().find(|(_, c)| {
            c.rotation.angle_to(&pose.rotation) < CLUSTER_DEG.to_radians()
                && (c.translation - pose.translation).norm() < CLUSTER_SIZE * size
        });
        match near {
            Some(c) => c.0 += *v as u64,
            None => clusters.push((*v as u64, *pose)),
        }
    }
    let mut order: Vec<usize> = (0..clusters.len()).collect();
    order.sort_by(|&a, &b| clusters[b].0.cmp(&clusters[a].0).then(a.cmp(&b)));
    order.iter().take(count).map(|&k| clusters[k].1).collect()
}

/// The quantised feature of a pair at offset `d` with normals `n1`, `n2`, or `None`
/// when the pair is degenerate or farther apart than `size`.
fn feature_key(
    d: &Vector3<f64>,
    n1: &Vector3<f64>,
    n2: &Vector3<f64>,
    step: f64,
    size: f64,
) -> Option<u32> {
    let length = d.norm();
    if !(length > 0.0 && length <= size) {
        return None;
    }
    let u = d / length;
    let a = ANGLE_BINS;
    let distance = (length / step) as u32;
    Some(((distance * a + bin(n1.dot(&u))) * a + bin(n2.dot(&u))) * a + bin(n1.dot(n2)))
}

/// The bin of the angle whose cosine is `c` among [`ANGLE_BINS`] equal bins over
/// [0, π]: the number of bin edges `cos(kπ/ANGLE_BINS)` above `c` (no `acos`: this runs
/// for every scene pair).
fn bin(c: f64) -> u32 {
    // A count of all edges, not a binary search: no data-dependent branch.
    ANGLE_EDGES.iter().map(|&edge| (edge > c) as u32).sum()
}

/// `cos(kπ/ANGLE_BINS)` for k = 1 … ANGLE_BINS − 1, decreasing.
static ANGLE_EDGES: std::sync::LazyLock<Vec<f64>> = std::sync::LazyLock::new(|| {
    (1..ANGLE_BINS)
        .map(|k| (k as f64 * PI / ANGLE_BINS as f64).cos())
        .collect()
});

/// The bin of the angle `theta` (radians, in (−3π, 3π)) over [−π, π). Branch-free: the
/// wrap is an integer remainder (this runs for every scene pair × model pair, and a
/// data-dependent branch there mispredicts a quarter of the time).
#[inline]
fn theta_bin(theta: f64) -> usize {
    // theta + 3π > 0, so truncation is floor (no call to `floor`, which baseline
    // x86-64 does not inline); the extra turn drops out of the remainder.
    let k = ((theta + 3.0 * PI) * (THETA_BINS as f64 / (2.0 * PI))) as usize;
    k % THETA_BINS
}

/// The angle of `v` about +x, from +y towards +z.
fn angle_about_x(v: &Vector3<f64>) -> f64 {
    v.z.atan2(v.y)
}

/// A rotation turning the unit vector `n` onto +x.
fn to_x_axis(n: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(n, &Vector3::x()).unwrap_or_else(|| {
        // n = −x: half a turn about z.
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), PI)
    })
}

/// Samples of `mesh` about `step` apart (one per occupied voxel of a fine area-uniform
/// sample) with outward unit normals from a PCA plane within `radius`.
fn model_samples(
    mesh: &MeshShape,
    step: f64,
    radius: f64,
) -> (Vec<Point3<f64>>, Vec<Vector3<f64>>) {
    let tri = &*mesh.mesh;
    let faces: Vec<([Point3<f64>; 3], Vector3<f64>, f64)> = tri
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| tri.vertices[i as usize]);
            let cross = (b - a).cross(&(c - a));
            (
                [a, b, c],
                cross.try_normalize(0.0).unwrap_or_default(),
                0.5 * cross.norm(),
            )
        })
        .collect();
    // Outward: a consistently wound closed mesh has a positive signed volume.
    let volume: f64 = faces
        .iter()
        .map(|([a, b, c], _, _)| a.coords.dot(&b.coords.cross(&c.coords)))
        .sum();
    let outward = if volume < 0.0 { -1.0 } else { 1.0 };
    let area: f64 = faces.iter().map(|f| f.2).sum();
    let fine = ((FINE_PER_SAMPLE * area / (step * step)).ceil() as usize).max(3);
    let mut cumulative = Vec::with_capacity(faces.len());
    let mut total = 0.0;
    for f in &faces {
        total += f.2;
        cumulative.push(total);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(MODEL_SEED);
    let (mut fine_points, mut fine_normals) = (Vec::with_capacity(fine), Vec::new());
    for _ in 0..fine {
        let at = rng.random::<f64>() * total;
        let k = cumulative.partition_point(|&c| c < at).min(faces.len() - 1);
        let ([a, b, c], n, _) = faces[k];
        let (mut u, mut v) = (rng.random::<f64>(), rng.random::<f64>());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        fine_points.push(a + (b - a) * u + (c - a) * v);
        fine_normals.push(n * outward);
    }
    let index = PointIndex::new(&fine_points);
    let mut seen = std::collections::HashSet::new();
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    for (p, face_normal) in fine_points.iter().zip(&fine_normals) {
        let voxel = (p.coords / step).map(|c| c.floor() as i64);
        if !seen.insert((voxel.x, voxel.y, voxel.z)) {
            continue;
        }
        let near: Vec<Point3<f64>> = index
            .within(p, radius * radius)
            .iter()
            .map(|&(i, _)| fine_points[i as usize])
            .collect();
        let Some((n, _, _)) = pca_plane(&near) else {
            continue;
        };
        let facing: Vector3<f64> = index
            .within(p, radius * radius)
            .iter()
            .map(|&(i, _)| fine_normals[i as usize])
            .sum::<Vector3<f64>>()
            + face_normal;
        points.push(*p);
        normals.push(if n.dot(&facing) < 0.0 { -n } else { n });
    }
    (points, normals)
}

/// Unit normals of `cloud` (sign arbitrary) from a PCA plane of each point's
/// [`NORMAL_NEIGHBOURS`] nearest, refitted on the [`NORMAL_TRIM`] share nearest the
/// first plane (clutter among a surface's neighbours tilts a plain fit).
fn scene_normals(cloud: &[Point3<f64>], index: &PointIndex) -> Vec<Normal> {
    cloud
        .par_iter()
        .map(|p| {
            let near: Vec<Point3<f64>> = index
                .nearest_n(p, NORMAL_NEIGHBOURS)
                .iter()
                .map(|&(i, _)| cloud[i as usize])
                .collect();
            let (n, _, _) = pca_plane(&near)?;
            let mean = near.iter().map(|q| q.coords).sum::<Vector3<f64>>() / near.len() as f64;
            let mut by_offset: Vec<(f64, Point3<f64>)> = near
                .iter()
                .map(|q| ((q.coords - mean).dot(&n).abs(), *q))
                .collect();
            by_offset.sort_by(|a, b| a.0.total_cmp(&b.0));
            let keep = ((NORMAL_TRIM * near.len() as f64).ceil() as usize).max(3);
            let trimmed: Vec<Point3<f64>> = by_offset.iter().take(keep).map(|e| e.1).collect();
            pca_plane(&trimmed).map(|(n, _, _)| n)
        })
        .collect()
}

/// `normals` turned towards each point's `sensor` (`sign` = −1: away from it).
fn oriented(
    cloud: &[Point3<f64>],
    normals: &[Normal],
    sensor: impl Fn(usize) -> Point3<f64>,
    sign: f64,
) -> Vec<Normal> {
    normals
        .iter()
        .enumerate()
        .map(|(i, n)| {
            n.map(|n| {
                let facing = (sensor(i) - cloud[i]).dot(&n) * sign;
                if facing < 0.0 { -n } else { n }
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::asymmetric_object;

    #[test]
    fn the_model_seen_whole_votes_for_its_own_pose() {
        // The model's own samples, moved by a known pose, as the scene: the top
        // hypothesis is that pose (within the quantisation).
        let mesh = asymmetric_object();
        let (lo, hi) = crate::cloud::bounds_of(&mesh.mesh.vertices).expect("vertices");
        let size = (hi - lo).norm();
        let model = PpfModel::new(&mesh, size);
        let truth = Pose::new(
            UnitQuaternion::from_euler_angles(0.4, -1.1, 2.0),
            Vector3::new(0.3, -0.2, 0.1),
        );
        let cloud: Vec<Point3<f64>> = model.points.iter().map(|p| truth.to_scene(p)).collect();
        let found = model.hypotheses(&cloud, &PointIndex::new(&cloud), None, 3);
        let best = found[0];
        assert!(
            best.rotation.angle_to(&truth.rotation).to_degrees() < 10.0,
            "{best:?}"
        );
        assert!((best.translation - truth.translation).norm() < 0.05 * size);
    }

    #[test]
    fn theta_bins_wrap_and_features_reject_far_pairs() {
        assert_eq!(theta_bin(PI), theta_bin(-PI));
        assert_eq!(theta_bin(3.0 * PI - 1e-9), THETA_BINS - 1);
        // The bins of the cosine agree with those of the angle.
        for k in 0..=1000 {
            let angle = k as f64 / 1000.0 * PI;
            let by_angle = ((angle / PI * ANGLE_BINS as f64) as u32).min(ANGLE_BINS - 1);
            let edge = (angle / PI * ANGLE_BINS as f64 - by_angle as f64).abs() < 1e-9;
            assert!(edge || bin(angle.cos()) == by_angle, "{angle}");
        }
        let n = Vector3::z();
        assert!(feature_key(&Vector3::new(2.0, 0.0, 0.0), &n, &n, 0.1, 1.0).is_none());
        assert!(feature_key(&Vector3::zeros(), &n, &n, 0.1, 1.0).is_none());
        assert!(feature_key(&Vector3::new(0.5, 0.0, 0.0), &n, &n, 0.1, 1.0).is_some());
    }
}
