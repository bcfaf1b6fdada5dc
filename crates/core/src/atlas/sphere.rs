//! The `Sphere` type: radius `R`, centred at the origin.

use std::f64::consts::{PI, TAU};

use nalgebra::{Point3, Vector3};

use super::TriMesh;
use super::numeric::{GOLDEN_ANGLE, sample_count, symmetric_roots};

/// Longitudes in [`sphere_mesh`]; latitude rings are spaced at half that count.
const SPHERE_SEGMENTS: usize = 48;

/// Fibonacci sphere: sample `i` of `n` at height `z = R(1 − (2i + 1)/n)` and azimuth
/// `i · golden angle`. By Archimedes' hat-box theorem equal z-intervals hold equal area,
/// so uniform heights give area-uniform samples.
pub(super) fn sphere_sample(radius: f64, spacing: f64) -> Vec<Point3<f64>> {
    let n = sample_count(4.0 * PI * radius * radius, spacing);
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let rho = (1.0 - z * z).max(0.0).sqrt();
            let phi = i as f64 * GOLDEN_ANGLE;
            Point3::new(
                radius * rho * phi.cos(),
                radius * rho * phi.sin(),
                radius * z,
            )
        })
        .collect()
}

/// Radial projection; the centre is equidistant to all points and maps to the north pole.
pub(super) fn sphere_closest(radius: f64, p: &Point3<f64>) -> Point3<f64> {
    let len = p.coords.norm();
    if len > 0.0 && len.is_finite() {
        Point3::from(p.coords * (radius / len))
    } else {
        Point3::new(0.0, 0.0, radius)
    }
}

/// A UV sphere: latitude rings stitched south to north, plus a fan at each pole.
pub(super) fn sphere_mesh(radius: f64) -> TriMesh {
    let n_lat = SPHERE_SEGMENTS / 2;
    let rings: Vec<Vec<Point3<f64>>> = (1..n_lat)
        .map(|k| {
            let polar = PI * (1.0 - k as f64 / n_lat as f64); // from the south pole up
            let (rho, z) = (radius * polar.sin(), radius * polar.cos());
            (0..SPHERE_SEGMENTS)
                .map(|j| {
                    let az = TAU * j as f64 / SPHERE_SEGMENTS as f64;
                    Point3::new(rho * az.cos(), rho * az.sin(), z)
                })
                .collect()
        })
        .collect();
    let mut mesh = TriMesh::from_rings(&rings);
    let n = SPHERE_SEGMENTS as u32;
    let top_ring = (rings.len() as u32 - 1) * n;
    let south = mesh.vertices.len() as u32;
    mesh.vertices.push(Point3::new(0.0, 0.0, -radius));
    mesh.vertices.push(Point3::new(0.0, 0.0, radius));
    for j in 0..n {
        let jn = (j + 1) % n;
        mesh.faces.push([south, jn, j]);
        mesh.faces.push([south + 1, top_ring + j, top_ring + jn]);
    }
    mesh
}

/// The quadratic |o + t d|² = R², solved from the ray's closest approach to the centre.
pub(super) fn sphere_ray(radius: f64, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
    let a = d.norm_squared();
    let t0 = -o.coords.dot(d) / a;
    let m = o + d * t0;
    let roots = symmetric_roots(t0, a, m.coords.norm_squared() - radius * radius)?;
    roots.into_iter().find(|&t| t >= 0.0)
}
