//! Seam merging: the primitives each tile owns (by centre) joined into one model.
//!
//! A surface crossing a seam is fitted by the tiles on both sides, each with its halo,
//! so its pieces overlap by up to twice the halo. In order:
//!
//! 1. **merge** ([`merge_pieces`]): two bounded planes from different tiles with parallel
//!    normals (within [`MERGE_ANGLE_DEG`]), each centre within the tolerance of the
//!    other's plane, and overlapping outlines become one plane, the union of the two
//!    outlines in the larger piece's frame; two cylinders with parallel axes, radii
//!    within [`MERGE_RADIUS_RATIO`], axes within the tolerance and overlapping (or
//!    abutting) extents become one cylinder spanning both; two spheres with centres and
//!    radii within the tolerance become the larger one. Repeated until nothing merges,
//!    so a wall across three tiles comes back as one plane.
//! 2. **de-duplicate** ([`dedup_on_seams`]): a remaining primitive lying mostly on
//!    another from a different tile ([`DUPLICATE_SHARE`] of its samples within the
//!    tolerance) is re-checked for existence on the seam points: it is dropped when the
//!    seam points' chamfer cost (each point's squared distance to the model, capped)
//!    rises by less than its description length ([`crate::compact`]'s MDL) without it.

use geo::{BooleanOps, LineString, MultiPolygon, Orient, Polygon, orient::Direction};
use nalgebra::{Point2, Point3, Vector3};

use crate::atlas::{PlaneShape, Rings, Shape};
use crate::compact::primitive_cost;
use crate::spatial::PointIndex;
use crate::{Primitive, Result};

/// The largest angle (degrees) between two pieces' normals (planes) or axes (cylinders)
/// for them to merge.
pub const MERGE_ANGLE_DEG: f64 = 5.0;

/// The largest ratio between two cylinders' or spheres' radii for them to merge.
pub const MERGE_RADIUS_RATIO: f64 = 1.15;

/// The share of a primitive's surface samples within the tolerance of another primitive
/// from a different tile above which it is a duplicate candidate for the re-check.
pub const DUPLICATE_SHARE: f64 = 0.5;

/// Samples per primitive, at most, for the duplicate test.
const DUPLICATE_SAMPLES: f64 = 400.0;

/// A primitive one tile owns, with where it came from.
#[derive(Debug, Clone)]
pub struct Piece {
    /// The primitive (scene coordinates).
    pub primitive: Primitive,
    /// Its existence probability.
    pub existence: f64,
    /// The tiles whose pieces it is made of (one before merging).
    pub tiles: Vec<usize>,
}

/// The tolerances of a merge, in scene units.
#[derive(Debug, Clone, Copy)]
pub struct MergeTolerance {
    /// Distance within which two surfaces are the same (the fit's cap: a point within it
    /// of a surface is explained by it).
    pub distance: f64,
    /// The noise σ for the description length of the re-check.
    pub noise: f64,
    /// Points of the cloud, for the description length (`ln J`).
    pub points: usize,
}

/// Merges pieces from different tiles that are one surface, until none merges (step 1
/// of the module docs). Pieces from the same tile are never merged with each other: the
/// tile's own fit already decided them.
pub fn merge_pieces(mut pieces: Vec<Piece>, tol: &MergeTolerance) -> Vec<Piece> {
    loop {
        let mut merged_any = false;
        let mut i = 0;
        while i < pieces.len() {
            let mut j = i + 1;
            while j < pieces.len() {
                let disjoint = !pieces[i].tiles.iter().any(|t| pieces[j].tiles.contains(t));
                let near = (pieces[i].primitive.center() - pieces[j].primitive.center()).norm()
                    <= pieces[i].primitive.bounding_radius()
                        + pieces[j].primitive.bounding_radius()
                        + tol.distance;
                let joined = (disjoint && near)
                    .then(|| merge_two(&pieces[i].primitive, &pieces[j].primitive, tol))
                    .flatten();
                if let Some(p) = joined {
                    let b = pieces.swap_remove(j);
                    let a = &mut pieces[i];
                    let (wa, wb) = (a.primitive.area(), b.primitive.area());
                    a.existence =
                        (a.existence * wa + b.existence * wb) / (wa + wb).max(f64::MIN_POSITIVE);
                    a.primitive = p;
                    a.tiles.extend(b.tiles);
                    merged_any = true;
                } else {
                    j += 1;
                }
            }
            i += 1;
        }
        if !merged_any {
            return pieces;
        }
    }
}

