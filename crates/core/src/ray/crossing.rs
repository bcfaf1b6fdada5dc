//! Where a ray first crosses a placed primitive, and the surface normal there.
//!
//! The measurement model (thesis §4.2.1, assumption 1) lets a primitive generate **one**
//! point per ray, around its first crossing, so only the first crossing at depth `t ≥ 0`
//! is needed; [`crate::Shape::ray_intersect`] gives it for every atlas type. The normal
//! sets the projected deviation `s = σ / |cos θ|` ([`super::RayModel::projected_sigma`]).

use nalgebra::{Point3, Vector3};

use crate::Primitive;
use crate::atlas::Shape;

/// The first crossing of a ray with a primitive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance from the ray origin to the crossing (scene units, ≥ 0).
    pub depth: f64,
    /// Unit surface normal at the crossing (scene frame), oriented against the ray
    /// (`normal · dir ≤ 0`).
    pub normal: Vector3<f64>,
}

impl Hit {
    /// `|cos θ|` between the ray and the surface normal, in `[0, 1]`.
    pub fn incidence(&self, dir: &Vector3<f64>) -> f64 {
        self.normal.dot(dir).abs().min(1.0)
    }
}

/// The first crossing of the ray `origin + t·dir` (`dir` a unit vector, scene frame,
/// `t ≥ 0`) with `prim`, or `None` when it misses. Non-finite input gives `None`.
pub fn first_hit(prim: &Primitive, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Hit> {
    let local_origin = prim.pose.to_local(origin);
    // Dividing by the scale keeps `t` in scene units: o + t·d ↦ o_l + t·(Rᵀ d / scale).
    let local_dir = prim.pose.rotation.inverse_transform_vector(dir) / prim.pose.scale;
    let depth = prim.shape.ray_intersect(&local_origin, &local_dir)?;
    if !depth.is_finite() {
        return None;
    }
    let p = local_origin + local_dir * depth;
    let n_local = local_normal(&prim.shape, &p, &local_dir)
        .try_normalize(1e-300)
        .unwrap_or_else(|| -local_dir.normalize());
    let mut normal = prim.pose.rotation * n_local;
    if normal.dot(dir) > 0.0 {
        normal = -normal;
    }
    Some(Hit { depth, normal })
}

/// An (unnormalised) normal of `shape` at its surface point `p` (local frame).
fn local_normal(shape: &Shape, p: &Point3<f64>, dir: &Vector3<f64>) -> Vector3<f64> {
    match shape {
        Shape::Disk { .. } | Shape::Square { .. } => Vector3::z(),
        Shape::Cylinder { .. } => Vector3::new(p.x, p.y, 0.0),
        Shape::Sphere { .. } => p.coords,
        Shape::Elbow { bend, .. } => {
            let rho = p.x.hypot(p.y);
            if rho == 0.0 {
                return Vector3::z();
            }
            // Minus the nearest point of the centre-line circle of radius `bend`.
            p.coords - Vector3::new(p.x, p.y, 0.0) * (bend / rho)
        }
        Shape::Mesh(_) => mesh_normal(shape, p, dir),
    }
}

/// A mesh's normal at `p` from the closest point of a point just in front of it on the ray.
fn mesh_normal(shape: &Shape, p: &Point3<f64>, dir: &Vector3<f64>) -> Vector3<f64> {
    let eps = 1e-6 * shape.bounding_radius().max(1e-3);
    let q = p - dir.normalize() * eps;
    q - shape.closest_point(&q)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Pose;
    use nalgebra::UnitQuaternion;

    #[test]
    fn hits_and_normals_of_every_analytic_type() {
        let x = Vector3::x();
        let o = Point3::origin();
        let at = |shape: Shape, rot: UnitQuaternion<f64>| {
            Primitive::new(shape, Pose::new(rot, Vector3::new(5.0, 0.0, 0.0)))
        };
        let facing =
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2);
        let square = first_hit(&at(Shape::Square { side: 1.0 }, facing), &o, &x).unwrap();
        assert!((square.depth - 5.0).abs() < 1e-12);
        assert!((square.normal + x).norm() < 1e-12);
        let cyl = Shape::Cylinder {
            length: 1.0,
            radius: 0.5,
        };
        let h = first_hit(&at(cyl, UnitQuaternion::identity()), &o, &x).unwrap();
        assert!((h.depth - 4.5).abs() < 1e-12 && (h.normal + x).norm() < 1e-12);
        let sph = first_hit(
            &at(Shape::Sphere { diameter: 2.0 }, UnitQuaternion::identity()),
            &o,
            &x,
        )
        .unwrap();
        assert!((sph.depth - 4.0).abs() < 1e-12 && (sph.normal + x).norm() < 1e-12);
        // From the torus centre (5, 0, 0) along the bisector of the quarter: the inner wall
        // at bend − radius, normal pointing back to the centre.
        let elbow = Shape::Elbow {
            bend: 1.0,
            radius: 0.2,
        };
        let d = Vector3::new(1.0, 1.0, 0.0).normalize();
        let c = Point3::new(5.0, 0.0, 0.0);
        let h = first_hit(&at(elbow, UnitQuaternion::identity()), &c, &d).unwrap();
        assert!((h.depth - 0.8).abs() < 1e-9, "{}", h.depth);
        assert!((h.normal + d).norm() < 1e-9);
        // Oblique incidence on a square: |cos| = cos 60°.
        let tilted = first_hit(
            &at(Shape::Square { side: 20.0 }, facing),
            &o,
            &Vector3::new(0.5, 0.75f64.sqrt(), 0.0),
        )
        .unwrap();
        assert!((tilted.incidence(&Vector3::new(0.5, 0.75f64.sqrt(), 0.0)) - 0.5).abs() < 1e-12);
        assert!((tilted.depth - 10.0).abs() < 1e-9);
    }

    #[test]
    fn scaled_poses_keep_depth_in_scene_units_and_misses_are_none() {
        let mut pose = Pose::new(UnitQuaternion::identity(), Vector3::new(5.0, 0.0, 0.0));
        pose.scale = 2.0;
        let sphere = Primitive::new(Shape::Sphere { diameter: 1.0 }, pose);
        let h = first_hit(&sphere, &Point3::origin(), &Vector3::x()).unwrap();
        assert!((h.depth - 4.0).abs() < 1e-12);
        assert!(first_hit(&sphere, &Point3::origin(), &Vector3::y()).is_none());
        assert!(first_hit(&sphere, &Point3::new(f64::NAN, 0.0, 0.0), &Vector3::x()).is_none());
    }
}
