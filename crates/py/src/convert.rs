//! numpy ↔ core conversions and the one place where core errors become Python exceptions.
//!
//! Every array argument is checked here (dimensions, shape, emptiness, finiteness) and a
//! bad one raises `ValueError` naming the argument. Arrays are read through ndarray
//! views, which honour strides, so Fortran-ordered or sliced inputs are read correctly
//! (`as_slice` alone would accept Fortran order and misread it).

use std::borrow::Cow;

use numpy::ndarray::{ArrayView1, ArrayView2, Axis};
use numpy::{PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use primfit_core::na::Point3;
use primfit_core::{Error, Limit, TriMesh};
use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyString;

/// Maps a core error onto the Python exception a caller expects: file problems are
/// `OSError`, everything else (bad arguments, shapes, file contents, size limits) is
/// `ValueError`. An error about one item of a list maps as its fault does. The message
/// is the core's one-line message, options named as in the library (and in the Python
/// keyword arguments).
pub fn to_py(e: Error) -> PyErr {
    let message = e.to_string();
    match e.root() {
        Error::Io { .. } => PyOSError::new_err(message),
        // The work stopped because Ctrl-C was pressed (`pool::cancellable`).
        Error::Cancelled => PyKeyboardInterrupt::new_err(message),
        Error::OutOfRange { .. }
        | Error::Unknown { .. }
        | Error::EmptyCloud
        | Error::NonFinite { .. }
        | Error::Mismatch { .. }
        | Error::IndexOutOfRange { .. }
        | Error::Missing { .. }
        | Error::Json { .. }
        | Error::Format { .. }
        | Error::UnknownFormat { .. }
        | Error::InvalidArgument(_) => PyValueError::new_err(message),
        // Refused before allocating: the caller can shrink the problem.
        Error::OverLimit { .. } => PyValueError::new_err(message),
        // `root` never returns an item wrapper.
        Error::Item { .. } => PyValueError::new_err(message),
    }
}

/// `Result<T, Error>` → `PyResult<T>` through [`to_py`].
pub trait ToPyResult<T> {
    /// Converts the error with [`to_py`].
    fn py(self) -> PyResult<T>;
}

impl<T> ToPyResult<T> for primfit_core::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(to_py)
    }
}

fn value_error(msg: String) -> PyErr {
    PyValueError::new_err(msg)
}

/// Checks that every value is finite.
fn check_finite<'a>(name: &str, values: impl IntoIterator<Item = &'a f64>) -> PyResult<()> {
    match values.into_iter().position(|v| !v.is_finite()) {
        Some(k) => Err(value_error(format!(
            "{name} contains NaN or infinite values (first at flat index {k})"
        ))),
        None => Ok(()),
    }
}

/// An `(M, 3)` array of finite coordinates as points. `M ≥ 1` unless `allow_empty`.
pub fn points(
    name: &str,
    a: &PyReadonlyArray2<'_, f64>,
    allow_empty: bool,
) -> PyResult<Vec<Point3<f64>>> {
    let v: ArrayView2<'_, f64> = a.as_array();
    if v.ncols() != 3 {
        return Err(value_error(format!(
            "{name} must have shape (M, 3), got {:?}",
            a.shape()
        )));
    }
    if v.nrows() == 0 && !allow_empty {
        return Err(value_error(format!(
            "{name} is empty (shape {:?}); at least one point is needed",
            a.shape()
        )));
    }
    check_finite(name, v.iter())?;
    Ok(v.axis_iter(Axis(0))
        .map(|r| Point3::new(r[0], r[1], r[2]))
        .collect())
}

/// A 1-D array as a slice: borrowed when contiguous, copied otherwise.
pub fn vector<'a>(a: &'a PyReadonlyArray1<'_, f64>) -> Cow<'a, [f64]> {
    let v: ArrayView1<'a, f64> = a.as_array();
    match v.to_slice() {
        Some(s) => Cow::Borrowed(s),
        None => Cow::Owned(v.to_vec()),
    }
}

/// Existence probabilities: length `n`, finite, each in `[0, 1]`.
pub fn probabilities(name: &str, p: &[f64], n: usize) -> PyResult<()> {
    if p.len() != n {
        return Err(value_error(format!(
            "{name} must have length N = {n} (one per candidate), got {}",
            p.len()
        )));
    }
    check_finite(name, p)?;
    match p.iter().position(|v| !(0.0..=1.0).contains(v)) {
        Some(k) => Err(value_error(format!(
            "{name}[{k}] = {} is not a probability in [0, 1]",
            p[k]
        ))),
        None => Ok(()),
    }
}

