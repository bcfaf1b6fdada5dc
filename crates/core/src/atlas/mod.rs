//! Primitive **types** (the thesis's atlas, §3.1): surfaces in their own local frame.
//!
//! A [`Shape`] knows its sizes and nothing about where it sits in a scene; a
//! [`crate::Primitive`] places it with a [`crate::Pose`]. Every shape offers:
//! deterministic, area-uniform surface samples at a given spacing; the exact
//! closest point on (and distance to) its surface; the first hit of a ray; a triangle
//! mesh for export. A `Mesh` type is built with [`MeshShape::new`] (or
//! [`Shape::from_mesh`]), which indexes the faces in a bounding-volume hierarchy so that
//! closest-point and ray queries take microseconds on meshes of 10⁵ faces.
//!
//! Local-frame conventions (all lengths in scene units before the pose's scale):
//!
//! | type | surface in its local frame |
//! |---|---|
//! | `Disk { diameter }` | the disk of radius `diameter/2` in the plane z = 0, centred at the origin, normal +z |
//! | `Square { side }` | the square `[-side/2, side/2]²` in the plane z = 0, normal +z |
//! | `Cylinder { length, radius }` | the open tube of radius `radius` around the z axis, z ∈ `[-length/2, length/2]` |
//! | `Elbow { bend, radius }` | a quarter torus: tube of radius `radius` around the centre-line arc of radius `bend` in the plane z = 0, from (bend, 0, 0) (tangent +y) to (0, bend, 0) (tangent −x); open ends |
//! | `Sphere { diameter }` | the sphere of radius `diameter/2` centred at the origin |
//! | `Mesh(MeshShape)` | a triangle mesh in its own coordinates |
//! | `Plane(PlaneShape)` | a polygon (outer ring, optional holes) in the plane z = 0, normal +z; built from points with [`PlaneShape::from_points`] or [`fit_plane`] |

mod bvh;
mod edge_slabs;
mod elbow;
mod mesh;
mod numeric;
mod occupancy;
mod outline;
mod planar;
mod plane;
mod plane_fit;
#[cfg(test)]
mod plane_tests;
mod shapes;
mod size;
mod sphere;
#[cfg(test)]
mod tests;
mod trimesh;
mod tube;

pub use elbow::elbow_rotation_between;
pub use mesh::MeshShape;
pub use occupancy::{MAX_OUTLINE_CELLS, MIN_COMPONENT_CELLS, MIN_HOLE_CELLS};
pub use plane::{MAX_PLANE_VERTICES, PlaneShape, Rings};
pub use plane_fit::{fit_plane, fit_plane_primitive, plane_frame};
pub use shapes::*;
pub use trimesh::TriMesh;
