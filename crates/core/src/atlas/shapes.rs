//! The [`Shape`] enum and its geometry. See the module docs of [`crate::atlas`] for the
//! local-frame conventions.

use std::f64::consts::TAU;

use nalgebra::{Point3, Vector3};
use serde_json::{Map, Value};

use super::elbow::{elbow_closest, elbow_mesh, elbow_ray, elbow_sample};
use super::mesh::no_faces_with_area;
use super::planar::{disk_closest, disk_mesh, disk_ray, disk_sample};
use super::planar::{square_closest, square_mesh, square_ray, square_sample};
use super::sphere::{sphere_closest, sphere_mesh, sphere_ray, sphere_sample};
use super::tube::{cylinder_closest, cylinder_mesh, cylinder_ray, cylinder_sample};
use super::{MeshShape, PlaneShape, TriMesh};
use crate::{Error, Result, check};

/// The name of a primitive type, as used on the command line and in JSON.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ShapeKind {
    /// Flat round patch.
    Disk,
    /// Flat square patch.
    Square,
    /// Open tube segment.
    Cylinder,
    /// Quarter-torus pipe bend.
    Elbow,
    /// Sphere.
    Sphere,
    /// Arbitrary triangle mesh.
    Mesh,
    /// Bounded planar polygon (outline and holes from the points it explains).
    Plane,
}

impl ShapeKind {
    /// All kinds, in a fixed order.
    pub const ALL: [ShapeKind; 7] = [
        ShapeKind::Disk,
        ShapeKind::Square,
        ShapeKind::Cylinder,
        ShapeKind::Elbow,
        ShapeKind::Sphere,
        ShapeKind::Mesh,
        ShapeKind::Plane,
    ];

    /// The lowercase name used on the CLI and in JSON (`"square"`, …).
    pub fn name(self) -> &'static str {
        match self {
            ShapeKind::Disk => "disk",
            ShapeKind::Square => "square",
            ShapeKind::Cylinder => "cylinder",
            ShapeKind::Elbow => "elbow",
            ShapeKind::Sphere => "sphere",
            ShapeKind::Mesh => "mesh",
            ShapeKind::Plane => "plane",
        }
    }

    /// Parses a name as written by [`ShapeKind::name`].
    pub fn parse(name: &str) -> Result<Self> {
        ShapeKind::ALL
            .into_iter()
            .find(|k| k.name() == name.trim().to_ascii_lowercase())
            .ok_or_else(|| Error::Unknown {
                what: "primitive type",
                value: name.into(),
                expected: "disk, square, cylinder, elbow, sphere, mesh or plane",
            })
    }
}

impl std::fmt::Display for ShapeKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A primitive type with its sizes, in its local frame (see [`crate::atlas`]).
#[derive(Debug, Clone)]
pub enum Shape {
    /// Round flat patch of the given diameter.
    Disk {
        /// Diameter.
        diameter: f64,
    },
    /// Square flat patch of the given side.
    Square {
        /// Side length.
        side: f64,
    },
    /// Open tube of the given length and radius.
    Cylinder {
        /// Length along the axis.
        length: f64,
        /// Tube radius.
        radius: f64,
    },
    /// Quarter torus: the right-angle pipe bend.
    Elbow {
        /// Bend radius of the centre line.
        bend: f64,
        /// Tube radius.
        radius: f64,
    },
    /// Sphere of the given diameter.
    Sphere {
        /// Diameter.
        diameter: f64,
    },
    /// Arbitrary triangle mesh.
    Mesh(MeshShape),
    /// Bounded planar polygon in z = 0 (see [`PlaneShape`]).
    Plane(PlaneShape),
}

impl Shape {
    /// The type's name.
    pub fn kind(&self) -> ShapeKind {
        match self {
            Shape::Disk { .. } => ShapeKind::Disk,
            Shape::Square { .. } => ShapeKind::Square,
            Shape::Cylinder { .. } => ShapeKind::Cylinder,
            Shape::Elbow { .. } => ShapeKind::Elbow,
            Shape::Sphere { .. } => ShapeKind::Sphere,
            Shape::Mesh(_) => ShapeKind::Mesh,
            Shape::Plane(_) => ShapeKind::Plane,
        }
    }

