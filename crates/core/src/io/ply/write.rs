//! PLY writers, streaming one element at a time through ply-rs-bw's `Writer`.
//!
//! Layouts written (binary little-endian or ascii, `comment primfit VERSION` first):
//!
//! ```text
//! element vertex N            # write_cloud                 # write_mesh
//! property double x, y, z     #   always                    #   always
//! property double nx, ny, nz  #   if cloud.normals          #
//! property uchar red, green, blue  # if cloud.colors        #   if colours (*)
//! property int label          #   if cloud.labels           #
//! property double sensor_x, sensor_y, sensor_z # if sensors #
//! element face F                                            #   always
//! property list uchar int vertex_indices                    #   always
//! property int primitive                                    #   if face_primitive
//! ```
//!
//! (*) `write_mesh` colours vertices when given `face_primitive`; `write_mesh_colored`
//! when given `vertex_colors`.

use std::io::Write;
use std::path::Path;

use ply_rs_bw::ply::{
    Addable, ElementDef, Encoding as PlyEncoding, Header, PropertyAccess, PropertyDef,
    PropertyType, ScalarType, Version,
};
use ply_rs_bw::writer::Writer;

use super::records::{
    FACE_LISTS, LABEL, NORMAL, PRIMITIVE, RGB, SENSOR, TriangleOut, VertexRecord, XYZ,
};
use crate::io::{Encoding, palette_color, write_atomic};
use crate::{Error, PointCloud, Result, TriMesh, check};

/// Writes `cloud` to `path` (atomically) as a PLY `vertex` element with the layout in
/// the module docs. Fails with [`Error::Mismatch`] if an attribute's length differs from
/// the number of points.
pub fn write_cloud(path: &Path, cloud: &PointCloud, encoding: Encoding) -> Result<()> {
    check_cloud(cloud)?;
    let vertex = cloud_element(cloud);
    let header = make_header(encoding, vec![vertex.clone()]);
    write_atomic(path, |w| {
        let writer = Writer::<VertexRecord>::new();
        writer
            .write_header(&mut &mut *w, &header)
            .map_err(|e| Error::io(path, e))?;
        for i in 0..cloud.len() {
            write_one(&writer, w, &cloud_record(cloud, i), &vertex, encoding, path)?;
        }
        Ok(())
    })
}

/// Writes `mesh` to `path` (atomically) as PLY `vertex` and `face` elements.
///
/// Writing fitted primitives as one mesh, each face tagged with its primitive (what
/// `primfit fit --mesh` writes), and reading it back:
///
/// ```
/// use primfit_core::io::{Encoding, read_mesh, write_mesh};
/// use primfit_core::na::{UnitQuaternion, Vector3};
/// use primfit_core::{Pose, Primitive, Shape};
///
/// let prims = [
///     Primitive::new(Shape::Square { side: 1.0 }, Pose::identity()),
///     Primitive::new(
///         Shape::Sphere { diameter: 0.5 },
///         Pose::new(UnitQuaternion::identity(), Vector3::new(2.0, 0.0, 0.0)),
///     ),
/// ];
/// let (mesh, owner) = primfit_core::fit::primitives_mesh(&prims); // owner: one per face
/// let dir = std::env::temp_dir().join(format!("primfit-doc-mesh-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// let path = dir.join("fitted.ply");
/// write_mesh(&path, &mesh, Some(&owner), Encoding::BinaryLittleEndian)?;
/// let back = read_mesh(&path)?;
/// assert_eq!((back.vertices.len(), back.faces.len()), (mesh.vertices.len(), mesh.faces.len()));
/// assert_eq!(back.vertices, mesh.vertices); // coordinates are written as doubles
/// std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// `face_primitive` (one value per face) adds a per-face `int primitive` property, so
/// that a viewer can colour by primitive, and also colours the vertices (`uchar red,
/// green, blue`): each vertex takes [`palette_color`] of the primitive of the first face
/// that uses it (grey for negative primitive indices or unused vertices), which MeshLab
/// and CloudCompare show as is. Fails with [`Error::Mismatch`] on a length mismatch and
/// [`Error::IndexOutOfRange`] on a face index that is out of range or does not fit an
/// `int`.
pub fn write_mesh(
    path: &Path,
    mesh: &TriMesh,
    face_primitive: Option<&[i32]>,
    encoding: Encoding,
) -> Result<()> {
    check_mesh(mesh, face_primitive, None)?;
    let colors = face_primitive.map(|p| primitive_colors(mesh, p));
    write_mesh_colored(path, mesh, face_primitive, colors.as_deref(), encoding)
}

