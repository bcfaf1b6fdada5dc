//! One pass over a survey file instead of one per tile: the file's points are cut into
//! per-tile spill files (each point goes to every tile whose haloed box holds it), and a
//! tile is then read from its own files. Several splitters may share the pass, each over
//! its own range of the file's points (`part`), writing its own files, so that the
//! decompression of a LAZ survey runs on every worker once.
//!
//! A spill file holds the tile's points as little-endian `f64` triples (24 bytes a point,
//! world coordinates, no header); its name is `tile-{tile}.part-{part}.xyz`. Memory is
//! bounded by [`SPILL_BUFFER_POINTS`], not by the file or the tile.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use nalgebra::Point3;

use super::TileGrid;
use crate::{Error, Result, io};

/// Points buffered across all tiles before they are appended to the spill files
/// (24 MiB of coordinates).
pub const SPILL_BUFFER_POINTS: usize = 1 << 20;

/// Bytes of one point in a spill file: three little-endian `f64`.
const SPILL_POINT_BYTES: usize = 24;

/// The spill file of tile `tile` written by splitter `part` in `dir`.
pub fn spill_path(dir: &Path, tile: usize, part: usize) -> PathBuf {
    dir.join(format!("tile-{tile}.part-{part}.xyz"))
}

/// Per-tile buffers of points waiting to be appended to their spill files.
struct Spill<'a> {
    dir: &'a Path,
    part: usize,
    buffers: Vec<Vec<[f64; 3]>>,
    buffered: usize,
    counts: Vec<u64>,
}

impl<'a> Spill<'a> {
    fn new(dir: &'a Path, part: usize, tiles: usize) -> Self {
        Spill {
            dir,
            part,
            buffers: vec![Vec::new(); tiles],
            buffered: 0,
            counts: vec![0; tiles],
        }
    }

    fn push(&mut self, tile: usize, p: [f64; 3]) -> Result<()> {
        self.buffers[tile].push(p);
        self.counts[tile] += 1;
        self.buffered += 1;
        if self.buffered >= SPILL_BUFFER_POINTS {
            self.flush()?;
        }
        Ok(())
    }

    /// Appends every tile's buffered points to its spill file (opened, written, closed:
    /// the number of open files does not grow with the tiles).
    fn flush(&mut self) -> Result<()> {
        for (tile, buffer) in self.buffers.iter_mut().enumerate() {
            if buffer.is_empty() {
                continue;
            }
            let path = spill_path(self.dir, tile, self.part);
            let file = OpenOptions::new()
                .create(true)
                .append(true)
                .open(&path)
                .map_err(|e| Error::io(&path, e))?;
            let mut out = BufWriter::with_capacity(1 << 16, file);
            for c in buffer.iter().flatten() {
                out.write_all(&c.to_le_bytes())
                    .map_err(|e| Error::io(&path, e))?;
            }
            out.flush().map_err(|e| Error::io(&path, e))?;
            buffer.clear();
        }
        self.buffered = 0;
        Ok(())
    }
}

/// Splits the points `first .. first + count` of the LAS/LAZ survey `path` into spill
/// files in `dir` (which must exist), one per tile of `grid` that receives points, as
/// splitter `part`. Returns how many points each tile received (its haloed box).
/// Files of an earlier split with the same `part` are replaced, not appended to.
pub fn split_survey(
    path: &Path,
    grid: &TileGrid,
    first: u64,
    count: u64,
    dir: &Path,
    part: usize,
) -> Result<Vec<u64>> {
    if !io::is_las(path)? {
        return Err(Error::format(
            path,
            "only LAS/LAZ surveys are split into tiles in one pass (convert it to LAZ)",
        ));
    }
    for tile in 0..grid.len() {
        let stale = spill_path(dir, tile, part);
        if stale.exists() {
            std::fs::remove_file(&stale).map_err(|e| Error::io(&stale, e))?;
        }
    }
    let mut spill = Spill::new(dir, part, grid.len());
    let mut failed = None;
    io::visit_las_range(path, first, count, &mut |batch: &[[f64; 3]]| {
        if failed.is_some() {
            return;
        }
        for &p in batch {
            for tile in grid.tiles_of(p[0], p[1]) {
                if let Err(e) = spill.push(tile, p) {
                    failed = Some(e);
                    return;
                }
            }
        }
    })?;
    if let Some(e) = failed {
        return Err(e);
    }
    spill.flush()?;
    Ok(spill.counts)
}

/// The points of tile `tile` from the spill files of splitters `0..parts` in `dir`
/// (a missing file is a part that gave the tile no point).
pub fn read_spilled_tile(dir: &Path, tile: usize, parts: usize) -> Result<Vec<Point3<f64>>> {
    let mut out = Vec::new();
    for part in 0..parts {
        let path = spill_path(dir, tile, part);
        let mut file = match File::open(&path) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(e) => return Err(Error::io(&path, e)),
        };
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes)
            .map_err(|e| Error::io(&path, e))?;
        if bytes.len() % SPILL_POINT_BYTES != 0 {
            let msg = format!("{} bytes is not a whole number of points", bytes.len());
            return Err(Error::format(&path, msg));
        }
        out.reserve(bytes.len() / SPILL_POINT_BYTES);
        for point in bytes.chunks_exact(SPILL_POINT_BYTES) {
            let c = |k: usize| f64::from_le_bytes(point[8 * k..8 * k + 8].try_into().unwrap());
            out.push(Point3::new(c(0), c(1), c(2)));
        }
    }
    Ok(out)
}
