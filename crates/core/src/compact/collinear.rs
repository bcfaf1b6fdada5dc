//! One cylinder for one pipe run: two cylinders of the model on the same axis (a run that
//! detection found in two pieces, side by side or overlapping) become one spanning both,
//! when that lowers the existence decision's loss.
//!
//! Region growing stops where a run's normals are disturbed (a bend's start, a gap in the
//! scan, a strip that passed for a plane), so one run can come out as two cylinders, each
//! paying its description length, overlapping where both reach (a chain of pipes, seed 7:
//! 2.8 % of the model's area covered twice) or leaving the stretch between them to planes.
//!
//! **Test.** Radii within 15 %, axes within [`MAX_AXIS_ANGLE_DEG`] and each centre within
//! half a radius of the other's axis; the pieces' extents along the common axis at most
//! their summed lengths apart. The merged cylinder has the length-weighted mean axis,
//! centre line and radius, and spans both extents.
//!
//! **Loss** ([`swap_gain`], `swap.rs`): a swap of the two pieces for the merged cylinder,
//! with the primitives whose members all lie within the cap of the merged cylinder
//! (strips that stood in for the stretch between the pieces) kept or replaced, whichever
//! costs less. Pairs are taken greedily, largest gain first, each cylinder once a pass,
//! until a pass merges nothing.

use std::borrow::Cow;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::mdl::primitive_cost;
use super::swap::{NearTree, SwapLoss};
use super::trim::{Cloud, Kept, Pricing};
use crate::detect::{CylinderFit, SurfaceModel, refit_cylinder};
use crate::{Primitive, Shape};

/// Largest angle between the two pieces' axes (degrees).
const MAX_AXIS_ANGLE_DEG: f64 = 5.0;

/// Largest relative difference of the two pieces' radii.
const RADIUS_TOLERANCE: f64 = 0.15;

/// Largest distance of a piece's centre from the other's axis, in tube radii.
const MAX_AXIS_OFFSET_RADII: f64 = 0.5;

/// The most merging passes (a run found in `n` pieces needs `⌈log₂ n⌉`).
const MAX_PASSES: usize = 8;

/// A cylinder's axis and extent (scene units).
#[derive(Debug, Clone, Copy)]
struct Piece {
    centre: Point3<f64>,
    axis: Vector3<f64>,
    length: f64,
    radius: f64,
}

impl Piece {
    fn of(p: &Primitive) -> Option<Piece> {
        let Shape::Cylinder { length, radius } = p.shape else {
            return None;
        };
        Some(Piece {
            centre: p.center(),
            axis: p.pose.rotation * Vector3::z(),
            length: p.pose.scale * length,
            radius: p.pose.scale * radius,
        })
    }
}

/// The cylinder spanning pieces `p` and `q` when they lie on one axis (module docs),
/// with the length-weighted mean axis, centre line and radius; `None` otherwise.
fn spanning(p: &Piece, q: &Piece) -> Option<CylinderFit> {
    let r = p.radius.max(q.radius);
    let q_axis = q.axis * p.axis.dot(&q.axis).signum();
    let off_axis = |c: &Point3<f64>, on: &Piece| (c - on.centre).cross(&on.axis).norm();
    if (p.radius - q.radius).abs() > RADIUS_TOLERANCE * r
        || p.axis.dot(&q_axis) < MAX_AXIS_ANGLE_DEG.to_radians().cos()
        || off_axis(&q.centre, p) > MAX_AXIS_OFFSET_RADII * r
        || off_axis(&p.centre, q) > MAX_AXIS_OFFSET_RADII * r
    {
        return None;
    }
    let total = p.length + q.length;
    let (wp, wq) = (p.length / total, q.length / total);
    let axis = (p.axis * wp + q_axis * wq).normalize();
    let centre = Point3::from(p.centre.coords * wp + q.centre.coords * wq);
    let extent = |piece: &Piece| {
        let t = (piece.centre - centre).dot(&axis);
        (t - piece.length / 2.0, t + piece.length / 2.0)
    };
    let ((a0, a1), (b0, b1)) = (extent(p), extent(q));
    if (b0 - a1).max(a0 - b1) > total {
        return None;
    }
    let (lo, hi) = (a0.min(b0), a1.max(b1));
    Some(CylinderFit {
        point: centre + axis * ((lo + hi) / 2.0),
        axis,
        radius: p.radius * wp + q.radius * wq,
        length: hi - lo,
        rms: 0.0,
    })
}

