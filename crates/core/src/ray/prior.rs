//! The existence prior of thesis §4.2.1, from point positions, normals and labels.
//!
//! The prior factorises, `p(Φ) = Π_i p(φ_i)`. Candidate centres sit on lattice nodes; a
//! node is a vertex of the eight lattice cells around it. `p(φ_i = 1)` is a small constant
//! (thesis: 0.1) when one of those eight cells holds a point that **counts** for the
//! candidate, and 0 otherwise (the candidate is dropped from the search). Which points
//! count:
//!
//! | candidate | labels (if the cloud has them) | normals (if the cloud has them) |
//! |---|---|---|
//! | flat (square, disk), face-up (normal ∥ `up`) | unknown (0) or ground (1) | within 45° of the candidate normal |
//! | flat, vertical (normal ⟂ `up`) | unknown (0), wall (2) or door (3) | within 45° of the candidate normal |
//! | flat, tilted | unknown (0) | within 45° of the candidate normal |
//! | cylinder | not ground, wall or door | more than 45° from the axis |
//! | elbow, sphere, mesh | not ground, wall or door | not used |
//!
//! The thesis's rule ("ground" points for face-up disks, "door"/"wall" points for the
//! others, their normals choosing face-forward or face-left/right) is the flat rows.

use std::collections::HashMap;

use nalgebra::{Point3, UnitQuaternion, Vector3};

use crate::atlas::ShapeKind;
use crate::check::{self, Interval};
use crate::error::{Remedy, Unit};
use crate::{Error, PointCloud, Primitive, Result};

/// The most lattice cells from the prior's origin to a point along an axis (cell
/// coordinates are `i64`; beyond this the floor is no longer exact).
const MAX_PRIOR_CELLS: f64 = 1e15;

/// `cos 45°`: a normal within 45° of an axis is "along" it.
const COS_45: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Label values (DESIGN §3).
const GROUND: i32 = 1;
const WALL: i32 = 2;
const DOOR: i32 = 3;

/// Parameters of the prior. Lengths in scene units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PriorOptions {
    /// `p(φ_i = 1)` of a supported candidate (thesis: 0.1), in `(0, 1)`.
    pub probability: f64,
    /// Lattice translation step (cell edge).
    pub spacing: f64,
    /// A lattice node.
    pub origin: Point3<f64>,
    /// Rotation of the lattice frame relative to the scene axes.
    pub frame: UnitQuaternion<f64>,
    /// The "up" direction (unit; ground is face-up).
    pub up: Vector3<f64>,
}

impl PriorOptions {
    /// The thesis's prior (0.1) on an axis-aligned lattice of step `spacing` through the
    /// origin, `up` = +z.
    pub fn new(spacing: f64) -> Self {
        PriorOptions {
            probability: 0.1,
            spacing,
            origin: Point3::origin(),
            frame: UnitQuaternion::identity(),
            up: Vector3::z(),
        }
    }

    /// Checks the ranges.
    pub fn validate(&self) -> Result<()> {
        check::in_interval("probability", self.probability, Interval::open(0.0, 1.0))?;
        check::positive("spacing", self.spacing)?;
        check::finite("origin", self.origin.coords.as_slice())?;
        if (self.up.norm() - 1.0).abs() > 1e-6 {
            let up = self.up.as_slice();
            return Err(Error::out_of_range(
                "up",
                format!("{up:?}"),
                "a unit vector",
            ));
        }
        Ok(())
    }

    /// Lattice coordinates (in cells) of a scene point.
    fn grid(&self, p: &Point3<f64>) -> Vector3<f64> {
        self.frame.inverse_transform_vector(&(p - self.origin)) / self.spacing
    }
}

/// What a candidate needs from a point to count as support.
#[derive(Debug, Clone, Copy)]
enum Need {
    /// A flat patch with this unit normal; `up`/`vertical` select the label rule.
    Flat { normal: Vector3<f64>, class: Class },
    /// A tube with this unit axis.
    Tube { axis: Vector3<f64> },
    /// Anything not labelled ground, wall or door.
    Other,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Class {
    FaceUp,
    Vertical,
    Tilted,
}

fn need_of(prim: &Primitive, up: &Vector3<f64>) -> Need {
    let z = prim.pose.rotation * Vector3::z();
    match prim.shape.kind() {
        ShapeKind::Square | ShapeKind::Disk | ShapeKind::Plane => {
            let c = z.dot(up).abs();
            let class = if c >= COS_45 {
                Class::FaceUp
            } else if c <= 1e-6 {
                Class::Vertical
            } else {
                Class::Tilted
            };
            Need::Flat { normal: z, class }
        }
        ShapeKind::Cylinder => Need::Tube { axis: z },
        _ => Need::Other,
    }
}

/// Whether point `j` of `cloud` supports a candidate with need `need`.
fn counts(need: &Need, cloud: &PointCloud, j: usize) -> bool {
    let label = cloud.labels.as_ref().map(|l| l[j]);
    let normal = cloud.normals.as_ref().map(|n| n[j]);
    let flat_label = matches!(label, Some(GROUND | WALL | DOOR));
    match need {
        Need::Flat { normal: a, class } => {
            let label_ok = matches!(
                (label, class),
                (None | Some(0), _)
                    | (Some(GROUND), Class::FaceUp)
                    | (Some(WALL | DOOR), Class::Vertical)
            );
            label_ok && normal.is_none_or(|n| n.dot(a).abs() >= COS_45 * n.norm())
        }
        Need::Tube { axis } => {
            !flat_label && normal.is_none_or(|n| n.dot(axis).abs() <= COS_45 * n.norm())
        }
        Need::Other => !flat_label,
    }
}

/// `p(φ_i = 1)` of every candidate: `options.probability` when a supporting point lies in
/// one of the eight lattice cells around the candidate's centre, else 0.
pub fn existence_prior(
    cloud: &PointCloud,
    candidates: &[Primitive],
    options: &PriorOptions,
) -> Result<Vec<f64>> {
    options.validate()?;
    check_attributes(cloud)?;
    let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    for (j, p) in cloud.points.iter().enumerate() {
        cells
            .entry(cell_of(options, j, p)?)
            .or_default()
            .push(j as u32);
    }
    Ok(candidates
        .iter()
        .map(|c| {
            let node = options.grid(&c.center()).map(|v| v.round() as i64);
            let need = need_of(c, &options.up);
            let supported = neighbour_cells(&node)
                .filter_map(|cell| cells.get(&cell))
                .flatten()
                .any(|&j| counts(&need, cloud, j as usize));
            if supported { options.probability } else { 0.0 }
        })
        .collect())
}

/// The eight cells that have `node` as a vertex.
fn neighbour_cells(node: &Vector3<i64>) -> impl Iterator<Item = [i64; 3]> + '_ {
    (0..8).map(move |k| {
        [
            node.x - (k & 1),
            node.y - ((k >> 1) & 1),
            node.z - ((k >> 2) & 1),
        ]
    })
}

