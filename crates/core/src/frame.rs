//! The lattice's frame: the scan's dominant orthogonal directions (a "Manhattan frame")
//! and a grid origin that puts lattice planes on the data.
//!
//! **Frame.** Given the unoriented local normals `n_k` of the flattest half of the
//! neighbourhoods (from [`crate::surface`]), a rotation
//! `R` with columns `e_1, e_2, e_3` is scored by
//!
//! `S(R) = Σ_k max_i κ(n_k · e_i)`,  `κ(c) = exp(−(1 − c²) / (2 s²))`,  `s = sin 10°`,
//!
//! i.e. each normal counts when it is within about 10° of some frame axis (either sign).
//! Candidates are the identity and frames built from pairs of sampled normals (`e_1 = n_a`,
//! `e_2` = `n_b` made orthogonal to it, `e_3 = e_1 × e_2`); the best is polished by
//! iterated weighted Procrustes (Kabsch: each normal, sign-flipped towards its nearest
//! axis, pulls that axis with weight κ) and written as the signed permutation of its axes
//! closest to the identity. Planar scenes (rooms, tables) give the frame of their walls; a
//! straight tube gives a frame with one axis along the tube (its normals lie on a great
//! circle, which passes near four axis directions only when the tube is an axis), so an
//! odd-angled pipe gets its orientation set from the data.
//!
//! **Origin.** In the frame, lattice axis `i` gets the offset `o_i` that puts grid planes
//! `o_i + spacing · ℤ` on the points whose normal is within 15° of `e_i`: the circular mean
//! of their coordinates with period `spacing` (for a tube along another axis, the points
//! on both flanks average to the tube's axis). An axis with (almost) no such points gets
//! the low end of the data (0.1 % quantile) plus half the candidate size, so the first
//! tile starts where the data starts.

use std::f64::consts::TAU;

use nalgebra::{Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;

use crate::surface::LocalPlane;
use crate::{Error, Primitive, Result, check};

/// `s` of the kernel κ: normals within about this angle of an axis count (radians).
const KERNEL_ANGLE: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// Normals within this angle of a lattice axis vote for its grid offset (radians).
const ORIGIN_ANGLE: f64 = 15.0 * std::f64::consts::PI / 180.0;

/// The flattest half of the local planes take part (see [`LocalPlane::flatness`]):
/// the threshold is their median flatness. A fixed threshold would keep almost nothing
/// on a noisy tube, where every neighbourhood is noisy.
fn flat_threshold(planes: &[LocalPlane]) -> f64 {
    if planes.is_empty() {
        return 0.0;
    }
    let mut f: Vec<f64> = planes.iter().map(|p| p.flatness).collect();
    let mid = (f.len() - 1) / 2;
    f.select_nth_unstable_by(mid, f64::total_cmp);
    f[mid]
}

/// Pairs of normals tried as frame candidates.
const CANDIDATE_PAIRS: usize = 256;

/// Normals used to score candidates (evenly strided).
const SCORE_NORMALS: usize = 4000;

/// Procrustes polishing iterations.
const POLISH_ITERATIONS: usize = 20;

/// A frame within this angle of the scene axes is snapped to them (radians): an already
/// aligned scan keeps its exact axes.
pub const SNAP_ANGLE: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// How the lattice frame is chosen (`--frame auto|axis|FILE`; the fit's default is
/// [`crate::fit::DEFAULT_FRAME`]).
#[derive(Debug, Clone, PartialEq)]
pub enum FrameChoice {
    /// The scene axes, origin as given (or 0): the behaviour of a plain lattice.
    Axis,
    /// Estimated from the cloud: the scan's dominant axes, and a grid origin on the data.
    Auto,
    /// A given rotation, and optionally a grid origin (otherwise one on the data).
    Given {
        /// Lattice frame → scene.
        rotation: UnitQuaternion<f64>,
        /// A lattice point, if fixed.
        origin: Option<Point3<f64>>,
    },
}

impl FrameChoice {
    /// The name written to `settings.frame.source`: `axis`, `auto` or `given`.
    pub fn name(&self) -> &'static str {
        match self {
            FrameChoice::Axis => "axis",
            FrameChoice::Auto => "auto",
            FrameChoice::Given { .. } => "given",
        }
    }

    /// Parses `auto` or `axis` (a file is read by the caller and passed to
    /// [`FrameChoice::from_json`]).
    pub fn parse(s: &str) -> Result<Self> {
        match s.trim() {
            "auto" => Ok(FrameChoice::Auto),
            "axis" => Ok(FrameChoice::Axis),
            o => Err(Error::Unknown {
                what: "frame",
                value: o.into(),
                expected: "auto, axis or a JSON file",
            }),
        }
    }

    /// A frame from JSON: `{"rotation": [w, x, y, z], "origin": [x, y, z]}` (origin
    /// optional), or a primfit `result.json`, whose `settings.frame.rotation` and
    /// `settings.origin` are reused (so a fit's lattice can be repeated on another scan).
    pub fn from_json(v: &Value) -> Result<Self> {
        let settings = v.get("settings");
        let frame = settings
            .and_then(|s| s.get("frame"))
            .or_else(|| v.get("rotation").map(|_| v))
            .ok_or_else(|| {
                Error::json("rotation", "[w, x, y, z] (or a result's settings.frame)")
            })?;
        let q = numbers(frame.get("rotation"), 4, "rotation")?;
        let rotation = check::unit_quaternion("rotation", [q[0], q[1], q[2], q[3]])?;
        let origin_value = match settings {
            Some(s) => s.get("origin"),
            None => v.get("origin"),
        };
        let origin = match origin_value {
            None | Some(Value::Null) => None,
            Some(o) => {
                let o = numbers(Some(o), 3, "origin")?;
                Some(Point3::new(o[0], o[1], o[2]))
            }
        };
        Ok(FrameChoice::Given { rotation, origin })
    }
}