/// The one cylinder for pieces `p` and `q`: `start` ([`spanning`]) re-fitted
/// (Levenberg–Marquardt, `detect/cylinder.rs`) to `points`, the pieces' members, where
/// there are enough of them (two pieces' axes a degree or two apart average to an axis
/// off both at the far ends), spanning both pieces.
fn merged(p: &Piece, q: &Piece, start: CylinderFit, points: &[Point3<f64>]) -> Option<Primitive> {
    let fit = refit_cylinder(points, &start).unwrap_or(start);
    // The re-fitted axis, spanning both pieces' ends projected onto it.
    let ends = [p, q].map(|piece| {
        let t = (piece.centre - fit.point).dot(&fit.axis);
        let half = piece.length / 2.0 * piece.axis.dot(&fit.axis).abs();
        (t - half, t + half)
    });
    let (lo, hi) = (ends[0].0.min(ends[1].0), ends[0].1.max(ends[1].1));
    let model = SurfaceModel::Cylinder {
        point: fit.point + fit.axis * ((lo + hi) / 2.0),
        axis: fit.axis,
        radius: fit.radius,
        length: hi - lo,
    };
    model.to_primitive()
}

/// `kept` (with their `existence`) with the cylinders that lie on one axis merged, pass
/// by pass (module docs). A merged cylinder's members are its pieces' (and replaced
/// strips'), its existence the higher of its pieces'. `sample_spacing` is the existence
/// decision's (scene units).
pub fn merge_collinear<'a>(
    cloud: Cloud,
    mut kept: Vec<Kept<'a>>,
    mut existence: Vec<f64>,
    pricing: Pricing,
    sample_spacing: f64,
) -> (Vec<Kept<'a>>, Vec<f64>) {
    for _ in 0..MAX_PASSES {
        let pieces: Vec<Option<Piece>> = kept.iter().map(|k| Piece::of(&k.primitive)).collect();
        let pairs: Vec<[usize; 2]> = (0..kept.len())
            .flat_map(|i| (i + 1..kept.len()).map(move |j| [i, j]))
            .filter(|&[i, j]| pieces[i].is_some() && pieces[j].is_some())
            .collect();
        // Pairs in parallel, collected in order: the same model on any number of threads.
        let mut scored: Vec<(f64, [usize; 2], Primitive, Vec<usize>)> = pairs
            .par_iter()
            .filter_map(|&[i, j]| {
                let (p, q) = (pieces[i].as_ref()?, pieces[j].as_ref()?);
                let start = spanning(p, q)?;
                // The pieces' members on their own surfaces (a piece fitted into a bend
                // holds points of the bend too).
                let points: Vec<Point3<f64>> = ([i, j].iter())
                    .flat_map(|&k| kept[k].members.iter().map(move |&m| (k, m)))
                    .map(|(k, m)| (k, cloud.points[m]))
                    .filter(|(k, y)| kept[*k].primitive.distance(y) <= pricing.cap)
                    .map(|(_, y)| y)
                    .collect();
                let one = merged(p, q, start, &points)?;
                let strips = strips_along(cloud, &kept, &one, [i, j], pricing.cap);
                let (gain, replace) = swap_gain(
                    cloud,
                    pricing,
                    sample_spacing,
                    &kept,
                    &[i, j],
                    &one,
                    &strips,
                );
                let replaced = if replace { strips } else { Vec::new() };
                (gain > 0.0).then_some((gain, [i, j], one, replaced))
            })
            .collect();
        if scored.is_empty() {
            break;
        }
        scored.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut used = vec![false; kept.len()];
        let mut merges = Vec::new();
        for (_, [i, j], one, replaced) in scored {
            if used[i] || used[j] || replaced.iter().any(|&k| used[k]) {
                continue;
            }
            for k in [i, j].into_iter().chain(replaced.iter().copied()) {
                used[k] = true;
            }
            let mut members: Vec<usize> = ([i, j].iter().chain(&replaced))
                .flat_map(|&k| kept[k].members.iter().copied())
                .collect();
            members.sort_unstable();
            members.dedup();
            let p = existence[i].max(existence[j]);
            merges.push((
                Kept {
                    primitive: one,
                    members: Cow::Owned(members),
                },
                p,
            ));
        }
        let (mut next, mut next_existence): (Vec<Kept>, Vec<f64>) = (kept.into_iter())
            .zip(existence)
            .zip(&used)
            .filter(|(_, used)| !**used)
            .map(|(k, _)| k)
            .unzip();
        for (k, p) in merges {
            next.push(k);
            next_existence.push(p);
        }
        (kept, existence) = (next, next_existence);
    }
    (kept, existence)
}

