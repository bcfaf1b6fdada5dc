//! The flat types: `Disk` (radius `R`) and `Square` (half-side `h`), both in the plane
//! z = 0 with normal +z.

use nalgebra::{Point3, Vector3};

use super::TriMesh;
use super::numeric::{GOLDEN_ANGLE, first_nonnegative, sample_count, slab, symmetric_roots};

/// Segments around the disk's rim in [`disk_mesh`]: the chord sagitta R(1 − cos(π/48)) is
/// 0.2 % of R and the polygon holds 99.7 % of the disk's area.
const DISK_SEGMENTS: u32 = 48;

/// Sunflower (Vogel) spiral: sample `i` of `n` at radius `R √((i + ½)/n)` and angle
/// `i · golden angle`. The radius law makes the count inside radius ρ proportional to ρ²,
/// i.e. to area, so the density is uniform.
pub(super) fn disk_sample(radius: f64, spacing: f64) -> Vec<Point3<f64>> {
    let n = sample_count(std::f64::consts::PI * radius * radius, spacing);
    (0..n)
        .map(|i| {
            let rho = radius * ((i as f64 + 0.5) / n as f64).sqrt();
            let theta = i as f64 * GOLDEN_ANGLE;
            Point3::new(rho * theta.cos(), rho * theta.sin(), 0.0)
        })
        .collect()
}

/// Projects onto the plane, then pulls points outside the rim radially onto it.
pub(super) fn disk_closest(radius: f64, p: &Point3<f64>) -> Point3<f64> {
    let rho = p.x.hypot(p.y);
    if rho <= radius {
        Point3::new(p.x, p.y, 0.0)
    } else {
        Point3::new(p.x * radius / rho, p.y * radius / rho, 0.0)
    }
}

/// A fan around the centre; rim vertices counter-clockwise seen from +z (normal +z).
pub(super) fn disk_mesh(radius: f64) -> TriMesh {
    let mut vertices = vec![Point3::origin()];
    vertices.extend((0..DISK_SEGMENTS).map(|j| {
        let theta = std::f64::consts::TAU * j as f64 / DISK_SEGMENTS as f64;
        Point3::new(radius * theta.cos(), radius * theta.sin(), 0.0)
    }));
    let faces = (0..DISK_SEGMENTS)
        .map(|j| [0, 1 + j, 1 + (j + 1) % DISK_SEGMENTS])
        .collect();
    TriMesh { vertices, faces }
}

/// The first hit with the disk: the plane crossing if it is inside the rim, or, for a
/// ray lying in the plane z = 0, the first point of the ray inside the disk.
pub(super) fn disk_ray(radius: f64, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
    plane_ray(
        o,
        d,
        |x, y| x.hypot(y) <= radius,
        |o, d| circle_entry(radius, o, d),
    )
}

/// The first `t ≥ 0` at which the 2-D ray `o + t·d` is inside the circle of `radius`.
fn circle_entry(radius: f64, o: [f64; 2], d: [f64; 2]) -> Option<f64> {
    let a = d[0] * d[0] + d[1] * d[1];
    if a == 0.0 {
        return (o[0].hypot(o[1]) <= radius).then_some(0.0);
    }
    // Shift to the ray's closest approach to the centre: a (t − t0)² + (ρ0² − R²).
    let t0 = -(o[0] * d[0] + o[1] * d[1]) / a;
    let (mx, my) = (o[0] + t0 * d[0], o[1] + t0 * d[1]);
    let [t_in, t_out] = symmetric_roots(t0, a, mx * mx + my * my - radius * radius)?;
    first_nonnegative(Some((t_in, t_out)))
}

/// The square's cell-centre grid: `ceil(side / spacing)` cells per side.
pub(super) fn square_sample(side: f64, spacing: f64) -> Vec<Point3<f64>> {
    debug_assert!(
        spacing.is_finite() && spacing > 0.0,
        "spacing must be positive and finite"
    );
    let n = ((side / spacing).ceil() as usize).max(1);
    let step = side / n as f64;
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            out.push(Point3::new(
                -side / 2.0 + (i as f64 + 0.5) * step,
                -side / 2.0 + (j as f64 + 0.5) * step,
                0.0,
            ));
        }
    }
    out
}

/// Projects onto the plane and clamps to the square.
pub(super) fn square_closest(side: f64, p: &Point3<f64>) -> Point3<f64> {
    let h = side / 2.0;
    Point3::new(p.x.clamp(-h, h), p.y.clamp(-h, h), 0.0)
}

/// Two triangles, counter-clockwise seen from +z.
pub(super) fn square_mesh(side: f64) -> TriMesh {
    let h = side / 2.0;
    TriMesh {
        vertices: vec![
            Point3::new(-h, -h, 0.0),
            Point3::new(h, -h, 0.0),
            Point3::new(h, h, 0.0),
            Point3::new(-h, h, 0.0),
        ],
        faces: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// The first hit with the square (see [`disk_ray`] for the in-plane case).
pub(super) fn square_ray(side: f64, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
    let h = side / 2.0;
    plane_ray(
        o,
        d,
        |x, y| x.abs() <= h && y.abs() <= h,
        |o, d| first_nonnegative(slab(o, d, [-h, -h], [h, h])),
    )
}

/// Ray against a flat patch of the plane z = 0. A ray crossing the plane hits where
/// `z = 0` if `inside(x, y)`; a ray lying in the plane (`o.z = d.z = 0`) is handed to
/// `in_plane` with its 2-D origin and direction.
pub(super) fn plane_ray(
    o: &Point3<f64>,
    d: &Vector3<f64>,
    inside: impl Fn(f64, f64) -> bool,
    in_plane: impl Fn([f64; 2], [f64; 2]) -> Option<f64>,
) -> Option<f64> {
    if d.z == 0.0 {
        return if o.z == 0.0 {
            in_plane([o.x, o.y], [d.x, d.y])
        } else {
            None
        };
    }
    let t = -o.z / d.z;
    // `+ 0.0` turns a −0 (origin on the plane) into +0.
    (t >= 0.0 && inside(o.x + t * d.x, o.y + t * d.y)).then_some(t + 0.0)
}
