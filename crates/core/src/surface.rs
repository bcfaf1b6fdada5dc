//! Local surface estimates of a scan: per-point normals, flatness and noise from a PCA of
//! each point's k nearest neighbours.
//!
//! For a point `y` with neighbours `N_k(y)` (itself included), let `C` be their 3 × 3
//! covariance with eigenvalues `λ0 ≤ λ1 ≤ λ2`. Then
//!
//! - the **normal** is the unit eigenvector of `λ0` (unoriented: `±n` are the same plane);
//! - the **flatness** `λ0 / (λ0 + λ1 + λ2)` ("surface variation", Pauly et al. 2002) is
//!   0 on a perfect plane and 1/3 for an isotropic blob;
//! - the **residual** `√λ0` is the standard deviation of the neighbours off their
//!   best-fit plane (scene units): on a flat, noisy surface it estimates the noise σ
//!   along the normal.
//!
//! The noise level of a sampled surface is floored at its resolution: [`noise_sigma`]
//! is `max(σ_pca, s/√12)` with `s` the point spacing ([`noise_floor`] gives the
//! derivation), so quantised depth, whose neighbourhoods are exactly planar, never
//! reports σ = 0.
//!
//! Estimates are taken on an evenly strided subsample (every `⌈J / max_points⌉`-th point),
//! so their cost does not grow with the scan; results are deterministic.

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};
use rayon::prelude::*;

use crate::spatial::{PointIndex, kth_distance_guess};

/// Neighbours per PCA (the point itself included). 32 rather than the usual 16: on a
/// noisy tube (σ = r/10) normals from 16 neighbours scatter by ~15°, which biased the
/// frame of a synthetic pipe by 5–9°; 32 brought it to 1–1.5° (measured).
pub const DEFAULT_NEIGHBOURS: usize = 32;

/// Most points on which local planes are estimated for the frame and the grid origin.
pub const DEFAULT_MAX_POINTS: usize = 20_000;

/// Most points on which local planes are estimated for the noise level
/// ([`noise_level`]): a median over the flattest 2 000 of 4 000 evenly strided
/// neighbourhoods is within a few per cent of the one over all of them, at a fifth of the
/// cost on a 20k-point cloud.
pub const NOISE_MAX_POINTS: usize = 4_000;

/// A local plane fitted to one point's neighbourhood.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalPlane {
    /// The point (scene coordinates).
    pub point: Point3<f64>,
    /// Unit normal, sign arbitrary.
    pub normal: Vector3<f64>,
    /// `λ0 / (λ0 + λ1 + λ2)` ∈ [0, 1/3]: 0 = perfectly flat.
    pub flatness: f64,
    /// `√λ0`: spread of the neighbours along the normal (scene units).
    pub residual: f64,
}

/// The local plane of `point` from its `k` nearest neighbours, or `None` when fewer than
/// three neighbours exist or they are all coincident. The neighbours are searched from
/// the squared radius `guess` when given ([`PointIndex::nearest_n_guessed`]: the same
/// neighbours).
fn local_plane(
    point: &Point3<f64>,
    index: &PointIndex,
    cloud: &[Point3<f64>],
    k: usize,
    guess: Option<f64>,
) -> Option<LocalPlane> {
    let hits = index.nearest_n_guessed(point, k.max(3), guess);
    if hits.len() < 3 {
        return None;
    }
    let neighbours: Vec<Point3<f64>> = hits
        .iter()
        .filter_map(|(i, _)| cloud.get(*i as usize).copied())
        .collect();
    let (normal, flatness, residual) = pca_plane(&neighbours)?;
    Some(LocalPlane {
        point: *point,
        normal,
        flatness,
        residual,
    })
}

