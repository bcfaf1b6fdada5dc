//! Sphere fitting of one segment: an algebraic fit, then Gauss–Newton (damped) on the
//! point-to-surface distances.
//!
//! The algebraic fit solves the linear least squares `|p|² = 2 c · p + k` for the centre
//! `c` and `k = ρ² − |c|²` (the sphere analogue of Kåsa's circle fit); the refinement
//! minimises `Σ (|p_i − c| − ρ)²` with `∂r_i/∂c = −(p_i − c)/|p_i − c|`, `∂r_i/∂ρ = −1`.

use nalgebra::{Matrix4, Point3, Vector3, Vector4};

/// At most this many points (evenly strided) enter the fit.
const MAX_FIT_POINTS: usize = 3000;

/// Most refinement iterations.
const MAX_ITERATIONS: usize = 30;

/// Damping of the refinement steps, relative to the diagonal of `JᵀJ`.
const DAMPING: f64 = 1e-6;

/// Steps shorter than this fraction of the radius end the refinement.
const MIN_RELATIVE_STEP: f64 = 1e-10;

/// A fitted sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereFit {
    /// Centre (scene coordinates).
    pub centre: Point3<f64>,
    /// Radius (scene units).
    pub radius: f64,
    /// RMS distance of the points from the sphere (scene units).
    pub rms: f64,
}

/// Fits a sphere to `points`, or `None` for fewer than four points or a degenerate
/// (coplanar) set.
pub fn fit_sphere(points: &[Point3<f64>]) -> Option<SphereFit> {
    if points.len() < 4 {
        return None;
    }
    let stride = points.len().div_ceil(MAX_FIT_POINTS).max(1);
    let used: Vec<Point3<f64>> = points.iter().step_by(stride).copied().collect();
    let mean = used.iter().map(|p| p.coords).sum::<Vector3<f64>>() / used.len() as f64;
    let mut ata = Matrix4::<f64>::zeros();
    let mut atb = Vector4::zeros();
    for p in &used {
        let d = p.coords - mean;
        let row = Vector4::new(2.0 * d.x, 2.0 * d.y, 2.0 * d.z, 1.0);
        ata += row * row.transpose();
        atb += row * d.norm_squared();
    }
    let sol = ata.cholesky()?.solve(&atb);
    let mut centre = Vector3::new(sol.x, sol.y, sol.z);
    let r2 = sol.w + centre.norm_squared();
    if !(r2 > 0.0 && r2.is_finite()) {
        return None;
    }
    let mut radius = r2.sqrt();
    centre += mean;
    for _ in 0..MAX_ITERATIONS {
        let mut jtj = Matrix4::<f64>::zeros();
        let mut jtr = Vector4::zeros();
        for p in &used {
            let d = p.coords - centre;
            let n = d.norm();
            if n <= f64::MIN_POSITIVE {
                continue;
            }
            let j = Vector4::new(-d.x / n, -d.y / n, -d.z / n, -1.0);
            jtj += j * j.transpose();
            jtr += j * (n - radius);
        }
        for k in 0..4 {
            jtj[(k, k)] *= 1.0 + DAMPING;
        }
        let step = jtj.cholesky()?.solve(&(-jtr));
        centre += step.xyz();
        radius += step.w;
        if step.norm() < MIN_RELATIVE_STEP * radius.abs() {
            break;
        }
    }
    if !(radius > 0.0 && radius.is_finite()) {
        return None;
    }
    let centre = Point3::from(centre);
    let ss: f64 = points
        .iter()
        .map(|p| ((p - centre).norm() - radius).powi(2))
        .sum();
    Some(SphereFit {
        centre,
        radius,
        rms: (ss / points.len() as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cap_of_a_sphere_is_recovered() {
        let c = Point3::new(1.0, -2.0, 0.5);
        let pts: Vec<Point3<f64>> = (0..40)
            .flat_map(|i| (0..40).map(move |j| (i, j)))
            .map(|(i, j)| {
                let (theta, phi) = (i as f64 * 0.03, j as f64 * 0.157);
                let s = if (i + j) % 2 == 0 { 0.001 } else { -0.001 };
                c + Vector3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ) * (0.3 + s)
            })
            .collect();
        let fit = fit_sphere(&pts).unwrap();
        assert!((fit.centre - c).norm() < 1e-3, "{}", fit.centre);
        assert!((fit.radius - 0.3).abs() < 1e-3 && fit.rms < 1.5e-3);
    }
}
