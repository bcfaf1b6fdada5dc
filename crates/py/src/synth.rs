//! Synthetic scenes with ground truth (core `synth`), for the `primfit.synth` module.
//!
//! Every function returns `(points (J, 3), truth_json)`: the sampled cloud and the true
//! primitives as a JSON list in the `result.json` format (the facade parses it).

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use primfit_core::atlas::MeshShape;
use primfit_core::na::Point3;
use primfit_core::synth::{
    self, Density, HallwayParams, Misalignment, NineCylinderParams, Noise, PartialViewParams,
    PipeParams, RegistrationParams, Scene, SixInARowParams, SixVariant,
};
use primfit_core::{Error, Primitive, Result};
use pyo3::prelude::*;

use crate::convert::{self, ToPyResult};
use crate::pool;

type SceneOutput<'py> = (Bound<'py, PyArray2<f64>>, String);

/// `(J, 3)` array of points (one copy from the core's point type).
pub fn points_array<'py>(py: Python<'py>, points: &[Point3<f64>]) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    Array2::from_shape_vec((points.len(), 3), flat)
        .expect("3 coordinates per point")
        .into_pyarray(py)
}

fn truth_json(truth: &[Primitive]) -> String {
    serde_json::Value::Array(truth.iter().map(Primitive::to_json).collect()).to_string()
}

/// Runs a generator with the GIL released and converts its scene.
fn generate<'py>(
    py: Python<'py>,
    make: impl FnOnce() -> Result<Scene> + Send,
) -> PyResult<SceneOutput<'py>> {
    let scene = pool::detached(py, make)?.py()?;
    Ok((
        points_array(py, &scene.cloud.points),
        truth_json(&scene.truth),
    ))
}

/// Points per unit area, or a total count (not both); `None` for both keeps `default`.
fn density(per_area: Option<f64>, total: Option<usize>, default: Density) -> Result<Density> {
    match (per_area, total) {
        (Some(_), Some(_)) => Err(Error::invalid(
            "give either density (per unit area) or points (total), not both",
        )),
        (Some(d), None) => Ok(Density::PerArea(d)),
        (None, Some(n)) => Ok(Density::Total(n)),
        (None, None) => Ok(default),
    }
}

/// A hallway of square tiles: floor, two walls, optional ceiling.
#[pyfunction]
#[pyo3(signature = (*, length=10.0, width=2.0, height=2.5, side=1.0, ceiling=false, density=None, points=None,
                    jitter=0.01, drift=0.0, offset=0.0, angle=0.0, seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn synth_hallway<'py>(
    py: Python<'py>,
    length: f64,
    width: f64,
    height: f64,
    side: f64,
    ceiling: bool,
    density: Option<f64>,
    points: Option<usize>,
    jitter: f64,
    drift: f64,
    offset: f64,
    angle: f64,
    seed: u64,
) -> PyResult<SceneOutput<'py>> {
    let params = HallwayParams {
        length,
        width,
        height,
        side,
        ceiling,
        density: self::density(density, points, HallwayParams::default().density).py()?,
        noise: Noise { jitter, drift },
        misalignment: Misalignment { offset, angle },
        seed,
    };
    generate(py, || synth::hallway(&params))
}

/// A pipe: straight runs of cylinders joined by elbows.
#[pyfunction]
#[pyo3(signature = (*, segments=4, max_run=3, segment_length=1.0, bend=None, radius=None, density=None,
                    points=None, jitter=0.005, drift=0.0, offset=0.0, angle=0.0, seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn synth_pipe<'py>(
    py: Python<'py>,
    segments: usize,
    max_run: usize,
    segment_length: f64,
    bend: Option<f64>,
    radius: Option<f64>,
    density: Option<f64>,
    points: Option<usize>,
    jitter: f64,
    drift: f64,
    offset: f64,
    angle: f64,
    seed: u64,
) -> PyResult<SceneOutput<'py>> {
    let params = PipeParams {
        segments,
        max_run,
        segment_length,
        bend,
        radius,
        density: self::density(density, points, PipeParams::default().density).py()?,
        noise: Noise { jitter, drift },
        misalignment: Misalignment { offset, angle },
        seed,
    };
    generate(py, || synth::pipe(&params))
}

