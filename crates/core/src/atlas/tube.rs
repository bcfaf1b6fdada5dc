//! The `Cylinder` type: the open tube of radius `r` around the z axis, z ∈ [−L/2, L/2].

use std::f64::consts::TAU;

use nalgebra::{Point3, Vector3};

use super::TriMesh;
use super::numeric::{cell_count, first_nonnegative, slab, symmetric_roots};

/// Segments around the tube in [`cylinder_mesh`] (sagitta r(1 − cos(π/48)) = 0.2 % of r).
pub(super) const TUBE_SEGMENTS: usize = 48;

/// Cell-centre grid in (θ, z): `round(2πr/spacing)` columns × `round(L/spacing)` rows.
/// The tube unrolls isometrically onto a 2πr × L rectangle, so a uniform grid there is
/// area-uniform on the tube.
pub(super) fn cylinder_sample(length: f64, radius: f64, spacing: f64) -> Vec<Point3<f64>> {
    let n_theta = cell_count(TAU * radius, spacing);
    let n_z = cell_count(length, spacing);
    let mut out = Vec::with_capacity(n_theta * n_z);
    for k in 0..n_z {
        let z = length * ((k as f64 + 0.5) / n_z as f64 - 0.5);
        for j in 0..n_theta {
            let theta = TAU * (j as f64 + 0.5) / n_theta as f64;
            out.push(Point3::new(radius * theta.cos(), radius * theta.sin(), z));
        }
    }
    out
}

/// The squared distance to the tube point at (θ, z) is `ρ² + r² − 2ρr cos(θ − θ_p) +
/// (z − z_p)²`, which separates: θ = θ_p and z clamped to the tube. On the axis (ρ = 0)
/// every θ is equally close and θ = 0 is returned.
pub(super) fn cylinder_closest(length: f64, radius: f64, p: &Point3<f64>) -> Point3<f64> {
    let h = length / 2.0;
    let rho = p.x.hypot(p.y);
    let (cos, sin) = if rho > 0.0 {
        (p.x / rho, p.y / rho)
    } else {
        (1.0, 0.0)
    };
    Point3::new(radius * cos, radius * sin, p.z.clamp(-h, h))
}

/// Two rings (z = −L/2 and z = +L/2) of [`TUBE_SEGMENTS`] vertices, outward normals.
pub(super) fn cylinder_mesh(length: f64, radius: f64) -> TriMesh {
    let ring = |z: f64| -> Vec<Point3<f64>> {
        (0..TUBE_SEGMENTS)
            .map(|j| {
                let theta = TAU * j as f64 / TUBE_SEGMENTS as f64;
                Point3::new(radius * theta.cos(), radius * theta.sin(), z)
            })
            .collect()
    };
    TriMesh::from_rings(&[ring(-length / 2.0), ring(length / 2.0)])
}

/// Intersects the infinite cylinder x² + y² = r² (a quadratic in t, solved from the ray's
/// closest approach to the axis to avoid cancellation), keeping hits with |z| ≤ L/2.
/// A ray parallel to the axis hits only if it runs along the tube wall.
pub(super) fn cylinder_ray(
    length: f64,
    radius: f64,
    o: &Point3<f64>,
    d: &Vector3<f64>,
) -> Option<f64> {
    let h = length / 2.0;
    let a = d.x * d.x + d.y * d.y;
    if a == 0.0 {
        let on_wall = (o.x.hypot(o.y) - radius).abs() <= 1e-12 * radius;
        return if on_wall {
            first_nonnegative(slab([o.z], [d.z], [-h], [h]))
        } else {
            None
        };
    }
    let t0 = -(o.x * d.x + o.y * d.y) / a;
    let (mx, my) = (o.x + t0 * d.x, o.y + t0 * d.y);
    let roots = symmetric_roots(t0, a, mx * mx + my * my - radius * radius)?;
    roots
        .into_iter()
        .find(|&t| t >= 0.0 && (o.z + t * d.z).abs() <= h)
}
