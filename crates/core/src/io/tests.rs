//! Tests of `io`: round trips, other tools' header conventions, every bad-input case,
//! atomic writes, and the bundled real scans.
//!
//! Fixtures are written by the tests into a fresh directory under the system temp
//! directory, removed when the test ends.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use nalgebra::{Point3, Vector3};

use super::*;
use crate::{Error, PointCloud, Result, TriMesh};

// ---------------------------------------------------------------------------------
// helpers

/// A scratch directory, removed on drop.
struct Scratch(PathBuf);

impl Scratch {
    fn new(tag: &str) -> Self {
        static N: AtomicUsize = AtomicUsize::new(0);
        let n = N.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("primfit-io-{}-{n}-{tag}", std::process::id()));
        fs::create_dir_all(&dir).expect("create scratch dir");
        Scratch(dir)
    }
    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.path(name);
        fs::write(&p, bytes).expect("write fixture");
        p
    }
    /// Names of the files in the directory, sorted.
    fn files(&self) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(&self.0)
            .expect("list scratch dir")
            .map(|e| {
                e.expect("dir entry")
                    .file_name()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        v.sort();
        v
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// Asserts `r` failed with a one-line message naming `path` and containing `needle`;
/// returns the message.
#[track_caller]
fn fails<T: std::fmt::Debug>(r: Result<T>, path: &Path, needle: &str) -> String {
    let e = r.expect_err("expected an error");
    let msg = e.to_string();
    assert!(!msg.contains('\n'), "message is not one line: {msg:?}");
    let name = path.file_name().expect("file name").to_string_lossy();
    assert!(
        msg.contains(&*name),
        "message does not name the file: {msg}"
    );
    assert!(msg.contains(needle), "message lacks {needle:?}: {msg}");
    msg
}

/// A header: `ply`, format, then `body_lines`, then `end_header`.
fn header(format: &str, body_lines: &[&str]) -> String {
    let mut s = format!("ply\nformat {format} 1.0\n");
    for l in body_lines {
        s.push_str(l);
        s.push('\n');
    }
    s.push_str("end_header\n");
    s
}

/// Little/big-endian byte builder for hand-written binary bodies.
struct Bytes {
    big: bool,
    buf: Vec<u8>,
}

impl Bytes {
    fn new(big: bool, header: &str) -> Self {
        Bytes {
            big,
            buf: header.as_bytes().to_vec(),
        }
    }
    fn f32(&mut self, v: f32) -> &mut Self {
        let b = if self.big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        };
        self.buf.extend_from_slice(&b);
        self
    }
    fn f64(&mut self, v: f64) -> &mut Self {
        let b = if self.big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        };
        self.buf.extend_from_slice(&b);
        self
    }
    fn i32(&mut self, v: i32) -> &mut Self {
        let b = if self.big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        };
        self.buf.extend_from_slice(&b);
        self
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        let b = if self.big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        };
        self.buf.extend_from_slice(&b);
        self
    }
    fn u8(&mut self, v: u8) -> &mut Self {
        self.buf.push(v);
        self
    }
}

/// A cloud with every attribute, with values that are not exact in `f32`.
fn full_cloud() -> PointCloud {
    let n = 5;
    let f = |i: usize, k: f64| 0.1 * i as f64 + k / 3.0;
    PointCloud {
        points: (0..n)
            .map(|i| Point3::new(f(i, 1.0), -f(i, 2.0), 1e-9 * f(i, 3.0)))
            .collect(),
        normals: Some(
            (0..n)
                .map(|i| Vector3::new(f(i, 0.0), 1.0, -0.5).normalize())
                .collect(),
        ),
        colors: Some((0..n).map(|i| [i as u8, 255 - i as u8, 128]).collect()),
        labels: Some((0..n).map(|i| i as i32 - 2).collect()),
        sensors: Some((0..n).map(|i| Point3::new(0.0, f(i, 5.0), 1.5)).collect()),
    }
}

/// A unit square as two triangles plus a triangle, and its face primitives.
fn small_mesh() -> (TriMesh, Vec<i32>) {
    let vertices = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(1.0, 1.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
        Point3::new(0.1, 0.2, 0.3),
        Point3::new(1.1, 0.2, 0.3),
        Point3::new(0.1, 1.2, 0.3),
    ];
    let faces = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]];
    (TriMesh { vertices, faces }, vec![0, 0, 1])
}

// ---------------------------------------------------------------------------------
// round trips

#[test]
fn io_cloud_round_trip_binary_all_attributes() {
    let dir = Scratch::new("rt-bin");
    let path = dir.path("cloud.ply");
    let cloud = full_cloud();
    write_cloud(&path, &cloud, Encoding::BinaryLittleEndian).expect("write");
    let (back, report) = read_cloud_report(&path).expect("read");
    assert_eq!(back, cloud);
    assert_eq!(
        report.format,
        CloudFormat::Ply(PlyFormat::BinaryLittleEndian)
    );
    assert_eq!(report.vertices_in_file, 5);
    assert!(report.ignored_properties.is_empty() && report.ignored_elements.is_empty());
    assert!(report.warnings().is_empty());
    assert!(report.comments.iter().any(|c| c.starts_with("primfit")));
    assert_eq!(
        dir.files(),
        vec!["cloud.ply"],
        "no temporary file left behind"
    );
}