    /// Checks that every size is finite and positive (and an elbow's tube fits inside its
    /// bend: `radius < bend`), that a mesh has at least one non-degenerate face and a
    /// plane a positive area (its rings were checked when it was built).
    pub fn validate(&self) -> Result<()> {
        let positive = |size: &str, v: f64| check::positive(&format!("{} {size}", self.kind()), v);
        match self {
            Shape::Disk { diameter } | Shape::Sphere { diameter } => {
                positive("diameter", *diameter)
            }
            Shape::Square { side } => positive("side", *side),
            Shape::Cylinder { length, radius } => {
                positive("length", *length)?;
                positive("radius", *radius)
            }
            Shape::Elbow { bend, radius } => {
                positive("bend", *bend)?;
                positive("radius", *radius)?;
                if radius >= bend {
                    let expected = format!("smaller than its bend radius ({bend})");
                    return Err(Error::out_of_range("elbow radius", radius, expected));
                }
                Ok(())
            }
            Shape::Mesh(m) => {
                if m.mesh.faces.is_empty() || m.mesh.area() <= 0.0 {
                    return Err(no_faces_with_area(&m.source));
                }
                Ok(())
            }
            Shape::Plane(p) => positive("area", p.area()),
        }
    }

    /// The sizes as the JSON object of DESIGN §3 (`{"side": 1.0}`, `{"length": …, "radius": …}`,
    /// `{"source": "…"}` for meshes, `{"area": …}` for planes, whose rings are written by
    /// [`crate::Primitive::to_json`] beside the sizes).
    pub fn sizes_json(&self) -> Value {
        let mut m = Map::new();
        let mut put = |k: &str, v: Value| {
            m.insert(k.to_string(), v);
        };
        match self {
            Shape::Disk { diameter } | Shape::Sphere { diameter } => {
                put("diameter", (*diameter).into())
            }
            Shape::Square { side } => put("side", (*side).into()),
            Shape::Cylinder { length, radius } => {
                put("length", (*length).into());
                put("radius", (*radius).into());
            }
            Shape::Elbow { bend, radius } => {
                put("bend", (*bend).into());
                put("radius", (*radius).into());
            }
            Shape::Mesh(ms) => put("source", ms.source.clone().into()),
            Shape::Plane(p) => put("area", p.area().into()),
        }
        Value::Object(m)
    }

    /// The number of continuous size parameters (for the compactness measure); a plane
    /// counts its vertex coordinates (2 per vertex), which describe its extent although
    /// refinement keeps them fixed ([`Shape::sizes`] is empty for planes).
    pub fn size_parameter_count(&self) -> usize {
        match self {
            Shape::Cylinder { .. } | Shape::Elbow { .. } => 2,
            Shape::Mesh(_) => 0,
            Shape::Plane(p) => 2 * p.vertex_count(),
            _ => 1,
        }
    }

    /// Surface area.
    pub fn area(&self) -> f64 {
        use std::f64::consts::PI;
        match self {
            Shape::Disk { diameter } => PI * diameter * diameter / 4.0,
            Shape::Square { side } => side * side,
            Shape::Cylinder { length, radius } => 2.0 * PI * radius * length,
            // Pappus: (2π r) · (π/2 · R) for a quarter torus.
            Shape::Elbow { bend, radius } => PI * PI * radius * bend,
            Shape::Sphere { diameter } => PI * diameter * diameter,
            Shape::Mesh(m) => m.mesh.area(),
            Shape::Plane(p) => p.area(),
        }
    }

    /// Radius of a ball about the local origin that contains the whole surface.
    pub fn bounding_radius(&self) -> f64 {
        match self {
            Shape::Disk { diameter } | Shape::Sphere { diameter } => diameter / 2.0,
            Shape::Square { side } => side * std::f64::consts::FRAC_1_SQRT_2,
            Shape::Cylinder { length, radius } => (radius * radius + length * length / 4.0).sqrt(),
            Shape::Elbow { bend, radius } => bend + radius,
            Shape::Mesh(m) => m.bounding_radius(),
            Shape::Plane(p) => p.bounding_radius(),
        }
    }

