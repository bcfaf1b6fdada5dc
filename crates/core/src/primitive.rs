//! [`Primitive`] = a [`Shape`] placed in the scene by a [`Pose`].

use nalgebra::{Point3, UnitQuaternion, Vector3};
use serde_json::{Value, json};

use crate::atlas::{MeshShape, Shape, ShapeKind, TriMesh};
use crate::{Error, Result};

/// A similarity transform from a shape's local frame to scene coordinates:
/// `x_scene = scale · R · x_local + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation `R` (JSON: unit quaternion `[w, x, y, z]`).
    pub rotation: UnitQuaternion<f64>,
    /// Translation, scene units.
    pub translation: Vector3<f64>,
    /// Uniform scale (dimensionless, > 0).
    pub scale: f64,
}

impl Default for Pose {
    fn default() -> Self {
        Pose::identity()
    }
}

impl Pose {
    /// The identity pose.
    pub fn identity() -> Self {
        Pose {
            rotation: UnitQuaternion::identity(),
            translation: Vector3::zeros(),
            scale: 1.0,
        }
    }
    /// A rotation and translation with unit scale.
    pub fn new(rotation: UnitQuaternion<f64>, translation: Vector3<f64>) -> Self {
        Pose {
            rotation,
            translation,
            scale: 1.0,
        }
    }
    /// Maps a local point to the scene.
    #[inline]
    pub fn to_scene(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.rotation * (p.coords * self.scale) + self.translation)
    }
    /// Maps a scene point to the local frame.
    #[inline]
    pub fn to_local(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(
            self.rotation
                .inverse_transform_vector(&(p.coords - self.translation))
                / self.scale,
        )
    }
    /// Composition `self ∘ other` (apply `other` first).
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * (other.translation * self.scale) + self.translation,
            scale: self.scale * other.scale,
        }
    }
    /// Parses DESIGN §3 pose JSON (`translation`, `rotation` `[w, x, y, z]`, optional
    /// `scale`, default 1). The quaternion is normalised; a zero one is an error.
    pub fn from_json(v: &Value) -> Result<Pose> {
        let t = numbers(v.get("translation"), 3, "pose.translation")?;
        let q = numbers(v.get("rotation"), 4, "pose.rotation")?;
        let quaternion = nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]);
        if !(quaternion.norm() > 1e-12) {
            return Err(Error::invalid(
                "pose.rotation must be a non-zero quaternion [w, x, y, z]",
            ));
        }
        let scale = match v.get("scale") {
            None | Some(Value::Null) => 1.0,
            Some(s) => s
                .as_f64()
                .filter(|s| s.is_finite() && *s > 0.0)
                .ok_or_else(|| {
                    Error::invalid(format!("pose.scale must be a positive number, got {s}"))
                })?,
        };
        Ok(Pose {
            rotation: UnitQuaternion::from_quaternion(quaternion),
            translation: Vector3::new(t[0], t[1], t[2]),
            scale,
        })
    }

    /// The pose as DESIGN §3 JSON.
    pub fn to_json(&self) -> Value {
        let q = self.rotation.quaternion();
        json!({
            "translation": [self.translation.x, self.translation.y, self.translation.z],
            "rotation": [q.w, q.i, q.j, q.k],
            "scale": self.scale,
        })
    }
}

/// A primitive: a shape and where it is.
#[derive(Debug, Clone)]
pub struct Primitive {
    /// The type with its sizes.
    pub shape: Shape,
    /// Local frame → scene.
    pub pose: Pose,
}

