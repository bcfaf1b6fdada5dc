//! The `Mesh` type: an arbitrary triangle mesh with a closest-point/ray index.

use std::sync::Arc;

use nalgebra::{Point3, Vector3};

use super::TriMesh;
use super::bvh::TriangleBvh;
use super::numeric::{apportion, r2, sample_count};
use crate::{Error, Result};

/// A triangle mesh used as a primitive type, with what closest-point queries need.
///
/// Build it with [`MeshShape::new`], which checks the mesh and builds a bounding-volume
/// hierarchy over its faces (about 0.1 s for 100 k faces); clones share both. The
/// public `mesh` field is the geometry the index was built from: to change the mesh,
/// build a new `MeshShape` rather than assigning the field.
#[derive(Clone)]
pub struct MeshShape {
    /// Where the mesh came from (a file path or a generator name); written to JSON.
    pub source: String,
    /// The mesh, in its own local frame.
    pub mesh: Arc<TriMesh>,
    /// Acceleration structure over `mesh`'s faces.
    index: Arc<TriangleBvh>,
    /// The largest vertex distance from the local origin.
    bounding_radius: f64,
}

impl std::fmt::Debug for MeshShape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshShape")
            .field("source", &self.source)
            .field("vertices", &self.mesh.vertices.len())
            .field("faces", &self.mesh.faces.len())
            .finish()
    }
}

impl MeshShape {
    /// Wraps `mesh` (local frame, same units as the scene before the pose's scale) as a
    /// primitive type and indexes it for queries.
    ///
    /// Errors ([`Error::IndexOutOfRange`], [`Error::NonFinite`], [`Error::InvalidArgument`])
    /// if a face refers to a missing vertex, a vertex is not finite, or the mesh has no
    /// face with positive area. Zero-area faces are allowed (they get no samples and act
    /// as segments in distance queries).
    pub fn new(source: impl Into<String>, mesh: impl Into<Arc<TriMesh>>) -> Result<MeshShape> {
        let (source, mesh) = (source.into(), mesh.into());
        check_mesh(&source, &mesh)?;
        let index = Arc::new(TriangleBvh::new(&mesh));
        let bounding_radius = mesh
            .vertices
            .iter()
            .map(|v| v.coords.norm())
            .fold(0.0, f64::max);
        Ok(MeshShape {
            source,
            mesh,
            index,
            bounding_radius,
        })
    }

    /// Radius of a ball about the local origin that contains the mesh (cached).
    pub fn bounding_radius(&self) -> f64 {
        self.bounding_radius
    }

    /// The closest point of the mesh's surface to `p` (local frame). Exact: the
    /// point-triangle closest point, over the faces the index cannot rule out.
    pub fn closest_point(&self, p: &Point3<f64>) -> Point3<f64> {
        // `new` guarantees at least one face, so the fallback is never used.
        self.index.closest_point(p).unwrap_or(*p)
    }

    /// [`MeshShape::closest_point`], starting from `hint`, a point on the surface (e.g.
    /// the answer for a nearby point): the same distance, found faster when `hint` is
    /// close to the answer.
    pub fn closest_point_near(&self, p: &Point3<f64>, hint: &Point3<f64>) -> Point3<f64> {
        self.index.closest_point_near(p, Some(hint)).unwrap_or(*p)
    }

    /// [`MeshShape::closest_point`] and the face it lies on, for a sweep of nearby
    /// points: the search starts from `face`, the face of the previous point's answer
    /// (`None`: no hint; the face is an opaque index, only for the next call), whose
    /// distance bounds it. Exact wherever the surface is within `reach` of `p` (local
    /// units); where it is not, the closest point of the hint face, a surface point
    /// farther than `reach` (no closer than the exact answer), which costs a fraction of
    /// an exact query far from a finely tessellated surface.
    pub fn closest_point_from_face(
        &self,
        p: &Point3<f64>,
        face: Option<u32>,
        reach: f64,
    ) -> (Point3<f64>, u32) {
        self.index
            .closest_face_near(p, face, reach)
            .unwrap_or((*p, 0))
    }

    /// The smallest `t ≥ 0` with `o + t d` on a face (`t` in units of `d`), or `None`.
    /// Rays lying in a face's plane do not hit that face (Möller–Trumbore convention).
    pub fn ray_intersect(&self, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
        self.index.ray_intersect(o, d)
    }

    /// Area-uniform samples: `round(area / spacing²)` (≥ 1) points split between faces in
    /// proportion to their areas by largest remainder, each face's share taken from
    /// consecutive terms of the R2 low-discrepancy sequence (one running sequence over the
    /// whole mesh) folded into the triangle.
    pub(super) fn sample(&self, spacing: f64) -> Vec<Point3<f64>> {
        let mesh = &*self.mesh;
        let areas: Vec<f64> = mesh.faces.iter().map(|f| mesh.triangle_area(f)).collect();
        let counts = apportion(&areas, sample_count(mesh.area(), spacing));
        let mut out = Vec::with_capacity(counts.iter().sum());
        for (face, &count) in mesh.faces.iter().zip(&counts) {
            let [a, b, c] = face.map(|i| mesh.vertices[i as usize]);
            out.extend(
                (out.len()..out.len() + count).map(|i| point_in_triangle(r2(i), &a, &b, &c)),
            );
        }
        out
    }
}

/// Maps a point of the unit square into triangle `abc`, area-uniformly: `(u, v)` with
/// `u + v > 1` is reflected through the square's centre into the lower-left half, which
/// is the parallelogram-to-triangle fold.
fn point_in_triangle(
    (u, v): (f64, f64),
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
) -> Point3<f64> {
    let (u, v) = if u + v > 1.0 {
        (1.0 - u, 1.0 - v)
    } else {
        (u, v)
    };
    a + (b - a) * u + (c - a) * v
}

/// The checks of [`MeshShape::new`].
fn check_mesh(source: &str, mesh: &TriMesh) -> Result<()> {
    if let Some(v) = mesh
        .vertices
        .iter()
        .position(|v| !v.iter().all(|c| c.is_finite()))
    {
        return Err(Error::NonFinite {
            what: format!("mesh {source:?} vertex"),
            index: v,
        });
    }
    mesh.check_indices(mesh.vertices.len(), &format!("mesh {source:?} faces"))?;
    let area = mesh.area();
    if area.is_nan() || area <= 0.0 {
        return Err(no_faces_with_area(source));
    }
    Ok(())
}

/// The error of a mesh whose faces all have zero area (or that has none).
pub(super) fn no_faces_with_area(source: &str) -> Error {
    Error::invalid(format!("mesh {source:?} has no faces with area"))
}