/// One primitive for `a` and `b` when they are one surface, else `None`.
pub fn merge_two(a: &Primitive, b: &Primitive, tol: &MergeTolerance) -> Option<Primitive> {
    // The larger piece gives the frame.
    let (a, b) = if a.area() >= b.area() { (a, b) } else { (b, a) };
    match (&a.shape, &b.shape) {
        (Shape::Plane(pa), Shape::Plane(pb)) => merge_planes(a, pa, b, pb, tol),
        (Shape::Cylinder { .. }, Shape::Cylinder { .. }) => merge_cylinders(a, b, tol),
        (Shape::Sphere { .. }, Shape::Sphere { .. }) => {
            let (ra, rb) = (a.bounding_radius(), b.bounding_radius());
            let same = (a.center() - b.center()).norm() <= tol.distance
                && ra.max(rb) <= MERGE_RADIUS_RATIO * ra.min(rb);
            same.then(|| a.clone())
        }
        _ => None,
    }
}

/// The local +z axis of a primitive in the scene (a plane's normal, a tube's axis).
fn axis(p: &Primitive) -> Vector3<f64> {
    p.pose.rotation * Vector3::z()
}

/// Whether two directions are parallel within [`MERGE_ANGLE_DEG`] (either sense).
fn parallel(u: &Vector3<f64>, v: &Vector3<f64>) -> bool {
    u.dot(v).abs() >= MERGE_ANGLE_DEG.to_radians().cos()
}

fn merge_planes(
    a: &Primitive,
    pa: &PlaneShape,
    b: &Primitive,
    pb: &PlaneShape,
    tol: &MergeTolerance,
) -> Option<Primitive> {
    let (na, nb) = (axis(a), axis(b));
    let off_a = (b.center() - a.center()).dot(&na).abs();
    let off_b = (a.center() - b.center()).dot(&nb).abs();
    if !parallel(&na, &nb) || off_a > tol.distance || off_b > tol.distance {
        return None;
    }
    let ga = to_multi(pa.parts(), |v| *v);
    // b's rings in a's local frame (its z dropped: within the tolerance of a's plane).
    let to_a = |v: &Point2<f64>| {
        let local = a
            .pose
            .to_local(&b.pose.to_scene(&Point3::new(v.x, v.y, 0.0)));
        Point2::new(local.x, local.y)
    };
    let gb = to_multi(pb.parts(), to_a);
    if ga.intersection(&gb).0.is_empty() {
        return None;
    }
    let union = ga.union(&gb).orient(Direction::Default);
    let parts: Vec<Rings> = union.0.iter().map(rings_of).collect();
    let shape = PlaneShape::from_parts(parts).ok()?;
    Some(Primitive::new(Shape::Plane(shape), a.pose))
}

/// A plane's parts as a geo multipolygon, each vertex mapped by `map`.
fn to_multi(parts: &[Rings], map: impl Fn(&Point2<f64>) -> Point2<f64>) -> MultiPolygon<f64> {
    let line = |r: &[Point2<f64>]| {
        LineString::from(
            r.iter()
                .map(|v| {
                    let m = map(v);
                    (m.x, m.y)
                })
                .collect::<Vec<_>>(),
        )
    };
    MultiPolygon::new(
        parts
            .iter()
            .map(|(o, h)| Polygon::new(line(o), h.iter().map(|r| line(r)).collect()))
            .collect(),
    )
}

/// A geo polygon as open rings.
fn rings_of(p: &Polygon<f64>) -> Rings {
    let open = |l: &LineString<f64>| {
        let mut v: Vec<Point2<f64>> = l.coords().map(|c| Point2::new(c.x, c.y)).collect();
        if v.len() > 1 && v.first() == v.last() {
            v.pop();
        }
        v
    };
    (open(p.exterior()), p.interiors().iter().map(open).collect())
}

