//! Trimming what the model covers twice: after the existence decision, a plane gives up
//! the part of its surface that a larger primitive of the model already covers.
//!
//! Detection merges planes that one plane explains and parallel layers within the cap
//! (`detect/merge.rs`), and the existence decision drops candidates that explain nothing
//! the others do not. What remains can still cross: on a stereo scan a wall far from the
//! camera comes out as a large plane and smaller patches tilted 5–10° off it (depth
//! layers and smoothing), each explaining points the other cannot; their outlines
//! overlap in a band around the line where they cross. Which tilted patches survive
//! depends on how ties between equidistant neighbours fall, so the share of the table
//! scan's model covered twice was 0.2–2.9 % over nine orders of the same points (as read
//! and eight permutations, `examples/order_study.rs`).
//!
//! **Rule.** Primitives are visited by decreasing area. A plane's points (those of the
//! segment it was outlined from) are dropped where a larger primitive, already final,
//! covers the plane's surface there: the test of [`crate::metrics::double_cover_share`]
//! (the other surface within the reach along the normal, and parallel to it within
//! [`crate::metrics::DOUBLE_COVER_MAX_ANGLE_DEG`]), with the cap as the reach, so those
//! points are explained by the larger primitive. The plane is outlined again from the
//! points left (possibly in several parts). What is left stays only if it explains its
//! points better than the larger primitives do by more than its description length
//! (`mdl.rs`): the trade the existence decision made for the whole. Faces meeting at an
//! edge (more than 45° apart) and coplanar tiles beside each other (not along the normal)
//! keep their points, so a plane that covers nothing twice is kept exactly as it was. A
//! cylinder or sphere, whose extent is parametric, is kept whole or dropped by the same
//! trade.

use std::borrow::Cow;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::candidates::{bounded_planes, outline_cell};
use super::mdl::primitive_cost;
use crate::metrics::{DOUBLE_COVER_MAX_ANGLE_DEG, covers_along, surface_normal};
use crate::spatial::PointIndex;
use crate::{Primitive, Shape};

/// A primitive of the model and the points it was built from.
#[derive(Debug, Clone)]
pub struct Kept<'a> {
    /// The primitive.
    pub primitive: Primitive,
    /// Indices into the cloud of the points it was outlined from (ascending).
    pub members: Cow<'a, [usize]>,
}

/// The cloud the model describes: its points, their index and point spacing (scene
/// units).
#[derive(Debug, Clone, Copy)]
pub struct Cloud<'a> {
    /// The points.
    pub points: &'a [Point3<f64>],
    /// Their index.
    pub index: &'a PointIndex,
    /// Their median spacing (scene units).
    pub spacing: f64,
}

/// How the existence decision priced a primitive: what a point within `cap` of it saves
/// and what the primitive itself costs (`mdl.rs`).
#[derive(Debug, Clone, Copy)]
pub struct Pricing {
    /// The cap: the distance within which a point is explained (scene units).
    pub cap: f64,
    /// The noise σ of the description length (scene units).
    pub noise: f64,
    /// The weight of the point term.
    pub point_weight: f64,
}

/// Each of `kept`, trimmed by the rule of the module docs: none, itself, or the parts
/// of a plane that nothing larger covers, in the order of `kept`.
pub fn trim_overlaps(cloud: Cloud, kept: &[Kept], pricing: Pricing) -> Vec<Vec<Primitive>> {
    let mut order: Vec<usize> = (0..kept.len()).collect();
    let area: Vec<f64> = kept.iter().map(|k| k.primitive.area()).collect();
    order.sort_by(|&a, &b| area[b].total_cmp(&area[a]).then(a.cmp(&b)));
    let mut trimmed: Vec<Vec<Primitive>> = vec![Vec::new(); kept.len()];
    for (place, &k) in order.iter().enumerate() {
        let larger: Vec<&Primitive> = order[..place].iter().flat_map(|&j| &trimmed[j]).collect();
        trimmed[k] = trim(cloud, &kept[k], &larger, pricing);
    }
    trimmed
}

