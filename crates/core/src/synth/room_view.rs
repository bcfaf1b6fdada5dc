//! How a [`RoomGeometry`] is seen: points on its visible surfaces, area-uniform or as a
//! depth camera sees them, with Kinect-type quantised depth, moved into the scene by a
//! yaw, a tilt, an offset and a unit; the ground truth in the same frame.
//!
//! **Quantised depth.** A structured-light sensor measures disparity `q ∝ 1/z` in
//! integer (sub-)pixel steps, so depth `z` (along the optical axis) takes the values
//! `1 / (n κ)`, `n` an integer: the step between levels is `dz = z² dq = κ z²`, with
//! `κ = 2.85·10⁻³ m⁻¹` for a Kinect ([`KINECT_DISPARITY_STEP`]; 1.1 cm at 2 m,
//! 4.6 cm at 4 m). Rounding to a step `s` moves a point by a uniform error on
//! `[−s/2, s/2]` along its ray, of deviation `s / √12`; [`RoomScene::sigma`] combines it
//! with the Gaussian noise as `√(σ² + mean(s²)/12)`.

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::common::{check_scene_points, gauss, mesh_cdf, sample_mesh, sample_shape_local};
use super::depth::{SensorParams, depth_sensor};
use super::room::RoomGeometry;
use crate::atlas::{PlaneShape, Shape};
use crate::check::{self, non_negative, positive};
use crate::{PointCloud, Pose, Primitive, Result};

/// Disparity step κ of a Kinect-type sensor (1/m): depth levels `κ z²` apart.
pub const KINECT_DISPARITY_STEP: f64 = 2.85e-3;

/// Depths (along the optical axis) below this are not measured (metres, a Kinect's
/// near limit).
pub const MIN_SENSOR_DEPTH: f64 = 0.5;

/// What produces the points (room frame, metres).
#[derive(Debug, Clone, PartialEq)]
pub enum RoomView {
    /// `density` points per m² on every visible surface, area-uniform, jittered by
    /// N(0, σ²) along the surface normal.
    Uniform {
        /// Points per m².
        density: f64,
    },
    /// As [`RoomView::Uniform`] (no occlusion), then every point's depth from `sensor`
    /// quantised (module docs); points nearer than [`MIN_SENSOR_DEPTH`] are dropped.
    QuantisedUniform {
        /// Points per m² before dropping.
        density: f64,
        /// The sensor (room frame), looking along its +x.
        sensor: Pose,
        /// Disparity step κ (1/m), e.g. [`KINECT_DISPARITY_STEP`].
        disparity_step: f64,
    },
    /// A depth camera at `sensor` ([`depth_sensor`]: pinhole, nearest crossing per
    /// pixel, so with occlusion), range noise σ, depth quantised; points nearer than
    /// [`MIN_SENSOR_DEPTH`] are dropped.
    DepthCamera {
        /// The sensor (room frame), looking along its +x.
        sensor: Pose,
        /// Pixels per row and rows.
        pixels: (usize, usize),
        /// Horizontal and vertical fields of view (radians, in (0, π)).
        fov: (f64, f64),
        /// Disparity step κ (1/m); 0: no quantisation.
        disparity_step: f64,
    },
}

/// Parameters of [`room`].
#[derive(Debug, Clone, PartialEq)]
pub struct RoomParams {
    /// The room (room frame, metres).
    pub geometry: RoomGeometry,
    /// How it is seen.
    pub view: RoomView,
    /// σ of the Gaussian noise (metres): along the normal, or along the ray for
    /// [`RoomView::DepthCamera`].
    pub sigma: f64,
    /// Rotation about the room's vertical (radians).
    pub yaw: f64,
    /// Then a tilt about the scene's x axis (radians).
    pub tilt: f64,
    /// Then an offset (metres).
    pub offset: Vector3<f64>,
    /// Scene units per metre (1: metres; 1e-3: the room a thousand times smaller).
    pub unit: f64,
    /// RNG seed.
    pub seed: u64,
}

