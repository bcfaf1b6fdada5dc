//! File input/output: point clouds in many formats, PLY triangle meshes, atomic file
//! writes, JSON.
//!
//! # Reading clouds
//!
//! [`read_cloud`] / [`read_cloud_report`] read a point cloud from any of these formats,
//! chosen by the file's extension (any case) and checked against its first bytes:
//!
//! | extension | format | reader |
//! |---|---|---|
//! | `.ply` | PLY ascii, binary little- or big-endian | `ply-rs-bw` under our header and body checks |
//! | `.pcd` | PCD (PCL) ascii, binary, binary_compressed; organised or not | hand-written, LZF by `lzf-rust` (see `io/pcd`) |
//! | `.las`, `.laz` | LAS 1.0–1.4, LAZ | the `las` crate with `laz` |
//! | `.e57` | E57 (all scans, poses applied) | the `e57` crate |
//! | `.xyz`, `.txt`, `.pts`, `.csv` | text, with or without a header row | hand-written |
//!
//! An unknown extension, or content that is another format's (a `.pcd` name on a LAS
//! file), is an [`Error::UnknownFormat`] naming the file and the formats accepted. A
//! regular file without an extension is recognised by its first bytes (text when it
//! has none of the magics); a pipe or device without one is read as PLY.
//!
//! Coordinates are kept as `f64` in the file's frame (LAS/LAZ/E57 georeferenced values
//! near 10⁶ m included; the fit works in a local frame, see `fit`).
//!
//! ## PLY
//!
//! The `vertex` element of any PLY file is read:
//!
//! | PLY vertex property | goes to | accepted types |
//! |---|---|---|
//! | `x, y, z` (required) | `points` | float, double, any integer type |
//! | `nx, ny, nz` or `normal_x, normal_y, normal_z` (PCL) | `normals` | float, double, any integer type |
//! | `red, green, blue` or `diffuse_red, diffuse_green, diffuse_blue` | `colors` | uchar as is; other integer types clamped to 0‥255; float/double read as 0‥1 and scaled by 255 |
//! | `label` | `labels` | any integer type (values beyond `i32` saturate) |
//! | `sensor_x, sensor_y, sensor_z` | `sensors` | float, double, any integer type |
//!
//! An optional attribute is present only when all of its properties are (e.g. all three
//! of `nx, ny, nz`). Other vertex properties (`intensity`, `confidence`, `alpha`, …) and
//! other elements (`face`, `edge`, …) are read past and listed in the [`ReadReport`].
//! Header type names may be the classic ones (`float`, `uchar`, `int`) or the sized
//! ones (`float32`, `uint8`, `int32`).
//!
//! ## Other formats
//!
//! PCD gives `x y z`, `normal_x normal_y normal_z` and packed `rgb`/`rgba`; LAS/LAZ and
//! E57 give positions and colours; text gives `x y z`, normals and colours by header
//! name (the modules `pcd`, `las`, `e57` and `text` say exactly what).
//!
//! ## For every format
//!
//! Points with a non-finite coordinate (NaN holes of organised PCD clouds, invalid E57
//! points) are dropped (from every attribute) and counted in
//! [`ReadReport::skipped_non_finite`]. An empty cloud is not an error here;
//! [`ReadReport::warnings`] mentions it.
//!
//! Every failure is an [`Error::Io`], [`Error::Format`] or [`Error::UnknownFormat`]
//! whose one-line message names the file and the fault (missing file, wrong magic,
//! unknown encoding or compression, truncated body, counts that disagree with each
//! other or are too large for the file, …). No memory proportional to a count in the
//! file is reserved before the file is known to be large enough to hold that many
//! points (or, for compressed bodies, before the count is within what the compressed
//! bytes can expand to), and a read never writes anything.
//!
//! [`read_mesh`] / [`read_mesh_report`] read `vertex` positions and the `face` element's
//! `vertex_indices` (or `vertex_index`) lists of a PLY file into a [`TriMesh`]; polygons
//! are fan-triangulated.
//!
//! # Writing
//!
//! [`write_cloud`] and [`write_mesh`] write PLY files in an [`Encoding`] (binary
//! little-endian by default, or ascii); coordinates, normals and sensor origins are
//! written as `double`, so a write/read round trip is lossless. Every writer goes through
//! [`write_atomic`]: the data goes to a temporary file beside the target that is renamed
//! over it only once complete, so a failed run never leaves a partial file or clobbers an
//! existing one. [`write_json_atomic`] does the same for JSON values.
//!
//! [`write_primitives_mesh`] writes fitted primitives as PLY, OBJ or glTF binary
//! (`.glb`), chosen by the path's extension ([`MeshFormat`]; see the `export` module).