#[test]
fn io_cloud_round_trip_ascii_all_attributes_is_exact() {
    let dir = Scratch::new("rt-ascii");
    let path = dir.path("cloud.ply");
    let cloud = full_cloud();
    write_cloud(&path, &cloud, Encoding::Ascii).expect("write");
    let text = fs::read_to_string(&path).expect("ascii file");
    assert!(text.starts_with("ply\nformat ascii 1.0\n"));
    assert!(text.contains("property double x\n"));
    let (back, report) = read_cloud_report(&path).expect("read");
    assert_eq!(back, cloud);
    assert_eq!(report.format, CloudFormat::Ply(PlyFormat::Ascii));
}

#[test]
fn io_cloud_round_trip_points_only_and_default_encoding() {
    let dir = Scratch::new("rt-bare");
    let path = dir.path("bare.ply");
    let cloud = PointCloud::from_points(vec![
        Point3::new(1.0, 2.0, 3.0),
        Point3::new(-4.0, 5.5, 1e300),
    ]);
    write_cloud(&path, &cloud, Encoding::default()).expect("write");
    let back = read_cloud(&path).expect("read");
    assert_eq!(back, cloud);
    assert!(back.normals.is_none() && back.colors.is_none());
    assert!(back.labels.is_none() && back.sensors.is_none());
}

#[test]
fn io_empty_cloud_is_read_and_reported() {
    let dir = Scratch::new("rt-empty");
    for enc in [Encoding::BinaryLittleEndian, Encoding::Ascii] {
        let path = dir.path("empty.ply");
        write_cloud(&path, &PointCloud::default(), enc).expect("write");
        let (back, report) = read_cloud_report(&path).expect("read");
        assert!(back.is_empty());
        assert_eq!(report.points_kept(), 0);
        assert!(report.warnings().iter().any(|w| w.contains("no points")));
    }
}

#[test]
fn io_mesh_round_trip_binary_and_ascii_with_primitives() {
    let dir = Scratch::new("rt-mesh");
    let (mesh, prims) = small_mesh();
    for enc in [Encoding::BinaryLittleEndian, Encoding::Ascii] {
        let path = dir.path("mesh.ply");
        write_mesh(&path, &mesh, Some(&prims), enc).expect("write");
        let (back, report) = read_mesh_report(&path).expect("read");
        assert_eq!(back, mesh);
        assert_eq!(report.faces_in_file, 3);
        assert_eq!(report.polygons_triangulated + report.skipped_degenerate, 0);
        let bytes = fs::read(&path).expect("file");
        let head = String::from_utf8_lossy(&bytes[..400.min(bytes.len())]).into_owned();
        assert!(
            head.contains("property list uchar int vertex_indices\nproperty int primitive\n"),
            "{head}"
        );
        assert!(
            head.contains("property uchar red\n"),
            "vertex colours by primitive: {head}"
        );
        // The same file as a cloud: vertex colours are the palette colours.
        let cloud = read_cloud(&path).expect("as cloud");
        let colors = cloud.colors.expect("colours");
        assert_eq!(colors[0], palette_color(0));
        assert_eq!(colors[4], palette_color(1));
    }
}

#[test]
fn io_mesh_without_primitives_and_with_explicit_colors() {
    let dir = Scratch::new("rt-mesh2");
    let (mesh, _) = small_mesh();
    let path = dir.path("plain.ply");
    write_mesh(&path, &mesh, None, Encoding::BinaryLittleEndian).expect("write");
    assert_eq!(read_mesh(&path).expect("read"), mesh);
    assert!(read_cloud(&path).expect("as cloud").colors.is_none());

    let colors: Vec<[u8; 3]> = (0..mesh.vertices.len()).map(|i| [i as u8, 2, 3]).collect();
    let path = dir.path("colored.ply");
    write_mesh_colored(&path, &mesh, None, Some(&colors), Encoding::Ascii).expect("write");
    assert_eq!(read_cloud(&path).expect("as cloud").colors, Some(colors));
}

// ---------------------------------------------------------------------------------
// encodings and value types written by hand

#[test]
fn io_big_endian_cloud_and_mesh_by_hand() {
    let dir = Scratch::new("be");
    let h = header(
        "binary_big_endian",
        &[
            "element vertex 4",
            "property float x",
            "property float y",
            "property float z",
            "property uchar red",
            "property uchar green",
            "property uchar blue",
            "property int label",
            "element face 1",
            "property list uchar uint vertex_indices",
        ],
    );
    let mut b = Bytes::new(true, &h);
    for (i, p) in [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.5],
        [0.0, 1.0, -0.25],
    ]
    .iter()
    .enumerate()
    {
        b.f32(p[0])
            .f32(p[1])
            .f32(p[2])
            .u8(10 * i as u8)
            .u8(1)
            .u8(2)
            .i32(i as i32 - 1);
    }
    b.u8(4).u32(0).u32(1).u32(2).u32(3);
    let path = dir.write("be.ply", &b.buf);

    let (cloud, report) = read_cloud_report(&path).expect("cloud");
    assert_eq!(report.format, CloudFormat::Ply(PlyFormat::BinaryBigEndian));
    assert_eq!(report.ignored_elements, vec!["face"]);
    assert_eq!(cloud.points[2], Point3::new(1.0, 1.0, 0.5));
    assert_eq!(cloud.colors.as_deref().expect("colours")[3], [30, 1, 2]);
    assert_eq!(cloud.labels, Some(vec![-1, 0, 1, 2]));

    let (mesh, report) = read_mesh_report(&path).expect("mesh");
    assert_eq!(
        mesh.faces,
        vec![[0, 1, 2], [0, 2, 3]],
        "quad split as a fan"
    );
    assert_eq!(report.polygons_triangulated, 1);
}

