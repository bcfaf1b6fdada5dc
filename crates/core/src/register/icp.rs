//! Trimmed ICP of one posed mesh against a cloud: the final local refinement of a pose
//! found by the particle filter.

use nalgebra::{Matrix3, Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use super::geometry::DistanceGrid;
use crate::Pose;
use crate::atlas::MeshShape;

/// Which pose parameters ICP may change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Freedom {
    /// Estimate the translation (else it stays as given).
    pub translation: bool,
    /// Estimate the uniform scale (else it stays as given).
    pub scale: bool,
}

/// Settings of [`refine`]. Distances in scene units.
#[derive(Debug, Clone, PartialEq)]
pub struct IcpOptions {
    /// Correspondence distance of the first iteration.
    pub start_distance: f64,
    /// Smallest correspondence distance (the inlier distance at the end).
    pub min_distance: f64,
    /// Factor applied to the correspondence distance after each iteration (in (0, 1]).
    pub shrink: f64,
    /// Iteration limit.
    pub max_iterations: usize,
    /// Stop once the distance is at its minimum and no surface point moved by more than
    /// this (scene units).
    pub tolerance: f64,
    /// Bounds of an estimated scale (`None` = unbounded). Trimmed ICP may otherwise
    /// shrink the model onto a few points: a small model has small residuals.
    pub scale_range: Option<(f64, f64)>,
}

/// Outcome of [`refine`].
#[derive(Debug, Clone)]
pub struct IcpResult {
    /// Refined pose (local mesh frame → scene).
    pub pose: Pose,
    /// Indices of the cloud points within `min_distance` of the refined surface.
    pub inliers: Vec<usize>,
    /// Root-mean-square distance of the inliers to the surface (scene units).
    pub rms: f64,
}

/// Trimmed ICP: each iteration pairs every cloud point within the current correspondence
/// distance τ of the posed surface with its exact closest surface point (points farther
/// away are trimmed: at high outlier rates most of the cloud), solves the best rigid
/// (or similarity, [`Freedom::scale`]) motion in closed form (Kabsch / Umeyama; with
/// the translation fixed, the uncentred Procrustes problem), and shrinks τ geometrically
/// to [`IcpOptions::min_distance`]. `mesh` and `grid` are in the mesh's local frame.
pub fn refine(
    mesh: &MeshShape,
    grid: &DistanceGrid,
    cloud: &[Point3<f64>],
    start: Pose,
    freedom: Freedom,
    options: &IcpOptions,
) -> IcpResult {
    let mut pose = start;
    let mut tau = options.start_distance.max(options.min_distance);
    let radius = mesh.bounding_radius();
    for _ in 0..options.max_iterations {
        let pairs = correspondences(mesh, grid, cloud, &pose, tau, radius);
        if pairs.len() < 3 {
            break;
        }
        let next = solve_motion(&pairs, &pose, freedom, options.scale_range);
        let moved = radius
            * (next.scale * next.rotation.angle_to(&pose.rotation)
                + (next.scale - pose.scale).abs())
            + (next.translation - pose.translation).norm();
        pose = next;
        let at_min = tau <= options.min_distance;
        tau = (tau * options.shrink).max(options.min_distance);
        if at_min && moved < options.tolerance {
            break;
        }
    }
    let pairs = correspondences(mesh, grid, cloud, &pose, options.min_distance, radius);
    let rms = if pairs.is_empty() {
        0.0
    } else {
        (pairs.iter().map(|p| p.2 * p.2).sum::<f64>() / pairs.len() as f64).sqrt()
    };
    IcpResult {
        pose,
        inliers: pairs.iter().map(|p| p.3).collect(),
        rms,
    }
}

