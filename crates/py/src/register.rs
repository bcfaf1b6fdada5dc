//! `register`: the CLI's `primfit register` on arrays — the pose(s) of a mesh in a cloud,
//! each with its calibrated existence.

use numpy::{IntoPyArray, PyArray1, PyReadonlyArray2};
use primfit_core::metrics::{self, MetricsOptions};
use primfit_core::register::{self as core_register, RegisterOptions};
use primfit_core::{Primitive, Result};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::convert::ToPyResult;
use crate::fit::mesh_shape;
use crate::io::cloud_arrays;
use crate::pool;

/// Finds the object `model` (a PLY mesh path, or `(vertices (V, 3) float64, faces (F, 3)
/// int64)`) in `cloud (J, 3)` (with the per-point sensor origins `sensors`, when known),
/// as `primfit register`: the full pose by default, the translation kept with
/// `rotation_only`, a scale searched in `scale = (lo, hi)`; `count` objects, or every
/// copy whose existence reaches `min_confidence`. Returns `(result_json, existence)`.
#[pyfunction]
#[pyo3(signature = (
    cloud, model, *, sensors=None, count=None, min_confidence=None, rotation_only=false,
    scale=None, seed=0
))]
#[allow(clippy::too_many_arguments)]
pub fn register<'py>(
    py: Python<'py>,
    cloud: PyReadonlyArray2<'py, f64>,
    model: &Bound<'py, PyAny>,
    sensors: Option<PyReadonlyArray2<'py, f64>>,
    count: Option<usize>,
    min_confidence: Option<f64>,
    rotation_only: bool,
    scale: Option<(f64, f64)>,
    seed: u64,
) -> PyResult<(String, Bound<'py, PyArray1<f64>>)> {
    let cloud = cloud_arrays(cloud, None, None, None, sensors, false)?;
    let mesh = mesh_shape(Some(model))?
        .ok_or_else(|| PyValueError::new_err("model: a mesh path or (vertices, faces)"))?;
    let d = RegisterOptions::default();
    let options = RegisterOptions {
        translation: !rotation_only,
        scale,
        count,
        min_confidence: min_confidence.unwrap_or(d.min_confidence),
        seed,
        ..d
    };
    options.validate().py()?;
    let (doc, existence) = pool::cancellable(py, |interrupt| -> Result<_> {
        let found = core_register::register(&cloud, &mesh, &options, interrupt)?;
        let prims: Vec<Primitive> = found.objects.iter().map(|o| o.primitive.clone()).collect();
        let m = metrics::evaluate(&cloud.points, &prims, None, &MetricsOptions::default())?;
        let existence: Vec<f64> = found.objects.iter().map(|o| o.existence).collect();
        Ok((found.to_json(options.to_json(), m.to_json()), existence))
    })?
    .py()?;
    let text = serde_json::to_string_pretty(&doc)
        .map_err(|e| PyValueError::new_err(format!("cannot write JSON: {e}")))?;
    Ok((text, existence.into_pyarray(py)))
}
