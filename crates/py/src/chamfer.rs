//! `ChamferProblem`: coefficients of the probabilistic chamfer built once, evaluated many
//! times (single vectors or batches), with the GIL released.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use primfit_core::Limit;
use primfit_core::Silent;
use primfit_core::budget;
use primfit_core::chamfer::{
    ChamferOptions, Coefficients, Evaluator, PointModel, SampleSets, check_memory,
};
use primfit_core::na::Point3;
use primfit_core::solve::{SolverOptions, solve_from};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use crate::convert::{self, ToPyResult};
use crate::pool;

/// `(totals (B,), grads (B, N))` of a batch evaluation.
type Batch<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray2<f64>>);

/// The probabilistic chamfer distance between a cloud and a fixed candidate set given
/// by explicit samples (DESIGN §2); its coefficients are computed once, here.
#[pyclass(module = "primfit._primfit", frozen)]
pub struct ChamferProblem {
    coeffs: Coefficients,
}

/// `None` and "unlimited" both mean every entry is kept (the exact loss).
fn exact_if_unlimited(v: Option<Limit>) -> Option<usize> {
    v.and_then(Limit::get)
}

impl From<Coefficients> for ChamferProblem {
    fn from(coeffs: Coefficients) -> Self {
        ChamferProblem { coeffs }
    }
}

/// Candidate samples and owners, and the candidate count (`n` or `max(owner) + 1`, ≥ 1).
fn candidate_samples(
    samples: &PyReadonlyArray2<'_, f64>,
    owner: &PyReadonlyArray1<'_, i64>,
    n: Option<usize>,
) -> PyResult<(Vec<Point3<f64>>, Vec<usize>, usize)> {
    let samples = convert::points("samples", samples, false)?;
    let owner = convert::indices("owner", owner)?;
    let n = n.unwrap_or_else(|| owner.iter().max().map_or(0, |m| m + 1));
    if n == 0 {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "there must be at least one candidate (N ≥ 1)",
        ));
    }
    Ok((samples, owner, n))
}

/// The loss options of the Python signature (explicit samples: nearest-sample distances).
fn chamfer_options(
    model: &str,
    alpha: Option<&Bound<'_, PyAny>>,
    beta: Option<&Bound<'_, PyAny>>,
    cap: f64,
    weights: (f64, f64),
) -> PyResult<ChamferOptions> {
    Ok(ChamferOptions {
        model: PointModel::parse(model).py()?,
        alpha: exact_if_unlimited(convert::limit("alpha", alpha)?),
        beta: exact_if_unlimited(convert::limit("beta", beta)?),
        cap,
        // Explicit samples carry no surface: distances are to the nearest sample.
        surface_distance: false,
        primitive_weight: weights.0,
        point_weight: weights.1,
    })
}

/// One problem per cloud against the same candidate samples, built in parallel (a batch
/// of training scenes); options as for `ChamferProblem`.
#[pyfunction]
#[pyo3(signature = (clouds, samples, owner, n=None, *, model="existence", alpha=None, beta=None, cap=0.0, weights=(1.0, 1.0)))]
#[allow(clippy::too_many_arguments)]
pub fn chamfer_problems(
    py: Python<'_>,
    clouds: Vec<PyReadonlyArray2<'_, f64>>,
    samples: PyReadonlyArray2<'_, f64>,
    owner: PyReadonlyArray1<'_, i64>,
    n: Option<usize>,
    model: &str,
    alpha: Option<&Bound<'_, PyAny>>,
    beta: Option<&Bound<'_, PyAny>>,
    cap: f64,
    weights: (f64, f64),
) -> PyResult<Vec<ChamferProblem>> {
    let clouds = clouds
        .iter()
        .enumerate()
        .map(|(b, c)| convert::points(&format!("clouds[{b}]"), c, false))
        .collect::<PyResult<Vec<_>>>()?;
    let (samples, owner, n) = candidate_samples(&samples, &owner, n)?;
    let options = chamfer_options(model, alpha, beta, cap, weights)?;
    let coeffs = pool::detached(py, || {
        let sets = SampleSets::new(&samples, &owner, n)?;
        let points = clouds.iter().map(Vec::len).sum();
        check_memory(points, &sets, &options, budget::default_memory_budget())?;
        clouds
            .par_iter()
            .map(|cloud| Coefficients::build(cloud, &sets, &options, &Silent))
            .collect::<primfit_core::Result<Vec<_>>>()
    })?
    .py()?;
    Ok(coeffs.into_iter().map(ChamferProblem::from).collect())
}