/// `n` finite numbers from a JSON array.
fn numbers(v: Option<&Value>, n: usize, what: &str) -> Result<Vec<f64>> {
    let out: Vec<f64> = v
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(Value::as_f64)
                .filter(|x| x.is_finite())
                .collect()
        })
        .unwrap_or_default();
    if out.len() != n || v.and_then(Value::as_array).map(Vec::len) != Some(n) {
        return Err(Error::json(what, format!("an array of {n} finite numbers")));
    }
    Ok(out)
}

/// An estimated frame and how well it explains the normals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameEstimate {
    /// Lattice frame → scene (columns of the matrix are the lattice axes).
    pub rotation: UnitQuaternion<f64>,
    /// Share of the flattest half of the normals within √2 times the kernel angle (≈ 14°)
    /// of a frame axis, in [0, 1]: near 1 for rooms, lower for tubes and free-form objects.
    pub support: f64,
}

/// κ(c) of the module docs for `c = n · e`.
#[inline]
fn kernel(c: f64) -> f64 {
    let s = KERNEL_ANGLE.sin();
    (-(1.0 - c * c).max(0.0) / (2.0 * s * s)).exp()
}

/// `(axis index, cosine)` of the frame axis nearest to `n` (either sign).
#[inline]
fn nearest_axis(m: &Matrix3<f64>, n: &Vector3<f64>) -> (usize, f64) {
    (0..3)
        .map(|i| (i, m.column(i).dot(n)))
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()).then(b.0.cmp(&a.0)))
        .unwrap_or((0, 0.0))
}

/// `S(R)` of the module docs.
fn score(m: &Matrix3<f64>, normals: &[Vector3<f64>]) -> f64 {
    normals.iter().map(|n| kernel(nearest_axis(m, n).1)).sum()
}

/// The frame `(a, b⊥, a × b⊥)`, or `None` when `a ∥ b`.
fn frame_from_pair(a: &Vector3<f64>, b: &Vector3<f64>) -> Option<Matrix3<f64>> {
    let b = b - a * a.dot(b);
    let nb = b.norm();
    if nb < 0.5 {
        return None; // closer than 30° to parallel: a poor second axis
    }
    let b = b / nb;
    Some(Matrix3::from_columns(&[*a, b, a.cross(&b)]))
}

/// One weighted Procrustes step: the rotation that best maps the frame axes onto the
/// sign-aligned normals assigned to them (weights κ).
fn procrustes_step(m: &Matrix3<f64>, normals: &[Vector3<f64>]) -> Matrix3<f64> {
    procrustes_step_weighted(m, normals, &vec![1.0; normals.len()])
}