mod atomic;
mod collect;
mod detect;
mod e57;
mod export;
mod guard;
pub(crate) mod json;
mod las;
pub use las::write_las;
mod palette;
mod pcd;
mod ply;
mod text;

#[cfg(test)]
mod tests;

use std::fmt;

use std::path::Path;

pub use atomic::{
    StagedFile, remove_temporary_files, stage, stage_json, writable_target, write_atomic,
    write_json_atomic,
};
pub use detect::{ACCEPTED_FORMATS, CloudFormat, PcdData, TextKind};
pub use export::{MESH_FORMATS, MeshFormat, write_primitives_mesh};
pub use palette::{PALETTE, palette_color};
pub use ply::{read_mesh, read_mesh_report, write_cloud, write_mesh, write_mesh_colored};

use self::detect::Kind;
#[allow(unused_imports)] // for the doc links above
use crate::{Error, PointCloud, Result, TriMesh};

/// Reads a point cloud from a file of any accepted format (see the [module
/// docs](crate::io)); [`read_cloud_report`] also says what was skipped.
///
/// ```
/// use primfit_core::io::read_cloud;
///
/// let dir = std::env::temp_dir().join(format!("primfit-doc-read-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// let path = dir.join("two.ply");
/// std::fs::write(&path, "ply
/// format ascii 1.0
/// element vertex 2
/// property float x
/// property float y
/// property float z
/// property uchar red
/// property uchar green
/// property uchar blue
/// end_header
/// 0 0 0 255 0 0
/// 1 2 3 0 0 255
/// ")?;
/// let cloud = read_cloud(&path)?;
/// assert_eq!(cloud.len(), 2);
/// assert_eq!((cloud.points[1].x, cloud.points[1].z), (1.0, 3.0));
/// assert_eq!(cloud.colors.as_deref(), Some(&[[255, 0, 0], [0, 0, 255]][..]));
/// assert!(cloud.normals.is_none());
///
/// // The same points as CSV text with a header row.
/// let csv = dir.join("two.csv");
/// std::fs::write(&csv, "x,y,z,red,green,blue\n0,0,0,255,0,0\n1,2,3,0,0,255\n")?;
/// assert_eq!(read_cloud(&csv)?, cloud);
/// std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn read_cloud(path: &Path) -> Result<PointCloud> {
    read_cloud_report(path).map(|(cloud, _)| cloud)
}

/// Reads a point cloud and reports on the file: its format, points skipped for a
/// non-finite coordinate, and the properties (and PLY elements) read past.
pub fn read_cloud_report(path: &Path) -> Result<(PointCloud, ReadReport)> {
    match detect::detect(path)? {
        Kind::Ply => ply::read_cloud_report(path),
        Kind::Pcd => pcd::read_cloud_report(path),
        Kind::Las => guard::decoder(path, "LAS/LAZ", || las::read_cloud_report(path)),
        Kind::E57 => guard::decoder(path, "E57", || e57::read_cloud_report(path)),
        Kind::Text(kind) => text::read_cloud_report(path, kind),
    }
}

/// How [`write_cloud`] and [`write_mesh`] encode a PLY body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Encoding {
    /// `format binary_little_endian 1.0`: compact and fast; the default.
    #[default]
    BinaryLittleEndian,
    /// `format ascii 1.0`: human-readable; values are written in Rust's shortest
    /// round-trip decimal form.
    Ascii,
}