#[test]
fn io_float_and_double_coordinates_little_endian() {
    let dir = Scratch::new("le");
    let xyz = ["property float x", "property float y", "property float z"];
    let mut lines = vec!["element vertex 2"];
    lines.extend(xyz);
    let mut b = Bytes::new(false, &header("binary_little_endian", &lines));
    b.f32(0.1).f32(0.2).f32(0.3).f32(-1.5).f32(2.5).f32(1e-3);
    let path = dir.write("f32.ply", &b.buf);
    let c = read_cloud(&path).expect("float");
    assert_eq!(
        c.points[0],
        Point3::new(f64::from(0.1f32), f64::from(0.2f32), f64::from(0.3f32))
    );

    let xyz = [
        "property double x",
        "property double y",
        "property double z",
    ];
    let mut lines = vec!["element vertex 1"];
    lines.extend(xyz);
    let mut b = Bytes::new(false, &header("binary_little_endian", &lines));
    b.f64(0.1).f64(0.2).f64(0.3);
    let path = dir.write("f64.ply", &b.buf);
    assert_eq!(
        read_cloud(&path).expect("double").points[0],
        Point3::new(0.1, 0.2, 0.3)
    );
}

#[test]
fn io_integer_coordinates_and_float_colors_are_tolerated() {
    let dir = Scratch::new("ints");
    let h = header(
        "ascii",
        &[
            "element vertex 2",
            "property short x",
            "property int y",
            "property uchar z",
            "property float red",
            "property float green",
            "property float blue",
            "property ushort label",
        ],
    );
    let path = dir.write(
        "ints.ply",
        format!("{h}-3 100000 7 1.0 0.5 0 0\n4 -5 0 0 0 0.2 65535\n").as_bytes(),
    );
    let c = read_cloud(&path).expect("read");
    assert_eq!(
        c.points,
        vec![
            Point3::new(-3.0, 100000.0, 7.0),
            Point3::new(4.0, -5.0, 0.0)
        ]
    );
    assert_eq!(c.colors, Some(vec![[255, 128, 0], [0, 0, 51]]));
    assert_eq!(c.labels, Some(vec![0, 65535]));
}

// ---------------------------------------------------------------------------------
// other tools' conventions

#[test]
fn io_sized_type_names_ascii_and_binary() {
    let dir = Scratch::new("sized");
    let lines = [
        "element vertex 2",
        "property float32 x",
        "property float32 y",
        "property float64 z",
        "property uint8 red",
        "property uint8 green",
        "property uint8 blue",
        "property int32 label",
        "property float32 intensity",
        "element face 1",
        "property list uint8 int32 vertex_indices",
    ];
    let text = format!(
        "{}1 2 3 4 5 6 7 0.5\n-1 -2 -3 9 8 7 -7 0.25\n3 0 1 1\n",
        header("ascii", &lines)
    );
    let path = dir.write("sized.ply", text.as_bytes());
    let (c, report) = read_cloud_report(&path).expect("ascii");
    assert_eq!(c.points[1], Point3::new(-1.0, -2.0, -3.0));
    assert_eq!(c.colors, Some(vec![[4, 5, 6], [9, 8, 7]]));
    assert_eq!(c.labels, Some(vec![7, -7]));
    assert_eq!(report.ignored_properties, vec!["intensity"]);

    let mut b = Bytes::new(false, &header("binary_little_endian", &lines));
    b.f32(1.0)
        .f32(2.0)
        .f64(3.0)
        .u8(4)
        .u8(5)
        .u8(6)
        .i32(7)
        .f32(0.5);
    b.f32(-1.0)
        .f32(-2.0)
        .f64(-3.0)
        .u8(9)
        .u8(8)
        .u8(7)
        .i32(-7)
        .f32(0.25);
    b.u8(3).i32(0).i32(1).i32(1);
    let path = dir.write("sized.bin.ply", &b.buf);
    assert_eq!(read_cloud(&path).expect("binary"), c);
}

#[test]
fn io_meshlab_ascii_with_quads_alpha_and_comments() {
    let dir = Scratch::new("meshlab");
    let h = "ply\nformat ascii 1.0\ncomment VCGLIB generated\nelement vertex 5\n\
             property float x\nproperty float y\nproperty float z\n\
             property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n\
             element face 3\nproperty list uchar int vertex_indices\ncomment trailing comment\nend_header\n";
    let body = "0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n0 1 0 9 9 9 255\n\
                0.5 0.5 1 1 2 3 255\n4 0 1 2 3 \n5 0 1 2 3 4\n2 0 1\n";
    let path = dir.write("meshlab.ply", format!("{h}{body}").as_bytes());
    let (mesh, report) = read_mesh_report(&path).expect("mesh");
    assert_eq!(mesh.vertices.len(), 5);
    assert_eq!(
        mesh.faces,
        vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3], [0, 3, 4]]
    );
    assert_eq!(report.polygons_triangulated, 2);
    assert_eq!(report.skipped_degenerate, 1);
    let (cloud, report) = read_cloud_report(&path).expect("cloud");
    assert_eq!(cloud.colors.expect("colours")[3], [9, 9, 9]);
    assert_eq!(report.ignored_properties, vec!["alpha"]);
    assert_eq!(
        report.comments,
        vec!["VCGLIB generated", "trailing comment"]
    );
}

