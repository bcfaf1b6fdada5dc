//! A tile's points from a file without holding the file: LAS/LAZ is read in batches and
//! only the points of the tile's haloed box are kept. Other formats are read whole and
//! then cut (their readers hold the cloud): convert a survey to LAZ to tile it with
//! bounded memory.

use std::path::Path;

use nalgebra::Point3;

use super::TileGrid;
use crate::{Error, Result, io};

/// The xyz bounds `(min, max)` of the survey in `path` (scene units) and its point
/// count: from the header of a LAS/LAZ file (no point is read), else from the points.
pub fn survey_bounds(path: &Path) -> Result<(Point3<f64>, Point3<f64>, u64)> {
    if io::is_las(path)? {
        let (lo, hi, n) = io::las_header_bounds(path)?;
        return Ok((Point3::from(lo), Point3::from(hi), n));
    }
    let cloud = io::read_cloud(path)?;
    let (lo, hi) = cloud.bounds().ok_or(Error::EmptyCloud)?;
    Ok((lo, hi, cloud.len() as u64))
}

/// The points of `path` in tile `tile`'s haloed box of `grid` (scene units). A LAS/LAZ
/// file is read one batch at a time, so memory is bounded by the tile, not the file.
pub fn read_tile(path: &Path, grid: &TileGrid, tile: usize) -> Result<Vec<Point3<f64>>> {
    let mut out = Vec::new();
    let mut keep = |x: f64, y: f64, z: f64| {
        if grid.in_haloed(tile, x, y) {
            out.push(Point3::new(x, y, z));
        }
    };
    if io::is_las(path)? {
        io::visit_las_points(path, &mut |batch: &[[f64; 3]]| {
            for [x, y, z] in batch {
                keep(*x, *y, *z);
            }
        })?;
    } else {
        for p in io::read_cloud(path)?.points {
            keep(p.x, p.y, p.z);
        }
    }
    Ok(out)
}