/// The encoding a PLY file was found to use (reading accepts all three of the format).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyFormat {
    /// `format ascii 1.0`.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

impl fmt::Display for PlyFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PlyFormat::Ascii => "ascii",
            PlyFormat::BinaryLittleEndian => "binary_little_endian",
            PlyFormat::BinaryBigEndian => "binary_big_endian",
        })
    }
}

/// What [`read_cloud_report`] found besides the cloud itself.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadReport {
    /// The file's format and encoding.
    pub format: CloudFormat,
    /// Number of points (PLY vertices) the file holds (kept + skipped).
    pub vertices_in_file: usize,
    /// Vertices dropped because a coordinate was NaN or infinite.
    pub skipped_non_finite: usize,
    /// Vertex properties (PCD fields, text columns) that were read past (e.g.
    /// `intensity`, `confidence`), in header order, including parts of incomplete
    /// attributes (e.g. `nx` without `ny`).
    pub ignored_properties: Vec<String>,
    /// Elements other than `vertex` that were read past (e.g. `face`), in header order.
    pub ignored_elements: Vec<String>,
    /// The header's `comment` and `obj_info` lines (PCD and text: `#` lines), without
    /// the keyword.
    pub comments: Vec<String>,
}

impl ReadReport {
    /// Number of points kept in the cloud.
    pub fn points_kept(&self) -> usize {
        self.vertices_in_file - self.skipped_non_finite
    }

    /// Human-readable notes on anything the caller may want to tell a user about:
    /// skipped points, an empty cloud. Empty when there is nothing to say.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.skipped_non_finite > 0 {
            out.push(format!(
                "skipped {} of {} points with a NaN or infinite coordinate",
                self.skipped_non_finite, self.vertices_in_file
            ));
        }
        if self.points_kept() == 0 {
            out.push("the cloud has no points".to_string());
        }
        out
    }
}

/// What [`read_mesh_report`] found besides the mesh itself.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MeshReport {
    /// The file's body encoding.
    pub format: PlyFormat,
    /// Number of faces in the file.
    pub faces_in_file: usize,
    /// Faces with more than three vertices, split into a fan of triangles.
    pub polygons_triangulated: usize,
    /// Faces with fewer than three vertices, dropped.
    pub skipped_degenerate: usize,
    /// Elements other than `vertex` and `face` that were read past.
    pub ignored_elements: Vec<String>,
}

/// Whether `path` is a LAS or LAZ file (by extension, checked by its first bytes), which
/// [`crate::tiles`] reads in batches; errs as [`read_cloud`] does on an unknown format.
pub(crate) fn is_las(path: &Path) -> Result<bool> {
    Ok(matches!(detect::detect(path)?, detect::Kind::Las))
}

/// The points of the LAS/LAZ file `path` in batches (see `las::visit_points`), a panic of
/// the decoder turned into an error as for [`read_cloud`].
pub(crate) fn visit_las_points(path: &Path, visit: &mut dyn FnMut(&[[f64; 3]])) -> Result<u64> {
    guard::decoder(path, "LAS/LAZ", || las::visit_points(path, visit))
}

/// The points `first .. first + count` of the LAS/LAZ file `path` in batches (see
/// `las::visit_point_range`), a decoder panic turned into an error.
pub(crate) fn visit_las_range(
    path: &Path,
    first: u64,
    count: u64,
    visit: &mut dyn FnMut(&[[f64; 3]]),
) -> Result<u64> {
    guard::decoder(path, "LAS/LAZ", || {
        las::visit_point_range(path, first, count, visit)
    })
}

/// The header bounds and point count of the LAS/LAZ file `path` (see `las::header_bounds`).
pub(crate) fn las_header_bounds(path: &Path) -> Result<([f64; 3], [f64; 3], u64)> {
    guard::decoder(path, "LAS/LAZ", || las::header_bounds(path))
}