#[test]
fn io_cloudcompare_binary_with_obj_info_and_scalar_fields() {
    let dir = Scratch::new("cc");
    let h = "ply\nformat binary_little_endian 1.0\ncomment Author: CloudCompare (TELECOM PARISTECH/EDF R&D)\n\
             obj_info Generated by CloudCompare!\nelement vertex 2\nproperty double x\nproperty double y\n\
             property double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
             property float scalar_Intensity\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n";
    let mut b = Bytes::new(false, h);
    b.f64(1.0)
        .f64(2.0)
        .f64(3.0)
        .u8(1)
        .u8(2)
        .u8(3)
        .f32(0.7)
        .f32(0.0)
        .f32(0.0)
        .f32(1.0);
    b.f64(4.0)
        .f64(5.0)
        .f64(6.0)
        .u8(4)
        .u8(5)
        .u8(6)
        .f32(0.1)
        .f32(1.0)
        .f32(0.0)
        .f32(0.0);
    let path = dir.write("cc.ply", &b.buf);
    let (c, report) = read_cloud_report(&path).expect("read");
    assert_eq!(c.normals, Some(vec![Vector3::z(), Vector3::x()]));
    assert_eq!(report.ignored_properties, vec!["scalar_Intensity"]);
    assert!(
        report
            .comments
            .contains(&"Generated by CloudCompare!".to_string())
    );
}

#[test]
fn io_open3d_binary_double_normals_colors() {
    let dir = Scratch::new("o3d");
    let h = "ply\nformat binary_little_endian 1.0\ncomment Created by Open3D\nelement vertex 1\n\
             property double x\nproperty double y\nproperty double z\nproperty double nx\n\
             property double ny\nproperty double nz\nproperty uchar red\nproperty uchar green\n\
             property uchar blue\nend_header\n";
    let mut b = Bytes::new(false, h);
    b.f64(0.5)
        .f64(0.25)
        .f64(0.125)
        .f64(0.0)
        .f64(-1.0)
        .f64(0.0)
        .u8(7)
        .u8(8)
        .u8(9);
    let path = dir.write("o3d.ply", &b.buf);
    let c = read_cloud(&path).expect("read");
    assert_eq!(c.normals, Some(vec![-Vector3::y()]));
    assert_eq!(c.colors, Some(vec![[7, 8, 9]]));
}

#[test]
fn io_pcl_ascii_with_nan_normal_names_and_extra_elements() {
    let dir = Scratch::new("pcl");
    let h = "ply\nformat ascii 1.0\ncomment PCL generated\nobj_info is_cyclic 0\nobj_info is_organized 1\n\
             element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             property float normal_x\nproperty float normal_y\nproperty float normal_z\nproperty float curvature\n\
             element camera 1\nproperty float view_px\nproperty float view_py\nproperty float view_pz\n\
             element range_grid 3\nproperty list uchar int vertex_indices\nend_header\n";
    let body = "1 2 3 0 0 1 0.01\nnan nan nan nan nan nan nan\n4 5 6 1 0 0 0\n0 0 0\n1 0\n0\n1 2\n";
    let path = dir.write("pcl.ply", format!("{h}{body}").as_bytes());
    let (c, report) = read_cloud_report(&path).expect("read");
    assert_eq!(
        c.points,
        vec![Point3::new(1.0, 2.0, 3.0), Point3::new(4.0, 5.0, 6.0)]
    );
    assert_eq!(c.normals, Some(vec![Vector3::z(), Vector3::x()]));
    assert_eq!(report.skipped_non_finite, 1);
    assert_eq!(report.ignored_elements, vec!["camera", "range_grid"]);
    assert_eq!(report.ignored_properties, vec!["curvature"]);
}

#[test]
fn io_vertex_index_int_counts_diffuse_colors_crlf_and_spacing() {
    let dir = Scratch::new("variants");
    let h = "ply\r\nformat ascii 1.0\r\nelement vertex 4\r\nproperty float x\r\nproperty float y\r\n\
             property float z\r\nproperty uchar diffuse_red\r\nproperty uchar diffuse_green\r\n\
             property uchar diffuse_blue\r\nelement face 1\r\nproperty list int int vertex_index\r\nend_header\r\n";
    let body = "0 0 0 1 2 3\r\n  1\t0 0 4 5 6  \r\n\r\n1 1 0 7 8 9\r\n0 1 0 .5e1 5. 0\r\n4 3 2 1 0\r\n\r\n   \r\n";
    let path = dir.write("variants.ply", format!("{h}{body}").as_bytes());
    let c = read_cloud(&path).expect("cloud");
    assert_eq!(
        c.colors,
        Some(vec![[1, 2, 3], [4, 5, 6], [7, 8, 9], [5, 5, 0]])
    );
    let m = read_mesh(&path).expect("mesh");
    assert_eq!(m.faces, vec![[3, 2, 1], [3, 1, 0]]);
}

#[test]
fn io_mesh_faces_before_vertices_and_extra_face_properties() {
    let dir = Scratch::new("order");
    let h = header(
        "ascii",
        &[
            "element face 1",
            "property uchar flags",
            "property list uchar uint vertex_indices",
            "property float quality",
            "element vertex 3",
            "property double x",
            "property double y",
            "property double z",
            "element edge 1",
            "property int vertex1",
            "property int vertex2",
        ],
    );
    let path = dir.write(
        "order.ply",
        format!("{h}7 3 2 1 0 0.5\n0 0 0\n1 0 0\n0 1 0\n0 1\n").as_bytes(),
    );
    let (m, report) = read_mesh_report(&path).expect("mesh");
    assert_eq!(m.faces, vec![[2, 1, 0]]);
    assert_eq!(report.ignored_elements, vec!["edge"]);
}

