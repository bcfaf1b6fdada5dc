//! A simulated depth sensor: ray-casts a scene's true primitives from a sequence of
//! poses, giving realistic multi-frame scans with sensor origins (for the ray likelihood
//! of [`crate::ray`]).
//!
//! The sensor is a pinhole camera: in its own frame it looks along **+x** with **+z** up;
//! pixel `(c, r)` of a `columns × rows` image looks along `(1, u_c, v_r)` with `u`, `v`
//! evenly spread over `±tan(fov/2)` (pixel centres). Each pixel's ray keeps the nearest
//! crossing with any true primitive within `max_range`; its range gets Gaussian noise
//! (`range_noise`, along the ray only), and the point is `origin + range · dir`.
//! Pixels that see nothing give no point.

use nalgebra::{Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::common::gauss;
use crate::check::{self, Interval, non_negative, positive};
use crate::{Error, PointCloud, Pose, Primitive, Result};

/// Parameters of [`depth_sensor`]. Angles in radians, lengths in scene units (metres).
#[derive(Debug, Clone, PartialEq)]
pub struct SensorParams {
    /// Sensor poses (sensor frame → scene), one frame each, in time order.
    pub poses: Vec<Pose>,
    /// Full horizontal field of view, in `(0, π)`.
    pub h_fov: f64,
    /// Full vertical field of view, in `(0, π)`.
    pub v_fov: f64,
    /// Pixels per row.
    pub columns: usize,
    /// Pixel rows.
    pub rows: usize,
    /// Crossings farther than this are not seen.
    pub max_range: f64,
    /// σ of the Gaussian range noise along each ray.
    pub range_noise: f64,
    /// Semantic label of each true primitive (same order as the truth), copied to the
    /// points it produces; `None`: the cloud has no labels.
    pub labels: Option<Vec<i32>>,
    /// Whether to store the true surface normal (facing the sensor) of every point.
    pub normals: bool,
    /// RNG seed of the noise.
    pub seed: u64,
}

impl Default for SensorParams {
    fn default() -> Self {
        SensorParams {
            poses: vec![Pose::identity()],
            h_fov: 90f64.to_radians(),
            v_fov: 60f64.to_radians(),
            columns: 64,
            rows: 48,
            max_range: 20.0,
            range_noise: 0.01,
            labels: None,
            normals: true,
            seed: 0,
        }
    }
}

impl SensorParams {
    fn validate(&self, truth: &[Primitive]) -> Result<()> {
        // Radians.
        let field_of_view = Interval::open(0.0, std::f64::consts::PI);
        check::in_interval("h_fov", self.h_fov, field_of_view)?;
        check::in_interval("v_fov", self.v_fov, field_of_view)?;
        check::at_least("columns", self.columns, 1)?;
        check::at_least("rows", self.rows, 1)?;
        positive("max_range", self.max_range)?;
        non_negative("range_noise", self.range_noise)?;
        if let Some(l) = &self.labels {
            check::same_len("labels", l.len(), "true primitives", truth.len())?;
        }
        for (k, pose) in self.poses.iter().enumerate() {
            check::finite(
                &format!("poses[{k}].translation"),
                pose.translation.as_slice(),
            )?;
        }
        Ok(())
    }

    /// Unit ray directions of every pixel in the sensor frame, row-major.
    fn pixel_dirs(&self) -> Vec<Vector3<f64>> {
        let (tu, tv) = ((self.h_fov / 2.0).tan(), (self.v_fov / 2.0).tan());
        let spread = |k: usize, n: usize, t: f64| t * (2.0 * (k as f64 + 0.5) / n as f64 - 1.0);
        (0..self.rows)
            .flat_map(|r| {
                (0..self.columns).map(move |c| {
                    Vector3::new(1.0, spread(c, self.columns, tu), spread(r, self.rows, tv))
                        .normalize()
                })
            })
            .collect()
    }
}

/// The error of a point `name` at `p` that coincides with the point `other`.
fn distinct_points(name: &str, p: &Point3<f64>, other: &str) -> Error {
    let expected = format!("a point other than {other}");
    Error::out_of_range(name, format!("{:?}", p.coords.as_slice()), expected)
}

/// A sensor pose at `eye` looking at `target`, with the sensor's +z as close to the
/// scene's +z as possible (+y when looking straight up or down).
pub fn look_at(eye: Point3<f64>, target: Point3<f64>) -> Result<Pose> {
    let forward = (target - eye)
        .try_normalize(1e-12)
        .ok_or_else(|| distinct_points("target", &target, "eye"))?;
    let up = [Vector3::z(), Vector3::y()]
        .iter()
        .find_map(|a| (a - forward * a.dot(&forward)).try_normalize(1e-6))
        .unwrap_or_else(Vector3::z);
    let left = up.cross(&forward);
    let m = Matrix3::from_columns(&[forward, left, up]);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    Ok(Pose::new(rotation, eye.coords))
}

/// `frames` poses evenly spaced from `from` to `to` (both included; one frame: `from`),
/// each looking `ahead` scene units further along the path and `drop` units lower: a
/// walk-through (e.g. down a hallway).
pub fn walk_poses(
    from: Point3<f64>,
    to: Point3<f64>,
    frames: usize,
    ahead: f64,
    drop: f64,
) -> Result<Vec<Pose>> {
    let dir = (to - from)
        .try_normalize(1e-12)
        .ok_or_else(|| distinct_points("to", &to, "from"))?;
    (0..frames)
        .map(|k| {
            let s = if frames > 1 {
                k as f64 / (frames - 1) as f64
            } else {
                0.0
            };
            let eye = from + (to - from) * s;
            look_at(eye, eye + dir * ahead - Vector3::z() * drop)
        })
        .collect()
}

/// `frames` poses on the horizontal circle of `radius` about `centre` (at `centre.z +
/// height`), each looking at `centre`: an orbit around a compact scene.
pub fn orbit_poses(
    centre: Point3<f64>,
    radius: f64,
    height: f64,
    frames: usize,
) -> Result<Vec<Pose>> {
    positive("radius", radius)?;
    (0..frames)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / frames.max(1) as f64;
            let eye = centre + Vector3::new(radius * a.cos(), radius * a.sin(), height);
            look_at(eye, centre)
        })
        .collect()
}

