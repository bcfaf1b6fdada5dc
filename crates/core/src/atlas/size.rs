//! The continuous size parameters of a [`Shape`]: reading and replacing them as a list,
//! their bounds under a growth factor, and how a surface point moves when one of them
//! grows (used by the refinement's Levenberg–Marquardt fitter, `crate::refine`).
//!
//! Sizes are in the shape's local units (scene units before the pose's scale), in a fixed
//! order per type: square: side; disk, sphere: diameter; cylinder: length, radius;
//! elbow: bend, radius; a mesh and a plane have none (a plane's extent is its polygon,
//! fixed by the points it was traced from).

use nalgebra::{Point3, Vector3};

use super::Shape;

impl Shape {
    /// The continuous sizes of the shape (local units), in a fixed order (cylinder:
    /// length, radius; elbow: bend, radius); empty for meshes and planes.
    pub fn sizes(&self) -> Vec<f64> {
        match self {
            Shape::Square { side } => vec![*side],
            Shape::Disk { diameter } | Shape::Sphere { diameter } => vec![*diameter],
            Shape::Cylinder { length, radius } => vec![*length, *radius],
            Shape::Elbow { bend, radius } => vec![*bend, *radius],
            Shape::Mesh(_) | Shape::Plane(_) => Vec::new(),
        }
    }

    /// The shape with its sizes replaced by `s` (local units, same order as
    /// [`Shape::sizes`]); sizes missing from `s` keep their value. The result is not
    /// validated.
    pub fn with_sizes(&self, s: &[f64]) -> Shape {
        let get = |k: usize, old: f64| s.get(k).copied().unwrap_or(old);
        match self {
            Shape::Square { side } => Shape::Square {
                side: get(0, *side),
            },
            Shape::Disk { diameter } => Shape::Disk {
                diameter: get(0, *diameter),
            },
            Shape::Sphere { diameter } => Shape::Sphere {
                diameter: get(0, *diameter),
            },
            Shape::Cylinder { length, radius } => Shape::Cylinder {
                length: get(0, *length),
                radius: get(1, *radius),
            },
            Shape::Elbow { bend, radius } => Shape::Elbow {
                bend: get(0, *bend),
                radius: get(1, *radius),
            },
            Shape::Mesh(m) => Shape::Mesh(m.clone()),
            Shape::Plane(p) => Shape::Plane(p.clone()),
        }
    }

    /// `[s / g, s · g]` for each size `s` ([`Shape::sizes`], local units), `g` the maximum
    /// growth factor (≥ 1, dimensionless).
    pub fn size_limits(&self, growth: f64) -> Vec<(f64, f64)> {
        self.sizes()
            .iter()
            .map(|s| (s / growth, s * growth))
            .collect()
    }

    /// `∂x/∂η_k` (local frame, local units) of the surface point at local `x` for each size
    /// `s_k = e^{η_k}` ([`Shape::sizes`] order), at fixed normalised surface coordinates:
    /// square, disk, sphere: the local point itself; cylinder: its axial component for
    /// the length and its radial one for the radius; elbow: the centre-line point for the
    /// bend, the tube offset for the radius. Empty for meshes and planes.
    pub fn size_tangents(&self, x: &Point3<f64>) -> Vec<Vector3<f64>> {
        match self {
            Shape::Square { .. } | Shape::Disk { .. } | Shape::Sphere { .. } => vec![x.coords],
            Shape::Cylinder { .. } => {
                vec![Vector3::new(0.0, 0.0, x.z), Vector3::new(x.x, x.y, 0.0)]
            }
            Shape::Elbow { bend, .. } => {
                let phi = x.y.atan2(x.x).clamp(0.0, std::f64::consts::FRAC_PI_2);
                let centre = Vector3::new(phi.cos(), phi.sin(), 0.0) * *bend;
                vec![centre, x.coords - centre]
            }
            Shape::Mesh(_) | Shape::Plane(_) => Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn size_tangents_match_finite_differences() {
        let h: f64 = 1e-6;
        let shapes = [
            Shape::Square { side: 1.3 },
            Shape::Disk { diameter: 0.9 },
            Shape::Sphere { diameter: 0.7 },
            Shape::Cylinder {
                length: 1.2,
                radius: 0.2,
            },
            Shape::Elbow {
                bend: 0.6,
                radius: 0.15,
            },
        ];
        // A material point: the closest point of a probe, in normalised coordinates.
        let probe = Point3::new(0.21, 0.33, 0.17);
        for shape in shapes {
            let s0 = shape.sizes();
            let x0 = shape.closest_point(&probe);
            for (k, t) in shape.size_tangents(&x0).iter().enumerate() {
                // Scale the surface point along with size k: compare with the closest
                // point of a slightly larger shape to the moved probe.
                let mut s = s0.clone();
                s[k] *= h.exp();
                let bigger = shape.with_sizes(&s);
                let moved = x0 + t * h;
                let d = bigger.distance(&moved);
                assert!(
                    d < 1e-9,
                    "{shape:?} size {k}: moved point is {d} off the surface"
                );
            }
        }
    }
}