/// The PCA plane of a set of points: `(unit normal, flatness, residual)` as in the
/// module docs, or `None` when fewer than three points are given or they all coincide.
pub fn pca_plane(points: &[Point3<f64>]) -> Option<(Vector3<f64>, f64, f64)> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mean = points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n;
    let cov = points
        .iter()
        .map(|p| {
            let d = p.coords - mean;
            d * d.transpose()
        })
        .sum::<Matrix3<f64>>()
        / n;
    let eigen = SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
    let lambda = order.map(|i| eigen.eigenvalues[i].max(0.0));
    let total = lambda.iter().sum::<f64>();
    if !(total.is_finite() && total > 0.0) {
        return None;
    }
    let normal = eigen.eigenvectors.column(order[0]).into_owned();
    let norm = normal.norm();
    if !(norm.is_finite() && norm > 0.0) {
        return None;
    }
    Some((normal / norm, lambda[0] / total, lambda[0].sqrt()))
}

/// Local planes of at most `max_points` evenly strided points of `cloud`, `k` neighbours
/// each (see the module docs). Points whose neighbourhood is degenerate are skipped. On
/// an even cloud of about a thousand points or more the searches start from a guessed
/// radius ([`kth_distance_guess`]), which finds the same neighbours faster.
pub fn local_planes(
    cloud: &[Point3<f64>],
    index: &PointIndex,
    k: usize,
    max_points: usize,
) -> Vec<LocalPlane> {
    let stride = cloud.len().div_ceil(max_points.max(1)).max(1);
    let probes: Vec<Point3<f64>> = cloud.iter().step_by(stride).copied().collect();
    let guess = kth_distance_guess(cloud, index, k.max(3));
    probes
        .par_iter()
        .filter_map(|p| local_plane(p, index, cloud, k, guess))
        .collect()
}

/// The scan's noise level σ (scene units): the median [`LocalPlane::residual`] of the
/// flattest half of `planes` (curved or creased neighbourhoods would overstate it).
/// `None` for no planes.
pub fn noise_level(planes: &[LocalPlane]) -> Option<f64> {
    if planes.is_empty() {
        return None;
    }
    let mut by_flatness: Vec<&LocalPlane> = planes.iter().collect();
    // Stable: planes of equal flatness keep their order, on any thread count.
    by_flatness.par_sort_by(|a, b| a.flatness.total_cmp(&b.flatness));
    let flat = &by_flatness[..by_flatness.len().div_ceil(2)];
    let mut r: Vec<f64> = flat.iter().map(|p| p.residual).collect();
    let mid = r.len() / 2;
    r.select_nth_unstable_by(mid, f64::total_cmp);
    Some(r[mid])
}

/// `1/√12`: the standard deviation of a uniform distribution of unit width.
const UNIFORM_SD_PER_WIDTH: f64 = 0.288_675_134_594_812_9;

/// The resolution floor of the noise level (scene units): `spacing / √12`.
///
/// **Why.** A sensor that samples a surface every `s` (the point spacing, scene units)
/// cannot report where the surface lies between its samples more finely than `s`: a
/// quantised depth sensor (Kinect-type) rounds the depth to steps of the same order as
/// the lateral spacing at that range, and any resampling to a grid of pitch `s` does
/// the same. The position error of rounding to a step `s` is uniform on `[−s/2, s/2]`,
/// whose standard deviation is `s/√12`. So `s/√12` is the smallest σ a sampled surface
/// can honestly claim, even where every neighbourhood is exactly planar (the local PCA
/// of [`noise_level`] then gives `σ = 0`: quantised depth yields terraces that are
/// perfectly flat between the steps).
pub fn noise_floor(spacing: f64) -> f64 {
    spacing.max(0.0) * UNIFORM_SD_PER_WIDTH
}

