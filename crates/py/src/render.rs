//! Pictures of a fit: `render` (a PNG, as `primfit render`).

use std::path::PathBuf;

use numpy::PyReadonlyArray2;
use primfit_core::Result;
use primfit_core::render::{RenderOptions, View, render as draw};
use pyo3::prelude::*;

use crate::convert::{self, ToPyResult};
use crate::io::{parse_primitives, primitive_list};
use crate::pool;

/// Renders `cloud` (J, 3), coloured by distance to the primitives (a JSON list in the
/// `result.json` format), and the shaded primitives as a PNG at `path` (atomically);
/// returns the distance at the top of the colour scale (scene units).
#[pyfunction]
#[pyo3(signature = (path, cloud, primitives_json, *, width=1200, height=900, view=None, scale=None))]
#[allow(clippy::too_many_arguments)]
pub fn render(
    py: Python<'_>,
    path: PathBuf,
    cloud: PyReadonlyArray2<'_, f64>,
    primitives_json: &str,
    width: u32,
    height: u32,
    view: Option<(f64, f64)>,
    scale: Option<f64>,
) -> PyResult<f64> {
    let points = convert::points("cloud", &cloud, false)?;
    let list = primitive_list(primitives_json)?;
    let view = match view {
        Some((azimuth, elevation)) => Some(format!("{azimuth},{elevation}").parse::<View>().py()?),
        None => None,
    };
    let options = RenderOptions {
        width,
        height,
        view,
        scale,
        max_points: None,
    };
    pool::detached(py, || -> Result<f64> {
        let (prims, _) = parse_primitives(&list)?;
        let picture = draw(&points, &prims, &options)?;
        picture.write_png(&path)?;
        Ok(picture.scale)
    })?
    .py()
}
