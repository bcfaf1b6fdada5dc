//! `fit`: the whole pipeline of the CLI's `primfit fit`, on an array; and `candidates`:
//! the candidate set such a fit would optimise over, as explicit samples.

use std::path::PathBuf;

use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use primfit_core::Silent;
use primfit_core::atlas::{MeshShape, ShapeKind};
use primfit_core::chamfer::PointModel;
use primfit_core::fit::FrameChoice;
use primfit_core::fit::{
    self as core_fit, FitOptions, FitResult, McmcFitOptions, MethodOptions, parse_types,
};
use primfit_core::metrics::{self, MetricsOptions};
use primfit_core::na::Point3;
use primfit_core::refine::RefineOptions;
use primfit_core::solve::{Parameterization, SolverOptions};
use primfit_core::{Limit, PointCloud, Result, io};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyString;

use crate::chamfer::ChamferProblem;
use crate::convert::{self, ToPyResult};
use crate::io::cloud_arrays;
use crate::pool;
use crate::synth::points_array;

/// Options of a fit: every flag of `primfit fit`, under the same names (`None` = the
/// library's default, [`FitOptions::default`], or a value derived from the cloud).
#[pyclass(module = "primfit._primfit", name = "FitOptions", frozen)]
pub struct PyFitOptions(pub(crate) FitOptions);

/// The options of `--method mcmc`, as given (`None` = the library's default).
struct McmcArgs {
    steps: Option<usize>,
    burn_in: Option<usize>,
    noise_rate: Option<f64>,
    sigma: Option<f64>,
    prior: Option<f64>,
}

#[pymethods]
impl PyFitOptions {
    #[new]
    #[pyo3(signature = (
        *, types=None, size=None, radius=None, bend=None, spacing=None, origin=None, frame=None,
        refine=None, refine_rounds=None, sample_spacing=None, model=None, alpha=None, beta=None,
        cap=None, weights=None, method=None, steps=None, burn_in=None, noise_rate=None,
        sigma=None, prior=None, parameterization=None, max_iterations=None, search_points=None,
        polish=None, seed=None, mesh_model=None, memory_budget=None,
        work_budget=None, free_space=None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        types: Option<&Bound<'_, PyAny>>,
        size: Option<f64>,
        radius: Option<f64>,
        bend: Option<f64>,
        spacing: Option<f64>,
        origin: Option<&Bound<'_, PyAny>>,
        frame: Option<&Bound<'_, PyAny>>,
        refine: Option<bool>,
        refine_rounds: Option<usize>,
        sample_spacing: Option<f64>,
        model: Option<&str>,
        alpha: Option<&Bound<'_, PyAny>>,
        beta: Option<&Bound<'_, PyAny>>,
        cap: Option<f64>,
        weights: Option<&Bound<'_, PyAny>>,
        method: Option<&str>,
        steps: Option<usize>,
        burn_in: Option<usize>,
        noise_rate: Option<f64>,
        sigma: Option<f64>,
        prior: Option<f64>,
        parameterization: Option<&str>,
        max_iterations: Option<usize>,
        search_points: Option<&Bound<'_, PyAny>>,
        polish: Option<bool>,
        seed: Option<u64>,
        mesh_model: Option<&Bound<'_, PyAny>>,
        memory_budget: Option<u64>,
        work_budget: Option<f64>,
        free_space: Option<bool>,
    ) -> PyResult<Self> {
        let d = FitOptions::default();
        let weights = convert::floats::<2>("weights", weights)?;
        let mcmc = McmcArgs {
            steps,
            burn_in,
            noise_rate,
            sigma,
            prior,
        };
        Ok(PyFitOptions(FitOptions {
            kinds: kinds(types)?.unwrap_or(d.kinds),
            size,
            radius,
            bend,
            spacing,
            origin: convert::floats::<3>("origin", origin)?.map(Point3::from),
            frame: frame_choice(py, frame)?.unwrap_or(d.frame),
            refine: refinement(refine, refine_rounds, d.refine),
            sample_spacing,
            model: model
                .map(PointModel::parse)
                .transpose()
                .py()?
                .unwrap_or(d.model),
            alpha: convert::limit("alpha", alpha)?.unwrap_or(d.alpha),
            beta: convert::limit("beta", beta)?.unwrap_or(d.beta),
            cap,
            primitive_weight: weights.map_or(d.primitive_weight, |w| w[0]),
            point_weight: weights.map_or(d.point_weight, |w| w[1]),
            mesh: mesh_shape(mesh_model)?,
            solver: SolverOptions {
                parameterization: parameterization
                    .map(Parameterization::parse)
                    .transpose()
                    .py()?
                    .unwrap_or(d.solver.parameterization),
                max_iterations: max_iterations.unwrap_or(d.solver.max_iterations),
                search_points: search_point_limit(search_points)?.unwrap_or(d.solver.search_points),
                polish: polish.unwrap_or(d.solver.polish),
                ..d.solver
            },
            method: method_options(method, mcmc)?.unwrap_or(d.method),
            memory_budget,
            work_budget,
            free_space: free_space.or(d.free_space),
            seed: seed.unwrap_or(d.seed),
        }))
    }
}

