//! Cylinder fitting of one segment: axis from the normals, centre and radius from an
//! algebraic circle fit, then Levenberg–Marquardt on the point-to-surface distances.
//!
//! 1. **Axis.** Every normal of a cylinder is perpendicular to its axis, so the axis is
//!    the direction least represented in the normals: the eigenvector of the smallest
//!    eigenvalue of `Σ n nᵀ` (the "normal sphere" / Gaussian image of the segment lies on
//!    a great circle whose pole is the axis).
//! 2. **Centre and radius.** The points projected on the plane perpendicular to the axis
//!    lie on a circle: Kåsa's algebraic fit (Kåsa 1976) solves the linear least squares
//!    `x² + y² + D x + E y + F ≈ 0`, centre `(−D/2, −E/2)`, radius `√(D²/4 + E²/4 − F)`.
//! 3. **Refinement.** LM over five parameters (two axis tilts, two axis offsets, the
//!    radius) on the geometric residuals `r_i = |(p_i − c) × a| − ρ`, which removes the
//!    Kåsa fit's bias towards small radii on partial arcs and corrects the axis.
//!
//! Jacobian in closed form: with `d = p − c`, `t = d · a`, `w = d − t a`, `e = w / |w|`,
//! a tilt `δa ⟂ a` changes `|w|` by `−t (e · δa)`, an offset `δc ⟂ a` by `−e · δc`, and
//! the radius by `−δρ`.

use nalgebra::{Matrix3, Point3, SMatrix, SVector, SymmetricEigen, Vector3};

/// At most this many points (evenly strided) enter the LM problem: a few thousand
/// residuals pin five parameters far below the noise.
const MAX_LM_POINTS: usize = 3000;

/// Most LM iterations.
const MAX_LM_ITERATIONS: usize = 50;

/// Damping of the first LM step, relative to the diagonal of `JᵀJ`.
const INITIAL_DAMPING: f64 = 1e-3;

/// Damping factor applied after a rejected (×) or accepted (÷) step.
const DAMPING_FACTOR: f64 = 4.0;

/// LM stops when a step lowers the cost by less than this fraction.
const MIN_RELATIVE_DECREASE: f64 = 1e-10;

/// 2-D points whose smaller principal spread is below this fraction of the larger
/// (squared) are collinear: no circle through them is determined.
const COLLINEAR: f64 = 1e-12;

/// A fitted cylinder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CylinderFit {
    /// The axis point at the middle of the points' axial extent.
    pub point: Point3<f64>,
    /// Unit axis direction (sign arbitrary).
    pub axis: Vector3<f64>,
    /// Radius (scene units).
    pub radius: f64,
    /// Axial extent of the points (scene units).
    pub length: f64,
    /// RMS distance of the points from the (infinite) cylinder surface (scene units).
    pub rms: f64,
}

impl CylinderFit {
    /// The perpendicular from the axis to `p` (scene units): its length is `p`'s distance
    /// from the axis, its direction the surface normal there.
    pub fn off_axis(&self, p: &Point3<f64>) -> Vector3<f64> {
        let d = p - self.point;
        d - self.axis * d.dot(&self.axis)
    }
}

/// Two unit vectors completing `a` (unit) to a right-handed orthonormal basis.
pub(crate) fn perpendicular_basis(a: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if a.x.abs() < 0.6 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = a.cross(&helper).normalize();
    (u, a.cross(&u))
}

/// The eigenvector of the smallest eigenvalue of `Σ n nᵀ` over `normals` (zero normals
/// add nothing), or `None` when there are no normals.
pub fn least_normal_direction(normals: &[Vector3<f64>]) -> Option<Vector3<f64>> {
    let m: Matrix3<f64> = normals.iter().map(|n| n * n.transpose()).sum();
    let eigen = SymmetricEigen::new(m);
    let (k, _) = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    eigen.eigenvectors.column(k).try_normalize(1e-300)
}

