//! [`TriMesh`]: an indexed triangle mesh (export format and the `mesh` primitive type).

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};

use crate::{Error, Result};

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

    /// Checks that every face index is below `limit` (the vertex count, or less where a
    /// file format caps indices). The error names the corner as `{name}[f][k]`, `name`
    /// being how the caller calls the face list.
    pub fn check_indices(&self, limit: usize, name: &str) -> Result<()> {
        for (f, face) in self.faces.iter().enumerate() {
            if let Some(k) = face.iter().position(|&i| i as usize >= limit) {
                return Err(Error::IndexOutOfRange {
                    what: format!("{name}[{f}][{k}]"),
                    index: face[k] as usize,
                    item: "vertex",
                    count: limit,
                });
            }
        }
        Ok(())
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

    /// The unit icosphere: a regular icosahedron whose faces are split in four `levels`
    /// times, new vertices pushed onto the unit sphere (12 + 10·(4^levels − 1) vertices,
    /// 20·4^levels faces, counter-clockwise seen from outside).
    pub fn unit_icosphere(levels: u32) -> TriMesh {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let raw = [
            [-1.0, t, 0.0],
            [1.0, t, 0.0],
            [-1.0, -t, 0.0],
            [1.0, -t, 0.0],
            [0.0, -1.0, t],
            [0.0, 1.0, t],
            [0.0, -1.0, -t],
            [0.0, 1.0, -t],
            [t, 0.0, -1.0],
            [t, 0.0, 1.0],
            [-t, 0.0, -1.0],
            [-t, 0.0, 1.0],
        ];
        let mut vertices: Vec<Point3<f64>> = raw
            .iter()
            .map(|v| Point3::from(Vector3::from(*v).normalize()))
            .collect();
        let mut faces: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
            let mut midpoint = |a: u32, b: u32, vertices: &mut Vec<Point3<f64>>| {
                *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let m = (vertices[a as usize].coords + vertices[b as usize].coords).normalize();
                    vertices.push(Point3::from(m));
                    vertices.len() as u32 - 1
                })
            };
            faces = faces
                .iter()
                .flat_map(|&[a, b, c]| {
                    let ab = midpoint(a, b, &mut vertices);
                    let bc = midpoint(b, c, &mut vertices);
                    let ca = midpoint(c, a, &mut vertices);
                    [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
                })
                .collect();
        }
        TriMesh { vertices, faces }
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