/// `(closest surface point (local), cloud point (scene), distance (scene), index)` for
/// every cloud point within `tau` of the posed surface.
fn correspondences(
    mesh: &MeshShape,
    grid: &DistanceGrid,
    cloud: &[Point3<f64>],
    pose: &Pose,
    tau: f64,
    radius: f64,
) -> Vec<(Point3<f64>, Point3<f64>, f64, usize)> {
    let reach = (radius * pose.scale + tau).powi(2);
    let slack = grid.cell();
    cloud
        .par_iter()
        .enumerate()
        .filter_map(|(j, y)| {
            if (y.coords - pose.translation).norm_squared() > reach {
                return None;
            }
            let local = pose.to_local(y);
            if grid.box_distance(&local) * pose.scale > tau {
                return None;
            }
            // The grid value is within one cell of the truth: skip points surely too far.
            if (grid.distance(&local) - slack) * pose.scale > tau {
                return None;
            }
            let c = mesh.closest_point(&local);
            let d = (local - c).norm() * pose.scale;
            (d <= tau).then_some((c, *y, d, j))
        })
        .collect()
}

/// The motion minimising `Σ ‖y − (s R c + t)‖²` over the free parameters, the scale
/// clamped to `range`.
fn solve_motion(
    pairs: &[(Point3<f64>, Point3<f64>, f64, usize)],
    pose: &Pose,
    f: Freedom,
    range: Option<(f64, f64)>,
) -> Pose {
    let n = pairs.len() as f64;
    let (mc, my) = if f.translation {
        (
            pairs.iter().map(|p| p.0.coords).sum::<Vector3<f64>>() / n,
            pairs.iter().map(|p| p.1.coords).sum::<Vector3<f64>>() / n,
        )
    } else {
        (Vector3::zeros(), pose.translation)
    };
    let mut h = Matrix3::zeros();
    let mut cc = 0.0;
    for (c, y, _, _) in pairs {
        let (a, b) = (c.coords - mc, y.coords - my);
        h += b * a.transpose();
        cc += a.norm_squared();
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return *pose;
    };
    let mut d = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * v_t;
    let rotation = UnitQuaternion::from_matrix(&r);
    let scale = if f.scale && cc > 0.0 {
        let trace = (svd.singular_values.component_mul(&d.diagonal())).sum();
        let s = (trace / cc).max(1e-9);
        range.map_or(s, |(lo, hi)| s.clamp(lo, hi))
    } else {
        pose.scale
    };
    if f.translation {
        Pose::anchored(rotation, scale, &Point3::from(mc), &Point3::from(my))
    } else {
        Pose {
            rotation,
            scale,
            ..*pose
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::asymmetric_object;

    #[test]
    fn recovers_a_small_offset_exactly_on_clean_data() {
        let mesh = asymmetric_object();
        let grid = DistanceGrid::new(&mesh, 32, 0.2);
        let truth = Pose {
            rotation: UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1),
            translation: Vector3::new(0.2, -0.1, 0.3),
            scale: 1.3,
        };
        let cloud: Vec<Point3<f64>> = crate::atlas::Shape::Mesh(mesh.clone())
            .sample_surface(0.05)
            .iter()
            .map(|p| truth.to_scene(p))
            .collect();
        let start = Pose {
            rotation: truth.rotation * UnitQuaternion::from_euler_angles(0.05, 0.04, -0.03),
            translation: truth.translation + Vector3::new(0.03, -0.02, 0.01),
            scale: 1.25,
        };
        let options = IcpOptions {
            start_distance: 0.2,
            min_distance: 0.01,
            shrink: 0.8,
            max_iterations: 100,
            tolerance: 1e-9,
            scale_range: None,
        };
        let free = Freedom {
            translation: true,
            scale: true,
        };
        let r = refine(&mesh, &grid, &cloud, start, free, &options);
        assert!(
            r.pose.rotation.angle_to(&truth.rotation) < 1e-4,
            "{:?}",
            r.pose
        );
        assert!((r.pose.translation - truth.translation).norm() < 1e-4);
        assert!((r.pose.scale - truth.scale).abs() < 1e-4);
        assert_eq!(r.inliers.len(), cloud.len());
        // Rotation only: translation and scale stay as given.
        let start = Pose {
            rotation: start.rotation,
            ..truth
        };
        let fixed = Freedom {
            translation: false,
            scale: false,
        };
        let r = refine(&mesh, &grid, &cloud, start, fixed, &options);
        assert!(r.pose.rotation.angle_to(&truth.rotation) < 1e-4);
        assert_eq!(r.pose.translation, truth.translation);
        assert_eq!(r.pose.scale, truth.scale);
    }
}
