//! Which primitive owns each input point during refinement.
//!
//! A point belongs to the primitive whose surface is nearest, within the trim distance;
//! farther points are outliers and pull nothing. Where tubes (cylinders, elbows) overlap,
//! noise would decide which owns each shared point and both would shrink, so among the
//! tubes whose surfaces are within a tie distance (the cloud's point spacing `h`) of the
//! nearest, the one whose centre is nearest relative to its bounding radius owns it:
//! overlaps split along their bisector. Patches keep the plain nearest-surface rule.
//! The measurements behind the rule are in `docs/refine.md` (*Ownership*).

use nalgebra::Point3;
use rayon::prelude::*;

use crate::atlas::Shape;
use crate::spatial::PointIndex;
use crate::spatial::PrimitiveIndex;
use crate::{Primitive, Result};

/// Who owns a point: the primitive whose surface is nearest, within the trim distance;
/// when that is a tube, among the tubes whose surfaces are within `tie` of that nearest
/// distance, the one whose centre is nearest relative to its bounding radius
/// (`|y − c| / R`). Overlapping coaxial tubes are thus split along their bisector rather
/// than by noise (module docs).
struct Ownership<'a> {
    prims: &'a [Primitive],
    index: PrimitiveIndex<'a>,
    /// kd-tree over the primitives' centres.
    centres: PointIndex,
    max_radius: f64,
    trim: f64,
    tie: f64,
}

impl<'a> Ownership<'a> {
    fn new(prims: &'a [Primitive], trim: f64, tie: f64) -> Result<Self> {
        let centres: Vec<Point3<f64>> = prims.iter().map(Primitive::center).collect();
        Ok(Ownership {
            prims,
            index: PrimitiveIndex::new(prims)?,
            centres: PointIndex::new(&centres),
            max_radius: prims
                .iter()
                .map(Primitive::bounding_radius)
                .fold(0.0, f64::max),
            trim,
            tie,
        })
    }

    /// The owner of `y`, if any.
    fn owner(&self, y: &Point3<f64>) -> Option<usize> {
        let (best, d0) = self.index.nearest(y).filter(|(_, d)| *d <= self.trim)?;
        if self.tie <= 0.0 || !is_tube(&self.prims[best]) {
            return Some(best);
        }
        let limit = d0 + self.tie;
        let reach = limit + self.max_radius;
        let relative = |k: usize| {
            let p = &self.prims[k];
            (y - p.center()).norm() / p.bounding_radius().max(f64::MIN_POSITIVE)
        };
        let mut owner = (relative(best), best);
        for (k, c2) in self.centres.within(y, reach * reach) {
            let k = k as usize;
            let p = &self.prims[k];
            if k == best
                || !is_tube(p)
                || c2.sqrt() - p.bounding_radius() > limit
                || p.distance(y) > limit
            {
                continue;
            }
            let candidate = (relative(k), k);
            if candidate.0 < owner.0 || (candidate.0 == owner.0 && k < owner.1) {
                owner = candidate;
            }
        }
        Some(owner.1)
    }
}

/// For each point, its owner among `prims` ([`Ownership`]).
pub(super) fn owners(
    points: &[Point3<f64>],
    prims: &[Primitive],
    trim: f64,
    tie: f64,
) -> Result<Vec<Option<usize>>> {
    let all: Vec<usize> = (0..points.len()).collect();
    owners_of(points, &all, prims, trim, tie)
}

/// For each of the points `which`, its owner among `prims` ([`Ownership`]).
pub(super) fn owners_of(
    points: &[Point3<f64>],
    which: &[usize],
    prims: &[Primitive],
    trim: f64,
    tie: f64,
) -> Result<Vec<Option<usize>>> {
    if prims.is_empty() {
        return Ok(vec![None; which.len()]);
    }
    let own = Ownership::new(prims, trim, tie)?;
    Ok(which.par_iter().map(|&j| own.owner(&points[j])).collect())
}

/// For each primitive, the indices of the points it owns ([`Ownership`]).
pub(super) fn assign(
    points: &[Point3<f64>],
    prims: &[Primitive],
    trim: f64,
    tie: f64,
) -> Result<Vec<Vec<usize>>> {
    let mut groups = vec![Vec::new(); prims.len()];
    for (j, o) in owners(points, prims, trim, tie)?.into_iter().enumerate() {
        if let Some(i) = o {
            groups[i].push(j);
        }
    }
    Ok(groups)
}

/// Cylinders and elbows: the types whose overlapping pieces [`Ownership`] splits.
fn is_tube(p: &Primitive) -> bool {
    matches!(p.shape, Shape::Cylinder { .. } | Shape::Elbow { .. })
}

#[cfg(test)]
mod tests {
    use nalgebra::{UnitQuaternion, Vector3};

    use super::*;
    use crate::Pose;

    /// Two coaxial cylinders overlapping over half their length (a joint): the shared
    /// points split at the bisector of their centres, not by the noise on each point; two
    /// coplanar squares keep the plain nearest-surface rule.
    #[test]
    fn overlapping_tubes_split_their_shared_points_at_the_bisector() {
        let cylinder = |z: f64| {
            Primitive::new(
                Shape::Cylinder {
                    length: 1.0,
                    radius: 0.1,
                },
                Pose::new(UnitQuaternion::identity(), Vector3::new(0.0, 0.0, z)),
            )
        };
        let tubes = [cylinder(0.0), cylinder(0.5)];
        // Points on the shared stretch z ∈ [0, 0.5], alternately just inside and just
        // outside the surface: the nearest-surface rule alone would tie-break by noise.
        let points: Vec<Point3<f64>> = (0..200)
            .map(|k| {
                let z = 0.0025 * k as f64 + 0.001;
                let r = if k % 2 == 0 { 0.1 - 1e-4 } else { 0.1 + 1e-4 };
                let a = 0.7 * k as f64;
                Point3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect();
        let owner = owners(&points, &tubes, 1.0, 0.01).unwrap();
        for (y, o) in points.iter().zip(&owner) {
            let expected = if y.z < 0.25 { 0 } else { 1 };
            assert_eq!(*o, Some(expected), "{y:?}");
        }
        // Without the tie rule (tie 0) the two equal distances do not split this way.
        let plain = owners(&points, &tubes, 1.0, 0.0).unwrap();
        assert_ne!(plain, owner);

        // Coplanar squares overlapping by half: the nearest surface decides (the point
        // just above the plane of the second square, lifted by 1e-4, goes to it).
        let square = |x: f64, z: f64| {
            Primitive::new(
                Shape::Square { side: 1.0 },
                Pose::new(UnitQuaternion::identity(), Vector3::new(x, 0.0, z)),
            )
        };
        let patches = [square(0.0, 0.0), square(0.5, 1e-4)];
        let y = [Point3::new(0.1, 0.0, 1e-4)];
        assert_eq!(owners(&y, &patches, 1.0, 0.01).unwrap(), vec![Some(1)]);
    }
}