impl Default for RoomParams {
    /// The default room, 1 500 points per m², σ = 5 mm, yawed 27°, tilted 2°.
    fn default() -> Self {
        RoomParams {
            geometry: RoomGeometry::default(),
            view: RoomView::Uniform { density: 1500.0 },
            sigma: 0.005,
            yaw: 27f64.to_radians(),
            tilt: 2f64.to_radians(),
            offset: Vector3::new(1.0, -2.0, 0.5),
            unit: 1.0,
            seed: 0,
        }
    }
}

/// A synthetic room with its ground truth (scene frame and units).
#[derive(Debug, Clone)]
pub struct RoomScene {
    /// The points; `labels` holds each point's true surface (an index into `truth`),
    /// `sensors` the sensor position for the sensor views.
    pub cloud: PointCloud,
    /// Every visible surface ([`RoomGeometry::surfaces`]), in the scene.
    pub truth: Vec<Primitive>,
    /// How many points each true surface produced.
    pub points_per_surface: Vec<usize>,
    /// Room frame (metres) → scene: `unit · (R p + offset)`.
    pub pose: Pose,
    /// The deviation of a point from its surface (scene units): the noise σ, combined
    /// with the quantisation's `step/√12` where depth is quantised (module docs).
    pub sigma: f64,
}

/// The room scene of `params` (same seed ⇒ bit-identical scene).
pub fn room(params: &RoomParams) -> Result<RoomScene> {
    non_negative("sigma", params.sigma)?;
    positive("unit", params.unit)?;
    check::finite("yaw, tilt", &[params.yaw, params.tilt])?;
    check::finite("offset", params.offset.as_slice())?;
    let surfaces = params.geometry.surfaces()?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let sigma = params.sigma;
    let (points, labels, sensor, step2) = match &params.view {
        RoomView::Uniform { density } => {
            let (p, l) = sample_surfaces(&surfaces, *density, sigma, &mut rng)?;
            (p, l, None, 0.0)
        }
        RoomView::QuantisedUniform {
            density,
            sensor,
            disparity_step,
        } => {
            positive("disparity_step", *disparity_step)?;
            let (p, l) = sample_surfaces(&surfaces, *density, sigma, &mut rng)?;
            let (p, l, s2) = quantise(p, l, sensor, *disparity_step);
            (p, l, Some(*sensor), s2)
        }
        RoomView::DepthCamera {
            sensor,
            pixels,
            fov,
            disparity_step,
        } => {
            non_negative("disparity_step", *disparity_step)?;
            let (p, l) = camera(&surfaces, sensor, *pixels, *fov, params)?;
            let (p, l, s2) = quantise(p, l, sensor, *disparity_step);
            (p, l, Some(*sensor), s2)
        }
    };
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), params.tilt)
        * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), params.yaw);
    let pose = Pose {
        rotation,
        translation: params.offset * params.unit,
        scale: params.unit,
    };
    let truth = surfaces
        .iter()
        .map(|s| scaled(s, &pose))
        .collect::<Result<Vec<_>>>()?;
    let mut points_per_surface = vec![0; truth.len()];
    for &l in &labels {
        points_per_surface[l as usize] += 1;
    }
    let mut cloud = PointCloud::from_points(points.iter().map(|p| pose.to_scene(p)).collect());
    cloud.sensors = sensor.map(|s| vec![pose.to_scene(&Point3::from(s.translation)); labels.len()]);
    cloud.labels = Some(labels);
    Ok(RoomScene {
        cloud,
        truth,
        points_per_surface,
        pose,
        sigma: (sigma * sigma + step2 / 12.0).sqrt() * params.unit,
    })
}