/// Up to nine vertical cylinders on a 3 × 3 grid (`mask` bit k ↔ cylinder k).
#[pyfunction]
#[pyo3(signature = (*, mask=0b1_1111_1111, pitch=1.0, radius=0.2, height=1.0, density=None, points=None,
                    jitter=0.01, drift=0.01, offset=0.0, seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn synth_nine_cylinders<'py>(
    py: Python<'py>,
    mask: u16,
    pitch: f64,
    radius: f64,
    height: f64,
    density: Option<f64>,
    points: Option<usize>,
    jitter: f64,
    drift: f64,
    offset: f64,
    seed: u64,
) -> PyResult<SceneOutput<'py>> {
    let params = NineCylinderParams {
        mask,
        pitch,
        radius,
        height,
        density: self::density(density, points, NineCylinderParams::default().density).py()?,
        noise: Noise { jitter, drift },
        offset,
        seed,
    };
    generate(py, || synth::nine_cylinders(&params))
}

/// Points seen from the origin on one of six candidates in a row along x (thesis §6.3).
#[pyfunction]
#[pyo3(signature = (*, variant="squares", first=7.0, step=1.0, true_index=3, size=1.0, points=500,
                    jitter=0.01, seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn synth_six_in_a_row<'py>(
    py: Python<'py>,
    variant: &str,
    first: f64,
    step: f64,
    true_index: usize,
    size: f64,
    points: usize,
    jitter: f64,
    seed: u64,
) -> PyResult<SceneOutput<'py>> {
    let variant = match variant {
        "squares" => SixVariant::Squares,
        "cylinders" => SixVariant::Cylinders,
        other => {
            return Err(Error::Unknown {
                what: "variant",
                value: other.into(),
                expected: "squares or cylinders",
            })
            .py();
        }
    };
    let params = SixInARowParams {
        variant,
        first,
        step,
        true_index,
        size,
        points,
        jitter,
        seed,
    };
    generate(py, || synth::six_in_a_row(&params).map(|s| s.scene))
}

/// A randomly posed mesh (default: the built-in asymmetric object) plus uniform outliers.
#[pyfunction]
#[pyo3(signature = (*, mesh=None, inliers=100, outliers=1900, translation=0.0, scale=None, outlier_box=1.0,
                    jitter=0.0, seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn synth_registration<'py>(
    py: Python<'py>,
    mesh: Option<(PyReadonlyArray2<'py, f64>, PyReadonlyArray2<'py, i64>)>,
    inliers: usize,
    outliers: usize,
    translation: f64,
    scale: Option<(f64, f64)>,
    outlier_box: f64,
    jitter: f64,
    seed: u64,
) -> PyResult<SceneOutput<'py>> {
    let mesh = match mesh {
        Some((v, f)) => MeshShape::new("python", convert::mesh(&v, &f)?).py()?,
        None => synth::asymmetric_object(),
    };
    let params = RegistrationParams {
        inliers,
        outliers,
        objects: 1,
        translation,
        scale,
        outlier_box,
        noise: Noise { jitter, drift: 0.0 },
        seed,
    };
    generate(py, || synth::registration(&mesh, &params))
}

/// A randomly posed mesh (default: the built-in asymmetric object) seen by a depth
/// sensor from one random viewpoint, with optional structured clutter and uniform
/// outliers (`synth::partial_view`).
#[pyfunction]
#[pyo3(signature = (*, mesh=None, inliers=400, outliers=3600, clutter_points=0, plane=false,
                    distractors=0, object=true, translation=0.0, range_noise=0.0, outlier_box=1.0,
                    seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn synth_partial_view<'py>(
    py: Python<'py>,
    mesh: Option<(PyReadonlyArray2<'py, f64>, PyReadonlyArray2<'py, i64>)>,
    inliers: usize,
    outliers: usize,
    clutter_points: usize,
    plane: bool,
    distractors: usize,
    object: bool,
    translation: f64,
    range_noise: f64,
    outlier_box: f64,
    seed: u64,
) -> PyResult<SceneOutput<'py>> {
    let mesh = match mesh {
        Some((v, f)) => MeshShape::new("python", convert::mesh(&v, &f)?).py()?,
        None => synth::asymmetric_object(),
    };
    let params = PartialViewParams {
        inliers,
        outliers,
        clutter_points,
        plane,
        distractors,
        object,
        translation,
        range_noise,
        outlier_box,
        seed,
    };
    generate(py, || synth::partial_view(&mesh, &params))
}
