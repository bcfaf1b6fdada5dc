//! Partial-view registration scenes: a randomly posed mesh seen by a depth sensor from
//! one random viewpoint (so only its near side, self-occluded, with range noise), among
//! structured clutter (a plane the object stands on, other objects beside it) and
//! uniform outliers. The ray-casting is [`depth_sensor`]'s.

use nalgebra::{Point3, Unit, UnitQuaternion, Vector3};
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::common::{LatticeHint, Scene, random_unit};
use super::depth::{SensorParams, depth_sensor, look_at};
use super::registration::random_rotation;
use crate::atlas::{MeshShape, Shape};
use crate::check::{self, non_negative, positive};
use crate::{PointCloud, Pose, Primitive, Result};

/// Sensor distance from the object's centre, in units of its bounding radius.
const VIEW_DISTANCE: f64 = 3.0;
/// Pixels per image side: enough that the object fills a few thousand pixels, of which
/// [`PartialViewParams::inliers`] are kept.
const PIXELS: usize = 128;
/// The image's half-width covers this many bounding radii around the object (so the
/// plane and the other objects are in view too).
const FIELD_RADII: f64 = 2.0;
/// Labels of the scanned points: the object, the structured clutter, uniform outliers.
const OBJECT_LABEL: i32 = 1;

/// Parameters of [`partial_view`]. Lengths in the mesh's units.
#[derive(Debug, Clone, PartialEq)]
pub struct PartialViewParams {
    /// Object points kept: a random subset of the pixels that see the object (all of
    /// them when fewer).
    pub inliers: usize,
    /// Uniform outliers in a cube around the object (half-side `outlier_box` × its
    /// bounding radius).
    pub outliers: usize,
    /// Points kept from the scan of the structured clutter (plane and other objects;
    /// all of them when fewer).
    pub clutter_points: usize,
    /// Whether a plane (facing the sensor) supports the object.
    pub plane: bool,
    /// Other objects (spheres and cylinders of about the object's size) beside it.
    pub distractors: usize,
    /// Whether the object is in the scene; `false`: clutter only, empty truth (the
    /// scene is built as if it were there, so the same seed gives the same clutter).
    pub object: bool,
    /// Largest translation per axis: uniform in `[-t, t]³`.
    pub translation: f64,
    /// σ of the Gaussian range noise along each ray, scene units.
    pub range_noise: f64,
    /// Half-side of the outlier cube, in bounding radii of the posed mesh.
    pub outlier_box: f64,
    /// RNG seed.
    pub seed: u64,
}

impl Default for PartialViewParams {
    fn default() -> Self {
        PartialViewParams {
            inliers: 400,
            outliers: 3600,
            clutter_points: 0,
            plane: false,
            distractors: 0,
            object: true,
            translation: 0.0,
            range_noise: 0.0,
            outlier_box: 1.0,
            seed: 0,
        }
    }
}

impl PartialViewParams {
    fn validate(&self) -> Result<()> {
        non_negative("translation", self.translation)?;
        non_negative("range_noise", self.range_noise)?;
        positive("outlier_box", self.outlier_box)?;
        check::at_most("distractors", self.distractors, 16)
    }
}

/// The centre of the mesh's bounding box (local frame) and the radius of the ball about
/// it that holds the mesh.
fn local_ball(mesh: &MeshShape) -> (Point3<f64>, f64) {
    let (lo, hi) = crate::cloud::bounds_of(&mesh.mesh.vertices)
        .unwrap_or((Point3::origin(), Point3::origin()));
    let centre = nalgebra::center(&lo, &hi);
    let radius = mesh
        .mesh
        .vertices
        .iter()
        .map(|v| (v - centre).norm())
        .fold(0.0, f64::max);
    (centre, radius)
}

/// A rotation taking local +z onto `normal`.
fn z_onto(normal: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::z(), normal).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(&Unit::new_normalize(Vector3::x()), std::f64::consts::PI)
    })
}

