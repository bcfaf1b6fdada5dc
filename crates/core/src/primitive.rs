//! [`Primitive`] = a [`Shape`] placed in the scene by a [`Pose`].

use nalgebra::{Point3, UnitQuaternion, Vector3};
use serde_json::{Value, json};

use crate::atlas::{Shape, TriMesh};

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
        Pose { rotation: UnitQuaternion::identity(), translation: Vector3::zeros(), scale: 1.0 }
    }
    /// A rotation and translation with unit scale.
    pub fn new(rotation: UnitQuaternion<f64>, translation: Vector3<f64>) -> Self {
        Pose { rotation, translation, scale: 1.0 }
    }
    /// Maps a local point to the scene.
    #[inline]
    pub fn to_scene(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.rotation * (p.coords * self.scale) + self.translation)
    }
    /// Maps a scene point to the local frame.
    #[inline]
    pub fn to_local(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.rotation.inverse_transform_vector(&(p.coords - self.translation)) / self.scale)
    }
    /// Composition `self ∘ other` (apply `other` first).
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * (other.translation * self.scale) + self.translation,
            scale: self.scale * other.scale,
        }
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
        self.pose.to_scene(&self.shape.closest_point(&self.pose.to_local(p)))
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
    /// DESIGN §3 JSON entry (without `existence`, which the caller adds).
    pub fn to_json(&self) -> Value {
        json!({ "type": self.shape.kind().name(), "size": self.shape.sizes_json(), "pose": self.pose.to_json() })
    }
}