/// Like [`write_mesh`], with explicit per-vertex colours (`None`: no colour properties)
/// instead of colours derived from `face_primitive`.
pub fn write_mesh_colored(
    path: &Path,
    mesh: &TriMesh,
    face_primitive: Option<&[i32]>,
    vertex_colors: Option<&[[u8; 3]]>,
    encoding: Encoding,
) -> Result<()> {
    check_mesh(mesh, face_primitive, vertex_colors)?;
    let vertex = mesh_vertex_element(mesh.vertices.len(), vertex_colors.is_some());
    let face = face_element(mesh.faces.len(), face_primitive.is_some());
    let header = make_header(encoding, vec![vertex.clone(), face.clone()]);
    write_atomic(path, |w| {
        let vertex_writer = Writer::<VertexRecord>::new();
        vertex_writer
            .write_header(&mut &mut *w, &header)
            .map_err(|e| Error::io(path, e))?;
        for (i, p) in mesh.vertices.iter().enumerate() {
            let rgb = vertex_colors.map_or([0; 3], |c| c[i]);
            let record = VertexRecord {
                xyz: p.coords.into(),
                rgb,
                ..Default::default()
            };
            write_one(&vertex_writer, w, &record, &vertex, encoding, path)?;
        }
        let face_writer = Writer::<TriangleOut>::new();
        for (i, f) in mesh.faces.iter().enumerate() {
            // Indices were checked to fit `i32` in `check_mesh`.
            let record = TriangleOut {
                indices: f.map(|v| v as i32),
                primitive: face_primitive.map_or(0, |p| p[i]),
            };
            write_one(&face_writer, w, &record, &face, encoding, path)?;
        }
        Ok(())
    })
}

/// Writes one element in `encoding`.
fn write_one<E: PropertyAccess>(
    writer: &Writer<E>,
    w: &mut dyn Write,
    record: &E,
    def: &ElementDef,
    encoding: Encoding,
    path: &Path,
) -> Result<()> {
    let mut w = w;
    let result = match encoding {
        Encoding::BinaryLittleEndian => writer.write_little_endian_element(&mut w, record, def),
        Encoding::Ascii => writer.write_ascii_element(&mut w, record, def),
    };
    result.map(|_| ()).map_err(|e| Error::io(path, e))
}

/// A header with `comment primfit VERSION` and the given elements.
fn make_header(encoding: Encoding, elements: Vec<ElementDef>) -> Header {
    let mut header = Header::new();
    header.encoding = match encoding {
        Encoding::BinaryLittleEndian => PlyEncoding::BinaryLittleEndian,
        Encoding::Ascii => PlyEncoding::Ascii,
    };
    header.version = Version { major: 1, minor: 0 };
    header.comments.push(format!("primfit {}", crate::VERSION));
    for e in elements {
        header.elements.add(e);
    }
    header
}

/// An element definition named `name` with `count` elements.
fn element(name: &str, count: usize, properties: Vec<(&str, PropertyType)>) -> ElementDef {
    let mut def = ElementDef::new(name.to_string());
    def.count = count;
    for (n, t) in properties {
        def.properties.add(PropertyDef::new(n.to_string(), t));
    }
    def
}

