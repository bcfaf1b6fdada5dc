//! Files: clouds in (every format `primfit_core::io::read_cloud` reads: PLY, PCD,
//! LAS/LAZ, E57, XYZ/PTS/CSV text) and out (PLY), meshes in, fitted primitives out as
//! one mesh (PLY, OBJ or glTF binary).

use std::path::PathBuf;

use numpy::ndarray::{Array2, ArrayView2, Axis};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use primfit_core::atlas::MeshShape;
use primfit_core::fit::primitives_mesh as primitives_core_mesh;
use primfit_core::io::{self, Encoding};
use primfit_core::na::Vector3;
use primfit_core::{PointCloud, Primitive, Result};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{self, ToPyResult};
use crate::pool;
use crate::synth::points_array;

/// `(vertices (V, 3), faces (F, 3))`.
type Mesh<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>);

/// A [`Mesh`] and the index of each face's primitive.
type OwnedMesh<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<i64>>,
    Bound<'py, PyArray1<i64>>,
);

fn encoding(ascii: bool) -> Encoding {
    if ascii {
        Encoding::Ascii
    } else {
        Encoding::BinaryLittleEndian
    }
}

/// `(J, 3)` rows as fixed-size arrays (shape checked).
fn triples<T: Copy>(name: &str, a: ArrayView2<'_, T>, rows: usize) -> PyResult<Vec<[T; 3]>> {
    if a.shape() != [rows, 3] {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape ({rows}, 3), got {:?}",
            a.shape()
        )));
    }
    Ok(a.axis_iter(Axis(0)).map(|r| [r[0], r[1], r[2]]).collect())
}

/// Reads a point cloud of any format `primfit_core::io::read_cloud` reads (by extension:
/// PLY, PCD, LAS/LAZ, E57, XYZ/PTS/CSV text): a dict with `points` (J, 3) and, when the
/// file has them, `normals` (J, 3), `colors` (J, 3) uint8, `labels` (J,) int32,
/// `sensors` (J, 3).
#[pyfunction]
pub fn read_ply<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let cloud = pool::detached(py, || io::read_cloud(&path))?.py()?;
    let out = PyDict::new(py);
    out.set_item("points", points_array(py, &cloud.points))?;
    if let Some(n) = &cloud.normals {
        let flat: Vec<f64> = n.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        out.set_item(
            "normals",
            Array2::from_shape_vec((n.len(), 3), flat)
                .expect("3 per row")
                .into_pyarray(py),
        )?;
    }
    if let Some(c) = cloud.colors {
        let len = c.len();
        let flat: Vec<u8> = c.into_iter().flatten().collect();
        out.set_item(
            "colors",
            Array2::from_shape_vec((len, 3), flat)
                .expect("3 per row")
                .into_pyarray(py),
        )?;
    }
    if let Some(l) = cloud.labels {
        out.set_item("labels", l.into_pyarray(py))?;
    }
    if let Some(s) = &cloud.sensors {
        out.set_item("sensors", points_array(py, s))?;
    }
    Ok(out)
}

/// Writes a PLY point cloud (atomically): binary little-endian, or ascii.
#[pyfunction]
#[pyo3(signature = (path, points, *, normals=None, colors=None, labels=None, sensors=None, ascii=false))]
#[allow(clippy::too_many_arguments)]
pub fn write_ply(
    py: Python<'_>,
    path: PathBuf,
    points: PyReadonlyArray2<'_, f64>,
    normals: Option<PyReadonlyArray2<'_, f64>>,
    colors: Option<PyReadonlyArray2<'_, u8>>,
    labels: Option<PyReadonlyArray1<'_, i32>>,
    sensors: Option<PyReadonlyArray2<'_, f64>>,
    ascii: bool,
) -> PyResult<()> {
    let cloud = cloud_arrays(points, normals, colors, labels, sensors, true)?;
    pool::detached(py, || io::write_cloud(&path, &cloud, encoding(ascii)))?.py()
}

