//! [`TubeLattice`]: the nearest of a partial tube's samples in constant time.
//!
//! A cylinder is sampled in rings (`n_z` rings of `n_θ` samples at equal angles, the same
//! angles in every ring), and a tube seen from one side keeps the samples of some
//! angular sectors, the same in every ring. In the tube's frame the squared distance from
//! `p = (r cos φ, r sin φ, z)` to sample `(R cos θ_j, R sin θ_j, z_k)` is
//! `r² + R² − 2rR cos(φ − θ_j) + (z − z_k)²`: the nearest sample is on the kept angle
//! nearest to `φ` (either side) and the ring nearest to `z`. The query measures those
//! few samples (with one more on each side against rounding) in scene coordinates, the
//! same `dx² + dy² + dz²` a kd-tree would; a point on the axis, where every angle is
//! equally near, gets the least of the measured ones, equal to the true least up to
//! rounding.

use std::f64::consts::TAU;

use nalgebra::Point3;

use crate::Pose;
use crate::spatial::{as_array, squared_distance};

/// How far (radians, or ring steps × rings) the samples may stray from equal angles and
/// equal ring steps and still be taken as a lattice: rounding only. The query's one extra
/// angle and ring on each side absorb far more.
const LAYOUT_TOLERANCE: f64 = 1e-9;

/// A tube's kept samples as a lattice of rings and kept angles (module docs).
#[derive(Debug, Clone)]
pub(super) struct TubeLattice {
    /// The tube's pose (its samples are `pose.to_scene` of the local ones).
    pose: Pose,
    /// Angle of local sample 0 (radians); sample `j` of a ring is at `theta0 + 2π j / n_θ`.
    theta0: f64,
    /// Samples per ring before sectors are dropped.
    n_theta: usize,
    /// Local height of ring 0 and the (positive) step between rings (tube units).
    z0: f64,
    dz: f64,
    /// Rings.
    n_z: usize,
    /// Per angle index, the kept angle index at or below it / at or above it (circular).
    down: Vec<u32>,
    up: Vec<u32>,
    /// Per kept angle index, its place within a ring of kept samples.
    rank: Vec<u32>,
    /// Kept samples per ring.
    kept_per_ring: usize,
}

impl TubeLattice {
    /// The lattice of `local` (a cylinder's local samples, ring after ring) with the
    /// samples of angle index `j` kept where `keep_angle[j]`; `None` when `local` is
    /// not such a lattice or nothing is kept (callers then use a kd-tree).
    pub(super) fn new(pose: Pose, local: &[Point3<f64>], keep_angle: &[bool]) -> Option<Self> {
        let n_theta = keep_angle.len();
        if n_theta == 0 || local.is_empty() || !local.len().is_multiple_of(n_theta) {
            return None;
        }
        let n_z = local.len() / n_theta;
        let ring_z = |k: usize| local[k * n_theta].z;
        let is_lattice = (0..local.len()).all(|s| {
            let (k, j) = (s / n_theta, s % n_theta);
            local[s].z == ring_z(k) && local[s].x == local[j].x && local[s].y == local[j].y
        });
        let theta0 = local[0].y.atan2(local[0].x);
        let equal_angles = (0..n_theta).all(|j| {
            let off = (local[j].y.atan2(local[j].x) - theta0).rem_euclid(TAU);
            let miss = (off - TAU * j as f64 / n_theta as f64).abs();
            miss.min(TAU - miss) <= LAYOUT_TOLERANCE
        });
        let (z0, dz) = (ring_z(0), if n_z > 1 { ring_z(1) - ring_z(0) } else { 1.0 });
        let equal_rings = dz > 0.0
            && (0..n_z).all(|k| {
                (ring_z(k) - z0 - k as f64 * dz).abs() <= LAYOUT_TOLERANCE * dz * n_z as f64
            });
        let kept: Vec<u32> = (0..n_theta as u32)
            .filter(|&j| keep_angle[j as usize])
            .collect();
        if !(is_lattice && equal_angles && equal_rings) || kept.is_empty() {
            return None;
        }
        let mut rank = vec![u32::MAX; n_theta];
        for (r, &j) in kept.iter().enumerate() {
            rank[j as usize] = r as u32;
        }
        Some(TubeLattice {
            pose,
            theta0,
            n_theta,
            z0,
            dz,
            n_z,
            down: circular_nearest(keep_angle, false),
            up: circular_nearest(keep_angle, true),
            rank,
            kept_per_ring: kept.len(),
        })
    }