impl Primitive {
    /// A primitive of `shape` at `pose`.
    pub fn new(shape: Shape, pose: Pose) -> Self {
        Primitive { shape, pose }
    }
    /// Area-uniform samples with about `spacing` (scene units) between neighbours, in scene coordinates.
    pub fn sample_surface(&self, spacing: f64) -> Vec<Point3<f64>> {
        self.shape
            .sample_surface(spacing / self.pose.scale)
            .iter()
            .map(|p| self.pose.to_scene(p))
            .collect()
    }
    /// Euclidean distance from a scene point to the surface.
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        self.pose.scale * self.shape.distance(&self.pose.to_local(p))
    }
    /// Closest surface point to a scene point, in scene coordinates.
    pub fn closest_point(&self, p: &Point3<f64>) -> Point3<f64> {
        self.pose
            .to_scene(&self.shape.closest_point(&self.pose.to_local(p)))
    }
    /// Surface area in scene units².
    pub fn area(&self) -> f64 {
        self.shape.area() * self.pose.scale * self.pose.scale
    }
    /// Centre of the bounding ball, scene coordinates.
    pub fn center(&self) -> Point3<f64> {
        Point3::from(self.pose.translation)
    }
    /// Radius of a ball about [`Primitive::center`] containing the surface.
    pub fn bounding_radius(&self) -> f64 {
        self.shape.bounding_radius() * self.pose.scale
    }
    /// Export mesh in scene coordinates.
    pub fn triangulate(&self) -> TriMesh {
        let mut m = self.shape.triangulate();
        for v in &mut m.vertices {
            *v = self.pose.to_scene(v);
        }
        m
    }
    /// The number of free parameters (pose: 3 rotation + 3 translation + 1 scale, plus sizes).
    pub fn parameter_count(&self) -> usize {
        7 + self.shape.size_parameter_count()
    }
    /// Parses one DESIGN §3 primitive entry. `load_mesh` turns a mesh entry's `source`
    /// into its mesh (e.g. by reading the PLY file it names).
    pub fn from_json(
        v: &Value,
        load_mesh: &dyn Fn(&str) -> Result<MeshShape>,
    ) -> Result<Primitive> {
        let kind = v
            .get("type")
            .and_then(Value::as_str)
            .ok_or_else(|| Error::invalid("primitive entry without a \"type\" string"))?;
        let kind = ShapeKind::parse(kind)?;
        let size = v.get("size").cloned().unwrap_or(Value::Null);
        let get = |key: &str| -> Result<f64> {
            size.get(key)
                .and_then(Value::as_f64)
                .ok_or_else(|| Error::invalid(format!("{kind} entry needs a numeric size.{key}")))
        };
        let shape = match kind {
            ShapeKind::Square => Shape::Square { side: get("side")? },
            ShapeKind::Disk => Shape::Disk {
                diameter: get("diameter")?,
            },
            ShapeKind::Sphere => Shape::Sphere {
                diameter: get("diameter")?,
            },
            ShapeKind::Cylinder => Shape::Cylinder {
                length: get("length")?,
                radius: get("radius")?,
            },
            ShapeKind::Elbow => Shape::Elbow {
                bend: get("bend")?,
                radius: get("radius")?,
            },
            ShapeKind::Mesh => {
                let source = size.get("source").and_then(Value::as_str).ok_or_else(|| {
                    Error::invalid("mesh entry needs size.source naming its PLY file")
                })?;
                Shape::Mesh(load_mesh(source)?)
            }
        };
        shape.validate()?;
        let pose = Pose::from_json(v.get("pose").unwrap_or(&Value::Null))?;
        Ok(Primitive { shape, pose })
    }

    /// DESIGN §3 JSON entry (without `existence`, which the caller adds).
    pub fn to_json(&self) -> Value {
        json!({ "type": self.shape.kind().name(), "size": self.shape.sizes_json(), "pose": self.pose.to_json() })
    }
}

/// `n` finite numbers from a JSON array.
fn numbers(v: Option<&Value>, n: usize, what: &str) -> Result<Vec<f64>> {
    let arr = v
        .and_then(Value::as_array)
        .ok_or_else(|| Error::invalid(format!("{what} must be an array of {n} numbers")))?;
    let out: Vec<f64> = arr
        .iter()
        .filter_map(Value::as_f64)
        .filter(|x| x.is_finite())
        .collect();
    if arr.len() != n || out.len() != n {
        return Err(Error::invalid(format!(
            "{what} must be an array of {n} finite numbers"
        )));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_round_trip_of_every_analytic_type() {
        let pose = Pose {
            rotation: UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
            translation: Vector3::new(1.0, -2.0, 0.5),
            scale: 1.5,
        };
        for shape in [
            Shape::Square { side: 1.0 },
            Shape::Disk { diameter: 0.7 },
            Shape::Sphere { diameter: 0.3 },
            Shape::Cylinder {
                length: 2.0,
                radius: 0.1,
            },
            Shape::Elbow {
                bend: 0.5,
                radius: 0.1,
            },
        ] {
            let p = Primitive::new(shape, pose);
            let back = Primitive::from_json(&p.to_json(), &|_| unreachable!()).unwrap();
            let (a, b) = (back.to_json(), p.to_json());
            assert_eq!((&a["type"], &a["size"]), (&b["type"], &b["size"]));
            assert!(back.pose.rotation.angle_to(&p.pose.rotation) < 1e-12);
            assert_eq!(
                (back.pose.translation, back.pose.scale),
                (p.pose.translation, p.pose.scale)
            );
            let x = Point3::new(0.3, 0.2, -0.1);
            assert!((back.distance(&x) - p.distance(&x)).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_json_is_an_error_not_a_panic() {
        let load = |_: &str| Err(Error::invalid("no meshes here"));
        for bad in [
            json!({}),
            json!({"type": "cone"}),
            json!({"type": "square", "size": {"side": -1.0}, "pose": {"translation": [0,0,0], "rotation": [1,0,0,0]}}),
            json!({"type": "square", "size": {"side": 1.0}, "pose": {"translation": [0,0], "rotation": [1,0,0,0]}}),
            json!({"type": "square", "size": {"side": 1.0}, "pose": {"translation": [0,0,0], "rotation": [0,0,0,0]}}),
            json!({"type": "mesh", "size": {"source": "x.ply"}, "pose": {"translation": [0,0,0], "rotation": [1,0,0,0]}}),
        ] {
            assert!(Primitive::from_json(&bad, &load).is_err(), "{bad}");
        }
    }
}