/// [`procrustes_step`] with an extra weight per direction.
fn procrustes_step_weighted(
    m: &Matrix3<f64>,
    normals: &[Vector3<f64>],
    weights: &[f64],
) -> Matrix3<f64> {
    let mut h = Matrix3::zeros();
    for (n, extra) in normals.iter().zip(weights) {
        let (i, c) = nearest_axis(m, n);
        let w = kernel(c) * extra;
        let aligned = n * c.signum();
        // Maximise Σ w aᵀ R e_i  ⇔  maximise tr(R H) with H = Σ w e_i aᵀ.
        h += w * Vector3::ith(i, 1.0) * aligned.transpose();
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return *m;
    };
    let v = v_t.transpose();
    let mut d = Matrix3::identity();
    if (v * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = v * d * u.transpose();
    if r.iter().all(|x| x.is_finite()) {
        r
    } else {
        *m
    }
}

/// The 24 proper signed permutation matrices.
fn signed_permutations() -> Vec<Matrix3<f64>> {
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut out = Vec::with_capacity(24);
    for p in perms {
        for signs in 0..8u32 {
            let mut m = Matrix3::zeros();
            for (col, &row) in p.iter().enumerate() {
                m[(row, col)] = if signs >> col & 1 == 1 { -1.0 } else { 1.0 };
            }
            if m.determinant() > 0.0 {
                out.push(m);
            }
        }
    }
    out
}

/// The same set of axes written as the rotation closest to the identity (largest
/// trace; ties by a fixed order), snapped to the identity within [`SNAP_ANGLE`].
fn canonical(m: &Matrix3<f64>) -> UnitQuaternion<f64> {
    let best = signed_permutations()
        .into_iter()
        .map(|p| m * p)
        .max_by(|a, b| a.trace().total_cmp(&b.trace()))
        .unwrap_or(*m);
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&best));
    if q.angle() < SNAP_ANGLE {
        UnitQuaternion::identity()
    } else {
        q
    }
}

/// The normals of the flattest half of `planes`, evenly strided to at most `max`.
fn flat_normals(planes: &[LocalPlane], max: usize) -> Vec<Vector3<f64>> {
    let threshold = flat_threshold(planes);
    let flat: Vec<Vector3<f64>> = planes
        .iter()
        .filter(|p| p.flatness <= threshold)
        .map(|p| p.normal)
        .collect();
    let stride = flat.len().div_ceil(max.max(1)).max(1);
    flat.into_iter().step_by(stride).collect()
}

