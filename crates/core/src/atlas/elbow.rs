//! The `Elbow` type: a quarter torus. With bend radius `B` and tube radius `r < B`, the
//! surface is `S(ψ, φ) = C(ψ) + r (cos φ e_ρ(ψ) + sin φ e_z)` for ψ ∈ [0, π/2], φ ∈ [0, 2π),
//! where `C(ψ) = B e_ρ(ψ)` is the centre-line arc and `e_ρ(ψ) = (cos ψ, sin ψ, 0)`.
//! Its area element is `dA = r (B + r cos φ) dφ dψ`; the ends ψ = 0 and ψ = π/2 are open.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use nalgebra::{Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};

use super::TriMesh;
use super::numeric::{apportion, cell_count, closest_on_circle, poly_roots_in, sample_count};
use super::tube::TUBE_SEGMENTS;

/// Rings along the quarter arc in [`elbow_mesh`]: 3.75° per segment, so the chord
/// sagitta on the outer equator is (B + r)(1 − cos(π/96)) < 0.06 % of the size.
const ARC_SEGMENTS: usize = 24;

/// The rotation of an elbow whose centre line enters with tangent `d_in` and leaves with
/// tangent `d_out` (unit, perpendicular): local x ↦ −`d_out`, y ↦ `d_in`, z ↦ their
/// cross product. The local arc runs from radial +x (tangent +y) to radial +y (tangent
/// −x), so with the torus centre at `entry + bend·d_out` the arc runs from `entry` to
/// `entry + bend·(d_in + d_out)`.
pub fn elbow_rotation_between(d_in: &Vector3<f64>, d_out: &Vector3<f64>) -> UnitQuaternion<f64> {
    let (ex, ey) = (-d_out, *d_in);
    let m = Matrix3::from_columns(&[ex, ey, ex.cross(&ey)]);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

/// Unit radial direction in the plane z = 0 at arc angle ψ.
fn e_rho(psi: f64) -> Vector3<f64> {
    Vector3::new(psi.cos(), psi.sin(), 0.0)
}

/// Unit tangent of the centre line at arc angle ψ (direction of increasing ψ).
fn tangent(psi: f64) -> Vector3<f64> {
    Vector3::new(-psi.sin(), psi.cos(), 0.0)
}

/// The surface point at arc angle ψ and tube angle φ (φ = 0 on the outer equator).
fn surface_point(bend: f64, radius: f64, psi: f64, phi: f64) -> Point3<f64> {
    let radial = bend + radius * phi.cos();
    Point3::new(radial * psi.cos(), radial * psi.sin(), radius * phi.sin())
}

/// Rows of constant φ around the tube, each a cell-centre run along the arc.
///
/// There are `round(2πr/spacing)` rows; row `j` stands for the band of tube angles
/// `φ_j ± Δ/2`, whose area is `(π/2) r (B Δ + 2 r cos φ_j sin(Δ/2))`. The total
/// `round(area/spacing²)` is split between rows in proportion to those band areas
/// (largest remainder), so the outer side of the bend, which has more area, gets
/// proportionally more samples.
pub(super) fn elbow_sample(bend: f64, radius: f64, spacing: f64) -> Vec<Point3<f64>> {
    let area = PI * PI * radius * bend;
    let n_phi = cell_count(TAU * radius, spacing);
    let delta = TAU / n_phi as f64;
    let phis: Vec<f64> = (0..n_phi).map(|j| j as f64 * delta).collect();
    let band_weights: Vec<f64> = phis
        .iter()
        .map(|phi| bend * delta + 2.0 * radius * phi.cos() * (delta / 2.0).sin())
        .collect();
    let counts = apportion(&band_weights, sample_count(area, spacing));
    let mut out = Vec::with_capacity(counts.iter().sum());
    for (&phi, &m) in phis.iter().zip(&counts) {
        out.extend(
            (0..m)
                .map(|k| surface_point(bend, radius, FRAC_PI_2 * (k as f64 + 0.5) / m as f64, phi)),
        );
    }
    out
}

/// Exact closest point.
///
/// Let `p` have azimuth α and distance ρ from the z axis, and let δ = α − ψ. The squared
/// distance from `p` to the tube circle at ψ is
/// `ρ² + B² + z² + r² − 2Bw − 2r √((w − B)² + z²)` with `w = ρ cos δ`, whose derivative in
/// `w` is at most `−2B + 2r < 0`. So the distance grows with the angular gap |δ|: the
/// best circle is at ψ = α when α lies on the arc, and otherwise at the nearer end
/// (the rim circles). The closest point on that circle finishes the job.
pub(super) fn elbow_closest(bend: f64, radius: f64, p: &Point3<f64>) -> Point3<f64> {
    let on_circle = |psi: f64| {
        closest_on_circle(
            p,
            &Point3::from(e_rho(psi) * bend),
            &tangent(psi),
            radius,
            &e_rho(psi),
        )
    };
    let alpha = p.y.atan2(p.x);
    if (0.0..=FRAC_PI_2).contains(&alpha) {
        return on_circle(alpha);
    }
    let (start, end) = (on_circle(0.0), on_circle(FRAC_PI_2));
    if (p - start).norm_squared() <= (p - end).norm_squared() {
        start
    } else {
        end
    }
}

/// [`ARC_SEGMENTS`] + 1 rings of [`TUBE_SEGMENTS`] vertices. Rings follow increasing ψ
/// (along the tangent t); a ring runs from e_ρ towards −e_z, which is counter-clockwise
/// about t because e_ρ × (−e_z) = t, so the faces face outward.
pub(super) fn elbow_mesh(bend: f64, radius: f64) -> TriMesh {
    let rings: Vec<Vec<Point3<f64>>> = (0..=ARC_SEGMENTS)
        .map(|k| {
            let psi = FRAC_PI_2 * k as f64 / ARC_SEGMENTS as f64;
            (0..TUBE_SEGMENTS)
                .map(|j| surface_point(bend, radius, psi, -TAU * j as f64 / TUBE_SEGMENTS as f64))
                .collect()
        })
        .collect();
    TriMesh::from_rings(&rings)
}

/// First hit with the quarter torus.
///
/// The ray is re-parameterised as `m + s u` with `u = d/|d|` and `m` the foot of the
/// perpendicular from the origin (the torus centre), which keeps the quartic well scaled.
/// With `k = |m|² + B² − r²` the full torus `(|x|² + B² − r²)² = 4B²(x² + y²)` becomes
/// `(s² + k)² − 4B²(a₂ s² + a₁ s + a₀) = 0`. Its real roots inside the bounding sphere
/// (radius B + r) are isolated exactly ([`poly_roots_in`]); the first with `t ≥ 0` that lies
/// on the quarter (x ≥ 0 and y ≥ 0) is the answer.
pub(super) fn elbow_ray(bend: f64, radius: f64, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
    let len = d.norm();
    let u = d / len;
    let t0 = -o.coords.dot(&u);
    let m = o + u * t0;
    let outer = bend + radius;
    let half_chord2 = outer * outer - m.coords.norm_squared();
    if half_chord2.is_nan() || half_chord2 < 0.0 {
        return None;
    }
    let half_chord = half_chord2.sqrt();
    let margin = 1e-9 * outer;
    // Tolerances for "t ≥ 0" (an origin on the surface) and "on the quarter" (a hit on a rim).
    let tol = 1e-12 * outer;

    let k = m.coords.norm_squared() + bend * bend - radius * radius;
    let b4 = 4.0 * bend * bend;
    let a2 = u.x * u.x + u.y * u.y;
    let a1 = 2.0 * (m.x * u.x + m.y * u.y);
    let a0 = m.x * m.x + m.y * m.y;
    let quartic = [k * k - b4 * a0, -b4 * a1, 2.0 * k - b4 * a2, 0.0, 1.0];
    let lo = (-half_chord).max(-t0 - tol) - margin;
    let roots = poly_roots_in(&quartic, lo, half_chord + margin);
    roots.into_iter().find_map(|s| {
        let hit = m + u * s;
        let t = t0 + s;
        (t >= -tol && hit.x >= -tol && hit.y >= -tol).then(|| t.max(0.0) / len)
    })
}
