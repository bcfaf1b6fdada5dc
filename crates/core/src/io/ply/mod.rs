//! PLY reading and writing. This module (with its submodules) is the only place that
//! uses `ply-rs-bw`; the rest of the crate sees [`PointCloud`] and [`TriMesh`].

mod body;
mod header;
mod records;
mod write;

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use nalgebra::{Point3, Vector3};
use ply_rs_bw::ply::ElementDef;

use self::body::Body;
use self::header::{PlyHeader, check_body_size, read_header};
use self::records::{FaceRecord, VertexRecord, VertexSchema, check_face_schema};
use super::{CloudFormat, MeshReport, ReadReport};
use crate::{Error, PointCloud, Result, TriMesh};

pub use self::write::{write_cloud, write_mesh, write_mesh_colored};

/// Ascii files and streams reserve at most this many elements up front (then grow as
/// data arrives).
const RESERVE_CAP: usize = 1 << 20;

/// An open PLY file: its checked header and a reader at the start of its body.
struct PlyFile {
    header: PlyHeader,
    body: Body<BufReader<File>>,
    /// False for pipes and devices, whose size is unknown: counts were not checked.
    sized: bool,
}

impl PlyFile {
    /// Opens `path`, reads and checks its header, and checks that the file is large
    /// enough for the element counts it declares (when it is a regular file; pipes and
    /// devices are read as a stream).
    fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let meta = file.metadata().map_err(|e| Error::io(path, e))?;
        if meta.is_dir() {
            return Err(Error::format(path, "is a directory, not a PLY file"));
        }
        let mut reader = BufReader::with_capacity(1 << 16, file);
        let header = read_header(&mut reader, path)?;
        let sized = meta.is_file();
        if sized {
            check_body_size(&header, meta.len().saturating_sub(header.byte_len), path)?;
        }
        let body = Body::new(reader, path, header.format, header.line_count);
        Ok(PlyFile {
            header,
            body,
            sized,
        })
    }

    /// The element definitions, in file order.
    fn elements(&self) -> Vec<ElementDef> {
        self.header.inner.elements.values().cloned().collect()
    }

    /// The element named `name`, or an error saying it is missing.
    fn require(&self, name: &str, path: &Path) -> Result<ElementDef> {
        self.header.element(name).cloned().ok_or_else(|| {
            let have = self.header.element_names().join(", ");
            let msg = format!("the PLY file has no '{name}' element (it has: [{have}])");
            Error::format(path, msg)
        })
    }

    /// How many elements of `def` to reserve room for.
    fn reserve(&self, def: &ElementDef) -> usize {
        // Binary counts were checked against the file size; ascii is capped too because
        // a short ascii value can stand for a large record, and so are unsized streams.
        if self.sized && self.header.format != super::PlyFormat::Ascii {
            def.count
        } else {
            def.count.min(RESERVE_CAP)
        }
    }
}

/// Reads the `vertex` element of a PLY file as a point cloud and reports on the file:
/// its format, points skipped for a non-finite coordinate, and the properties and
/// elements read past. [`crate::io::read_cloud_report`] sends `.ply` files here.
pub(crate) fn read_cloud_report(path: &Path) -> Result<(PointCloud, ReadReport)> {
    let mut file = PlyFile::open(path)?;
    let vertex = file.require("vertex", path)?;
    let schema = VertexSchema::of(&vertex, path)?;
    let mut cloud = CloudBuilder::new(&schema, file.reserve(&vertex));
    let mut ignored_elements = Vec::new();
    for def in file.elements() {
        if def.name == vertex.name {
            file.body.read_element(&def, |_, r: VertexRecord| {
                cloud.push(&r);
                Ok(())
            })?;
        } else {
            file.body.skip_element(&def)?;
            ignored_elements.push(def.name);
        }
    }
    let comments = file.header.comments();
    let format = file.header.format;
    file.body.finish()?;
    let report = ReadReport {
        format: CloudFormat::Ply(format),
        vertices_in_file: vertex.count,
        skipped_non_finite: cloud.skipped,
        ignored_properties: schema.ignored,
        ignored_elements,
        comments,
    };
    Ok((cloud.cloud, report))
}

/// Collects vertex records into a cloud, dropping non-finite points.
struct CloudBuilder {
    cloud: PointCloud,
    skipped: usize,
}

impl CloudBuilder {
    /// An empty cloud with the attributes of `schema`, room for `reserve` points.
    fn new(schema: &VertexSchema, reserve: usize) -> Self {
        let cloud = PointCloud {
            points: Vec::with_capacity(reserve),
            normals: column(schema.normals, reserve),
            colors: column(schema.colors, reserve),
            labels: column(schema.labels, reserve),
            sensors: column(schema.sensors, reserve),
        };
        CloudBuilder { cloud, skipped: 0 }
    }