#[test]
fn io_non_finite_points_are_dropped_from_every_attribute() {
    let dir = Scratch::new("nan");
    let h = header(
        "ascii",
        &[
            "element vertex 5",
            "property float x",
            "property float y",
            "property float z",
            "property float nx",
            "property float ny",
            "property float nz",
            "property int label",
        ],
    );
    let body =
        "0 0 0 1 0 0 10\nNaN 0 0 1 0 0 11\n1 inf 0 1 0 0 12\n2 0 -inf 1 0 0 13\n3 0 0 nan 0 0 14\n";
    let path = dir.write("nan.ply", format!("{h}{body}").as_bytes());
    let (c, report) = read_cloud_report(&path).expect("read");
    assert_eq!(report.skipped_non_finite, 3);
    assert_eq!(report.points_kept(), 2);
    assert_eq!(c.labels, Some(vec![10, 14]), "labels follow their points");
    assert_eq!(c.points[1], Point3::new(3.0, 0.0, 0.0));
    assert_eq!(c.normals.as_ref().map(Vec::len), Some(2));
    assert!(report.warnings()[0].contains("skipped 3 of 5"));

    let mut lines = vec![
        "element vertex 2",
        "property float x",
        "property float y",
        "property float z",
    ];
    lines.push("property int label");
    let mut b = Bytes::new(false, &header("binary_little_endian", &lines));
    b.f32(f32::NAN)
        .f32(0.0)
        .f32(0.0)
        .i32(1)
        .f32(1.0)
        .f32(2.0)
        .f32(3.0)
        .i32(2);
    let path = dir.write("nan.bin.ply", &b.buf);
    let (c, report) = read_cloud_report(&path).expect("read");
    assert_eq!((c.labels, report.skipped_non_finite), (Some(vec![2]), 1));
}

// ---------------------------------------------------------------------------------
// bad input

#[test]
fn io_missing_file() {
    let dir = Scratch::new("missing");
    let path = dir.path("nope.ply");
    let r = read_cloud(&path);
    assert!(matches!(r, Err(Error::Io { .. })));
    fails(r, &path, "No such file");
    fails(read_mesh(&path), &path, "No such file");
}

#[test]
fn io_directory_and_empty_file() {
    let dir = Scratch::new("dir");
    let sub = dir.path("sub.ply");
    fs::create_dir(&sub).expect("mkdir");
    fails(read_cloud(&sub), &sub, "is a directory");
    let empty = dir.write("empty.ply", b"");
    fails(read_cloud(&empty), &empty, "empty");
    // A device (size unknown, so read as a stream).
    let null = Path::new("/dev/null");
    if null.exists() {
        fails(read_cloud(null), null, "empty");
    }
}