/// A `(B, N)` array in row-major order: borrowed when C-contiguous, copied otherwise.
pub fn rows<'a>(
    name: &str,
    a: &'a PyReadonlyArray2<'_, f64>,
    n: usize,
) -> PyResult<Cow<'a, [f64]>> {
    let v: ArrayView2<'a, f64> = a.as_array();
    if v.ncols() != n {
        return Err(value_error(format!(
            "{name} must have shape (B, N) with N = {n}, got {:?}",
            a.shape()
        )));
    }
    let flat = match v.to_slice() {
        // `to_slice` on an ndarray view is `Some` only for standard (C) layout.
        Some(s) => Cow::Borrowed(s),
        None => Cow::Owned(v.iter().copied().collect()),
    };
    for (b, row) in flat.chunks(n.max(1)).enumerate() {
        probabilities(&format!("{name}[{b}]"), row, n)?;
    }
    Ok(flat)
}

/// Candidate indices: each in `0..n`, as `usize`.
pub fn indices(name: &str, a: &PyReadonlyArray1<'_, i64>) -> PyResult<Vec<usize>> {
    a.as_array()
        .iter()
        .enumerate()
        .map(|(k, &o)| {
            usize::try_from(o).map_err(|_| value_error(format!("{name}[{k}] = {o} is negative")))
        })
        .collect()
}

/// A count limit: `None` → `None` (the library's default); a positive int; or `"inf"` /
/// `math.inf` → [`Limit::All`].
pub fn limit(name: &str, v: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Limit>> {
    let Some(v) = v else { return Ok(None) };
    if v.is_none() {
        return Ok(None);
    }
    if let Ok(s) = v.cast::<PyString>() {
        return match s.to_str()? {
            "inf" | "all" => Ok(Some(Limit::All)),
            other => Err(value_error(format!(
                "{name} must be a positive integer or 'inf', got {other:?}"
            ))),
        };
    }
    if let Ok(k) = v.extract::<i64>() {
        return match usize::try_from(k) {
            Ok(k) if k >= 1 => Ok(Some(Limit::At(k))),
            _ => Err(value_error(format!(
                "{name} must be at least 1 (or 'inf'), got {k}"
            ))),
        };
    }
    match v.extract::<f64>() {
        Ok(f) if f == f64::INFINITY => Ok(Some(Limit::All)),
        _ => Err(value_error(format!(
            "{name} must be a positive integer or 'inf', got {v}"
        ))),
    }
}

/// `N` finite numbers from any iterable (a list, a tuple, a numpy array); `None` stays
/// `None`.
pub fn floats<const N: usize>(
    name: &str,
    v: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<[f64; N]>> {
    let Some(v) = v.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    let values: Vec<f64> = v
        .try_iter()
        .and_then(|items| items.map(|x| x?.extract::<f64>()).collect())
        .map_err(|_| value_error(format!("{name} must be {N} numbers, got {v}")))?;
    let array: [f64; N] = values
        .try_into()
        .map_err(|_| value_error(format!("{name} must be {N} numbers, got {v}")))?;
    check_finite(name, &array)?;
    Ok(Some(array))
}

/// A triangle mesh from `(V, 3)` vertices and `(F, 3)` integer faces.
pub fn mesh(
    vertices: &PyReadonlyArray2<'_, f64>,
    faces: &PyReadonlyArray2<'_, i64>,
) -> PyResult<TriMesh> {
    let vertices = points("mesh vertices", vertices, false)?;
    let f = faces.as_array();
    if f.ncols() != 3 {
        return Err(value_error(format!(
            "mesh faces must have shape (F, 3), got {:?}",
            faces.shape()
        )));
    }
    let faces = f
        .axis_iter(Axis(0))
        .map(|r| {
            let idx = |k: usize| {
                u32::try_from(r[k])
                    .map_err(|_| value_error(format!("mesh face index {} is out of range", r[k])))
            };
            Ok([idx(0)?, idx(1)?, idx(2)?])
        })
        .collect::<PyResult<Vec<_>>>()?;
    Ok(TriMesh { vertices, faces })
}