fn merge_cylinders(a: &Primitive, b: &Primitive, tol: &MergeTolerance) -> Option<Primitive> {
    let (
        Shape::Cylinder {
            length: la,
            radius: ra,
        },
        Shape::Cylinder {
            length: lb,
            radius: rb,
        },
    ) = (&a.shape, &b.shape)
    else {
        return None;
    };
    let (sa, sb) = (a.pose.scale, b.pose.scale);
    let (ra, rb, la, lb) = (ra * sa, rb * sb, la * sa, lb * sb);
    let (ua, ub) = (axis(a), axis(b));
    if !parallel(&ua, &ub) || ra.max(rb) > MERGE_RADIUS_RATIO * ra.min(rb) {
        return None;
    }
    let d = b.center() - a.center();
    let t = d.dot(&ua);
    let off_axis = (d - ua * t).norm();
    if off_axis > tol.distance.max(0.25 * ra.min(rb)) {
        return None;
    }
    // Extents along a's axis; b's half length projected on it.
    let hb = 0.5 * lb * ua.dot(&ub).abs();
    let (lo, hi) = ((-0.5 * la).min(t - hb), (0.5 * la).max(t + hb));
    let gap = (t - hb - 0.5 * la).max(-0.5 * la - (t + hb));
    if gap > tol.distance {
        return None;
    }
    let radius = (ra * la + rb * lb) / (la + lb);
    let mut pose = a.pose;
    pose.translation = (a.center() + ua * (0.5 * (lo + hi))).coords;
    let shape = Shape::Cylinder {
        length: (hi - lo) / sa,
        radius: radius / sa,
    };
    Some(Primitive::new(shape, pose))
}

/// Drops duplicates across seams by an existence re-check on `seam` points (step 2 of
/// the module docs); returns the pieces kept, in their order.
pub fn dedup_on_seams(
    pieces: Vec<Piece>,
    seam: &[Point3<f64>],
    tol: &MergeTolerance,
) -> Result<Vec<Piece>> {
    let cap2 = tol.distance * tol.distance;
    let mut keep = vec![true; pieces.len()];
    // Smallest first: a small duplicate goes before the large surface it lies on.
    let mut order: Vec<usize> = (0..pieces.len()).collect();
    order.sort_by(|&i, &j| {
        pieces[i]
            .primitive
            .area()
            .total_cmp(&pieces[j].primitive.area())
    });
    let seam_index = (!seam.is_empty()).then(|| PointIndex::new(seam));
    for &i in &order {
        let pi = &pieces[i].primitive;
        let spacing = (pi.area() / DUPLICATE_SAMPLES)
            .sqrt()
            .max(tol.distance * 0.5);
        let samples = pi.sample_surface(spacing);
        if samples.is_empty() {
            continue;
        }
        let near: Vec<usize> = (0..pieces.len())
            .filter(|&j| j != i && keep[j])
            .filter(|&j| !pieces[i].tiles.iter().any(|t| pieces[j].tiles.contains(t)))
            .filter(|&j| {
                let pj = &pieces[j].primitive;
                (pi.center() - pj.center()).norm()
                    <= pi.bounding_radius() + pj.bounding_radius() + tol.distance
            })
            .collect();
        let covered = samples
            .iter()
            .filter(|s| {
                near.iter()
                    .any(|&j| pieces[j].primitive.distance(s) <= tol.distance)
            })
            .count();
        if (covered as f64) < DUPLICATE_SHARE * samples.len() as f64 {
            continue;
        }
        // The re-check: seam points near the candidate, their capped cost with and
        // without it (the model's other primitives near it stay).
        let Some(index) = &seam_index else {
            keep[i] = false;
            continue;
        };
        let reach = pi.bounding_radius() + tol.distance;
        let local = index.within(&pi.center(), reach * reach);
        let mut rise = 0.0;
        for (k, _) in local {
            let y = &seam[k as usize];
            let others = near
                .iter()
                .map(|&j| pieces[j].primitive.distance(y).powi(2))
                .fold(cap2, f64::min);
            let with = pi.distance(y).powi(2).min(others);
            rise += others - with;
        }
        if rise < primitive_cost(pi, tol.noise, tol.points) {
            keep[i] = false;
        }
    }
    Ok(pieces
        .into_iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(p))
        .collect())
}
