//! The six-in-a-row toy of thesis §4.3: a sensor at the origin looking along +x and six
//! candidates one behind the other; the points come from one of them.

use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::common::{LatticeHint, Scene, axis_rotation, gauss, sample_shape_local};
use crate::atlas::Shape;
use crate::check::{self, non_negative, positive};
use crate::{Error, PointCloud, Pose, Primitive, Result};

/// Which candidates the toy uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SixVariant {
    /// Squares facing the sensor (normal along x), side `size`.
    #[default]
    Squares,
    /// Vertical cylinders (axis z) of length `size` and radius `size / 4`.
    Cylinders,
}

/// Parameters of [`six_in_a_row`]. Lengths in metres.
///
/// Candidate i (i = 0..6) sits at `(first + i·step, 0, 0)`; the lattice spacing is
/// `step`, origin 0 (so `first` must be a multiple of `step`).
#[derive(Debug, Clone, PartialEq)]
pub struct SixInARowParams {
    /// Squares or cylinders.
    pub variant: SixVariant,
    /// Distance of the nearest candidate from the sensor (thesis: 7 m).
    pub first: f64,
    /// Distance between consecutive candidates (thesis: 1 m).
    pub step: f64,
    /// Index (0..6) of the candidate the points come from (thesis: 3, the one at 10 m).
    pub true_index: usize,
    /// Square side / cylinder length.
    pub size: f64,
    /// Number of points.
    pub points: usize,
    /// σ of the range noise along each ray (metres): the ray model's noise is in depth only.
    pub jitter: f64,
    /// RNG seed.
    pub seed: u64,
}

impl Default for SixInARowParams {
    fn default() -> Self {
        SixInARowParams {
            variant: SixVariant::Squares,
            first: 7.0,
            step: 1.0,
            true_index: 3,
            size: 1.0,
            points: 500,
            jitter: 0.01,
            seed: 0,
        }
    }
}

/// The toy scene with its candidates.
#[derive(Debug, Clone)]
pub struct SixInARow {
    /// Cloud (with `sensors` set to the origin for every point), truth = the one true
    /// candidate, lattice hint.
    pub scene: Scene,
    /// The six candidates, nearest first.
    pub candidates: Vec<Primitive>,
    /// Index into `candidates` of the true one.
    pub true_index: usize,
}

/// Samples the visible side of the true candidate as seen from the origin: squares are
/// fully visible; for a cylinder only points whose outward normal faces the sensor are
/// kept (exact visibility for a convex tube). Noise is added along each ray (range).
pub fn six_in_a_row(params: &SixInARowParams) -> Result<SixInARow> {
    positive("first", params.first)?;
    positive("step", params.step)?;
    positive("size", params.size)?;
    non_negative("jitter", params.jitter)?;
    check::at_most("true_index", params.true_index, 5)?;
    check::multiple_of("first", params.first, params.step, "step")?;
    let (shape, rot) = match params.variant {
        SixVariant::Squares => (Shape::Square { side: params.size }, axis_rotation(0)),
        SixVariant::Cylinders => {
            if params.size / 4.0 >= params.first {
                // The cylinders must not contain the sensor.
                let expected = format!(
                    "more than the cylinder radius size / 4 = {}",
                    params.size / 4.0
                );
                return Err(Error::out_of_range("first", params.first, expected));
            }
            (
                Shape::Cylinder {
                    length: params.size,
                    radius: params.size / 4.0,
                },
                axis_rotation(2),
            )
        }
    };
    let candidates: Vec<Primitive> = (0..6)
        .map(|i| {
            let x = params.first + i as f64 * params.step;
            Primitive::new(shape.clone(), Pose::new(rot, Vector3::new(x, 0.0, 0.0)))
        })
        .collect();
    let truth = candidates[params.true_index].clone();
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut points = Vec::with_capacity(params.points);
    while points.len() < params.points {
        let local = sample_shape_local(&truth.shape, &mut rng);
        let p = truth.pose.to_scene(&local);
        if let Shape::Cylinder { .. } = truth.shape {
            // Outward normal in the local frame is (x, y, 0); visible iff it faces the sensor.
            let n = truth.pose.rotation * Vector3::new(local.x, local.y, 0.0);
            if n.dot(&(-p.coords)) <= 0.0 {
                continue;
            }
        }
        let range = p.coords.norm();
        let z = (range + params.jitter * gauss(&mut rng)).max(0.0);
        points.push(Point3::from(p.coords * (z / range)));
    }
    let n = points.len();
    let mut cloud = PointCloud::from_points(points);
    cloud.sensors = Some(vec![Point3::origin(); n]);
    Ok(SixInARow {
        scene: Scene {
            cloud,
            truth: vec![truth],
            lattice: LatticeHint {
                spacing: params.step,
                origin: Point3::origin(),
                shapes: vec![shape],
            },
            misalignment: Pose::identity(),
        },
        candidates,
        true_index: params.true_index,
    })
}