/// The dominant frame of `planes` (see the module docs), or `None` when fewer than 3
/// normals exist. Deterministic for a given `seed`.
pub fn estimate_frame(planes: &[LocalPlane], seed: u64) -> Option<FrameEstimate> {
    let normals = flat_normals(planes, SCORE_NORMALS);
    if normals.len() < 3 {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut best = Matrix3::identity();
    let mut best_score = score(&best, &normals);
    for _ in 0..CANDIDATE_PAIRS {
        let a = normals[rng.random_range(0..normals.len())];
        let b = normals[rng.random_range(0..normals.len())];
        if let Some(m) = frame_from_pair(&a, &b) {
            let s = score(&m, &normals);
            if s > best_score {
                best = m;
                best_score = s;
            }
        }
    }
    let all = flat_normals(planes, usize::MAX);
    for _ in 0..POLISH_ITERATIONS {
        best = procrustes_step(&best, &all);
    }
    let rotation = canonical(&best);
    let m = rotation.to_rotation_matrix().into_inner();
    let near = (2.0f64.sqrt() * KERNEL_ANGLE).cos();
    let support = all
        .iter()
        .filter(|n| nearest_axis(&m, n).1.abs() >= near)
        .count() as f64
        / all.len() as f64;
    Some(FrameEstimate { rotation, support })
}

/// The grid origin for a lattice of `spacing` in frame `rotation` (see the module docs);
/// `size` is the candidates' main extent. Returns the scene origin for empty input.
pub fn grid_origin(
    planes: &[LocalPlane],
    points: &[Point3<f64>],
    rotation: &UnitQuaternion<f64>,
    spacing: f64,
    size: f64,
) -> Point3<f64> {
    if points.is_empty() || spacing.is_nan() || spacing <= 0.0 {
        return Point3::origin();
    }
    let m = rotation.to_rotation_matrix().into_inner();
    let cos_max = ORIGIN_ANGLE.cos();
    let threshold = flat_threshold(planes);
    let flat: Vec<&LocalPlane> = planes.iter().filter(|p| p.flatness <= threshold).collect();
    let mut offset = Vector3::zeros();
    for i in 0..3 {
        let axis = m.column(i).into_owned();
        let coords: Vec<f64> = flat
            .iter()
            .filter(|p| p.normal.dot(&axis).abs() >= cos_max)
            .map(|p| p.point.coords.dot(&axis))
            .collect();
        offset[i] = if coords.len() * 20 >= flat.len().max(1) {
            circular_mean(&coords, spacing)
        } else {
            low_end(points, &axis) + size / 2.0
        };
    }
    Point3::from(m * offset)
}

/// The lattice frame and origin that fit already refined `primitives` best: starting
/// from `start`, Procrustes iterations on the primitives' local axes (each primitive's
/// three rotated axes, weighted by its area) give the rotation; the origin along each
/// axis is the area-weighted circular mean, with period `spacing`, of the primitives'
/// centre coordinates (centres of lattice candidates sit on grid nodes).
pub fn realign(
    primitives: &[Primitive],
    start: &UnitQuaternion<f64>,
    spacing: f64,
) -> (UnitQuaternion<f64>, Point3<f64>) {
    let mut axes = Vec::new();
    let mut weights = Vec::new();
    for p in primitives {
        let m = p.pose.rotation.to_rotation_matrix().into_inner();
        for i in 0..3 {
            axes.push(m.column(i).into_owned());
            weights.push(p.area());
        }
    }
    let mut m = start.to_rotation_matrix().into_inner();
    for _ in 0..POLISH_ITERATIONS {
        m = procrustes_step_weighted(&m, &axes, &weights);
    }
    let rotation = canonical(&m);
    let r = rotation.to_rotation_matrix().into_inner();
    let mut offset = Vector3::zeros();
    for i in 0..3 {
        let axis = r.column(i).into_owned();
        let (s, c) = primitives.iter().fold((0.0, 0.0), |(s, c), p| {
            let a = TAU * p.pose.translation.dot(&axis) / spacing;
            (s + p.area() * a.sin(), c + p.area() * a.cos())
        });
        offset[i] = if s == 0.0 && c == 0.0 {
            0.0
        } else {
            s.atan2(c) * spacing / TAU
        };
    }
    (rotation, Point3::from(r * offset))
}

/// The circular mean of `values` with period `period`, in `[−period/2, period/2]`.
fn circular_mean(values: &[f64], period: f64) -> f64 {
    let (s, c) = values.iter().fold((0.0, 0.0), |(s, c), v| {
        let a = TAU * v / period;
        (s + a.sin(), c + a.cos())
    });
    if s == 0.0 && c == 0.0 {
        0.0
    } else {
        s.atan2(c) * period / TAU
    }
}

/// The 0.1 % quantile of the points' coordinates along `axis`.
fn low_end(points: &[Point3<f64>], axis: &Vector3<f64>) -> f64 {
    let stride = points.len().div_ceil(100_000).max(1);
    let mut c: Vec<f64> = points
        .iter()
        .step_by(stride)
        .map(|p| p.coords.dot(axis))
        .collect();
    let k = (c.len() / 1000).min(c.len() - 1);
    c.select_nth_unstable_by(k, f64::total_cmp);
    c[k]
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn plane(n: Vector3<f64>, at: Vector3<f64>) -> LocalPlane {
        LocalPlane {
            point: Point3::from(at),
            normal: n.normalize(),
            flatness: 0.0,
            residual: 0.0,
        }
    }

    /// Normals of a room rotated by `r`: 3 walls, uneven counts.
    fn room(r: &UnitQuaternion<f64>) -> Vec<LocalPlane> {
        let mut out = Vec::new();
        for (axis, count) in [(Vector3::x(), 50), (Vector3::y(), 80), (Vector3::z(), 120)] {
            for k in 0..count {
                let at = Vector3::new(k as f64 * 0.01, 0.3, 0.7);
                out.push(plane(r * axis, r * at));
            }
        }
        out
    }

    fn same_axes(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>, tol: f64) -> bool {
        let (ma, mb) = (a.to_rotation_matrix(), b.to_rotation_matrix());
        (0..3).all(|i| {
            (0..3).any(|j| ma.matrix().column(i).dot(&mb.matrix().column(j)).abs() > 1.0 - tol)
        })
    }

    #[test]
    fn recovers_a_rotated_room() {
        let r = UnitQuaternion::from_euler_angles(0.3, -0.7, 1.1);
        let e = estimate_frame(&room(&r), 0).unwrap();
        assert!(same_axes(&e.rotation, &r, 1e-9), "{:?}", e.rotation);
        assert!(e.support > 0.99);
    }

    #[test]
    fn aligned_room_keeps_the_identity() {
        let r = UnitQuaternion::from_euler_angles(0.001, 0.0, -0.002);
        let e = estimate_frame(&room(&r), 0).unwrap();
        assert_eq!(e.rotation, UnitQuaternion::identity());
    }

    #[test]
    fn a_tube_gets_an_axis_along_it() {
        let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
        let u = axis.cross(&Vector3::x()).normalize();
        let v = axis.cross(&u);
        let planes: Vec<LocalPlane> = (0..360)
            .map(|k| {
                let t = (k as f64).to_radians();
                plane(u * t.cos() + v * t.sin(), Vector3::zeros())
            })
            .collect();
        let e = estimate_frame(&planes, 1).unwrap();
        let m = e.rotation.to_rotation_matrix().into_inner();
        assert!(
            (0..3).any(|i| m.column(i).dot(&axis).abs() > 1.0 - 1e-6),
            "{m}"
        );
    }

    #[test]
    fn origin_puts_grid_planes_on_the_walls() {
        let r = UnitQuaternion::from_euler_angles(0.2, 0.1, -0.4);
        // Walls at x = 0.3 and x = 0.8 (a spacing apart), floor at z = 0.1; nothing along y.
        let mut planes = Vec::new();
        let mut points = Vec::new();
        for k in 0..100 {
            let t = k as f64 * 0.01;
            for (n, at) in [
                (Vector3::x(), Vector3::new(0.3, t, 1.0)),
                (Vector3::x(), Vector3::new(0.8, t, 1.0)),
                (Vector3::z(), Vector3::new(t, t, 0.1)),
            ] {
                planes.push(plane(r * n, r * at));
                points.push(Point3::from(r * at));
            }
        }
        let o = grid_origin(&planes, &points, &r, 0.5, 1.0);
        let local = r.inverse_transform_point(&o);
        let phase = |c: f64| (c / 0.5 - (c / 0.5).round()).abs() * 0.5;
        assert!(phase(local.x - 0.3) < 1e-9, "{local}");
        assert!(phase(local.z - 0.1) < 1e-9, "{local}");
        // y: low end of the data (0) plus half the size.
        assert!((local.y - 0.5).abs() < 1e-9, "{local}");
    }

    #[test]
    fn frame_json_forms() {
        let f = FrameChoice::from_json(&json!({"rotation": [1.0, 0.0, 0.0, 0.0]})).unwrap();
        assert_eq!(
            f,
            FrameChoice::Given {
                rotation: UnitQuaternion::identity(),
                origin: None
            }
        );
        let doc = json!({"settings": {"frame": {"rotation": [0.0, 0.0, 0.0, 2.0]}, "origin": [1.0, 2.0, 3.0]}});
        let FrameChoice::Given { rotation, origin } = FrameChoice::from_json(&doc).unwrap() else {
            panic!("not a given frame");
        };
        assert!((rotation.angle() - std::f64::consts::PI).abs() < 1e-12);
        assert_eq!(origin, Some(Point3::new(1.0, 2.0, 3.0)));
        assert!(FrameChoice::from_json(&json!({"rotation": [0, 0, 0, 0]})).is_err());
        assert!(FrameChoice::from_json(&json!({})).is_err());
        assert!(FrameChoice::parse("sideways").is_err());
        assert_eq!(FrameChoice::parse("auto").unwrap(), FrameChoice::Auto);
    }
}
