//! [`Primitive`] = a [`Shape`] placed in the scene by a [`Pose`]; what the fitter asks of
//! one (distance, closest point, samples, area, mesh, JSON) and where a ray first crosses
//! it ([`Primitive::first_hit`], a [`Hit`]).

use nalgebra::{Point3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::atlas::{MeshShape, PlaneShape, Shape, ShapeKind, TriMesh};
use crate::{Error, Result, check};

/// Relative slack of the height bound of [`Primitive::distance_within`] (dimensionless).
const HEIGHT_BOUND_SLACK: f64 = 1e-9;

/// A similarity transform from a shape's local frame to scene coordinates:
/// `x_scene = scale · R · x_local + translation`. Serde reads and writes it as DESIGN §3
/// JSON (see [`Pose::from_json`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(into = "PoseDoc", try_from = "PoseDoc")]
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
    /// The pose of `rotation` and `scale` that takes the local point `local` to the scene
    /// point `scene`: its translation is `scene − s·R·local` (scene units).
    pub fn anchored(
        rotation: UnitQuaternion<f64>,
        scale: f64,
        local: &Point3<f64>,
        scene: &Point3<f64>,
    ) -> Self {
        Pose {
            rotation,
            translation: scene.coords - rotation * (local.coords * scale),
            scale,
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
        let scale = match v.get("scale") {
            None | Some(Value::Null) => None,
            Some(s) => Some(
                s.as_f64()
                    .ok_or_else(|| Error::out_of_range("pose.scale", s, "a positive number"))?,
            ),
        };
        Pose::checked(PoseDoc {
            translation: [t[0], t[1], t[2]],
            rotation: [q[0], q[1], q[2], q[3]],
            scale,
        })
    }

    /// The pose of a parsed [`PoseDoc`]: the quaternion normalised (a zero one is an
    /// error), the scale positive (default 1).
    fn checked(doc: PoseDoc) -> Result<Pose> {
        let rotation = check::unit_quaternion("pose.rotation", doc.rotation)?;
        check::finite("pose.translation", &doc.translation)?;
        let scale = doc.scale.unwrap_or(1.0);
        if !(scale.is_finite() && scale > 0.0) {
            return Err(Error::out_of_range(
                "pose.scale",
                scale,
                "a positive number",
            ));
        }
        Ok(Pose {
            rotation,
            translation: Vector3::from(doc.translation),
            scale,
        })
    }

    /// The pose as DESIGN §3 JSON.
    pub fn to_json(&self) -> Value {
        serde_json::to_value(self).unwrap_or(Value::Null)
    }
}

/// DESIGN §3 pose JSON: `translation` `[x, y, z]`, `rotation` `[w, x, y, z]`, `scale`
/// (read as 1 when absent or null).
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
struct PoseDoc {
    translation: [f64; 3],
    rotation: [f64; 4],
    #[serde(default)]
    scale: Option<f64>,
}

impl From<Pose> for PoseDoc {
    fn from(p: Pose) -> Self {
        let q = p.rotation.quaternion();
        PoseDoc {
            translation: p.translation.into(),
            rotation: [q.w, q.i, q.j, q.k],
            scale: Some(p.scale),
        }
    }
}

impl TryFrom<PoseDoc> for Pose {
    type Error = Error;
    fn try_from(doc: PoseDoc) -> Result<Pose> {
        Pose::checked(doc)
    }
}

/// The first crossing of a ray with a primitive ([`Primitive::first_hit`]).
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
    /// [`Primitive::distance`], or `None` when it is certainly more than `bound` (scene
    /// units): a flat shape (square, disk, plane) lies in its local plane `z = 0`, so no
    /// point of it is nearer than the point's height over that plane, which rules most
    /// of them out before their outline is searched.
    pub fn distance_within(&self, p: &Point3<f64>, bound: f64) -> Option<f64> {
        let local = self.pose.to_local(p);
        let flat = matches!(
            self.shape,
            Shape::Square { .. } | Shape::Disk { .. } | Shape::Plane(_)
        );
        // The height, shrunk by far more than its rounding, stays below the distance
        // computed from the same local point.
        if flat && self.pose.scale * local.z.abs() * (1.0 - HEIGHT_BOUND_SLACK) > bound {
            return None;
        }
        Some(self.pose.scale * self.shape.distance(&local))
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
    /// The first crossing of the ray `origin + t·dir` (`dir` a unit vector, scene frame,
    /// `t ≥ 0`) with this primitive, or `None` when it misses. Non-finite input gives `None`.
    ///
    /// The ray measurement model (thesis §4.2.1, assumption 1) lets a primitive generate
    /// **one** point per ray, around its first crossing, so only the first crossing at
    /// depth `t ≥ 0` is needed; [`Shape::ray_intersect`] gives it for every atlas type.
    /// The normal sets the projected deviation `s = σ / |cos θ|`
    /// ([`crate::ray::RayModel::projected_sigma`]).
    ///
    /// ```
    /// use primfit_core::na::{Point3, UnitQuaternion, Vector3};
    /// use primfit_core::{Pose, Primitive, Shape};
    ///
    /// // A sphere of radius 1 five metres along x, seen from the origin.
    /// let at = Pose::new(UnitQuaternion::identity(), Vector3::new(5.0, 0.0, 0.0));
    /// let sphere = Primitive::new(Shape::Sphere { diameter: 2.0 }, at);
    /// let hit = sphere.first_hit(&Point3::origin(), &Vector3::x()).unwrap();
    /// assert!((hit.depth - 4.0).abs() < 1e-12);
    /// assert!((hit.normal + Vector3::x()).norm() < 1e-12); // facing the ray
    /// assert!(sphere.first_hit(&Point3::origin(), &Vector3::y()).is_none());
    /// ```
    pub fn first_hit(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Hit> {
        let local_origin = self.pose.to_local(origin);
        // Dividing by the scale keeps `t` in scene units: o + t·d ↦ o_l + t·(Rᵀ d / scale).
        let local_dir = self.pose.rotation.inverse_transform_vector(dir) / self.pose.scale;
        let depth = self.shape.ray_intersect(&local_origin, &local_dir)?;
        if !depth.is_finite() {
            return None;
        }
        let p = local_origin + local_dir * depth;
        let n_local = local_normal(&self.shape, &p, &local_dir)
            .try_normalize(1e-300)
            .unwrap_or_else(|| -local_dir.normalize());
        let mut normal = self.pose.rotation * n_local;
        if normal.dot(dir) > 0.0 {
            normal = -normal;
        }
        Some(Hit { depth, normal })
    }
    /// Parses one DESIGN §3 primitive entry. `load_mesh` turns a mesh entry's `source`
    /// into its mesh (e.g. by reading the PLY file it names). A `plane` entry carries its
    /// polygon beside `size` and `pose`: `"outline": [[x, y], …]` and optionally
    /// `"holes": [[[x, y], …], …]`, in its local frame (its `size` is ignored), and, for
    /// a plane of several disjoint parts, `"more_parts": [{"outline": …, "holes": …}, …]`
    /// beside its largest part.
    pub fn from_json(
        v: &Value,
        load_mesh: &dyn Fn(&str) -> Result<MeshShape>,
    ) -> Result<Primitive> {
        let kind = v
            .get("type")
            .and_then(Value::as_str)
            .ok_or_else(|| Error::json("type", "a string naming the primitive type"))?;
        let kind = ShapeKind::parse(kind)?;
        let size = v.get("size").cloned().unwrap_or(Value::Null);
        let get = |key: &str| -> Result<f64> {
            size.get(key)
                .and_then(Value::as_f64)
                .ok_or_else(|| Error::json(format!("size.{key}"), format!("a number (a {kind})")))
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
                let source = size
                    .get("source")
                    .and_then(Value::as_str)
                    .ok_or_else(|| Error::json("size.source", "the name of the mesh's PLY file"))?;
                Shape::Mesh(load_mesh(source)?)
            }
            ShapeKind::Plane => Shape::Plane(PlaneShape::from_rings_json(
                v.get("outline"),
                v.get("holes"),
                v.get("more_parts"),
            )?),
        };
        shape.validate()?;
        let pose = Pose::from_json(v.get("pose").unwrap_or(&Value::Null))?;
        Ok(Primitive { shape, pose })
    }

    /// DESIGN §3 JSON entry (without `existence`, which the caller adds); a plane adds
    /// its `outline` and `holes` (local frame, see [`Primitive::from_json`]).
    pub fn to_json(&self) -> Value {
        serde_json::to_value(self).unwrap_or(Value::Null)
    }
}

impl Serialize for Primitive {
    /// The DESIGN §3 entry: `type`, `size` (the shape's sizes), `pose`, and for a plane
    /// its `outline` and `holes`. Reading one back needs a mesh loader:
    /// [`Primitive::from_json`].
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct Entry<'a> {
            #[serde(rename = "type")]
            kind: &'static str,
            size: Value,
            pose: &'a Pose,
            #[serde(skip_serializing_if = "Option::is_none")]
            outline: Option<Value>,
            #[serde(skip_serializing_if = "Option::is_none")]
            holes: Option<Value>,
            #[serde(skip_serializing_if = "Option::is_none")]
            more_parts: Option<Value>,
        }
        let (outline, holes, more_parts) = match &self.shape {
            Shape::Plane(p) => {
                let (outline, holes, more) = p.rings_json();
                (Some(outline), Some(holes), more)
            }
            _ => (None, None, None),
        };
        Entry {
            kind: self.shape.kind().name(),
            size: self.shape.sizes_json(),
            pose: &self.pose,
            outline,
            holes,
            more_parts,
        }
        .serialize(s)
    }
}

/// `n` finite numbers from a JSON array.
fn numbers(v: Option<&Value>, n: usize, what: &str) -> Result<Vec<f64>> {
    let arr = v
        .and_then(Value::as_array)
        .ok_or_else(|| Error::json(what, format!("an array of {n} numbers")))?;
    let out: Vec<f64> = arr
        .iter()
        .filter_map(Value::as_f64)
        .filter(|x| x.is_finite())
        .collect();
    if arr.len() != n || out.len() != n {
        return Err(Error::json(what, format!("an array of {n} finite numbers")));
    }
    Ok(out)
}

/// An (unnormalised) normal of `shape` at its surface point `p` (local frame), for a ray
/// along `dir` (local frame).
fn local_normal(shape: &Shape, p: &Point3<f64>, dir: &Vector3<f64>) -> Vector3<f64> {
    match shape {
        Shape::Disk { .. } | Shape::Square { .. } | Shape::Plane(_) => Vector3::z(),
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
mod tests;