/// `round(density × area)` points area-uniformly on each surface (in order), each
/// jittered by N(0, σ²) along the surface normal; with each point's surface index.
fn sample_surfaces(
    surfaces: &[Primitive],
    density: f64,
    sigma: f64,
    rng: &mut ChaCha8Rng,
) -> Result<(Vec<Point3<f64>>, Vec<i32>)> {
    positive("density", density)?;
    let total: f64 = surfaces.iter().map(|s| s.area() * density).sum();
    check_scene_points(
        &format!("a room at {density} points per m²"),
        total,
        "density",
    )?;
    let (mut points, mut labels) = (Vec::new(), Vec::new());
    for (i, s) in surfaces.iter().enumerate() {
        let count = (s.area() * density).round() as usize;
        let cdf = match &s.shape {
            Shape::Plane(p) => Some(mesh_cdf(p.mesh())),
            _ => None,
        };
        for _ in 0..count {
            let (local, normal) = match (&s.shape, &cdf) {
                (Shape::Plane(p), Some(c)) => (sample_mesh(p.mesh(), c, rng), Vector3::z()),
                (shape, _) => {
                    let q = sample_shape_local(shape, rng);
                    let radial = Vector3::new(q.x, q.y, 0.0);
                    (q, radial.try_normalize(0.0).unwrap_or_else(Vector3::z))
                }
            };
            points.push(s.pose.to_scene(&(local + normal * (sigma * gauss(rng)))));
            labels.push(i as i32);
        }
    }
    Ok((points, labels))
}

/// The points a depth camera at `sensor` sees of `surfaces`, range noise σ.
fn camera(
    surfaces: &[Primitive],
    sensor: &Pose,
    (columns, rows): (usize, usize),
    (h_fov, v_fov): (f64, f64),
    params: &RoomParams,
) -> Result<(Vec<Point3<f64>>, Vec<i32>)> {
    let cloud = depth_sensor(
        surfaces,
        &SensorParams {
            poses: vec![*sensor],
            h_fov,
            v_fov,
            columns,
            rows,
            max_range: 2.0 * params.geometry.size.norm(),
            range_noise: params.sigma,
            labels: Some((0..surfaces.len() as i32).collect()),
            normals: false,
            seed: params.seed,
        },
    )?;
    let labels = cloud.labels.unwrap_or_default();
    Ok((cloud.points, labels))
}

/// Each point's depth from `sensor` (along its +x) rounded to the disparity grid of
/// step `kappa` (none when 0); points nearer than [`MIN_SENSOR_DEPTH`] dropped. Returns
/// the kept points, their labels, and the mean squared depth step `κ² z⁴` over them.
fn quantise(
    points: Vec<Point3<f64>>,
    labels: Vec<i32>,
    sensor: &Pose,
    kappa: f64,
) -> (Vec<Point3<f64>>, Vec<i32>, f64) {
    let origin = Point3::from(sensor.translation);
    let forward = sensor.rotation * Vector3::x();
    let (mut out, mut kept, mut step2) = (Vec::new(), Vec::new(), 0.0);
    for (p, l) in points.into_iter().zip(labels) {
        let d = p - origin;
        let z = d.dot(&forward);
        if z < MIN_SENSOR_DEPTH {
            continue;
        }
        if kappa > 0.0 {
            let level = (1.0 / (z * kappa)).round().max(1.0);
            let zq = 1.0 / (level * kappa);
            out.push(origin + d * (zq / z));
            step2 += (kappa * z * z).powi(2);
        } else {
            out.push(p);
        }
        kept.push(l);
    }
    let n = kept.len().max(1) as f64;
    (out, kept, step2 / n)
}

