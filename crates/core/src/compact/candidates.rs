//! Candidates proposed from a [`Detection`]: each planar segment becomes one bounded
//! `plane` whose parts are the connected parts of its points (the outline ends where its
//! points end; a surface cut by occlusion shadows stays one primitive), each cylinder or
//! sphere segment its bounded primitive.

use nalgebra::{Point2, Point3};
use rayon::prelude::*;

use crate::atlas::{PlaneShape, plane_frame};
use crate::detect::{Detection, Segment, SurfaceModel};
use crate::spatial::PointIndex;
use crate::{Primitive, Shape};

/// Outline cells per point spacing: the occupancy grid of a plane's outline has cells of
/// this many of its own points' median spacings, so that the sampling gaps of a real
/// scan (stereo holes, scan lines) are bridged while a patch still ends within about
/// one cell of its last point.
pub const OUTLINE_CELLS_PER_SPACING: f64 = 3.0;

/// Angular sectors of a tube: a cylinder candidate's samples are kept in the sectors
/// (and their neighbours) that hold its segment's points, so that the back of a
/// cylinder seen from one side is not charged as surface with no data (10° sectors).
pub const TUBE_SECTORS: usize = 36;

/// Points probed for a segment's median spacing.
const SPACING_PROBES: usize = 500;

/// One proposed candidate and the detected segment it comes from.
#[derive(Debug, Clone)]
pub struct Proposal {
    /// The candidate primitive.
    pub primitive: Primitive,
    /// Index of its segment in [`Detection::segments`].
    pub segment: usize,
}

/// The candidates of every segment of `detection` over `points`, in segment order.
/// Segments whose points give no outline (too few, degenerate) propose nothing.
pub fn propose(points: &[Point3<f64>], detection: &Detection) -> Vec<Proposal> {
    let per_segment: Vec<Vec<Proposal>> = detection
        .segments
        .par_iter()
        .enumerate()
        .map(|(s, segment)| {
            segment_candidates(points, segment, detection.spacing)
                .into_iter()
                .map(|primitive| Proposal {
                    primitive,
                    segment: s,
                })
                .collect()
        })
        .collect();
    per_segment.into_iter().flatten().collect()
}

/// The primitives of one segment (`fallback_spacing`: the cloud's point spacing, used
/// when the segment's own cannot be measured).
fn segment_candidates(
    points: &[Point3<f64>],
    segment: &Segment,
    fallback_spacing: f64,
) -> Vec<Primitive> {
    match segment.model {
        SurfaceModel::Plane { normal, .. } => {
            let own: Vec<Point3<f64>> = segment.points.iter().map(|&i| points[i]).collect();
            let spacing = own_spacing(&own).unwrap_or(fallback_spacing);
            bounded_planes(&own, normal, OUTLINE_CELLS_PER_SPACING * spacing)
        }
        _ => segment.primitive().into_iter().collect(),
    }
}

/// The median nearest-neighbour distance among `points`.
fn own_spacing(points: &[Point3<f64>]) -> Option<f64> {
    let index = PointIndex::new(points);
    index
        .median_spacing(points, SPACING_PROBES)
        .filter(|s| *s > 0.0)
}

/// The bounded plane of `points` (all on the plane of `normal`), one part per connected
/// part of them. When the parts together are too complex for one plane
/// ([`crate::atlas::MAX_PLANE_VERTICES`]: a large, much fragmented surface), one plane
/// per part instead, so that no surface is lost; none when they give no outline.
fn bounded_planes(
    points: &[Point3<f64>],
    normal: nalgebra::Vector3<f64>,
    cell: f64,
) -> Vec<Primitive> {
    let Ok(pose) = plane_frame(points, Some(normal)) else {
        return Vec::new();
    };
    let local: Vec<Point2<f64>> = points
        .iter()
        .map(|p| {
            let q = pose.to_local(p);
            Point2::new(q.x, q.y)
        })
        .collect();
    let shapes = match PlaneShape::whole_from_points(&local, cell) {
        Ok(whole) => vec![whole],
        Err(_) => PlaneShape::parts_from_points(&local, cell).unwrap_or_default(),
    };
    shapes
        .into_iter()
        .map(|shape| Primitive::new(Shape::Plane(shape), pose))
        .collect()
}

/// The samples (scene coordinates, about `spacing` apart) by which a candidate is judged:
/// all of a plane's or a sphere's; of a cylinder, those in the angular sectors around
/// its axis where its segment's points (`segment` indices into `points`) lie, with one
/// sector of margin ([`TUBE_SECTORS`]). Never empty for a valid primitive.
pub fn supported_samples(
    primitive: &Primitive,
    segment: &[usize],
    points: &[Point3<f64>],
    spacing: f64,
) -> Vec<Point3<f64>> {
    let local = primitive.shape.sample_surface(spacing);
    let kept: Vec<Point3<f64>> = match primitive.shape {
        Shape::Cylinder { .. } => {
            let sector = |p: &Point3<f64>| {
                let t = p.y.atan2(p.x).rem_euclid(std::f64::consts::TAU);
                ((t / std::f64::consts::TAU * TUBE_SECTORS as f64) as usize).min(TUBE_SECTORS - 1)
            };
            let mut occupied = [false; TUBE_SECTORS];
            for &i in segment {
                occupied[sector(&primitive.pose.to_local(&points[i]))] = true;
            }
            let near = |k: usize| {
                occupied[k]
                    || occupied[(k + 1) % TUBE_SECTORS]
                    || occupied[(k + TUBE_SECTORS - 1) % TUBE_SECTORS]
            };
            local.iter().filter(|p| near(sector(p))).copied().collect()
        }
        _ => local,
    };
    let kept = if kept.is_empty() {
        primitive.shape.sample_surface(spacing)
    } else {
        kept
    };
    kept.iter().map(|p| primitive.pose.to_scene(p)).collect()
}