    /// Deterministic, area-uniform samples of the surface with roughly `spacing` between
    /// neighbours (local frame, same length unit as the sizes). About `area / spacing²`
    /// points (the square uses `ceil(side / spacing)²`), never fewer than one; the same
    /// input always gives the same points in the same order. A spacing so fine (or zero,
    /// negative, NaN) that more than [`Shape::MAX_SAMPLES`] points would result is raised
    /// to the finest allowed one, so no argument can exhaust memory.
    ///
    /// Layouts: square, cell-centre grid; disk, sunflower spiral; cylinder, cell-centre
    /// (θ, z) grid; elbow, rows of constant tube angle with counts proportional to their
    /// band's area; sphere, Fibonacci lattice; mesh, per-face counts proportional to face
    /// area with R2 low-discrepancy points inside each face; plane, the cell centres of a
    /// grid of pitch `spacing` centred on its bounding box that fall inside the polygon.
    pub fn sample_surface(&self, spacing: f64) -> Vec<Point3<f64>> {
        let spacing = self.safe_spacing(spacing);
        match self {
            Shape::Disk { diameter } => disk_sample(diameter / 2.0, spacing),
            Shape::Square { side } => square_sample(*side, spacing),
            Shape::Cylinder { length, radius } => cylinder_sample(*length, *radius, spacing),
            Shape::Elbow { bend, radius } => elbow_sample(*bend, *radius, spacing),
            Shape::Sphere { diameter } => sphere_sample(diameter / 2.0, spacing),
            Shape::Mesh(m) => m.sample(spacing),
            Shape::Plane(p) => p.sample(spacing),
        }
    }

    /// Most samples [`Shape::sample_surface`] returns (4 Mi points, 96 MiB).
    pub const MAX_SAMPLES: f64 = (1u64 << 22) as f64;

    /// `spacing` made safe to sample with: never so fine that the surface would get more
    /// than [`Shape::MAX_SAMPLES`] samples (this also catches 0, negative and NaN spacings).
    fn safe_spacing(&self, spacing: f64) -> f64 {
        // A grid of a × b cells at spacing h has at most ab/h² + (a + b)/h + 1 cells:
        // bounding both the area term and the longest grid line keeps a thin tube of
        // huge radius (one row of 2πr/h cells) within the limit too.
        let by_area = (self.area() / Self::MAX_SAMPLES).sqrt();
        let finest = by_area.max(self.longest_grid_line() / Self::MAX_SAMPLES);
        if spacing.is_finite() && spacing >= finest {
            spacing
        } else {
            finest.max(f64::MIN_POSITIVE)
        }
    }

    /// The longest run of samples of one grid line in [`Shape::sample_surface`]'s layout
    /// (local units): a tube's circumference or length; 0 where the count follows the
    /// area alone.
    fn longest_grid_line(&self) -> f64 {
        match self {
            Shape::Cylinder { length, radius } => (TAU * radius).max(*length),
            Shape::Elbow { radius, .. } => TAU * radius,
            Shape::Square { side } => *side,
            _ => 0.0,
        }
    }

    /// The closest point of the surface to `p` (local frame), exact up to rounding.
    /// Open tubes and the elbow include their rim circles; where several surface points
    /// are equally close (a point on a cylinder's axis, the sphere's centre, …) any one of
    /// them is returned.
    pub fn closest_point(&self, p: &Point3<f64>) -> Point3<f64> {
        match self {
            Shape::Disk { diameter } => disk_closest(diameter / 2.0, p),
            Shape::Square { side } => square_closest(*side, p),
            Shape::Cylinder { length, radius } => cylinder_closest(*length, *radius, p),
            Shape::Elbow { bend, radius } => elbow_closest(*bend, *radius, p),
            Shape::Sphere { diameter } => sphere_closest(diameter / 2.0, p),
            Shape::Mesh(m) => m.closest_point(p),
            Shape::Plane(s) => s.closest_point(p),
        }
    }

