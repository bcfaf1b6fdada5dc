//! What the PCD, LAS, E57 and text readers share: a cloud built point by point (points
//! with a non-finite coordinate dropped and counted), and ascii lines read with a
//! length limit.

use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

use nalgebra::{Point3, Vector3};

use super::{CloudFormat, ReadReport};
use crate::{Error, PointCloud, Result};

/// Readers reserve at most this many points up front when a count is not yet known to
/// be backed by the file's size (then grow as data arrives).
pub(crate) const RESERVE_CAP: usize = 1 << 20;

/// The longest text line read, in bytes.
pub(crate) const MAX_LINE_BYTES: u64 = 16 << 20;

/// A cloud built point by point.
pub(crate) struct Collector {
    cloud: PointCloud,
    skipped: usize,
}

impl Collector {
    /// An empty cloud with normals and colours if asked, room for `reserve` points
    /// (capped at [`RESERVE_CAP`] unless `trusted`).
    pub fn new(normals: bool, colors: bool, reserve: usize, trusted: bool) -> Self {
        let reserve = if trusted {
            reserve
        } else {
            reserve.min(RESERVE_CAP)
        };
        let cloud = PointCloud {
            points: Vec::with_capacity(reserve),
            normals: normals.then(|| Vec::with_capacity(reserve)),
            colors: colors.then(|| Vec::with_capacity(reserve)),
            ..Default::default()
        };
        Collector { cloud, skipped: 0 }
    }

    /// Appends one point (its normal and colour go where the cloud has them), or counts
    /// it as skipped when a coordinate is not finite.
    pub fn push(&mut self, xyz: [f64; 3], normal: [f64; 3], rgb: [u8; 3]) {
        if !xyz.iter().all(|v| v.is_finite()) {
            self.skipped += 1;
            return;
        }
        let c = &mut self.cloud;
        c.points.push(Point3::from(xyz));
        if let Some(n) = c.normals.as_mut() {
            n.push(Vector3::from(normal));
        }
        if let Some(v) = c.colors.as_mut() {
            v.push(rgb);
        }
    }

    /// Number of points seen (kept and skipped).
    pub fn seen(&self) -> usize {
        self.cloud.len() + self.skipped
    }

    /// Mutable access to the colours (for a rescale once all are known).
    pub fn colors_mut(&mut self) -> Option<&mut Vec<[u8; 3]>> {
        self.cloud.colors.as_mut()
    }

    /// The cloud and its report.
    pub fn finish(
        self,
        format: CloudFormat,
        ignored_properties: Vec<String>,
        comments: Vec<String>,
    ) -> (PointCloud, ReadReport) {
        let report = ReadReport {
            format,
            vertices_in_file: self.seen(),
            skipped_non_finite: self.skipped,
            ignored_properties,
            ignored_elements: Vec::new(),
            comments,
        };
        (self.cloud, report)
    }
}

/// Reads a text body line by line, with a length limit, counting lines.
pub(crate) struct Lines<R> {
    reader: R,
    path: PathBuf,
    /// 1-based number of the line last read.
    line_no: usize,
    /// The line last read, without its line ending.
    text: String,
}

impl<R: BufRead> Lines<R> {
    /// A line reader whose next line is line `first_line` of the file.
    pub fn new(reader: R, path: &Path, first_line: usize) -> Self {
        Lines {
            reader,
            path: path.to_path_buf(),
            line_no: first_line.saturating_sub(1),
            text: String::new(),
        }
    }

    /// Reads the next line ([`Lines::line`]); `false` at the end of the file. Fails on
    /// a line longer than [`MAX_LINE_BYTES`] or one that is not UTF-8 text.
    pub fn next_line(&mut self) -> Result<bool> {
        let mut buf = std::mem::take(&mut self.text).into_bytes();
        buf.clear();
        let n = (&mut self.reader)
            .take(MAX_LINE_BYTES)
            .read_until(b'\n', &mut buf)
            .map_err(|e| Error::io(&self.path, e))?;
        if n == 0 {
            return Ok(false);
        }
        self.line_no += 1;
        if n as u64 == MAX_LINE_BYTES && !buf.ends_with(b"\n") {
            return Err(self.error(format!("longer than {MAX_LINE_BYTES} bytes")));
        }
        if buf.contains(&0) {
            return Err(self.error("a NUL byte: not text"));
        }
        while buf.last().is_some_and(|b| *b == b'\n' || *b == b'\r') {
            buf.pop();
        }
        self.text = String::from_utf8(buf).map_err(|_| self.error("not UTF-8 text"))?;
        Ok(true)
    }

    /// The line last read.
    pub fn line(&self) -> &str {
        &self.text
    }

    /// An error about the line last read.
    pub fn error(&self, msg: impl std::fmt::Display) -> Error {
        Error::format(&self.path, format!("line {}: {msg}", self.line_no))
    }
}
