//! [`SurfaceModel`]: the surface a segment is explained by (plane, cylinder, sphere), its
//! point distances, and the [`Primitive`] of a bounded one.

use nalgebra::{Point3, UnitQuaternion, Vector3};

use crate::{Pose, Primitive, Shape};

/// The surface that explains a segment. Lengths in scene units; directions are unit
/// vectors with arbitrary sign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SurfaceModel {
    /// The infinite plane `normal · (x − point) = 0`; `point` is the centroid of the
    /// segment's points.
    Plane {
        /// A point of the plane (the segment's centroid).
        point: Point3<f64>,
        /// Unit normal.
        normal: Vector3<f64>,
    },
    /// A cylinder of `radius` around the axis through `point` along `axis`, bounded to
    /// the axial extent of its points: `point` is the axial midpoint, `length` the extent.
    Cylinder {
        /// The axis point at the middle of the points' axial extent.
        point: Point3<f64>,
        /// Unit axis direction.
        axis: Vector3<f64>,
        /// Radius (scene units).
        radius: f64,
        /// Axial extent of the points (scene units).
        length: f64,
    },
    /// A sphere.
    Sphere {
        /// Centre.
        centre: Point3<f64>,
        /// Radius (scene units).
        radius: f64,
    },
}

impl SurfaceModel {
    /// The model's type name (`plane`, `cylinder`, `sphere`).
    pub fn name(&self) -> &'static str {
        match self {
            SurfaceModel::Plane { .. } => "plane",
            SurfaceModel::Cylinder { .. } => "cylinder",
            SurfaceModel::Sphere { .. } => "sphere",
        }
    }

    /// Distance from `p` to the **unbounded** surface (the plane, the infinite
    /// cylinder, the sphere), scene units.
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        match self {
            SurfaceModel::Plane { point, normal } => (p - point).dot(normal).abs(),
            SurfaceModel::Cylinder {
                point,
                axis,
                radius,
                ..
            } => {
                let d = p - point;
                ((d - axis * d.dot(axis)).norm() - radius).abs()
            }
            SurfaceModel::Sphere { centre, radius } => ((p - centre).norm() - radius).abs(),
        }
    }

    /// The bounded primitive of a cylinder or sphere model: `Shape::Cylinder { length,
    /// radius }` at the pose whose local z axis is the cylinder's axis and whose origin is
    /// the axial midpoint; `Shape::Sphere { diameter }` at the centre. `None` for a
    /// plane (its bounded primitive needs the extent of its points) and for a degenerate
    /// size (length or radius not positive and finite).
    pub fn to_primitive(&self) -> Option<Primitive> {
        match *self {
            SurfaceModel::Plane { .. } => None,
            SurfaceModel::Cylinder {
                point,
                axis,
                radius,
                length,
            } => {
                let ok = |v: f64| v.is_finite() && v > 0.0;
                if !(ok(radius) && ok(length)) {
                    return None;
                }
                let shape = Shape::Cylinder { length, radius };
                Some(Primitive::new(shape, Pose::new(z_to(&axis), point.coords)))
            }
            SurfaceModel::Sphere { centre, radius } => {
                if !(radius.is_finite() && radius > 0.0) {
                    return None;
                }
                let shape = Shape::Sphere {
                    diameter: 2.0 * radius,
                };
                Some(Primitive::new(
                    shape,
                    Pose::new(UnitQuaternion::identity(), centre.coords),
                ))
            }
        }
    }
}

/// A rotation taking the local z axis onto the unit vector `axis` (a half turn about x
/// when `axis` is −z).
pub fn z_to(axis: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::z(), axis).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cylinder_primitive_matches_the_model() {
        for axis in [
            Vector3::new(0.3, -0.5, 0.8).normalize(),
            -Vector3::z(),
            Vector3::z(),
        ] {
            let model = SurfaceModel::Cylinder {
                point: Point3::new(1.0, 2.0, 3.0),
                axis,
                radius: 0.04,
                length: 0.1,
            };
            let prim = model.to_primitive().unwrap();
            assert!((prim.pose.rotation * Vector3::z() - axis).norm() < 1e-12);
            // A point on the surface in the middle is at distance 0 from both.
            let (u, _) = super::super::cylinder::perpendicular_basis(&axis);
            let on = Point3::new(1.0, 2.0, 3.0) + u * 0.04 + axis * 0.02;
            assert!(prim.distance(&on) < 1e-12 && model.distance(&on) < 1e-12);
            // Past the end: the bounded primitive is farther than the infinite surface.
            let past = on + axis * 0.1;
            assert!(prim.distance(&past) > 0.04 && model.distance(&past) < 1e-12);
        }
        let plane = SurfaceModel::Plane {
            point: Point3::origin(),
            normal: Vector3::z(),
        };
        assert!(plane.to_primitive().is_none());
        assert_eq!(plane.distance(&Point3::new(4.0, 1.0, -0.5)), 0.5);
    }
}
