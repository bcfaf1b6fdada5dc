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
        self.faces.extend(other.faces.iter().map(|f| f.map(|i| i + base)));
        start..self.faces.len()
    }
}