/// `kept` without what `larger` covers within the cap (module docs): itself when nothing
/// is covered; else a plane outlined from its points left, a cylinder or sphere whole,
/// if those points are worth it ([`worth_keeping`]); else nothing.
fn trim(cloud: Cloud, kept: &Kept, larger: &[&Primitive], pricing: Pricing) -> Vec<Primitive> {
    let (a, reach) = (&kept.primitive, pricing.cap);
    let (centre, radius) = (a.center(), a.bounding_radius());
    let near: Vec<&Primitive> = larger
        .iter()
        .copied()
        .filter(|b| (b.center() - centre).norm() <= radius + b.bounding_radius() + reach)
        .filter(|b| may_cover(a, b, reach))
        .collect();
    if near.is_empty() {
        return vec![a.clone()];
    }
    let plane_normal = a.pose.rotation * Vector3::z();
    let covered: Vec<bool> = kept
        .members
        .par_iter()
        .map(|&i| {
            let x = a.closest_point(&cloud.points[i]);
            let normal = match a.shape {
                Shape::Plane(_) => plane_normal,
                _ => surface_normal(a, &x, cloud.spacing),
            };
            near.iter().any(|b| {
                (x - b.center()).norm() - b.bounding_radius() <= reach
                    && plane_offset(b, &x).is_none_or(|d| d <= reach)
                    && covers_along(&x, &normal, b, reach, cloud.spacing)
            })
        })
        .collect();
    if !covered.contains(&true) {
        return vec![a.clone()];
    }
    let rest: Vec<usize> = (kept.members.iter().zip(&covered))
        .filter(|&(_, &c)| !c)
        .map(|(&i, _)| i)
        .collect();
    let parts = match a.shape {
        Shape::Plane(_) if !rest.is_empty() => {
            let own: Vec<Point3<f64>> = rest.iter().map(|&i| cloud.points[i]).collect();
            let cell = outline_cell(cloud.points, cloud.index, &rest, cloud.spacing);
            bounded_planes(&own, plane_normal, cell)
        }
        Shape::Plane(_) => Vec::new(),
        _ => vec![a.clone()],
    };
    if worth_keeping(cloud, &rest, &parts, &near, pricing) {
        parts
    } else {
        Vec::new()
    }
}

/// Whether `b` may cover some of plane or surface `a` within `reach` (a quick test
/// before the point-by-point one): two planes only if they are parallel within
/// [`DOUBLE_COVER_MAX_ANGLE_DEG`] (a plane's normal is the same everywhere) and `a`'s
/// bounding ball comes within `reach` of `b`'s plane.
fn may_cover(a: &Primitive, b: &Primitive, reach: f64) -> bool {
    let (Shape::Plane(_), Shape::Plane(_)) = (&a.shape, &b.shape) else {
        return true;
    };
    let (na, nb) = (
        a.pose.rotation * Vector3::z(),
        b.pose.rotation * Vector3::z(),
    );
    let parallel = na.dot(&nb).abs() >= DOUBLE_COVER_MAX_ANGLE_DEG.to_radians().cos();
    parallel && plane_offset(b, &a.center()).is_some_and(|d| d <= a.bounding_radius() + reach)
}

/// The distance from `x` to the infinite plane of `b` when `b` is a plane (a lower bound
/// of its distance to `b`), else `None`.
fn plane_offset(b: &Primitive, x: &Point3<f64>) -> Option<f64> {
    matches!(b.shape, Shape::Plane(_)).then(|| b.pose.to_local(x).z.abs() * b.pose.scale)
}