    /// `(sample index, squared distance)` of the sample of `samples` (the kept samples
    /// in scene coordinates, ring after ring, as [`TubeLattice::new`] kept them) nearest
    /// to `y`; ties to the lower index.
    pub(super) fn nearest(&self, samples: &[Point3<f64>], y: &Point3<f64>) -> (u32, f64) {
        let p = self.pose.to_local(y);
        let n = self.n_theta;
        let turns = (p.y.atan2(p.x) - self.theta0).rem_euclid(TAU) / TAU;
        let below = ((turns * n as f64).floor() as usize) % n;
        let (down, up) = (self.down[below] as usize, self.up[(below + 1) % n] as usize);
        let angles = [
            down,
            self.down[(down + n - 1) % n] as usize,
            up,
            self.up[(up + 1) % n] as usize,
        ];
        let ring = ((p.z - self.z0) / self.dz).round();
        let ring = if ring.is_finite() {
            ring.clamp(0.0, (self.n_z - 1) as f64) as usize
        } else {
            0
        };
        let mut best = (u32::MAX, f64::INFINITY);
        for k in ring.saturating_sub(1)..=(ring + 1).min(self.n_z - 1) {
            for &j in &angles {
                let s = k * self.kept_per_ring + self.rank[j] as usize;
                let d = squared_distance(&as_array(y), &as_array(&samples[s]));
                if d < best.1 || (d == best.1 && (s as u32) < best.0) {
                    best = (s as u32, d);
                }
            }
        }
        best
    }
}

/// For each index of the circle `keep`, the nearest kept index at or above it (`up`) or
/// at or below it (`!up`), going round. `keep` has at least one kept index.
fn circular_nearest(keep: &[bool], up: bool) -> Vec<u32> {
    let n = keep.len();
    let mut out = vec![0u32; n];
    // From a kept index, walk the other way round once, carrying the last kept index seen.
    let start = keep.iter().position(|&k| k).unwrap_or(0);
    let back = |j: usize| if up { (j + n - 1) % n } else { (j + 1) % n };
    let mut last = start;
    let mut j = start;
    for _ in 0..n {
        if keep[j] {
            last = j;
        }
        out[j] = last as u32;
        j = back(j);
    }
    out
}

#[cfg(test)]
mod tests {
    use nalgebra::{UnitQuaternion, Vector3};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::Shape;