/// `types` as a list of names or one comma-separated string.
fn kinds(types: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Vec<ShapeKind>>> {
    let Some(types) = types.filter(|t| !t.is_none()) else {
        return Ok(None);
    };
    let names: Vec<String> = match types.cast::<PyString>() {
        Ok(s) => s.to_str()?.split(',').map(str::to_owned).collect(),
        Err(_) => types
            .try_iter()?
            .map(|t| t?.extract::<String>())
            .collect::<PyResult<_>>()?,
    };
    let names: Vec<&str> = names
        .iter()
        .map(|t| t.trim())
        .filter(|t| !t.is_empty())
        .collect();
    Ok(Some(parse_types(&names).py()?))
}

/// `frame`: `"auto"`, `"axis"`, a dict `{"rotation": [w, x, y, z], "origin": [x, y, z]}`
/// (or a `result.json` document), or the path of such a JSON file, as `--frame`.
fn frame_choice(py: Python<'_>, frame: Option<&Bound<'_, PyAny>>) -> PyResult<Option<FrameChoice>> {
    let Some(frame) = frame.filter(|f| !f.is_none()) else {
        return Ok(None);
    };
    let text = if let Ok(s) = frame.cast::<PyString>() {
        match s.to_str()? {
            name @ ("auto" | "axis") => return FrameChoice::parse(name).py().map(Some),
            path => std::fs::read_to_string(path)
                .map_err(|e| PyOSError::new_err(format!("frame {path:?}: {e}")))?,
        }
    } else {
        let json = py.import("json")?;
        json.call_method1("dumps", (frame,))?.extract::<String>()?
    };
    let value: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| PyValueError::new_err(format!("frame is not valid JSON: {e}")))?;
    FrameChoice::from_json(&value).py().map(Some)
}

/// Refinement on (the default) or off (`refine=False`), with `refine_rounds` rounds.
fn refinement(
    on: Option<bool>,
    rounds: Option<usize>,
    default: Option<RefineOptions>,
) -> Option<RefineOptions> {
    if on == Some(false) {
        return None;
    }
    let base = default.unwrap_or_default();
    Some(RefineOptions {
        rounds: rounds.unwrap_or(base.rounds),
        ..base
    })
}

/// `search_points`: a count, `0` or `"inf"` for one phase on every point.
fn search_point_limit(v: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Limit>> {
    match v {
        Some(v) if v.extract::<i64>().ok() == Some(0) => Ok(Some(Limit::All)),
        other => convert::limit("search_points", other),
    }
}

/// The method called `name` with its options (ignored by `chamfer`, as by the CLI).
fn method_options(name: Option<&str>, a: McmcArgs) -> PyResult<Option<MethodOptions>> {
    let Some(name) = name else { return Ok(None) };
    Ok(Some(match MethodOptions::parse(name).py()? {
        MethodOptions::Mcmc(d) => MethodOptions::Mcmc(McmcFitOptions {
            rate: a.noise_rate,
            sigma: a.sigma,
            prior: a.prior.unwrap_or(d.prior),
            steps: a.steps,
            burn_in: a.burn_in,
            ..d
        }),
        chamfer => chamfer,
    }))
}

/// `mesh_model`: the path of a PLY mesh (as `--mesh-model`), or `(vertices (V, 3)
/// float64, faces (F, 3) int64)`.
pub(crate) fn mesh_shape(mesh_model: Option<&Bound<'_, PyAny>>) -> PyResult<Option<MeshShape>> {
    let Some(m) = mesh_model.filter(|m| !m.is_none()) else {
        return Ok(None);
    };
    if let Ok(path) = m.extract::<PathBuf>() {
        let mesh = io::read_mesh(&path).py()?;
        return MeshShape::new(path.display().to_string(), mesh)
            .py()
            .map(Some);
    }
    let (v, f): (PyReadonlyArray2<'_, f64>, PyReadonlyArray2<'_, i64>) = m.extract()?;
    MeshShape::new("python", convert::mesh(&v, &f)?)
        .py()
        .map(Some)
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

/// Fits primitives to `cloud (J, 3)` (with the per-point `normals`, `labels` and sensor
/// origins `sensors` the `mcmc` method uses), as `primfit fit`. Returns `(result_json,
/// existence)`: the `result.json` document (settings, metrics, primitives) and the
/// existence probability of each chosen primitive.
#[pyfunction]
#[pyo3(signature = (cloud, options, *, normals=None, labels=None, sensors=None))]
pub fn fit<'py>(
    py: Python<'py>,
    cloud: PyReadonlyArray2<'py, f64>,
    options: &PyFitOptions,
    normals: Option<PyReadonlyArray2<'py, f64>>,
    labels: Option<PyReadonlyArray1<'py, i32>>,
    sensors: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<(String, Bound<'py, PyArray1<f64>>)> {
    let cloud = cloud_arrays(cloud, normals, None, labels, sensors, false)?;
    let (doc, existence) = pool::cancellable(py, |interrupt| -> Result<_> {
        let result = core_fit::fit(&cloud, &options.0, interrupt)?;
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

/// Reads back a fit's `result.json` (checked against the library's schema,
/// [`FitResult::from_json`]): the existence of each primitive. Mesh sources are read as
/// paths.
#[pyfunction]
pub fn read_result<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let doc: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| PyValueError::new_err(format!("the result is not valid JSON: {e}")))?;
    let existence = pool::detached(py, || -> Result<Vec<f64>> {
        let load = |source: &str| -> Result<MeshShape> {
            MeshShape::new(source, io::read_mesh(std::path::Path::new(source))?)
        };
        Ok(FitResult::from_json(&doc, &load)?.0.existence)
    })?
    .py()?;
    Ok(existence.into_pyarray(py))
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
        let (settings, set) = core_fit::fit_candidates(&cloud, &options.0)?;
        let (samples, owner) = core_fit::candidate_samples(&set, settings.memory_budget)?;
        let owner: Vec<i64> = owner.into_iter().map(|o| o as i64).collect();
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
    let coeffs = pool::detached(py, || {
        core_fit::fit_problem(&cloud, &options.0, &Silent).map(|(_, coefficients)| coefficients)
    })?
    .py()?;
    Ok(coeffs.into())
}
