//! `fit`: the whole pipeline of the CLI's `primfit fit`, on an array; and `candidates`:
//! the candidate set such a fit would optimise over, as explicit samples.

use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use primfit_core::atlas::{MeshShape, ShapeKind};
use primfit_core::chamfer::{CandidateGeometry, Coefficients, PointModel};
use primfit_core::fit::{self as core_fit, FitOptions, Settings};
use primfit_core::lattice::CandidateSet;
use primfit_core::metrics::{self, MetricsOptions};
use primfit_core::na::Point3;
use primfit_core::progress::Silent;
use primfit_core::solve::{Parameterization, SolverOptions};
use primfit_core::spatial::PointIndex;
use primfit_core::{PointCloud, Result};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

use crate::chamfer::ChamferProblem;
use crate::convert::{self, ToPyResult};
use crate::pool;
use crate::synth::points_array;

/// Options of a fit, as the flags of `primfit fit` (None = derived from the cloud).
#[pyclass(module = "primfit._primfit", name = "FitOptions", frozen)]
pub struct PyFitOptions(FitOptions);

#[pymethods]
impl PyFitOptions {
    #[new]
    #[pyo3(signature = (
        *, types=None, size=None, radius=None, bend=None, spacing=None, origin=None,
        sample_spacing=None, model="existence", alpha=None, beta=None, cap=None, weights=None,
        parameterization="box", max_iterations=200, polish=true, mesh_model=None, seed=0,
        memory_budget=None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        types: Option<Vec<String>>,
        size: Option<f64>,
        radius: Option<f64>,
        bend: Option<f64>,
        spacing: Option<f64>,
        origin: Option<[f64; 3]>,
        sample_spacing: Option<f64>,
        model: &str,
        alpha: Option<&Bound<'_, PyAny>>,
        beta: Option<&Bound<'_, PyAny>>,
        cap: Option<f64>,
        weights: Option<(f64, f64)>,
        parameterization: &str,
        max_iterations: usize,
        polish: bool,
        mesh_model: Option<(PyReadonlyArray2<'_, f64>, PyReadonlyArray2<'_, i64>)>,
        seed: u64,
        memory_budget: Option<u64>,
    ) -> PyResult<Self> {
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
        let d = FitOptions::lattice();
        Ok(PyFitOptions(FitOptions {
            kinds,
            size,
            radius,
            bend,
            spacing,
            origin: origin.map(|[x, y, z]| Point3::new(x, y, z)),
            sample_spacing,
            model: PointModel::parse(model).py()?,
            alpha: convert::limit("alpha", alpha)?.unwrap_or(d.alpha),
            beta: convert::limit("beta", beta)?.unwrap_or(d.beta),
            cap,
            primitive_weight: weights.map_or(d.primitive_weight, |w| w.0),
            point_weight: weights.map_or(d.point_weight, |w| w.1),
            mesh,
            solver: SolverOptions {
                parameterization: Parameterization::parse(parameterization).py()?,
                max_iterations,
                polish,
                ..Default::default()
            },
            memory_budget,
            seed,
            ..d
        }))
    }
}

/// `(settings_json, samples (K, 3), owner (K,), primitives_json)`.
type CandidateArrays<'py> = (
    String,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<i64>>,
    String,
);

fn json_text(v: &serde_json::Value) -> PyResult<String> {
    serde_json::to_string_pretty(v)
        .map_err(|e| PyRuntimeError::new_err(format!("cannot write JSON: {e}")))
}

/// Fits primitives to `cloud (J, 3)`. Returns `(result_json, existence)`: the
/// `result.json` document (settings, metrics, primitives) and the existence probability
/// of each chosen primitive.
#[pyfunction]
pub fn fit<'py>(
    py: Python<'py>,
    cloud: PyReadonlyArray2<'py, f64>,
    options: &PyFitOptions,
) -> PyResult<(String, Bound<'py, PyArray1<f64>>)> {
    let cloud = PointCloud::from_points(convert::points("cloud", &cloud, false)?);
    let (doc, existence) = pool::detached(py, || -> Result<_> {
        let result = core_fit::fit(&cloud, &options.0, &Silent)?;
        let m = metrics::evaluate(
            &cloud.points,
            &result.primitives,
            None,
            &MetricsOptions::default(),
        )?;
        Ok((result.to_json(m.to_json()), result.existence))
    })?
    .py()?;
    Ok((json_text(&doc)?, existence.into_pyarray(py)))
}

/// The candidates a fit of `cloud` with `options` would optimise over (the lattice after
/// the occupancy prior). Returns `(settings_json, samples (K, 3), owner (K,),
/// primitives_json)`: every candidate's surface samples in scene coordinates, the
/// candidate of each sample, and the candidates as primitives.
#[pyfunction]
pub fn candidates<'py>(
    py: Python<'py>,
    cloud: PyReadonlyArray2<'py, f64>,
    options: &PyFitOptions,
) -> PyResult<CandidateArrays<'py>> {
    let cloud = PointCloud::from_points(convert::points("cloud", &cloud, false)?);
    let (settings, samples, owner, primitives) = pool::detached(py, || -> Result<_> {
        let index = PointIndex::new(&cloud.points);
        let settings = Settings::resolve(&cloud, &index, &options.0)?;
        let set = CandidateSet::build(&settings.lattice(), &cloud)?;
        let (mut samples, mut owner, mut buf) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..set.len() {
            set.scene_samples(i, &mut buf);
            samples.extend_from_slice(&buf);
            owner.extend(std::iter::repeat_n(i as i64, buf.len()));
        }
        let primitives: Vec<_> = (0..set.len()).map(|i| set.primitive(i).to_json()).collect();
        Ok((
            settings.to_json(),
            samples,
            owner,
            serde_json::Value::Array(primitives),
        ))
    })?
    .py()?;
    Ok((
        json_text(&settings)?,
        points_array(py, &samples),
        owner.into_pyarray(py),
        json_text(&primitives)?,
    ))
}

/// The loss a fit of `cloud` with `options` minimises, over the same candidates and with
/// the same settings (model, alpha, beta, cap, weights, surface distances).
#[pyfunction]
pub fn fit_problem(
    py: Python<'_>,
    cloud: PyReadonlyArray2<'_, f64>,
    options: &PyFitOptions,
) -> PyResult<ChamferProblem> {
    let cloud = PointCloud::from_points(convert::points("cloud", &cloud, false)?);
    let coeffs = pool::detached(py, || -> Result<_> {
        let index = PointIndex::new(&cloud.points);
        let settings = Settings::resolve(&cloud, &index, &options.0)?;
        let set = CandidateSet::build(&settings.lattice(), &cloud)?;
        Coefficients::build(&cloud.points, &set, &settings.chamfer, &Silent)
    })?
    .py()?;
    Ok(coeffs.into())
}