    /// A tilted, scaled tube of radius 0.04 and length 0.1 sampled at 2 mm, its
    /// samples kept in `sectors` (angle index ranges).
    fn tube(keep: impl Fn(usize, usize) -> bool) -> (TubeLattice, Vec<Point3<f64>>) {
        let shape = Shape::Cylinder {
            length: 0.1,
            radius: 0.04,
        };
        let local = shape.sample_surface(0.002);
        let n_theta = local.iter().filter(|p| p.z == local[0].z).count();
        let keep_angle: Vec<bool> = (0..n_theta).map(|j| keep(j, n_theta)).collect();
        let mut pose = Pose::new(
            UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0),
            Vector3::new(0.5, -0.2, 1.3),
        );
        pose.scale = 1.7;
        let lattice = TubeLattice::new(pose, &local, &keep_angle).expect("a lattice");
        let scene = local
            .iter()
            .enumerate()
            .filter(|(s, _)| keep_angle[s % n_theta])
            .map(|(_, p)| pose.to_scene(p))
            .collect();
        (lattice, scene)
    }

    fn brute(samples: &[Point3<f64>], y: &Point3<f64>) -> (u32, f64) {
        let mut best = (u32::MAX, f64::INFINITY);
        for (s, q) in samples.iter().enumerate() {
            let d = squared_distance(&as_array(y), &as_array(q));
            if d < best.1 {
                best = (s as u32, d);
            }
        }
        best
    }

    /// Equal to brute force over the kept samples (index and distance) for points near
    /// and far, inside and outside, beyond the ends, in kept and dropped sectors, with one
    /// sector, two apart, and the whole circle kept.
    #[test]
    fn nearest_matches_brute_force() {
        let keeps: [&dyn Fn(usize, usize) -> bool; 4] = [
            &|j, n| j < n / 3,
            &|j, n| j < n / 8 || (j > n / 2 && j < 3 * n / 4),
            &|j, n| j == n / 5,
            &|_, _| true,
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for keep in keeps {
            let (lattice, samples) = tube(keep);
            let centre = lattice.pose.to_scene(&Point3::origin());
            for _ in 0..4000 {
                let scale = [0.01, 0.07, 0.3, 3.0][rng.random_range(0..4)];
                let y = centre
                    + Vector3::new(
                        rng.random_range(-scale..scale),
                        rng.random_range(-scale..scale),
                        rng.random_range(-scale..scale),
                    );
                let (got, truth) = (lattice.nearest(&samples, &y), brute(&samples, &y));
                assert_eq!(got.1.to_bits(), truth.1.to_bits(), "query {y}");
                assert_eq!(got.0, truth.0, "query {y}");
            }
        }
    }

    /// A point on the axis: every kept angle is (nearly) equally near; the answer is
    /// within rounding of the true least.
    #[test]
    fn on_the_axis_is_within_rounding() {
        let (lattice, samples) = tube(|j, n| j < n / 2);
        for z in [-0.3, 0.0, 0.01, 0.2] {
            let y = lattice.pose.to_scene(&Point3::new(0.0, 0.0, z));
            let (got, truth) = (lattice.nearest(&samples, &y).1, brute(&samples, &y).1);
            assert!(
                (got - truth).abs() <= 1e-12 * truth,
                "z {z}: {got} vs {truth}"
            );
        }
    }

    #[test]
    fn circular_nearest_wraps() {
        let keep = [false, true, false, false, true, false];
        assert_eq!(circular_nearest(&keep, true), [1, 1, 4, 4, 4, 1]);
        assert_eq!(circular_nearest(&keep, false), [4, 1, 1, 1, 4, 4]);
    }

    #[test]
    fn not_a_lattice_is_refused() {
        let local = [Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.5)];
        assert!(TubeLattice::new(Pose::identity(), &local, &[true, true]).is_none());
        assert!(TubeLattice::new(Pose::identity(), &local[..1], &[false]).is_none());
        // Unequal angles in a ring; two rings at one height.
        let ring = |z: f64, angles: &[f64]| -> Vec<Point3<f64>> {
            angles
                .iter()
                .map(|t| Point3::new(t.cos(), t.sin(), z))
                .collect()
        };
        let uneven = ring(0.0, &[0.1, 0.5, 3.0]);
        assert!(TubeLattice::new(Pose::identity(), &uneven, &[true, false, true]).is_none());
        let even = [0.1, 0.1 + TAU / 3.0, 0.1 + 2.0 * TAU / 3.0];
        let flat = [ring(0.0, &even), ring(0.0, &even)].concat();
        assert!(TubeLattice::new(Pose::identity(), &flat, &[true, false, true]).is_none());
        let stacked = [ring(0.0, &even), ring(0.5, &even)].concat();
        assert!(TubeLattice::new(Pose::identity(), &stacked, &[true, false, true]).is_some());
    }
}
