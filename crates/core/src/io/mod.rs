//! File input/output: PLY point clouds and triangle meshes, atomic file writes, JSON.
//!
//! # Reading
//!
//! [`read_cloud`] / [`read_cloud_report`] read the `vertex` element of any PLY file
//! (ascii, binary little- or big-endian) into a [`PointCloud`]:
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
//! ones (`float32`, `uint8`, `int32`). Points with a non-finite coordinate are dropped
//! (from every attribute) and counted in [`ReadReport::skipped_non_finite`]. An empty
//! cloud is not an error here; [`ReadReport::warnings`] mentions it.
//!
//! [`read_mesh`] / [`read_mesh_report`] read `vertex` positions and the `face` element's
//! `vertex_indices` (or `vertex_index`) lists into a [`TriMesh`]; polygons are
//! fan-triangulated.
//!
//! Every failure is an [`Error::Io`] or [`Error::Format`] whose one-line message names
//! the file and the fault (missing file, not a PLY file, unknown format, truncated body,
//! header counts that disagree with the body, counts too large for the file, …). No
//! memory proportional to a header count is reserved before the file is known to be
//! large enough to hold that many elements.
//!
//! # Writing
//!
//! [`write_cloud`] and [`write_mesh`] write PLY files in an [`Encoding`] (binary
//! little-endian by default, or ascii); coordinates, normals and sensor origins are
//! written as `double`, so a write/read round trip is lossless. Every writer goes through
//! [`write_atomic`]: the data goes to a temporary file beside the target that is renamed
//! over it only once complete, so a failed run never leaves a partial file or clobbers an
//! existing one. [`write_json_atomic`] does the same for JSON values.

mod atomic;
pub mod json;
mod palette;
mod ply;

#[cfg(test)]
mod tests;

use std::fmt;

pub use atomic::{StagedFile, stage, stage_json, write_atomic, write_json_atomic};
pub use palette::{PALETTE, palette_color};
pub use ply::{
    read_cloud, read_cloud_report, read_mesh, read_mesh_report, write_cloud, write_mesh,
    write_mesh_colored,
};

#[allow(unused_imports)] // for the doc links above
use crate::{Error, PointCloud, TriMesh};

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
    /// The file's body encoding.
    pub format: PlyFormat,
    /// Number of vertices the file holds (kept + skipped).
    pub vertices_in_file: usize,
    /// Vertices dropped because a coordinate was NaN or infinite.
    pub skipped_non_finite: usize,
    /// Vertex properties that were read past (e.g. `intensity`, `confidence`), in header
    /// order, including parts of incomplete attributes (e.g. `nx` without `ny`).
    pub ignored_properties: Vec<String>,
    /// Elements other than `vertex` that were read past (e.g. `face`), in header order.
    pub ignored_elements: Vec<String>,
    /// The header's `comment` and `obj_info` lines, without the keyword.
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