/// One pixel's nearest crossing: `(truth index, depth, normal)`.
fn nearest(
    truth: &[Primitive],
    o: &Point3<f64>,
    d: &Vector3<f64>,
    max: f64,
) -> Option<(usize, f64, Vector3<f64>)> {
    truth
        .iter()
        .enumerate()
        .filter_map(|(k, p)| p.first_hit(o, d).map(|h| (k, h.depth, h.normal)))
        .filter(|h| h.1 <= max)
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// Scans `truth` from every pose of `params` and returns the cloud with `sensors` set
/// (and `normals`, `labels` as asked). Points are ordered by frame, then pixel.
pub fn depth_sensor(truth: &[Primitive], params: &SensorParams) -> Result<PointCloud> {
    params.validate(truth)?;
    let pixels = params.pixel_dirs();
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut cloud = PointCloud::default();
    let (mut sensors, mut normals, mut labels) = (Vec::new(), Vec::new(), Vec::new());
    for pose in &params.poses {
        let origin = Point3::from(pose.translation);
        let hits: Vec<Option<(usize, f64, Vector3<f64>)>> = pixels
            .par_iter()
            .map(|d| nearest(truth, &origin, &(pose.rotation * d), params.max_range))
            .collect();
        for (d, hit) in pixels.iter().zip(hits) {
            let Some((k, depth, normal)) = hit else {
                continue;
            };
            let range = depth + params.range_noise * gauss(&mut rng);
            if range <= 0.0 {
                continue;
            }
            cloud.points.push(origin + (pose.rotation * d) * range);
            sensors.push(origin);
            normals.push(normal);
            if let Some(l) = &params.labels {
                labels.push(l[k]);
            }
        }
    }
    cloud.sensors = Some(sensors);
    cloud.normals = params.normals.then_some(normals);
    cloud.labels = params.labels.as_ref().map(|_| labels);
    Ok(cloud)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::Shape;
    use crate::synth::axis_rotation;

    fn wall_and_floor() -> Vec<Primitive> {
        vec![
            Primitive::new(
                Shape::Square { side: 4.0 },
                Pose::new(axis_rotation(0), Vector3::new(5.0, 0.0, 1.0)),
            ),
            Primitive::new(
                Shape::Square { side: 6.0 },
                Pose::new(axis_rotation(2), Vector3::new(3.0, 0.0, 0.0)),
            ),
        ]
    }

    fn params() -> SensorParams {
        SensorParams {
            poses: vec![
                look_at(Point3::new(0.0, 0.0, 1.0), Point3::new(5.0, 0.0, 0.5)).unwrap(),
                look_at(Point3::new(0.5, 1.0, 1.2), Point3::new(5.0, -0.5, 0.5)).unwrap(),
            ],
            labels: Some(vec![2, 1]),
            columns: 32,
            rows: 24,
            ..Default::default()
        }
    }

    #[test]
    fn points_lie_on_the_truth_and_carry_their_sensor() {
        let truth = wall_and_floor();
        let cloud = depth_sensor(&truth, &params()).unwrap();
        let (sensors, labels, normals) = (
            cloud.sensors.as_ref().unwrap(),
            cloud.labels.as_ref().unwrap(),
            cloud.normals.as_ref().unwrap(),
        );
        assert!(cloud.len() > 800, "{}", cloud.len());
        let origins: std::collections::BTreeSet<[u64; 3]> = sensors
            .iter()
            .map(|s| [s.x.to_bits(), s.y.to_bits(), s.z.to_bits()])
            .collect();
        assert_eq!(origins.len(), 2);
        for j in 0..cloud.len() {
            let k = if labels[j] == 2 { 0 } else { 1 };
            // Range noise σ = 1 cm along rays that meet the surfaces at ≥ ~10°.
            assert!(truth[k].distance(&cloud.points[j]) < 0.06, "point {j}");
            assert!(normals[j].dot(&(cloud.points[j] - sensors[j])) < 0.0);
        }
        assert!(labels.contains(&1) && labels.contains(&2));
    }

    #[test]
    fn same_seed_same_scan_and_bad_params_are_errors() {
        let truth = wall_and_floor();
        assert_eq!(
            depth_sensor(&truth, &params()).unwrap(),
            depth_sensor(&truth, &params()).unwrap()
        );
        for bad in [
            SensorParams {
                h_fov: 4.0,
                ..params()
            },
            SensorParams {
                rows: 0,
                ..params()
            },
            SensorParams {
                labels: Some(vec![1]),
                ..params()
            },
            SensorParams {
                range_noise: -1.0,
                ..params()
            },
        ] {
            assert!(depth_sensor(&truth, &bad).is_err());
        }
        assert!(look_at(Point3::origin(), Point3::origin()).is_err());
        assert!(walk_poses(Point3::origin(), Point3::origin(), 3, 1.0, 0.0).is_err());
        let walk = walk_poses(Point3::origin(), Point3::new(4.0, 0.0, 0.0), 3, 1.0, 0.0).unwrap();
        assert_eq!(walk[2].translation, Vector3::new(4.0, 0.0, 0.0));
        assert!((walk[1].rotation * Vector3::x() - Vector3::x()).norm() < 1e-12);
        let orbit = orbit_poses(Point3::origin(), 2.0, 1.0, 4).unwrap();
        assert!((orbit[1].translation - Vector3::new(0.0, 2.0, 1.0)).norm() < 1e-12);
    }
}