/// The floored noise level σ (scene units): `max(σ_pca, spacing/√12)`, with `σ_pca` the
/// [`noise_level`] of `planes` and the floor [`noise_floor`] of the cloud's point
/// `spacing` (median nearest-neighbour distance, [`PointIndex::median_spacing`](crate::PointIndex::median_spacing)).
/// Never 0 for a positive spacing; the floor alone when `planes` is empty.
pub fn noise_sigma(planes: &[LocalPlane], spacing: f64) -> f64 {
    noise_level(planes).unwrap_or(0.0).max(noise_floor(spacing))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tilted_plane(noise: f64) -> Vec<Point3<f64>> {
        // A 2 m × 2 m grid on the plane with normal (1, 1, 1)/√3, with a deterministic
        // ±noise offset along the normal.
        let n = Vector3::new(1.0, 1.0, 1.0).normalize();
        let u = Vector3::new(1.0, -1.0, 0.0).normalize();
        let v = n.cross(&u);
        (0..60)
            .flat_map(|i| (0..60).map(move |j| (i, j)))
            .map(|(i, j)| {
                let s = if (i * 7 + j * 3) % 2 == 0 {
                    noise
                } else {
                    -noise
                };
                Point3::from(u * (i as f64 / 30.0) + v * (j as f64 / 30.0) + n * s)
            })
            .collect()
    }

    #[test]
    fn normals_of_a_tilted_plane() {
        let pts = tilted_plane(0.0);
        let idx = PointIndex::new(&pts);
        let planes = local_planes(&pts, &idx, 16, 500);
        assert!(planes.len() >= 400);
        let n = Vector3::new(1.0, 1.0, 1.0).normalize();
        for p in &planes {
            assert!(p.normal.dot(&n).abs() > 1.0 - 1e-9, "{:?}", p.normal);
            assert!(p.flatness < 1e-12);
        }
        assert!(noise_level(&planes).unwrap() < 1e-9);
    }

    #[test]
    fn noise_level_follows_the_offsets() {
        let pts = tilted_plane(0.01);
        let idx = PointIndex::new(&pts);
        let sigma = noise_level(&local_planes(&pts, &idx, 16, 1000)).unwrap();
        assert!((sigma - 0.01).abs() < 0.003, "σ = {sigma}");
    }

    #[test]
    fn the_floor_keeps_exactly_planar_neighbourhoods_above_zero() {
        // Exactly planar: σ_pca = 0, so σ is the floor of the 1/30 grid pitch.
        let pts = tilted_plane(0.0);
        let idx = PointIndex::new(&pts);
        let planes = local_planes(&pts, &idx, 16, 500);
        let spacing = idx.median_spacing(&pts, 1000).unwrap();
        assert!((spacing - 1.0 / 30.0).abs() < 1e-9);
        let sigma = noise_sigma(&planes, spacing);
        assert!(
            (sigma - spacing / 12f64.sqrt()).abs() < 1e-12,
            "σ = {sigma}"
        );
        // Rounding to a step s spreads points uniformly over ±s/2: sd s/√12.
        let s = 0.01;
        let n = 100_000;
        let var = (0..n)
            .map(|i| {
                let x = i as f64 * 0.000_737_1;
                let e = x - (x / s).round() * s;
                e * e
            })
            .sum::<f64>()
            / n as f64;
        assert!((var.sqrt() - noise_floor(s)).abs() < 1e-4 * s / 0.01);
        // Noisier than the floor: the PCA estimate wins.
        let noisy = tilted_plane(0.01);
        let idx = PointIndex::new(&noisy);
        let sigma = noise_sigma(&local_planes(&noisy, &idx, 16, 1000), 1.0 / 30.0);
        assert!((sigma - 0.01).abs() < 0.003, "σ = {sigma}");
        assert_eq!(noise_sigma(&[], 0.3), noise_floor(0.3));
    }

    #[test]
    fn degenerate_input_gives_nothing() {
        let pts = vec![Point3::origin(); 5];
        let idx = PointIndex::new(&pts);
        assert!(local_planes(&pts, &idx, 16, 10).is_empty());
        assert!(noise_level(&[]).is_none());
    }
}