/// `p` (room frame, metres) moved by `pose` into the scene, with unit scale: its shape
/// scaled by `pose.scale`.
fn scaled(p: &Primitive, pose: &Pose) -> Result<Primitive> {
    let k = pose.scale;
    let shape = match &p.shape {
        Shape::Plane(s) => {
            let ring = |r: &[nalgebra::Point2<f64>]| r.iter().map(|v| v * k).collect();
            Shape::Plane(PlaneShape::new(
                ring(s.outline()),
                s.holes().iter().map(|h| ring(h)).collect(),
            )?)
        }
        Shape::Cylinder { length, radius } => Shape::Cylinder {
            length: length * k,
            radius: radius * k,
        },
        other => other.clone(),
    };
    let placed = pose.compose(&p.pose);
    Ok(Primitive::new(
        shape,
        Pose::new(placed.rotation, placed.translation),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::look_at;

    fn corner_sensor() -> Pose {
        look_at(Point3::new(0.4, 0.4, 1.6), Point3::new(4.0, 3.0, 0.6)).unwrap()
    }

    /// RMS distance of each point to its own true surface.
    fn rms_to_truth(s: &RoomScene) -> f64 {
        let labels = s.cloud.labels.as_ref().unwrap();
        let sum: f64 = s
            .cloud
            .points
            .iter()
            .zip(labels)
            .map(|(p, &l)| s.truth[l as usize].distance(p).powi(2))
            .sum();
        (sum / labels.len() as f64).sqrt()
    }

    #[test]
    fn uniform_points_lie_on_their_surface_within_sigma_in_any_unit() {
        let params = RoomParams {
            view: RoomView::Uniform { density: 200.0 },
            ..Default::default()
        };
        let a = room(&params).unwrap();
        assert_eq!(a.truth.len(), 15);
        let area: f64 = a.truth.iter().map(Primitive::area).sum();
        assert!(((a.cloud.len() as f64) - 200.0 * area).abs() < 15.0);
        let rms = rms_to_truth(&a);
        assert!((rms / 0.005 - 1.0).abs() < 0.05, "rms {rms}");
        assert_eq!(a.sigma, 0.005);
        // Same seed, same scene; a thousandth of the size, the same scene scaled.
        let b = room(&params).unwrap();
        assert_eq!(a.cloud, b.cloud);
        let small = room(&RoomParams {
            unit: 1e-3,
            ..params
        })
        .unwrap();
        for (p, q) in a.cloud.points.iter().zip(&small.cloud.points) {
            assert!((p * 1e-3 - q).norm() < 1e-12);
        }
        assert!((rms_to_truth(&small) - 1e-3 * rms).abs() < 1e-9);
        assert!((small.truth[0].area() - 1e-6 * a.truth[0].area()).abs() < 1e-15);
    }

    #[test]
    fn quantised_depth_lies_on_the_disparity_levels() {
        let sensor = corner_sensor();
        let params = RoomParams {
            view: RoomView::QuantisedUniform {
                density: 300.0,
                sensor,
                disparity_step: KINECT_DISPARITY_STEP,
            },
            sigma: 0.0,
            yaw: 0.0,
            tilt: 0.0,
            offset: Vector3::zeros(),
            ..Default::default()
        };
        let s = room(&params).unwrap();
        let forward = sensor.rotation * Vector3::x();
        for p in &s.cloud.points {
            let z = (p - Point3::from(sensor.translation)).dot(&forward);
            let level = 1.0 / (z * KINECT_DISPARITY_STEP);
            assert!(z >= MIN_SENSOR_DEPTH - 0.05);
            assert!((level - level.round()).abs() < 1e-6, "z = {z}");
        }
        // The points' deviation from the truth is about the step/√12 the scene claims
        // (smaller, since rays meet surfaces obliquely: only the normal part counts).
        let rms = rms_to_truth(&s);
        assert!(rms < s.sigma && rms > 0.3 * s.sigma, "{rms} vs {}", s.sigma);
    }

    #[test]
    fn a_depth_camera_sees_the_faces_in_front_of_it() {
        let params = RoomParams {
            view: RoomView::DepthCamera {
                sensor: corner_sensor(),
                pixels: (160, 120),
                fov: (58f64.to_radians(), 45f64.to_radians()),
                disparity_step: KINECT_DISPARITY_STEP,
            },
            ..Default::default()
        };
        let s = room(&params).unwrap();
        assert!(s.cloud.len() > 15_000, "{}", s.cloud.len());
        assert!(s.cloud.sensors.as_ref().unwrap().len() == s.cloud.len());
        // Looking from the corner (0, 0) into the room: the walls x = 0 and y = 0 behind
        // the sensor are not seen; the floor and the far walls are.
        let n = &s.points_per_surface;
        assert!(n[0] > 1000 && n[2] > 1000 && n[4] > 1000, "{n:?}");
        assert!(n[1] == 0 && n[3] == 0, "{n:?}");
        let rms = rms_to_truth(&s);
        assert!(rms < 1.5 * s.sigma, "{rms} vs {}", s.sigma);
    }
}