/// The lattice cell of point `j` at `p`; fails on a point that is not finite or too many
/// cells from the origin for `i64` cell coordinates.
fn cell_of(options: &PriorOptions, j: usize, p: &Point3<f64>) -> Result<[i64; 3]> {
    if !p.iter().all(|c| c.is_finite()) {
        return Err(Error::NonFinite {
            what: "point".into(),
            index: j,
        });
    }
    let g = options.grid(p);
    let far = g.amax();
    if far.is_nan() || far >= MAX_PRIOR_CELLS {
        return Err(Error::OverLimit {
            what: format!("point {j}"),
            need: far,
            limit: MAX_PRIOR_CELLS,
            unit: Unit::Count("cells from the prior's origin"),
            remedies: vec![Remedy::Raise("spacing"), Remedy::Nearer("origin")],
        });
    }
    Ok([g.x.floor() as i64, g.y.floor() as i64, g.z.floor() as i64])
}

fn check_attributes(cloud: &PointCloud) -> Result<()> {
    if let Some(l) = &cloud.labels {
        check::same_len("labels", l.len(), "points", cloud.len())?;
    }
    if let Some(v) = &cloud.normals {
        check::same_len("normals", v.len(), "points", cloud.len())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Pose;
    use crate::atlas::Shape;
    use crate::synth::axis_rotation;

    fn square(axis: usize, at: [f64; 3]) -> Primitive {
        Primitive::new(
            Shape::Square { side: 1.0 },
            Pose::new(axis_rotation(axis), Vector3::from(at)),
        )
    }

    #[test]
    fn labels_and_normals_pick_the_orientation() {
        // One ground point just above the floor node (1, 1, 0) with an up normal, and one
        // wall point near node (0, 1, 2) with an x normal.
        let mut cloud =
            PointCloud::from_points(vec![Point3::new(0.9, 0.9, 0.1), Point3::new(0.1, 1.1, 1.9)]);
        cloud.labels = Some(vec![GROUND, WALL]);
        cloud.normals = Some(vec![Vector3::z(), Vector3::x()]);
        let cands = [
            square(2, [1.0, 1.0, 0.0]), // face-up at the ground point: yes
            square(0, [1.0, 1.0, 0.0]), // vertical, x normal, near the ground point only
            square(0, [0.0, 1.0, 2.0]), // vertical x at the wall point: yes
            square(1, [0.0, 1.0, 2.0]), // vertical y at the wall point: normal says no
            square(2, [0.0, 1.0, 2.0]), // face-up at the wall point: label says no
            square(2, [5.0, 5.0, 5.0]), // far from every point
        ];
        let prior = existence_prior(&cloud, &cands, &PriorOptions::new(1.0)).unwrap();
        assert_eq!(prior, vec![0.1, 0.0, 0.1, 0.0, 0.0, 0.0]);
        // Without labels or normals every occupied neighbourhood counts.
        let bare = PointCloud::from_points(cloud.points.clone());
        let prior = existence_prior(&bare, &cands, &PriorOptions::new(1.0)).unwrap();
        assert_eq!(prior, vec![0.1, 0.1, 0.1, 0.1, 0.1, 0.0]);
    }

    #[test]
    fn bad_input_is_an_error() {
        let mut cloud = PointCloud::from_points(vec![Point3::origin()]);
        cloud.labels = Some(vec![]);
        assert!(existence_prior(&cloud, &[], &PriorOptions::new(1.0)).is_err());
        let cloud = PointCloud::from_points(vec![Point3::origin()]);
        let mut o = PriorOptions::new(1.0);
        o.probability = 1.0;
        assert!(existence_prior(&cloud, &[], &o).is_err());
    }
}