/// The structured clutter around an object at `centre` (bounding radius `r`, surface
/// `object`) seen from direction `view`: a plane under it whose normal faces the sensor,
/// and `count` spheres and cylinders standing on it beside the object.
fn clutter(
    object: &Primitive,
    centre: Point3<f64>,
    r: f64,
    view: &Vector3<f64>,
    params: &PartialViewParams,
    rng: &mut ChaCha8Rng,
) -> Vec<Primitive> {
    // Up: a random direction at most ~70° from the view direction.
    let up = loop {
        let u = random_unit(rng);
        if u.dot(view) > 0.35 {
            break u;
        }
    };
    let vertices = object.triangulate().vertices;
    let drop = vertices
        .iter()
        .map(|v| -(v - centre).dot(&up))
        .fold(0.0, f64::max);
    let base = centre - up * drop;
    let mut out = Vec::new();
    if params.plane {
        let side = 2.0 * FIELD_RADII * r * 1.5;
        out.push(Primitive::new(
            Shape::Square { side },
            Pose::new(z_onto(&up), base.coords),
        ));
    }
    let across = up.cross(view).try_normalize(1e-9).unwrap_or_else(|| {
        let any = if up.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        up.cross(&any).normalize()
    });
    for k in 0..params.distractors {
        let size = r * (0.4 + 0.4 * rng.random::<f64>());
        let side = if k % 2 == 0 { 1.0 } else { -1.0 };
        let along = (1.6 + 0.5 * (k / 2) as f64) * r;
        let shift = across * side * along + up.cross(&across) * (rng.random::<f64>() - 0.5) * r;
        let shape = if k % 2 == 0 {
            Shape::Sphere { diameter: size }
        } else {
            Shape::Cylinder {
                length: size * 1.5,
                radius: size / 3.0,
            }
        };
        let lift = if k % 2 == 0 { size / 2.0 } else { size * 0.75 };
        let at = base + shift + up * lift;
        out.push(Primitive::new(shape, Pose::new(z_onto(&up), at.coords)));
    }
    out
}

/// `keep` indices of `0..n` at random (all of them, in order, when `n ≤ keep`).
fn subset(n: usize, keep: usize, rng: &mut ChaCha8Rng) -> Vec<usize> {
    let mut ids: Vec<usize> = (0..n).collect();
    if n > keep {
        ids.shuffle(rng);
        ids.truncate(keep);
        ids.sort_unstable();
    }
    ids
}

/// `mesh` under a random pose, seen by a depth sensor from one random viewpoint
/// ([`VIEW_DISTANCE`] bounding radii away, [`PIXELS`]² pixels), with the structured
/// clutter of `params` and `outliers` uniform points in a cube around the object. The
/// cloud lists the object's points first (a random subset of `inliers`), then the
/// clutter's, then the outliers; every point carries the sensor's origin. The truth is
/// the posed mesh (empty when `params.object` is false).
pub fn partial_view(mesh: &MeshShape, params: &PartialViewParams) -> Result<Scene> {
    params.validate()?;
    let shape = Shape::Mesh(mesh.clone());
    shape.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let rotation = random_rotation(&mut rng);
    let t = params.translation;
    let translation = Vector3::from_fn(|_, _| (2.0 * rng.random::<f64>() - 1.0) * t);
    let object = Primitive::new(shape, Pose::new(rotation, translation));
    let (local_centre, r) = local_ball(mesh);
    let centre = object.pose.to_scene(&local_centre);
    let view = random_unit(&mut rng);
    let eye = centre + view * (VIEW_DISTANCE * r);
    let others = clutter(&object, centre, r, &view, params, &mut rng);
    let mut scanned = Vec::with_capacity(others.len() + 1);
    scanned.push(object.clone());
    scanned.extend(others);
    let fov = 2.0 * (FIELD_RADII / VIEW_DISTANCE).atan();
    let labels = (0..scanned.len())
        .map(|k| if k == 0 { OBJECT_LABEL } else { 0 })
        .collect();
    let scan = depth_sensor(
        &scanned,
        &SensorParams {
            poses: vec![look_at(eye, centre)?],
            h_fov: fov,
            v_fov: fov,
            columns: PIXELS,
            rows: PIXELS,
            max_range: 2.0 * VIEW_DISTANCE * r,
            range_noise: params.range_noise,
            labels: Some(labels),
            normals: false,
            seed: rng.random(),
        },
    )?;
    let scan_labels = scan.labels.unwrap_or_default();
    let split = |label_is_object: bool| -> Vec<Point3<f64>> {
        scan.points
            .iter()
            .zip(&scan_labels)
            .filter(|(_, l)| (**l == OBJECT_LABEL) == label_is_object)
            .map(|(p, _)| *p)
            .collect()
    };
    let (seen, around) = (split(true), split(false));
    let mut points = Vec::new();
    if params.object {
        let keep = subset(seen.len(), params.inliers, &mut rng);
        points.extend(keep.iter().map(|&i| seen[i]));
    }
    let keep = subset(around.len(), params.clutter_points, &mut rng);
    points.extend(keep.iter().map(|&i| around[i]));
    let half = params.outlier_box * r;
    points.extend(
        (0..params.outliers)
            .map(|_| centre + Vector3::from_fn(|_, _| (2.0 * rng.random::<f64>() - 1.0) * half)),
    );
    let mut cloud = PointCloud::from_points(points);
    cloud.sensors = Some(vec![eye; cloud.len()]);
    Ok(Scene {
        cloud,
        lattice: LatticeHint {
            spacing: r,
            origin: Point3::origin(),
            shapes: vec![object.shape.clone()],
        },
        truth: if params.object { vec![object] } else { vec![] },
        misalignment: Pose::identity(),
    })
}