/// Kåsa's circle through 2-D points `(x, y)`: `(centre, radius)`, or `None` when the
/// points are collinear or too few.
pub fn kasa_circle(xy: &[(f64, f64)]) -> Option<((f64, f64), f64)> {
    if xy.len() < 3 {
        return None;
    }
    // Centre the data for conditioning; the fit is translation-equivariant.
    let n = xy.len() as f64;
    let (mx, my) = xy
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = Vector3::zeros();
    let scatter = xy
        .iter()
        .fold(nalgebra::Matrix2::<f64>::zeros(), |m, &(x, y)| {
            let d = nalgebra::Vector2::new(x - mx, y - my);
            m + d * d.transpose()
        });
    let spread = scatter.symmetric_eigenvalues();
    let spans_a_plane = spread.min() > COLLINEAR * spread.max();
    if !spans_a_plane {
        return None;
    }
    for &(x, y) in xy {
        let (x, y) = (x - mx, y - my);
        let row = Vector3::new(x, y, 1.0);
        ata += row * row.transpose();
        atb += row * -(x * x + y * y);
    }
    let sol = ata.cholesky()?.solve(&atb);
    let (cx, cy) = (-sol.x / 2.0, -sol.y / 2.0);
    let r2 = cx * cx + cy * cy - sol.z;
    (r2 > 0.0 && r2.is_finite()).then(|| ((cx + mx, cy + my), r2.sqrt()))
}

/// Fits a cylinder to `points` with their unit `normals` (same length), or `None` when
/// the initial estimates are degenerate.
pub fn fit_cylinder(points: &[Point3<f64>], normals: &[Vector3<f64>]) -> Option<CylinderFit> {
    if points.len() < 6 || points.len() != normals.len() {
        return None;
    }
    let axis = least_normal_direction(normals)?;
    let centroid =
        Point3::from(points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64);
    let (u, v) = perpendicular_basis(&axis);
    let xy: Vec<(f64, f64)> = points
        .iter()
        .map(|p| {
            let d = p - centroid;
            (d.dot(&u), d.dot(&v))
        })
        .collect();
    let ((cx, cy), radius) = kasa_circle(&xy)?;
    let start = Axis {
        point: centroid + u * cx + v * cy,
        dir: axis,
        radius,
    };
    let stride = points.len().div_ceil(MAX_LM_POINTS).max(1);
    let used: Vec<Point3<f64>> = points.iter().step_by(stride).copied().collect();
    let fitted = refine(&used, start);
    Some(fitted.finish(points))
}

/// Re-fits a cylinder from a known one (merging): LM from `start` on `points`.
pub fn refit_cylinder(points: &[Point3<f64>], start: &CylinderFit) -> Option<CylinderFit> {
    if points.len() < 6 {
        return None;
    }
    let stride = points.len().div_ceil(MAX_LM_POINTS).max(1);
    let used: Vec<Point3<f64>> = points.iter().step_by(stride).copied().collect();
    let axis = Axis {
        point: start.point,
        dir: start.axis,
        radius: start.radius,
    };
    Some(refine(&used, axis).finish(points))
}

/// An infinite cylinder: a point on the axis, the unit axis, the radius.
#[derive(Debug, Clone, Copy)]
struct Axis {
    point: Point3<f64>,
    dir: Vector3<f64>,
    radius: f64,
}

impl Axis {
    /// Signed distance of `p` from the surface (scene units).
    fn residual(&self, p: &Point3<f64>) -> f64 {
        let d = p - self.point;
        (d - self.dir * d.dot(&self.dir)).norm() - self.radius
    }

    /// Sum of squared residuals.
    fn cost(&self, points: &[Point3<f64>]) -> f64 {
        points.iter().map(|p| self.residual(p).powi(2)).sum()
    }

    /// The cylinder with the axial extent and RMS of `points`.
    fn finish(&self, points: &[Point3<f64>]) -> CylinderFit {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in points {
            let t = (p - self.point).dot(&self.dir);
            lo = lo.min(t);
            hi = hi.max(t);
        }
        let rms = (self.cost(points) / points.len().max(1) as f64).sqrt();
        CylinderFit {
            point: self.point + self.dir * ((lo + hi) / 2.0),
            axis: self.dir,
            radius: self.radius,
            length: (hi - lo).max(0.0),
            rms,
        }
    }

    /// `JᵀJ` and `Jᵀr` of the residuals at this cylinder (parameters: tilts along `u`,
    /// `v`, offsets along `u`, `v`, radius).
    fn normal_equations(&self, points: &[Point3<f64>]) -> (SMatrix<f64, 5, 5>, SVector<f64, 5>) {
        let (u, v) = perpendicular_basis(&self.dir);
        let mut jtj = SMatrix::<f64, 5, 5>::zeros();
        let mut jtr = SVector::<f64, 5>::zeros();
        for p in points {
            let d = p - self.point;
            let t = d.dot(&self.dir);
            let w = d - self.dir * t;
            let rho = w.norm();
            if rho <= f64::MIN_POSITIVE {
                continue;
            }
            let e = w / rho;
            let (eu, ev) = (e.dot(&u), e.dot(&v));
            let j = SVector::<f64, 5>::from([-t * eu, -t * ev, -eu, -ev, -1.0]);
            jtj += j * j.transpose();
            jtr += j * (rho - self.radius);
        }
        (jtj, jtr)
    }