/// A cloud from its arrays (checked: shapes, one entry per point, finite coordinates);
/// empty only with `allow_empty`.
pub fn cloud_arrays(
    points: PyReadonlyArray2<'_, f64>,
    normals: Option<PyReadonlyArray2<'_, f64>>,
    colors: Option<PyReadonlyArray2<'_, u8>>,
    labels: Option<PyReadonlyArray1<'_, i32>>,
    sensors: Option<PyReadonlyArray2<'_, f64>>,
    allow_empty: bool,
) -> PyResult<PointCloud> {
    let points = convert::points(
        if allow_empty { "points" } else { "cloud" },
        &points,
        allow_empty,
    )?;
    let j = points.len();
    let normals = match normals {
        Some(n) => Some(
            triples("normals", n.as_array(), j)?
                .into_iter()
                .map(Vector3::from)
                .collect(),
        ),
        None => None,
    };
    let colors = match colors {
        Some(c) => Some(triples("colors", c.as_array(), j)?),
        None => None,
    };
    let labels = match labels {
        Some(l) if l.len() != j => {
            return Err(PyValueError::new_err(format!(
                "labels must have shape ({j},), got {:?}",
                l.shape()
            )));
        }
        Some(l) => Some(l.as_array().to_vec()),
        None => None,
    };
    let sensors = match sensors {
        Some(s) if s.shape()[0] != j => {
            return Err(PyValueError::new_err(format!(
                "sensors must have shape ({j}, 3), got {:?}",
                s.shape()
            )));
        }
        Some(s) => Some(convert::points("sensors", &s, true)?),
        None => None,
    };
    let cloud = PointCloud {
        points,
        normals,
        colors,
        labels,
        sensors,
    };
    Ok(cloud)
}

/// Reads a PLY triangle mesh: `(vertices (V, 3), faces (F, 3) int64)`.
#[pyfunction]
pub fn read_mesh<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Mesh<'py>> {
    let mesh = pool::detached(py, || io::read_mesh(&path))?.py()?;
    let faces: Vec<i64> = mesh.faces.iter().flatten().map(|&i| i64::from(i)).collect();
    let faces = Array2::from_shape_vec((mesh.faces.len(), 3), faces).expect("3 per face");
    Ok((points_array(py, &mesh.vertices), faces.into_pyarray(py)))
}

/// The triangle mesh of primitives (a JSON list in the `result.json` format), as
/// `primfit fit --mesh` exports it: `(vertices (V, 3), faces (F, 3) int64, primitive
/// (F,) int64)`, `primitive[f]` the index of the primitive face `f` belongs to.
#[pyfunction]
pub fn primitives_mesh<'py>(py: Python<'py>, primitives_json: &str) -> PyResult<OwnedMesh<'py>> {
    let list = primitive_list(primitives_json)?;
    let (mesh, owner) = pool::detached(py, || -> Result<_> {
        let (prims, _) = parse_primitives(&list)?;
        Ok(primitives_core_mesh(&prims))
    })?
    .py()?;
    let faces: Vec<i64> = mesh.faces.iter().flatten().map(|&i| i64::from(i)).collect();
    let faces = Array2::from_shape_vec((mesh.faces.len(), 3), faces).expect("3 per face");
    let owner: Vec<i64> = owner.into_iter().map(i64::from).collect();
    Ok((
        points_array(py, &mesh.vertices),
        faces.into_pyarray(py),
        owner.into_pyarray(py),
    ))
}

/// Primitives (a JSON list in the `result.json` format) and their `existence` when
/// every entry has one. Mesh primitives are read from their `source` file, so call this
/// with the GIL released.
pub fn parse_primitives(list: &[serde_json::Value]) -> Result<(Vec<Primitive>, Option<Vec<f64>>)> {
    let load = |source: &str| -> Result<MeshShape> {
        MeshShape::new(source, io::read_mesh(std::path::Path::new(source))?)
    };
    let prims = list
        .iter()
        .enumerate()
        .map(|(k, v)| Primitive::from_json(v, &load).map_err(|e| e.in_item("primitive", k)))
        .collect::<Result<Vec<_>>>()?;
    let existence = list
        .iter()
        .map(|v| v.get("existence").and_then(serde_json::Value::as_f64))
        .collect();
    Ok((prims, existence))
}

/// A JSON list of primitives as text, parsed (not yet checked as primitives).
pub fn primitive_list(primitives_json: &str) -> PyResult<Vec<serde_json::Value>> {
    let doc: serde_json::Value = serde_json::from_str(primitives_json)
        .map_err(|e| PyValueError::new_err(format!("primitives are not valid JSON: {e}")))?;
    match doc {
        serde_json::Value::Array(list) => Ok(list),
        _ => Err(PyValueError::new_err("primitives must be a list")),
    }
}

/// Writes primitives (a JSON list in the `result.json` format) as one triangle mesh in
/// the format of the path's extension: PLY (per-face `primitive` index), OBJ or glTF
/// binary (`.glb`, existence in each node's extras). Mesh primitives are read from their
/// `source` file.
#[pyfunction]
#[pyo3(signature = (path, primitives_json, *, ascii=false))]
pub fn write_mesh(
    py: Python<'_>,
    path: PathBuf,
    primitives_json: &str,
    ascii: bool,
) -> PyResult<()> {
    let list = primitive_list(primitives_json)?;
    pool::detached(py, || -> Result<()> {
        let (prims, existence) = parse_primitives(&list)?;
        io::write_primitives_mesh(&path, &prims, existence.as_deref(), encoding(ascii))
    })?
    .py()
}