/// Whether `parts` explain the points `rest` better than `near` do by more than they
/// cost: the existence decision's own trade, what adding them saves of the point term
/// `w Σ min(d², cap²)` (a point pays for the nearer of both) against their description
/// length `k σ² ln J` (`mdl.rs`).
fn worth_keeping(
    cloud: Cloud,
    rest: &[usize],
    parts: &[Primitive],
    near: &[&Primitive],
    pricing: Pricing,
) -> bool {
    if parts.is_empty() {
        return false;
    }
    let cap2 = pricing.cap * pricing.cap;
    // The capped squared distance from `x` to the nearest of `to`.
    let cost_of = |x: &Point3<f64>, to: &mut dyn Iterator<Item = &Primitive>| {
        to.map(|p| p.distance(x).powi(2)).fold(cap2, f64::min)
    };
    // Collected, then summed in order: the same sum on any thread count.
    let gains: Vec<f64> = rest
        .par_iter()
        .map(|&i| {
            let x = &cloud.points[i];
            let before = cost_of(x, &mut near.iter().copied());
            (before - cost_of(x, &mut parts.iter())).max(0.0)
        })
        .collect();
    let gain: f64 = gains.iter().sum();
    let cost: f64 = (parts.iter())
        .map(|p| primitive_cost(p, pricing.noise, cloud.points.len()))
        .sum();
    pricing.point_weight * gain > cost
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector3};

    use super::*;
    use crate::metrics::double_cover_share;

    /// Grid pitch of the test surfaces (scene units).
    const PITCH: f64 = 0.02;

    /// The cap of the test scenes: three point spacings.
    const CAP: f64 = 3.0 * PITCH;

    /// Grid points `(u, v)` over `[u0, u1] × [v0, v1]` at [`PITCH`], mapped to the scene.
    fn grid(
        (u0, u1): (f64, f64),
        (v0, v1): (f64, f64),
        at: impl Fn(f64, f64) -> Point3<f64>,
    ) -> Vec<Point3<f64>> {
        let steps = |a: f64, b: f64| ((b - a) / PITCH).round() as usize;
        (0..=steps(u0, u1))
            .flat_map(|i| (0..=steps(v0, v1)).map(move |j| (i, j)))
            .map(|(i, j)| at(u0 + i as f64 * PITCH, v0 + j as f64 * PITCH))
            .collect()
    }

    /// The model of `surfaces` (each points and normal) as one cloud: a bounded plane per
    /// surface, outlined from its points as the candidates are, and the trimmed model.
    fn trimmed(
        surfaces: &[(Vec<Point3<f64>>, Vector3<f64>)],
    ) -> (Vec<Kept<'static>>, Vec<Vec<Primitive>>) {
        let points: Vec<Point3<f64>> = surfaces.iter().flat_map(|s| s.0.clone()).collect();
        let index = PointIndex::new(&points);
        let cloud = Cloud {
            points: &points,
            index: &index,
            spacing: PITCH,
        };
        let mut start = 0;
        let kept: Vec<Kept> = surfaces
            .iter()
            .map(|(pts, normal)| {
                let members: Vec<usize> = (start..start + pts.len()).collect();
                start += pts.len();
                let cell = outline_cell(&points, &index, &members, PITCH);
                let mut planes = bounded_planes(pts, *normal, cell);
                assert_eq!(planes.len(), 1);
                Kept {
                    primitive: planes.remove(0),
                    members: members.into(),
                }
            })
            .collect();
        let pricing = Pricing {
            cap: CAP,
            noise: PITCH / 12f64.sqrt(),
            point_weight: 1.0,
        };
        let out = trim_overlaps(cloud, &kept, pricing);
        (kept, out)
    }

    fn floor() -> (Vec<Point3<f64>>, Vector3<f64>) {
        let pts = grid((-1.0, 1.0), (-1.0, 1.0), |x, y| Point3::new(x, y, 0.0));
        (pts, Vector3::z())
    }

    fn unchanged(kept: &Kept, out: &[Primitive]) -> bool {
        out.len() == 1 && out[0].to_json() == kept.primitive.to_json()
    }

    #[test]
    fn a_patch_crossing_a_larger_plane_loses_the_band_the_plane_covers() {
        // A 0.6 m patch tilted 20° about y, crossing the floor along x = 0: within the cap
        // of the floor for |x| ≤ CAP / tan 20° = 0.165 m.
        let tilt = 20f64.to_radians();
        let patch = grid((-0.3, 0.3), (-0.3, 0.3), |u, y| {
            Point3::new(u * tilt.cos(), y, u * tilt.sin())
        });
        let normal = Vector3::new(-tilt.sin(), 0.0, tilt.cos());
        let (kept, out) = trimmed(&[floor(), (patch, normal)]);
        assert!(
            unchanged(&kept[0], &out[0]),
            "the larger plane is kept as it was"
        );
        assert_eq!(
            out[1].len(),
            1,
            "the patch stays: its ends are far from the floor"
        );
        let patch = &out[1][0];
        // Its surface no longer runs through the crossing line, and what the floor covered
        // twice is mostly gone (the outline's cells reach about one cell into the band).
        assert!(
            patch.distance(&Point3::origin()) > 0.1,
            "{}",
            patch.distance(&Point3::origin())
        );
        let h = 2.0 * PITCH;
        let before = [kept[0].primitive.clone(), kept[1].primitive.clone()];
        let after = [out[0][0].clone(), patch.clone()];
        let (before, after) = (
            double_cover_share(&before, h, h / 2.0).unwrap(),
            double_cover_share(&after, h, h / 2.0).unwrap(),
        );
        assert!(before > 0.02, "{before}");
        assert!(after < before / 4.0, "{before} → {after}");
    }

    #[test]
    fn a_layer_within_the_cap_of_a_larger_plane_is_dropped() {
        let layer = grid((-0.3, 0.3), (-0.3, 0.3), |x, y| {
            Point3::new(x, y, CAP / 3.0)
        });
        let (kept, out) = trimmed(&[floor(), (layer, Vector3::z())]);
        assert!(unchanged(&kept[0], &out[0]));
        assert!(out[1].is_empty(), "{:?}", out[1].len());
    }

    #[test]
    fn faces_meeting_at_an_edge_and_tiles_side_by_side_are_kept_as_they_were() {
        // A wall standing on the floor's edge, and a coplanar tile beside the floor.
        let wall = grid((-1.0, 1.0), (0.0, 1.0), |y, z| Point3::new(1.0, y, z));
        let tile = grid((1.0 + PITCH, 1.6), (-1.0, 1.0), |x, y| {
            Point3::new(x, y, 0.0)
        });
        for other in [(wall, Vector3::x()), (tile, Vector3::z())] {
            let (kept, out) = trimmed(&[floor(), other]);
            assert!(unchanged(&kept[0], &out[0]));
            assert!(unchanged(&kept[1], &out[1]));
        }
    }
}
