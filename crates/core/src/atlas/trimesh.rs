//! [`TriMesh`]: an indexed triangle mesh (export format and the `mesh` primitive type).

use nalgebra::Point3;

/// An indexed triangle mesh. Faces index into `vertices` counter-clockwise
/// (outward normal by the right-hand rule).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles as vertex indices.
    pub faces: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Total surface area.
    pub fn area(&self) -> f64 {
        self.faces.iter().map(|f| self.triangle_area(f)).sum()
    }

    /// Area of one face.
    pub fn triangle_area(&self, f: &[u32; 3]) -> f64 {
        let [a, b, c] = f.map(|i| self.vertices[i as usize]);
        0.5 * (b - a).cross(&(c - a)).norm()
    }

    /// Appends `other`, re-indexing its faces; returns the range of face indices added.
    pub fn append(&mut self, other: &TriMesh) -> std::ops::Range<usize> {
        let base = self.vertices.len() as u32;
        let start = self.faces.len();
        self.vertices.extend_from_slice(&other.vertices);
        self.faces
            .extend(other.faces.iter().map(|f| f.map(|i| i + base)));
        start..self.faces.len()
    }

    /// Stitches closed rings of equal length into a tube (internal helper of the atlas).
    ///
    /// The rings must follow one another along some axis `w`, and each ring's points must
    /// run counter-clockwise around `w` (right-hand rule); the faces then have outward
    /// normals. Every quad between two rings is split into two triangles.
    pub(crate) fn from_rings(rings: &[Vec<Point3<f64>>]) -> TriMesh {
        let n = rings.first().map_or(0, Vec::len) as u32;
        let vertices: Vec<Point3<f64>> = rings.iter().flatten().copied().collect();
        let mut faces = Vec::with_capacity(2 * n as usize * rings.len().saturating_sub(1));
        for k in 1..rings.len() as u32 {
            let (lower, upper) = ((k - 1) * n, k * n);
            for j in 0..n {
                let jn = (j + 1) % n;
                faces.push([lower + j, lower + jn, upper + jn]);
                faces.push([lower + j, upper + jn, upper + j]);
            }
        }
        TriMesh { vertices, faces }
    }
}