#[test]
fn io_not_a_ply_file() {
    let dir = Scratch::new("magic");
    let png = dir.write("image.ply", b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR");
    fails(read_cloud(&png), &png, "not a PLY file");
    let stl = dir.write("cube.ply", b"solid cube\nfacet normal 0 0 1\n");
    fails(read_cloud(&stl), &stl, "not a PLY file");
    // A large binary blob without a newline: rejected after a bounded read.
    let blob = dir.write("blob.ply", &vec![7u8; 3 << 20]);
    fails(read_cloud(&blob), &blob, "not a PLY file");
}

#[test]
fn io_bad_header_lines() {
    let dir = Scratch::new("header");
    let cases: &[(&str, &str, &str)] = &[
        (
            "fmt.ply",
            "ply\nformat binary_middle_endian 1.0\nelement vertex 0\nend_header\n",
            "unknown format 'binary_middle_endian'",
        ),
        (
            "nofmt.ply",
            "ply\nelement vertex 0\nproperty float x\nend_header\n",
            "format",
        ),
        (
            "noend.ply",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
            "no 'end_header'",
        ),
        (
            "kw.ply",
            "ply\nformat ascii 1.0\nelemnt vertex 1\nend_header\n",
            "line 3: unknown keyword 'elemnt'",
        ),
        (
            "count.ply",
            "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n",
            "count '-3'",
        ),
        (
            "huge.ply",
            "ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\nend_header\n",
            "non-negative integer",
        ),
        (
            "type.ply",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty int64 x\nend_header\n0\n",
            "line 4: cannot parse 'property int64 x'",
        ),
        (
            "orphan.ply",
            "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
            "before any element",
        ),
        (
            "dup.ply",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\nend_header\n1 1\n",
            "declared twice",
        ),
        (
            "dupel.ply",
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nelement vertex 0\nend_header\n",
            "element 'vertex' is declared twice",
        ),
    ];
    for (name, text, needle) in cases {
        let path = dir.write(name, text.as_bytes());
        fails(read_cloud(&path), &path, needle);
    }
    let long = format!(
        "ply\nformat ascii 1.0\n{}",
        "comment aaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\n".repeat(40_000)
    );
    let path = dir.write("long.ply", long.as_bytes());
    fails(read_cloud(&path), &path, "longer than");
}

#[test]
fn io_missing_coordinates_and_missing_vertex_element() {
    let dir = Scratch::new("schema");
    let h = header(
        "ascii",
        &[
            "element vertex 1",
            "property float x",
            "property float y",
            "property float w",
        ],
    );
    let path = dir.write("noz.ply", format!("{h}1 2 3\n").as_bytes());
    fails(read_cloud(&path), &path, "no 'z' property");
    let h = header(
        "ascii",
        &[
            "element vertex 1",
            "property float x",
            "property float y",
            "property list uchar float z",
        ],
    );
    let path = dir.write("listz.ply", format!("{h}1 2 1 3\n").as_bytes());
    fails(read_cloud(&path), &path, "'z' is a list");
    let h = header(
        "ascii",
        &["element face 1", "property list uchar int vertex_indices"],
    );
    let path = dir.write("nov.ply", format!("{h}3 0 1 2\n").as_bytes());
    fails(
        read_cloud(&path),
        &path,
        "no 'vertex' element (it has: [face])",
    );
}

#[test]
fn io_truncated_binary_body() {
    let dir = Scratch::new("trunc-bin");
    let lines = [
        "element vertex 3",
        "property float x",
        "property float y",
        "property float z",
    ];
    let mut b = Bytes::new(false, &header("binary_little_endian", &lines));
    b.f32(1.0).f32(2.0).f32(3.0).f32(4.0).f32(5.0);
    let path = dir.write("short.ply", &b.buf);
    fails(read_cloud(&path), &path, "truncated file or corrupt count");

    // Lists make the size check a lower bound only: the cut is found while reading.
    let lines = [
        "element vertex 3",
        "property float x",
        "property float y",
        "property float z",
        "element face 2",
        "property list uchar int vertex_indices",
    ];
    let mut b = Bytes::new(false, &header("binary_little_endian", &lines));
    for _ in 0..9 {
        b.f32(0.5);
    }
    b.u8(3).i32(0).i32(1).i32(2).u8(3).i32(0).i32(1);
    let path = dir.write("cut-face.ply", &b.buf);
    fails(
        read_mesh(&path),
        &path,
        "the file ends inside 'face' element 1 of 2",
    );
    fails(
        read_cloud(&path),
        &path,
        "the file ends inside 'face' element 1 of 2",
    );
}

#[test]
fn io_truncated_ascii_body_and_count_mismatches() {
    let dir = Scratch::new("trunc-ascii");
    let h = header(
        "ascii",
        &[
            "element vertex 3",
            "property float x",
            "property float y",
            "property float z",
        ],
    );
    let path = dir.write(
        "fewer.ply",
        format!("{h}1.5 2.5 3.5\n4.5 5.5 6.5\n").as_bytes(),
    );
    fails(
        read_cloud(&path),
        &path,
        "the file ends after 2 of 3 'vertex' elements",
    );
    let path = dir.write(
        "cut.ply",
        format!("{h}1.5 2.5 3.5\n4.5 5.5 6.5\n7.5 8.5").as_bytes(),
    );
    fails(
        read_cloud(&path),
        &path,
        "line 10 ('vertex' element 2): too few values: missing 'z'",
    );
    let path = dir.write(
        "more.ply",
        format!("{h}1 2 3\n4 5 6\n7 8 9\n10 11 12\n").as_bytes(),
    );
    fails(
        read_cloud(&path),
        &path,
        "line 11: unexpected data '10 11 12' after the last element",
    );
    let path = dir.write("wide.ply", format!("{h}1 2 3\n4 5 6 7\n7 8 9\n").as_bytes());
    fails(
        read_cloud(&path),
        &path,
        "line 9 ('vertex' element 1): unexpected extra value '7'",
    );
    let path = dir.write(
        "word.ply",
        format!("{h}1 2 3\n4 five 6\n7 8 9\n").as_bytes(),
    );
    fails(read_cloud(&path), &path, "'five' is not a number");
    // Whitespace after the last element is fine.
    let path = dir.write(
        "ws.ply",
        format!("{h}1 2 3\n4 5 6\n7 8 9\n\n  \t\n").as_bytes(),
    );
    assert_eq!(read_cloud(&path).expect("trailing whitespace").len(), 3);
}

#[test]
fn io_ascii_value_out_of_type_range() {
    let dir = Scratch::new("range");
    let h = header(
        "ascii",
        &[
            "element vertex 1",
            "property float x",
            "property float y",
            "property float z",
            "property uchar red",
        ],
    );
    let path = dir.write("range.ply", format!("{h}1 2 3 300\n").as_bytes());
    fails(read_cloud(&path), &path, "300 is out of range for uchar");
}

#[test]
fn io_binary_trailing_bytes() {
    let dir = Scratch::new("trail-bin");
    let lines = [
        "element vertex 1",
        "property float x",
        "property float y",
        "property float z",
    ];
    let mut b = Bytes::new(false, &header("binary_little_endian", &lines));
    b.f32(1.0).f32(2.0).f32(3.0);
    let mut ok = b.buf.clone();
    ok.extend_from_slice(b"\n");
    let path = dir.write("newline.ply", &ok);
    assert_eq!(
        read_cloud(&path)
            .expect("a trailing newline is tolerated")
            .len(),
        1
    );
    b.f32(4.0);
    let path = dir.write("extra.ply", &b.buf);
    fails(
        read_cloud(&path),
        &path,
        "unexpected data right after the last element",
    );
}

#[test]
fn io_absurd_counts_fail_fast_without_allocating() {
    let dir = Scratch::new("absurd");
    let start = Instant::now();
    for format in ["binary_little_endian", "binary_big_endian", "ascii"] {
        let lines = [
            "element vertex 4000000000",
            "property float x",
            "property float y",
            "property float z",
        ];
        let mut text = header(format, &lines).into_bytes();
        text.resize(200, b'1');
        let path = dir.write(&format!("absurd-{format}.ply"), &text);
        let msg = fails(read_cloud(&path), &path, "4000000000 'vertex' elements");
        assert!(msg.contains("truncated file or corrupt count"), "{msg}");
        fails(read_mesh(&path), &path, "4000000000");
    }
    // An absurd face count after a valid vertex element.
    let lines = [
        "element vertex 1",
        "property float x",
        "property float y",
        "property float z",
        "element face 4000000000",
        "property list uchar int vertex_indices",
    ];
    let mut b = Bytes::new(false, &header("binary_little_endian", &lines));
    b.f32(1.0).f32(2.0).f32(3.0).u8(3).i32(0).i32(0).i32(0);
    let path = dir.write("absurd-face.ply", &b.buf);
    fails(read_mesh(&path), &path, "4000000000 'face' elements");
    // An absurd list length inside a face: ply-rs-bw caps its reservation; the read
    // then hits the end of the file.
    let lines = [
        "element vertex 1",
        "property float x",
        "property float y",
        "property float z",
        "element face 1",
        "property list uint int vertex_indices",
    ];
    let mut b = Bytes::new(false, &header("binary_little_endian", &lines));
    b.f32(1.0).f32(2.0).f32(3.0).u32(4_000_000_000).i32(0);
    let path = dir.write("absurd-list.ply", &b.buf);
    fails(
        read_mesh(&path),
        &path,
        "the file ends inside 'face' element 0 of 1",
    );
    let text = format!("{}1 2 3\n4000000000 0 0 0\n", header("ascii", &lines));
    let path = dir.write("absurd-list-ascii.ply", text.as_bytes());
    fails(
        read_mesh(&path),
        &path,
        "list declares 4000000000 values but has 3",
    );
    // Elements without properties take no bytes: a huge count is read past at once.
    let lines = [
        "element vertex 1",
        "property float x",
        "property float y",
        "property float z",
        "element nothing 4000000000",
    ];
    let path = dir.write(
        "empty-elements.ply",
        format!("{}1 2 3\n", header("ascii", &lines)).as_bytes(),
    );
    assert_eq!(read_cloud(&path).expect("zero-size elements").len(), 1);
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "took {:?}",
        start.elapsed()
    );
}

