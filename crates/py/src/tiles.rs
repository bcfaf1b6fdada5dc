//! Tiled fitting for `primfit.dask`: the grid, one tile's points from a file, the fit of
//! one tile (on a Dask worker), and the merge of the tiles (on the coordinator). Each
//! is a thin call into [`primfit_core::tiles`] with the GIL released.

use std::path::PathBuf;

use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use primfit_core::atlas::MeshShape;
use primfit_core::na::Point3;
use primfit_core::tiles::{self, TileFit, TileGrid};
use primfit_core::{Error, Result, bounds_of, io};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::convert::{self, ToPyResult};
use crate::fit::PyFitOptions;
use crate::pool;
use crate::synth::points_array;

fn grid_json(grid: &TileGrid) -> String {
    serde_json::to_string(grid).expect("a grid is plain numbers")
}

fn parse_grid(text: &str) -> PyResult<TileGrid> {
    serde_json::from_str(text).map_err(|e| PyValueError::new_err(format!("bad tile grid: {e}")))
}

fn make_grid(
    lo: &Point3<f64>,
    hi: &Point3<f64>,
    points: u64,
    tile_size: Option<f64>,
    halo: Option<f64>,
) -> Result<TileGrid> {
    let size = tile_size.unwrap_or_else(|| tiles::default_tile_size(lo, hi, points));
    TileGrid::new(lo, hi, size, tiles::default_halo(size, halo))
}

/// The tile grid of the survey in `path` (JSON) and its point count: LAS/LAZ bounds come
/// from the header, other formats are read.
#[pyfunction]
#[pyo3(signature = (path, tile_size=None, halo=None))]
pub fn tile_grid_file(
    py: Python<'_>,
    path: PathBuf,
    tile_size: Option<f64>,
    halo: Option<f64>,
) -> PyResult<(String, u64)> {
    let (grid, n) = pool::detached(py, || -> Result<_> {
        let (lo, hi, n) = tiles::survey_bounds(&path)?;
        Ok((make_grid(&lo, &hi, n, tile_size, halo)?, n))
    })?
    .py()?;
    Ok((grid_json(&grid), n))
}

/// The tile grid (JSON) of the points `cloud (J, 3)`.
#[pyfunction]
#[pyo3(signature = (cloud, tile_size=None, halo=None))]
pub fn tile_grid_array(
    cloud: PyReadonlyArray2<'_, f64>,
    tile_size: Option<f64>,
    halo: Option<f64>,
) -> PyResult<String> {
    let points = convert::points("cloud", &cloud, false)?;
    let (lo, hi) = bounds_of(&points).ok_or(Error::EmptyCloud).py()?;
    Ok(grid_json(
        &make_grid(&lo, &hi, points.len() as u64, tile_size, halo).py()?,
    ))
}

/// The points `(n, 3)` of tile `tile` of `grid` (its haloed box) read from `path`
/// (LAS/LAZ in batches).
#[pyfunction]
pub fn tile_points<'py>(
    py: Python<'py>,
    path: PathBuf,
    grid: &str,
    tile: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let grid = parse_grid(grid)?;
    let points = pool::detached(py, || tiles::read_tile(&path, &grid, tile))?.py()?;
    Ok(points_array(py, &points))
}

/// Splits the points `first .. first + count` of the LAS/LAZ survey `path` into per-tile
/// spill files in `dir` as splitter `part` ([`tiles::split_survey`]); returns the points
/// each tile received.
#[pyfunction]
pub fn split_survey(
    py: Python<'_>,
    path: PathBuf,
    grid: &str,
    first: u64,
    count: u64,
    dir: PathBuf,
    part: usize,
) -> PyResult<Vec<u64>> {
    let grid = parse_grid(grid)?;
    pool::detached(py, || {
        tiles::split_survey(&path, &grid, first, count, &dir, part)
    })?
    .py()
}

/// The points `(n, 3)` of tile `tile` from the spill files of splitters `0..parts` in
/// `dir` ([`tiles::read_spilled_tile`]).
#[pyfunction]
pub fn spilled_tile_points<'py>(
    py: Python<'py>,
    dir: PathBuf,
    tile: usize,
    parts: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let points = pool::detached(py, || tiles::read_spilled_tile(&dir, tile, parts))?.py()?;
    Ok(points_array(py, &points))
}

/// Fits tile `tile` of `grid` from `points (n, 3)` (at least its haloed box) with
/// `options`; returns the tile as JSON ([`TileFit::to_json`]).
#[pyfunction]
pub fn fit_tile(
    py: Python<'_>,
    points: PyReadonlyArray2<'_, f64>,
    grid: &str,
    tile: usize,
    options: &PyFitOptions,
) -> PyResult<String> {
    let grid = parse_grid(grid)?;
    let points = convert::points("points", &points, true)?;
    let doc = pool::cancellable(py, |interrupt| -> Result<_> {
        Ok(tiles::fit_tile(&points, &grid, tile, &options.0, interrupt)?.to_json())
    })?
    .py()?;
    Ok(doc.to_string())
}

/// Merges the tiles' JSON documents into one fit: returns `(result_json, existence)` as
/// `fit` does, the measures joined from the tiles' ([`tiles::joined_metrics`]).
#[pyfunction]
pub fn merge_tiles<'py>(
    py: Python<'py>,
    tiles_json: Vec<String>,
) -> PyResult<(String, Bound<'py, PyArray1<f64>>)> {
    let (doc, existence) = pool::detached(py, || -> Result<_> {
        let load = |source: &str| -> Result<MeshShape> {
            MeshShape::new(source, io::read_mesh(std::path::Path::new(source))?)
        };
        let mut fits = Vec::with_capacity(tiles_json.len());
        for (k, text) in tiles_json.iter().enumerate() {
            let doc: serde_json::Value = serde_json::from_str(text)
                .map_err(|e| Error::json(format!("tile {k}"), e.to_string()))?;
            fits.push(TileFit::from_json(&doc, &load)?);
        }
        let (result, metrics) = tiles::merge_tiles(fits)?;
        Ok((result.to_json(metrics.to_json()), result.existence))
    })?
    .py()?;
    let text = serde_json::to_string_pretty(&doc)
        .map_err(|e| PyValueError::new_err(format!("cannot write JSON: {e}")))?;
    Ok((text, existence.into_pyarray(py)))
}