    /// This cylinder moved by the parameter step `s`; the axis point is moved to the
    /// foot of `anchor` so the parameterisation stays centred.
    fn stepped(&self, s: &SVector<f64, 5>, anchor: &Point3<f64>) -> Axis {
        let (u, v) = perpendicular_basis(&self.dir);
        let dir = (self.dir + u * s[0] + v * s[1]).normalize();
        let point = self.point + u * s[2] + v * s[3];
        let point = point + dir * (anchor - point).dot(&dir);
        Axis {
            point,
            dir,
            radius: self.radius + s[4],
        }
    }
}

/// Levenberg–Marquardt on the geometric residuals from `start`.
fn refine(points: &[Point3<f64>], start: Axis) -> Axis {
    let anchor = Point3::from(
        points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len().max(1) as f64,
    );
    let mut cur = start;
    let mut cost = cur.cost(points);
    let mut lambda = INITIAL_DAMPING;
    for _ in 0..MAX_LM_ITERATIONS {
        let (jtj, jtr) = cur.normal_equations(points);
        let mut improved = false;
        for _ in 0..8 {
            let mut a = jtj;
            for k in 0..5 {
                a[(k, k)] += lambda * (jtj[(k, k)] + 1e-12);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&(-jtr))) else {
                lambda *= DAMPING_FACTOR;
                continue;
            };
            let next = cur.stepped(&step, &anchor);
            let next_cost = next.cost(points);
            if next_cost.is_finite() && next_cost < cost && next.radius > 0.0 {
                let decrease = (cost - next_cost) / cost.max(f64::MIN_POSITIVE);
                cur = next;
                cost = next_cost;
                lambda /= DAMPING_FACTOR;
                improved = decrease > MIN_RELATIVE_DECREASE;
                break;
            }
            lambda *= DAMPING_FACTOR;
        }
        if !improved {
            break;
        }
    }
    cur
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    #[test]
    fn kasa_recovers_a_circle() {
        let xy: Vec<(f64, f64)> = (0..50)
            .map(|i| {
                let t = i as f64 * 0.05;
                (3.0 + 2.0 * t.cos(), -1.0 + 2.0 * t.sin())
            })
            .collect();
        let ((cx, cy), r) = kasa_circle(&xy).unwrap();
        assert!((cx - 3.0).abs() < 1e-9 && (cy + 1.0).abs() < 1e-9 && (r - 2.0).abs() < 1e-9);
        assert!(kasa_circle(&[(0.0, 0.0), (1.0, 1.0), (2.0, 2.0)]).is_none());
    }

    #[test]
    fn a_noisy_half_cylinder_is_recovered() {
        let axis = Vector3::new(0.3, -0.2, 1.0).normalize();
        let (u, v) = perpendicular_basis(&axis);
        let centre = Point3::new(0.5, 0.2, 1.0);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (r, sigma) = (0.04, 0.001);
        let mut pts = Vec::new();
        let mut normals = Vec::new();
        for _ in 0..3000 {
            let phi: f64 = rng.random::<f64>() * std::f64::consts::PI;
            let h: f64 = rng.random::<f64>() * 0.12 - 0.06;
            let radial = u * phi.cos() + v * phi.sin();
            let noise: f64 = sigma * rng.sample::<f64, _>(StandardNormal);
            pts.push(centre + axis * h + radial * (r + noise));
            // Normals tilted by a few degrees, as a PCA would give.
            normals.push((radial + axis * 0.05 * (rng.random::<f64>() - 0.5)).normalize());
        }
        let fit = fit_cylinder(&pts, &normals).unwrap();
        assert!((fit.radius - r).abs() < 0.03 * r, "r = {}", fit.radius);
        assert!(
            fit.axis.dot(&axis).abs() > 2f64.to_radians().cos(),
            "{}",
            fit.axis
        );
        assert!((fit.rms - sigma).abs() < 0.2 * sigma, "rms = {}", fit.rms);
        assert!((fit.length - 0.12).abs() < 0.005);
        let d = fit.point - centre;
        assert!((d - axis * d.dot(&axis)).norm() < 0.002);
    }
}