/// `(name, scalar type)` pairs for three property names.
fn triple(names: [&'static str; 3], t: ScalarType) -> Vec<(&'static str, PropertyType)> {
    names
        .into_iter()
        .map(|n| (n, PropertyType::Scalar(t.clone())))
        .collect()
}

/// The `vertex` element `write_cloud` writes for `cloud`.
fn cloud_element(cloud: &PointCloud) -> ElementDef {
    let mut props = triple(XYZ, ScalarType::Double);
    if cloud.normals.is_some() {
        props.extend(triple(NORMAL, ScalarType::Double));
    }
    if cloud.colors.is_some() {
        props.extend(triple(RGB, ScalarType::UChar));
    }
    if cloud.labels.is_some() {
        props.push((LABEL, PropertyType::Scalar(ScalarType::Int)));
    }
    if cloud.sensors.is_some() {
        props.extend(triple(SENSOR, ScalarType::Double));
    }
    element("vertex", cloud.len(), props)
}

/// The `vertex` element `write_mesh` writes.
fn mesh_vertex_element(count: usize, colors: bool) -> ElementDef {
    let mut props = triple(XYZ, ScalarType::Double);
    if colors {
        props.extend(triple(RGB, ScalarType::UChar));
    }
    element("vertex", count, props)
}

/// The `face` element `write_mesh` writes.
fn face_element(count: usize, primitive: bool) -> ElementDef {
    let list = PropertyType::List(ScalarType::UChar, ScalarType::Int);
    let mut props = vec![(FACE_LISTS[0], list)];
    if primitive {
        props.push((PRIMITIVE, PropertyType::Scalar(ScalarType::Int)));
    }
    element("face", count, props)
}

/// Point `i` of `cloud` as a record (absent attributes left at zero).
fn cloud_record(cloud: &PointCloud, i: usize) -> VertexRecord {
    VertexRecord {
        xyz: cloud.points[i].coords.into(),
        normal: cloud.normals.as_ref().map_or([0.0; 3], |v| v[i].into()),
        rgb: cloud.colors.as_ref().map_or([0; 3], |v| v[i]),
        label: cloud.labels.as_ref().map_or(0, |v| v[i]),
        sensor: cloud
            .sensors
            .as_ref()
            .map_or([0.0; 3], |v| v[i].coords.into()),
    }
}

/// Colour of vertices that no face with a primitive index ≥ 0 uses.
const UNCOLORED: [u8; 3] = [160, 160, 160];

/// Per-vertex colours: the palette colour of the first face using each vertex.
/// `face_primitive` and the face indices must have been checked.
fn primitive_colors(mesh: &TriMesh, face_primitive: &[i32]) -> Vec<[u8; 3]> {
    let mut colors = vec![None; mesh.vertices.len()];
    for (f, &p) in mesh.faces.iter().zip(face_primitive) {
        let Ok(p) = usize::try_from(p) else { continue };
        for &v in f {
            colors[v as usize].get_or_insert(palette_color(p));
        }
    }
    colors.into_iter().map(|c| c.unwrap_or(UNCOLORED)).collect()
}

/// Checks that every attribute of `cloud` has one entry per point.
fn check_cloud(cloud: &PointCloud) -> Result<()> {
    let n = cloud.len();
    let lens = [
        ("normals", cloud.normals.as_ref().map(Vec::len)),
        ("colors", cloud.colors.as_ref().map(Vec::len)),
        ("labels", cloud.labels.as_ref().map(Vec::len)),
        ("sensors", cloud.sensors.as_ref().map(Vec::len)),
    ];
    lens.iter()
        .filter_map(|(what, len)| len.map(|l| (what, l)))
        .try_for_each(|(what, len)| check::same_len(what, len, "points", n))
}

/// Checks attribute lengths and face indices of a mesh to write.
fn check_mesh(
    mesh: &TriMesh,
    face_primitive: Option<&[i32]>,
    vertex_colors: Option<&[[u8; 3]]>,
) -> Result<()> {
    if let Some(p) = face_primitive {
        check::same_len("face_primitive", p.len(), "faces", mesh.faces.len())?;
    }
    if let Some(c) = vertex_colors {
        check::same_len("vertex_colors", c.len(), "vertices", mesh.vertices.len())?;
    }
    // PLY `int` indices: at most i32::MAX.
    mesh.check_indices(mesh.vertices.len().min(i32::MAX as usize + 1), "faces")
}

#[cfg(test)]
mod tests {
    //! Our output read back by ply-rs-bw's generic reader: a second opinion on the
    //! files' validity, independent of our own reader.

    use super::*;
    use nalgebra::Point3;
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};

    /// A fresh path under the temp directory (the file is removed by the caller).
    fn temp_path(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("primfit-io-write-{}-{name}", std::process::id()))
    }

    #[test]
    fn io_written_files_parse_with_ply_rs_bw_default_reader() {
        let cloud = PointCloud {
            labels: Some(vec![7, -1]),
            colors: Some(vec![[1, 2, 3], [4, 5, 6]]),
            ..PointCloud::from_points(vec![
                Point3::new(0.5, 1.5, 2.5),
                Point3::new(-1.0, 0.0, 1e-7),
            ])
        };
        let mesh = TriMesh {
            vertices: cloud.points.clone(),
            faces: vec![[0, 1, 1]],
        };
        for encoding in [Encoding::Ascii, Encoding::BinaryLittleEndian] {
            let path = temp_path("cloud.ply");
            write_cloud(&path, &cloud, encoding).expect("write cloud");
            let bytes = std::fs::read(&path).expect("read");
            std::fs::remove_file(&path).expect("remove");
            let ply = Parser::<DefaultElement>::new()
                .read_ply(&mut &bytes[..])
                .expect("parse");
            let v = &ply.payload["vertex"];
            assert_eq!(v.len(), 2);
            assert_eq!(v[1]["z"], Property::Double(1e-7));
            assert_eq!(v[0]["label"], Property::Int(7));
            assert_eq!(v[1]["blue"], Property::UChar(6));

            let path = temp_path("mesh.ply");
            write_mesh(&path, &mesh, Some(&[3]), encoding).expect("write mesh");
            let bytes = std::fs::read(&path).expect("read");
            std::fs::remove_file(&path).expect("remove");
            let ply = Parser::<DefaultElement>::new()
                .read_ply(&mut &bytes[..])
                .expect("parse");
            let f = &ply.payload["face"];
            assert_eq!(f[0]["vertex_indices"], Property::ListInt(vec![0, 1, 1]));
            assert_eq!(f[0]["primitive"], Property::Int(3));
        }
    }
}
