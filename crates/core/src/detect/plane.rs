//! Least-squares planes from point moments: the count, the sum and the sum of outer
//! products of a point set are enough to fit its plane (PCA: the normal is the
//! eigenvector of the smallest eigenvalue of the covariance, the plane passes through the
//! centroid) and to give the RMS distance of the set from **any** plane. Moments of a
//! union are the sums of the parts' moments, so merging tests cost O(1)
//! ([`super::merge`]).

use std::ops::AddAssign;

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

/// Zeroth, first and second moments of a point set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moments {
    /// Number of points.
    pub count: f64,
    /// `Σ p` (scene units).
    pub sum: Vector3<f64>,
    /// `Σ (p − o)(p − o)ᵀ` about the reference `o` (scene units²).
    pub outer: Matrix3<f64>,
    /// The reference point `o` the second moments are taken about (the first point
    /// added): keeps the sums well conditioned far from the origin.
    pub origin: Vector3<f64>,
}

impl Default for Moments {
    fn default() -> Self {
        Moments {
            count: 0.0,
            sum: Vector3::zeros(),
            outer: Matrix3::zeros(),
            origin: Vector3::zeros(),
        }
    }
}

/// A fitted plane: `n · (x − point) = 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneFit {
    /// The centroid of the points (on the plane).
    pub point: Point3<f64>,
    /// Unit normal, sign arbitrary.
    pub normal: Vector3<f64>,
    /// RMS distance of the points from the plane (scene units).
    pub rms: f64,
}

impl Moments {
    /// The moments of `points[i]` for every `i` of `ids`.
    pub fn of(points: &[Point3<f64>], ids: &[usize]) -> Self {
        let mut m = Moments {
            origin: ids.first().map_or(Vector3::zeros(), |&i| points[i].coords),
            ..Default::default()
        };
        for &i in ids {
            m.add(&points[i]);
        }
        m
    }

    /// Adds one point.
    pub fn add(&mut self, p: &Point3<f64>) {
        if self.count == 0.0 {
            self.origin = p.coords;
        }
        let d = p.coords - self.origin;
        self.count += 1.0;
        self.sum += p.coords;
        self.outer += d * d.transpose();
    }

    /// The centroid (`None` for no points).
    pub fn centroid(&self) -> Option<Point3<f64>> {
        (self.count > 0.0).then(|| Point3::from(self.sum / self.count))
    }

    /// `Σ (p − c)(p − c)ᵀ` about the centroid `c` (scene units²).
    fn scatter(&self) -> Matrix3<f64> {
        let mean = self.sum / self.count - self.origin;
        self.outer - mean * mean.transpose() * self.count
    }

    /// The least-squares plane, or `None` for fewer than three points or a degenerate
    /// (collinear) set.
    pub fn plane(&self) -> Option<PlaneFit> {
        if self.count < 3.0 {
            return None;
        }
        let eigen = SymmetricEigen::new(self.scatter());
        let (k, lambda) = eigen
            .eigenvalues
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))?;
        let normal = eigen.eigenvectors.column(k).try_normalize(1e-300)?;
        let rms = (lambda.max(0.0) / self.count).sqrt();
        Some(PlaneFit {
            point: self.centroid()?,
            normal,
            rms,
        })
    }

    /// RMS distance of the points from the plane through `point` with unit normal
    /// `normal` (scene units; 0 for no points).
    pub fn rms_about(&self, point: &Point3<f64>, normal: &Vector3<f64>) -> f64 {
        if self.count <= 0.0 {
            return 0.0;
        }
        let offset = (self.sum / self.count - point.coords).dot(normal);
        let spread = normal.dot(&(self.scatter() * normal)).max(0.0) / self.count;
        (spread + offset * offset).sqrt()
    }
}

impl AddAssign<&Moments> for Moments {
    fn add_assign(&mut self, other: &Moments) {
        if other.count == 0.0 {
            return;
        }
        if self.count == 0.0 {
            *self = *other;
            return;
        }
        // Move `other`'s second moments to this reference: Σ(p−o)(p−o)ᵀ with
        // p − o = (p − o') + (o' − o).
        let shift = other.origin - self.origin;
        let rel = other.sum - other.origin * other.count;
        self.outer += other.outer
            + rel * shift.transpose()
            + shift * rel.transpose()
            + shift * shift.transpose() * other.count;
        self.count += other.count;
        self.sum += other.sum;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moments_of_a_union_fit_the_union() {
        let n = Vector3::new(1.0, 2.0, 2.0) / 3.0;
        let u = n.cross(&Vector3::x()).normalize();
        let v = n.cross(&u);
        let at = |a: f64, b: f64, h: f64| {
            Point3::from(Vector3::new(5.0, -3.0, 100.0) + u * a + v * b + n * h)
        };
        let pts: Vec<Point3<f64>> = (0..400)
            .map(|i| {
                at(
                    (i % 20) as f64 * 0.1,
                    (i / 20) as f64 * 0.1,
                    if (i + i / 20) % 2 == 0 { 0.01 } else { -0.01 },
                )
            })
            .collect();
        let all: Vec<usize> = (0..400).collect();
        let whole = Moments::of(&pts, &all);
        let mut parts = Moments::of(&pts, &all[..150]);
        parts += &Moments::of(&pts, &all[150..]);
        let (a, b) = (whole.plane().unwrap(), parts.plane().unwrap());
        assert!(a.normal.dot(&n).abs() > 1.0 - 1e-9 && b.normal.dot(&n).abs() > 1.0 - 1e-9);
        assert!(
            (a.rms - 0.01).abs() < 1e-9 && (b.rms - 0.01).abs() < 1e-9,
            "{} {}",
            a.rms,
            b.rms
        );
        // RMS about a plane shifted by 0.02 along n: √(0.01² + 0.02²).
        let shifted = a.point + n * 0.02;
        assert!((whole.rms_about(&shifted, &n) - 0.0005f64.sqrt()).abs() < 1e-9);
        assert!(Moments::of(&pts, &all[..2]).plane().is_none());
    }
}