#[test]
fn io_mesh_bad_indices_and_missing_faces() {
    let dir = Scratch::new("mesh-bad");
    let v = [
        "element vertex 4",
        "property float x",
        "property float y",
        "property float z",
    ];
    let verts = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n";
    let mut lines = v.to_vec();
    lines.extend(["element face 2", "property list uchar int vertex_indices"]);
    let h = header("ascii", &lines);
    let path = dir.write(
        "range.ply",
        format!("{h}{verts}3 0 1 2\n4 0 1 7 3\n").as_bytes(),
    );
    fails(
        read_mesh(&path),
        &path,
        "face 1: vertex index 7 is out of range (the file has 4 vertices)",
    );
    let path = dir.write(
        "neg.ply",
        format!("{h}{verts}3 0 1 2\n3 0 -1 2\n").as_bytes(),
    );
    fails(
        read_mesh(&path),
        &path,
        "face 1: vertex index -1 is out of range",
    );
    let path = dir.write(
        "nofaces.ply",
        format!("{}{verts}", header("ascii", &v)).as_bytes(),
    );
    fails(read_mesh(&path), &path, "no 'face' element");
    let mut lines = v.to_vec();
    lines.extend(["element face 1", "property list uchar float vertex_indices"]);
    let path = dir.write(
        "floatidx.ply",
        format!("{}{verts}3 0 1 2\n", header("ascii", &lines)).as_bytes(),
    );
    fails(read_mesh(&path), &path, "no integer list 'vertex_indices'");
    let path = dir.write(
        "nanv.ply",
        format!("{h}0 0 0\nnan 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n").as_bytes(),
    );
    fails(
        read_mesh(&path),
        &path,
        "mesh vertex 1 has a non-finite coordinate",
    );
}

// ---------------------------------------------------------------------------------
// writers and atomic writes

#[test]
fn io_write_rejects_inconsistent_input_without_creating_files() {
    let dir = Scratch::new("write-bad");
    let mut cloud = full_cloud();
    cloud.labels.as_mut().expect("labels").pop();
    let path = dir.path("bad.ply");
    assert!(matches!(
        write_cloud(&path, &cloud, Encoding::Ascii),
        Err(Error::Mismatch { what: "labels", .. })
    ));
    let (mut mesh, prims) = small_mesh();
    assert!(matches!(
        write_mesh(&path, &mesh, Some(&prims[1..]), Encoding::Ascii),
        Err(Error::Mismatch {
            what: "face_primitive",
            ..
        })
    ));
    mesh.faces.push([0, 1, 99]);
    let e = write_mesh(&path, &mesh, None, Encoding::Ascii).expect_err("bad index");
    assert!(e.to_string().contains("faces[3][2] = 99"), "{e}");
    assert!(dir.files().is_empty(), "{:?}", dir.files());
}

#[test]
fn io_write_atomic_failure_keeps_old_file_and_leaves_no_temp() {
    let dir = Scratch::new("atomic");
    let path = dir.write("out.json", b"old");
    let r = write_atomic(&path, |w| {
        w.write_all(b"partial").map_err(|e| Error::io("x", e))?;
        Err(Error::invalid("simulated failure"))
    });
    assert!(r.is_err());
    assert_eq!(fs::read(&path).expect("old file"), b"old");
    assert_eq!(dir.files(), vec!["out.json"]);

    // A panic inside the writer also cleans up.
    let caught = std::panic::catch_unwind(|| {
        let _ = write_atomic(&path, |_| panic!("simulated panic"));
    });
    assert!(caught.is_err());
    assert_eq!(dir.files(), vec!["out.json"]);
    assert_eq!(fs::read(&path).expect("old file"), b"old");

    write_atomic(&path, |w| {
        w.write_all(b"new").map_err(|e| Error::io("x", e))
    })
    .expect("write");
    assert_eq!(fs::read(&path).expect("new file"), b"new");
    assert_eq!(dir.files(), vec!["out.json"]);
}