    /// Euclidean distance from `p` to the surface (local frame); equal to
    /// `‖p − closest_point(p)‖`, with closed forms for the tubes (no trigonometry: this is
    /// the point term's inner loop).
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        // √(a² + b²): `f64::hypot` guards against overflow that scene coordinates never
        // reach, at several times the cost.
        let norm2 = |a: f64, b: f64| (a * a + b * b).sqrt();
        match self {
            Shape::Cylinder { length, radius } => {
                let beyond = (p.z.abs() - length / 2.0).max(0.0);
                norm2(norm2(p.x, p.y) - radius, beyond)
            }
            // Within the bend's quarter (0 ≤ angle ≤ π/2) the nearest tube circle lies in
            // the plane through p and the z axis: distance to a circle of that plane.
            Shape::Elbow { bend, radius } if p.x >= 0.0 && p.y >= 0.0 => {
                (norm2(norm2(p.x, p.y) - bend, p.z) - radius).abs()
            }
            // Outside it, the nearest point is on one of the two end circles (as in
            // `elbow_closest`): the circle at angle 0 has centre (B, 0, 0) and axis y, the
            // one at π/2 centre (0, B, 0) and axis x; the distance to a circle of radius r
            // is √((ρ − r)² + a²) with ρ the in-plane distance from its centre and a the
            // offset along its axis.
            Shape::Elbow { bend, radius } => {
                let start = norm2(norm2(p.x - bend, p.z) - radius, p.y);
                let end = norm2(norm2(p.y - bend, p.z) - radius, p.x);
                start.min(end)
            }
            _ => (p - self.closest_point(p)).norm(),
        }
    }

    /// A triangle mesh of the surface for export (local frame), fine enough that its
    /// deviation from the true surface is below 1 % of the shape's size. Vertices lie on
    /// the surface and faces wind counter-clockwise seen from outside (from +z for the
    /// flat types). Curved types use 48 segments around; a mesh returns itself.
    pub fn triangulate(&self) -> TriMesh {
        match self {
            Shape::Disk { diameter } => disk_mesh(diameter / 2.0),
            Shape::Square { side } => square_mesh(*side),
            Shape::Cylinder { length, radius } => cylinder_mesh(*length, *radius),
            Shape::Elbow { bend, radius } => elbow_mesh(*bend, *radius),
            Shape::Sphere { diameter } => sphere_mesh(diameter / 2.0),
            Shape::Mesh(m) => (*m.mesh).clone(),
            Shape::Plane(p) => p.mesh().clone(),
        }
    }

    /// The smallest `t ≥ 0` such that `origin + t·dir` lies on the surface (local frame),
    /// or `None` if the ray misses. `dir` need not be unit length; `t` is in units of
    /// `dir` (so with a unit `dir` it is a distance). An origin on the surface gives
    /// `Some(0.0)`. A zero `dir` hits only if `origin` is on the surface. Rays that merely
    /// graze a curved surface (tangent to within rounding) count as hits.
    pub fn ray_intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<f64> {
        let len2 = dir.norm_squared();
        if len2.is_nan() {
            return None;
        }
        if len2 == 0.0 {
            return (self.distance(origin) == 0.0).then_some(0.0);
        }
        match self {
            Shape::Disk { diameter } => disk_ray(diameter / 2.0, origin, dir),
            Shape::Square { side } => square_ray(*side, origin, dir),
            Shape::Cylinder { length, radius } => cylinder_ray(*length, *radius, origin, dir),
            Shape::Elbow { bend, radius } => elbow_ray(*bend, *radius, origin, dir),
            Shape::Sphere { diameter } => sphere_ray(diameter / 2.0, origin, dir),
            Shape::Mesh(m) => m.ray_intersect(origin, dir),
            Shape::Plane(p) => p.ray_intersect(origin, dir),
        }
    }

    /// A `Mesh` shape from a triangle mesh (see [`MeshShape::new`] for the checks).
    pub fn from_mesh(
        source: impl Into<String>,
        mesh: impl Into<std::sync::Arc<TriMesh>>,
    ) -> Result<Shape> {
        MeshShape::new(source, mesh).map(Shape::Mesh)
    }
}