    /// Appends one point to every attribute, or counts it as skipped.
    fn push(&mut self, r: &VertexRecord) {
        if !r.is_finite() {
            self.skipped += 1;
            return;
        }
        let c = &mut self.cloud;
        c.points.push(Point3::from(r.xyz));
        if let Some(v) = c.normals.as_mut() {
            v.push(Vector3::from(r.normal));
        }
        if let Some(v) = c.colors.as_mut() {
            v.push(r.rgb);
        }
        if let Some(v) = c.labels.as_mut() {
            v.push(r.label);
        }
        if let Some(v) = c.sensors.as_mut() {
            v.push(Point3::from(r.sensor));
        }
    }
}

/// An attribute column with room for `reserve` entries, if `present`.
fn column<T>(present: bool, reserve: usize) -> Option<Vec<T>> {
    present.then(|| Vec::with_capacity(reserve))
}

/// Reads a triangle mesh: `vertex` positions and `face` index lists (`vertex_indices`
/// or `vertex_index`). Polygons are fan-triangulated, faces of fewer than three
/// vertices dropped; see [`read_mesh_report`].
pub fn read_mesh(path: &Path) -> Result<TriMesh> {
    read_mesh_report(path).map(|(mesh, _)| mesh)
}

/// Reads a triangle mesh and reports on the file. Fails on a vertex with a non-finite
/// coordinate (faces refer to it, so it cannot be dropped), on a missing `face`
/// element, and on a vertex index out of range (naming the face).
pub fn read_mesh_report(path: &Path) -> Result<(TriMesh, MeshReport)> {
    let mut file = PlyFile::open(path)?;
    let vertex = file.require("vertex", path)?;
    VertexSchema::of(&vertex, path)?;
    let face = file.require("face", path)?;
    check_face_schema(&face, path)?;
    let mut mesh = TriMesh {
        vertices: Vec::with_capacity(file.reserve(&vertex)),
        faces: Vec::with_capacity(file.reserve(&face)),
    };
    let mut report = MeshReport {
        format: file.header.format,
        faces_in_file: face.count,
        polygons_triangulated: 0,
        skipped_degenerate: 0,
        ignored_elements: Vec::new(),
    };
    for def in file.elements() {
        if def.name == vertex.name {
            file.body.read_element(&def, |i, r: VertexRecord| {
                push_vertex(&mut mesh.vertices, i, &r, path)
            })?;
        } else if def.name == face.name {
            let mut triangulate = FanTriangulator {
                n_vertices: vertex.count,
                report: &mut report,
            };
            file.body.read_element(&def, |i, r: FaceRecord| {
                triangulate.push(i, &r.indices, &mut mesh.faces, path)
            })?;
        } else {
            file.body.skip_element(&def)?;
            report.ignored_elements.push(def.name);
        }
    }
    file.body.finish()?;
    Ok((mesh, report))
}

/// Appends vertex `i`, failing if a coordinate is not finite.
fn push_vertex(out: &mut Vec<Point3<f64>>, i: usize, r: &VertexRecord, path: &Path) -> Result<()> {
    if !r.is_finite() {
        let msg = format!("mesh vertex {i} has a non-finite coordinate {:?}", r.xyz);
        return Err(Error::format(path, msg));
    }
    out.push(Point3::from(r.xyz));
    Ok(())
}

/// Splits faces into triangles, checking their indices.
struct FanTriangulator<'a> {
    n_vertices: usize,
    report: &'a mut MeshReport,
}

impl FanTriangulator<'_> {
    /// Appends face `i` (vertex indices `poly`) as the fan `(v0, vk, vk+1)`.
    fn push(&mut self, i: usize, poly: &[i64], out: &mut Vec<[u32; 3]>, path: &Path) -> Result<()> {
        let checked = |v: i64| {
            usize::try_from(v)
                .ok()
                .filter(|&u| u < self.n_vertices)
                .and_then(|u| u32::try_from(u).ok())
                .ok_or_else(|| {
                    let msg = format!(
                        "face {i}: vertex index {v} is out of range (the file has {} vertices)",
                        self.n_vertices
                    );
                    Error::format(path, msg)
                })
        };
        let ids = poly
            .iter()
            .map(|&v| checked(v))
            .collect::<Result<Vec<u32>>>()?;
        match ids.len() {
            0..=2 => self.report.skipped_degenerate += 1,
            3 => out.push([ids[0], ids[1], ids[2]]),
            _ => {
                self.report.polygons_triangulated += 1;
                out.extend(ids.windows(2).skip(1).map(|w| [ids[0], w[0], w[1]]));
            }
        }
        Ok(())
    }
}