/// Two outputs that must appear together: the first is staged, and a failure of the
/// second drops it (old file kept, no temporary left); committed, it replaces the target.
#[test]
fn io_staged_file_is_written_only_on_commit() {
    let dir = Scratch::new("staged");
    let json = dir.write("result.json", b"old");
    let staged = stage_json(&json, &serde_json::json!({"new": true})).expect("stage");
    assert_eq!(fs::read(&json).expect("old file"), b"old");
    assert_eq!(dir.files().len(), 2, "{:?}", dir.files()); // the staged temporary
    let missing = dir.path("no/such/dir/fitted.ply");
    let second = write_mesh(&missing, &TriMesh::default(), None, Encoding::Ascii);
    assert!(second.is_err());
    drop(staged);
    assert_eq!(fs::read(&json).expect("old file"), b"old");
    assert_eq!(dir.files(), vec!["result.json"]);

    stage_json(&json, &serde_json::json!({"new": true}))
        .expect("stage")
        .commit()
        .expect("commit");
    assert_eq!(
        fs::read_to_string(&json).expect("new file"),
        "{\n  \"new\": true\n}\n"
    );
    assert_eq!(dir.files(), vec!["result.json"]);
}

#[test]
fn io_write_atomic_bad_targets() {
    let dir = Scratch::new("atomic-bad");
    let missing = dir.path("no/such/dir/out.ply");
    let r = write_cloud(&missing, &full_cloud(), Encoding::Ascii);
    assert!(matches!(r, Err(Error::Io { .. })));
    fails(r, &missing, "out.ply");
    let sub = dir.path("taken");
    fs::create_dir(&sub).expect("mkdir");
    fails(
        write_cloud(&sub, &full_cloud(), Encoding::Ascii),
        &sub,
        "taken",
    );
    assert_eq!(dir.files(), vec!["taken"], "no temporary file left");
}

#[test]
fn io_write_json_atomic_round_trip() {
    let dir = Scratch::new("json");
    let path = dir.path("result.json");
    let v =
        serde_json::json!({ "primfit": crate::VERSION, "primitives": [ { "type": "square" } ] });
    write_json_atomic(&path, &v).expect("write");
    let text = fs::read_to_string(&path).expect("read");
    assert!(text.ends_with("}\n"));
    let back: serde_json::Value = serde_json::from_str(&text).expect("parse");
    assert_eq!(back, v);
}

#[test]
fn io_palette_cycles() {
    assert_eq!(palette_color(0), PALETTE[0]);
    assert_eq!(palette_color(PALETTE.len() + 1), PALETTE[1]);
}

// ---------------------------------------------------------------------------------
// real files

/// The bundled scans, when present (`None` with a printed note otherwise). Looked for
/// in `$PRIMFIT_DATA_DIR`, then `shared/data` inside the repository, then beside it.
fn data_file(name: &str) -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let candidates = [
        std::env::var_os("PRIMFIT_DATA_DIR").map(PathBuf::from),
        Some(root.join("shared/data")),
        Some(root.join("../shared/data")),
    ];
    match candidates.into_iter().flatten().find(|d| d.is_dir()) {
        Some(dir) => Some(dir.join(name)),
        None => {
            println!("note: skipping the {name} test: no shared/data folder found");
            None
        }
    }
}

#[test]
fn io_real_bunny_ascii_with_faces() {
    let Some(path) = data_file("bunny.ply") else {
        return;
    };
    let (cloud, report) = read_cloud_report(&path).expect("bunny");
    assert_eq!(cloud.len(), 35947);
    assert_eq!(report.format, CloudFormat::Ply(PlyFormat::Ascii));
    assert_eq!(report.ignored_properties, vec!["confidence", "intensity"]);
    assert_eq!(report.ignored_elements, vec!["face"]);
    let mesh = read_mesh(&path).expect("bunny mesh");
    assert_eq!(mesh.vertices.len(), 35947);
    assert_eq!(mesh.faces.len(), 69451);
}

#[test]
fn io_real_sac_plane_test() {
    let Some(path) = data_file("sac_plane_test.ply") else {
        return;
    };
    let cloud = read_cloud(&path).expect("sac_plane_test");
    assert_eq!(cloud.len(), 3283);
    assert_eq!(cloud.normals.as_ref().map(Vec::len), Some(3283));
}

#[test]
fn io_real_table_scene_mug() {
    let Some(path) = data_file("table_scene_mug_stereo_textured.ply") else {
        return;
    };
    let (cloud, report) = read_cloud_report(&path).expect("table_scene_mug");
    assert_eq!(cloud.len(), 209280);
    assert_eq!(cloud.colors.as_ref().map(Vec::len), Some(209280));
    assert_eq!(report.skipped_non_finite, 0);
    // And it survives a write/read round trip unchanged.
    let dir = Scratch::new("mug");
    let out = dir.path("mug.ply");
    write_cloud(&out, &cloud, Encoding::BinaryLittleEndian).expect("write");
    assert_eq!(read_cloud(&out).expect("read back"), cloud);
}