/// The primitives other than `pieces` whose members all lie within `cap` of `one`.
fn strips_along(
    cloud: Cloud,
    kept: &[Kept],
    one: &Primitive,
    pieces: [usize; 2],
    cap: f64,
) -> Vec<usize> {
    (0..kept.len())
        .filter(|k| !pieces.contains(k))
        .filter(|&k| {
            let members = &kept[k].members;
            !members.is_empty()
                && (one.center() - kept[k].primitive.center()).norm()
                    <= one.bounding_radius() + kept[k].primitive.bounding_radius()
                && members
                    .iter()
                    .all(|&j| one.distance(&cloud.points[j]) <= cap)
        })
        .collect()
}

/// The loss saved (loss units) by replacing the primitives `old_ids` of `kept` with `new`,
/// keeping or replacing `patch_ids` (whichever costs less), and whether they are replaced
/// (`swap.rs`). The points measured are those within the cap of a changed primitive;
/// each changed primitive's term is exact (one sample per `spacing`).
fn swap_gain(
    cloud: Cloud,
    pricing: Pricing,
    spacing: f64,
    kept: &[Kept],
    old_ids: &[usize],
    new: &Primitive,
    patch_ids: &[usize],
) -> (f64, bool) {
    let cap = pricing.cap;
    let of =
        |ids: &[usize]| -> Vec<&Primitive> { ids.iter().map(|&k| &kept[k].primitive).collect() };
    let (old, patches) = (of(old_ids), of(patch_ids));
    let mut near: Vec<u32> = (old.iter().chain(&patches).chain([&new]))
        .flat_map(|p| {
            cloud
                .index
                .within(&p.center(), (p.bounding_radius() + cap).powi(2))
        })
        .map(|(j, _)| j)
        .collect();
    near.sort_unstable();
    near.dedup();
    let points: Vec<Point3<f64>> = near.iter().map(|&j| cloud.points[j as usize]).collect();
    let tree = NearTree::of_cloud(cloud.index, cap, spacing);
    let price =
        |p: &Primitive| tree.exact_term(p) + primitive_cost(p, pricing.noise, cloud.points.len());
    let stay: Vec<usize> = (0..kept.len())
        .filter(|k| !old_ids.contains(k) && !patch_ids.contains(k))
        .collect();
    let patch_price: f64 = patches.iter().map(|p| price(p)).sum();
    let swap = SwapLoss::new(points, 1.0, &of(&stay), &patches, patch_price, pricing);
    let old_price: f64 = old.iter().map(|p| price(p)).sum();
    let before = swap.point_cost(&old).keep + old_price;
    let (after, replace) = swap.point_cost(&[new]).best();
    (before - price(new) - after, replace)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::PointIndex;
    use nalgebra::UnitQuaternion;

    /// Tube radius, noise σ and point spacing of the test pipe.
    const R: f64 = 0.1;
    const SIGMA: f64 = 0.005;
    const SPACING: f64 = 0.02;

    /// A cylinder along x from `x0` to `x1`, its axis at `(y, 0)`.
    fn along_x(x0: f64, x1: f64, y: f64) -> Primitive {
        let rotation =
            UnitQuaternion::rotation_between(&Vector3::z(), &Vector3::x()).expect("not opposite");
        let shape = Shape::Cylinder {
            length: x1 - x0,
            radius: R,
        };
        let centre = Vector3::new((x0 + x1) / 2.0, y, 0.0);
        Primitive::new(shape, crate::Pose::new(rotation, centre))
    }

    /// Points (σ jitter) on the cylinders `truth`.
    fn points_on(truth: &[Primitive]) -> Vec<Point3<f64>> {
        crate::synth::jittered_samples(truth, SPACING, SIGMA, 3)
    }

    /// `model` after [`merge_collinear`], each primitive's members the points within
    /// the cap of it.
    fn merge(points: &[Point3<f64>], model: &[Primitive]) -> Vec<Primitive> {
        let index = PointIndex::new(points);
        let cloud = Cloud {
            points,
            index: &index,
            spacing: SPACING,
        };
        let cap = 5.0 * SIGMA;
        let pricing = Pricing {
            cap,
            noise: SIGMA,
            point_weight: 1.0,
        };
        let kept = (model.iter())
            .map(|p| {
                let members = (0..points.len()).filter(|&j| p.distance(&points[j]) <= cap);
                Kept {
                    primitive: p.clone(),
                    members: Cow::Owned(members.collect()),
                }
            })
            .collect();
        let existence = vec![1.0; model.len()];
        let (kept, _) = merge_collinear(cloud, kept, existence, pricing, SPACING);
        kept.into_iter().map(|k| k.primitive).collect()
    }

    #[test]
    fn two_pieces_of_one_run_become_one_cylinder() {
        let points = points_on(&[along_x(0.0, 3.0, 0.0)]);
        // Overlapping, and side by side with a small gap.
        for pieces in [[(0.0, 1.8), (1.6, 3.0)], [(0.0, 1.45), (1.55, 3.0)]] {
            let model: Vec<Primitive> = pieces.iter().map(|&(a, b)| along_x(a, b, 0.0)).collect();
            let merged = merge(&points, &model);
            assert_eq!(merged.len(), 1, "{pieces:?}: {merged:?}");
            let Shape::Cylinder { length, radius } = merged[0].shape else {
                panic!("{merged:?}");
            };
            assert!((length - 3.0).abs() < 0.02, "{length}");
            assert!((radius - R).abs() < 0.1 * SIGMA, "{radius}");
            let axis = merged[0].pose.rotation * Vector3::z();
            assert!(axis.x.abs() > (0.5f64).to_radians().cos(), "{axis}");
        }
    }

    #[test]
    fn separate_pipes_stay_separate() {
        // Two collinear pipes with a metre between them: nothing there to explain.
        let (a, b) = (along_x(0.0, 1.5, 0.0), along_x(2.5, 4.0, 0.0));
        let points = points_on(&[a.clone(), b.clone()]);
        assert_eq!(merge(&points, &[a, b]).len(), 2);
        // Two parallel pipes side by side.
        let (a, b) = (along_x(0.0, 2.0, 0.0), along_x(0.0, 2.0, 3.0 * R));
        let points = points_on(&[a.clone(), b.clone()]);
        assert_eq!(merge(&points, &[a, b]).len(), 2);
    }
}