#[pymethods]
impl ChamferProblem {
    #[new]
    #[pyo3(signature = (cloud, samples, owner, n=None, *, model="existence", alpha=None, beta=None, cap=0.0, weights=(1.0, 1.0)))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        cloud: PyReadonlyArray2<'_, f64>,
        samples: PyReadonlyArray2<'_, f64>,
        owner: PyReadonlyArray1<'_, i64>,
        n: Option<usize>,
        model: &str,
        alpha: Option<&Bound<'_, PyAny>>,
        beta: Option<&Bound<'_, PyAny>>,
        cap: f64,
        weights: (f64, f64),
    ) -> PyResult<Self> {
        let cloud = convert::points("cloud", &cloud, false)?;
        let (samples, owner, n) = candidate_samples(&samples, &owner, n)?;
        let options = chamfer_options(model, alpha, beta, cap, weights)?;
        let coeffs = pool::detached(py, || {
            let sets = SampleSets::new(&samples, &owner, n)?;
            check_memory(
                cloud.len(),
                &sets,
                &options,
                budget::default_memory_budget(),
            )?;
            Coefficients::build(&cloud, &sets, &options, &Silent)
        })?
        .py()?;
        Ok(ChamferProblem { coeffs })
    }

    /// Number of candidates N.
    #[getter]
    fn n_candidates(&self) -> usize {
        self.coeffs.candidates()
    }

    /// Number of cloud points J.
    #[getter]
    fn n_points(&self) -> usize {
        self.coeffs.points()
    }

    /// Number of (point, candidate[, sample]) entries of the point term.
    #[getter]
    fn n_entries(&self) -> usize {
        self.coeffs.entries()
    }

    /// `(primitive_weight, point_weight)`.
    #[getter]
    fn weights(&self) -> (f64, f64) {
        (
            self.coeffs.options.primitive_weight,
            self.coeffs.options.point_weight,
        )
    }

    /// The primitive-term coefficients `g_i` (a copy).
    #[getter]
    fn g<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.coeffs.g.clone().into_pyarray(py)
    }

    /// `(primitive_term, point_term, grad)` at `p`; `grad` is of the weighted total.
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        p: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<(f64, f64, Bound<'py, PyArray1<f64>>)> {
        let p = convert::vector(&p);
        convert::probabilities("p", &p, self.coeffs.candidates())?;
        let (value, grad) = pool::detached(py, || {
            let mut grad = vec![0.0; self.coeffs.candidates()];
            let value = Evaluator::new(&self.coeffs).evaluate(&p, &mut grad);
            (value, grad)
        })?;
        Ok((value.primitive, value.point, grad.into_pyarray(py)))
    }

    /// `(totals (B,), grads (B, N))` for a batch `P` of shape `(B, N)`, scenes in parallel.
    fn evaluate_batch<'py>(
        &self,
        py: Python<'py>,
        p: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Batch<'py>> {
        let n = self.coeffs.candidates();
        let flat = convert::rows("P", &p, n)?;
        let b = flat.len() / n;
        let (totals, grads) = pool::detached(py, || {
            let mut grads = vec![0.0; b * n];
            let totals: Vec<f64> = flat
                .par_chunks(n)
                .zip(grads.par_chunks_mut(n))
                .map_init(
                    || Evaluator::new(&self.coeffs),
                    |ev, (p, g)| ev.evaluate(p, g).total,
                )
                .collect();
            (totals, grads)
        })?;
        let grads = Array2::from_shape_vec((b, n), grads).expect("b · n gradient cells");
        Ok((totals.into_pyarray(py), grads.into_pyarray(py)))
    }

    /// Minimises the loss over existence from `start` (N,) with the fit's solver
    /// (projected L-BFGS, threshold, polish; defaults of `primfit fit`): a dict of
    /// `probability` (N,), `exists` (N,), `iterations`, `evaluations`, `stop`, `history`
    /// (the loss after every iteration) and `binary` (the final scene's loss).
    #[pyo3(signature = (start, *, max_iterations=None, polish=true))]
    fn solve<'py>(
        &self,
        py: Python<'py>,
        start: PyReadonlyArray1<'py, f64>,
        max_iterations: Option<usize>,
        polish: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let start = convert::vector(&start).into_owned();
        convert::probabilities("start", &start, self.coeffs.candidates())?;
        let d = SolverOptions::default();
        let options = SolverOptions {
            max_iterations: max_iterations.unwrap_or(d.max_iterations),
            polish,
            ..d
        };
        let solution =
            pool::detached(py, || solve_from(&self.coeffs, start, &options, &Silent))?.py()?;
        let out = PyDict::new(py);
        out.set_item("probability", solution.probability.into_pyarray(py))?;
        out.set_item("exists", solution.exists.into_pyarray(py))?;
        out.set_item("iterations", solution.iterations)?;
        out.set_item("evaluations", solution.evaluations)?;
        out.set_item("stop", solution.stop.name())?;
        out.set_item("history", solution.history.into_pyarray(py))?;
        out.set_item("binary", solution.binary.total)?;
        Ok(out)
    }

    fn __repr__(&self) -> String {
        let o = &self.coeffs.options;
        format!(
            "ChamferProblem(points={}, candidates={}, entries={}, model={:?}, cap={}, weights=({}, {}))",
            self.coeffs.points(),
            self.coeffs.candidates(),
            self.coeffs.entries(),
            o.model.name(),
            o.cap,
            o.primitive_weight,
            o.point_weight
        )
    }
}
