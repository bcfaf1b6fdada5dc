//! `fit`: the whole pipeline of the CLI's `primfit fit`, on an array.

use numpy::{IntoPyArray, PyArray1, PyReadonlyArray2};
use primfit_core::atlas::{MeshShape, ShapeKind};
use primfit_core::chamfer::PointModel;
use primfit_core::fit::{FitOptions, fit as core_fit};
use primfit_core::metrics::{self, MetricsOptions};
use primfit_core::na::Point3;
use primfit_core::progress::Silent;
use primfit_core::solve::{Parameterization, SolverOptions};
use primfit_core::{PointCloud, Result};
use pyo3::prelude::*;

use crate::convert::{self, ToPyResult};
use crate::pool;

/// What the facade needs of a fit: the result JSON (settings, metrics, primitives) and
/// the existence probability of each chosen primitive.
type FitOutput<'py> = (String, Bound<'py, PyArray1<f64>>);

/// Fits primitives to `cloud (J, 3)`; options as `primfit fit` (None = derived from the
/// cloud). Returns `(result_json, existence)`.
#[pyfunction]
#[pyo3(signature = (
    cloud, *, types=None, size=None, radius=None, bend=None, spacing=None, origin=None,
    sample_spacing=None, model="existence", alpha=None, beta=None, cap=None, weights=None,
    parameterization="box", max_iterations=200, polish=true, mesh_model=None, seed=0,
    memory_budget=None
))]
#[allow(clippy::too_many_arguments)]
pub fn fit<'py>(
    py: Python<'py>,
    cloud: PyReadonlyArray2<'py, f64>,
    types: Option<Vec<String>>,
    size: Option<f64>,
    radius: Option<f64>,
    bend: Option<f64>,
    spacing: Option<f64>,
    origin: Option<[f64; 3]>,
    sample_spacing: Option<f64>,
    model: &str,
    alpha: Option<&Bound<'py, PyAny>>,
    beta: Option<&Bound<'py, PyAny>>,
    cap: Option<f64>,
    weights: Option<(f64, f64)>,
    parameterization: &str,
    max_iterations: usize,
    polish: bool,
    mesh_model: Option<(PyReadonlyArray2<'py, f64>, PyReadonlyArray2<'py, i64>)>,
    seed: u64,
    memory_budget: Option<u64>,
) -> PyResult<FitOutput<'py>> {
    let cloud = PointCloud::from_points(convert::points("cloud", &cloud, false)?);
    let types = types.unwrap_or_else(|| vec!["square".into()]);
    let kinds = types
        .iter()
        .map(|t| ShapeKind::parse(t))
        .collect::<Result<Vec<_>>>()
        .py()?;
    let mesh = match mesh_model {
        Some((v, f)) => Some(MeshShape::new("python", convert::mesh(&v, &f)?).py()?),
        None => None,
    };
    let options = FitOptions {
        kinds,
        size,
        radius,
        bend,
        spacing,
        origin: origin.map(|[x, y, z]| Point3::new(x, y, z)),
        sample_spacing,
        model: PointModel::parse(model).py()?,
        alpha: convert::limit("alpha", alpha)?,
        beta: convert::limit("beta", beta)?,
        cap,
        primitive_weight: weights.map(|w| w.0),
        point_weight: weights.map(|w| w.1),
        mesh,
        solver: SolverOptions {
            parameterization: Parameterization::parse(parameterization).py()?,
            max_iterations,
            polish,
            ..Default::default()
        },
        memory_budget,
        seed,
    };
    let (doc, existence) = py
        .detach(|| {
            pool::run(|| -> Result<_> {
                let result = core_fit(&cloud, &options, &Silent)?;
                let metrics = measure(&cloud, &result)?;
                Ok((result.to_json(metrics), result.existence))
            })
        })?
        .py()?;
    let text = serde_json::to_string_pretty(&doc).map_err(|e| {
        pyo3::exceptions::PyRuntimeError::new_err(format!("cannot write result JSON: {e}"))
    })?;
    Ok((text, existence.into_pyarray(py)))
}

/// The measures of DESIGN §4 for a fit against its cloud.
fn measure(cloud: &PointCloud, result: &primfit_core::fit::FitResult) -> Result<serde_json::Value> {
    let m = metrics::evaluate(
        &cloud.points,
        &result.primitives,
        None,
        &MetricsOptions::default(),
    )?;
    Ok(m.to_json())
}
