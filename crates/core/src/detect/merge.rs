//! Merging segments that describe the same surface.
//!
//! **Rule (description length).** Two segments of the same type merge when **one**
//! primitive explains their union within the noise: the union's refitted model leaves
//! each part's points with an RMS of at most `t σ_part` (`t` the tolerance, `σ_part`
//! the part's noise) and at most [`MAX_RMS_GROWTH`] times what the part's own model
//! leaves (or its σ, if larger) — beyond that the union's model is a compromise between
//! two surfaces, not one surface seen twice. Cylinders must also have radii within
//! `t σ` of each other (`RADIUS_RATIO_GAP`). One primitive then describes the same points as two at the same
//! residual cost, so the shorter description wins (an MDL argument: equal data cost,
//! one model's parameters fewer). Adjacency is **not** required: a wall split in two by
//! an occluder in front of it is one plane; its extent (the two point sets) is left to
//! the bounded primitive built from the points.
//!
//! Testing each part (not only the union) matters: a small segment tilted off a large
//! one barely moves the union's RMS, but its own points are far from the union's plane.
//! Plane unions cost O(1) from moments ([`super::plane::Moments`]), so every pair of
//! planes is tested, whatever their normals: the normal of a part need not be the
//! surface's. Quantised depth turns a wall seen obliquely into treads facing the sensor
//! (each exactly flat between two depth levels), whose fine-scale normals point along
//! the line of sight, tens of degrees off the wall's; the wall's plane explains them
//! within their noise (the coarse σ, about step/√12), so they join it. A Kinect-type
//! frame of a room (`synth` preset `kinect`) went from 52 to 16 primitives for its 11
//! surfaces with this. Cylinders are filtered first (axes within the growing angle,
//! radii and axis lines close): their union needs a refit.
//!
//! **Layers.** Two *parallel* planes (normals within the growing angle) also merge when
//! they are at most [`LAYER_SIGMAS`] σ apart (the smaller σ of the two), the distance
//! within which the compact model counts a point as explained
//! ([`crate::compact::CAP_SIGMAS`]): two planes closer than that explain each other's
//! points, so keeping both covers one surface twice. This is what quantised depth makes
//! of a wall seen face-on: stereo disparity steps cut it into interleaved flat layers one
//! depth step apart (6 mm at 2 m on the shared table scan, about 4 σ of the layers' own
//! noise), each flat within the noise, none of which is a surface of its own. Steps
//! larger than the cap (a book on a table, a stair) stay apart.
//!
//! Order: segments are visited by decreasing size (ties: lower first point), each
//! absorbing every later segment that passes, until no pair merges; the result does not
//! depend on the thread count.

use nalgebra::Point3;

use super::SurfaceModel;
use super::cylinder::{CylinderFit, refit_cylinder};
use super::plane::Moments;

/// Cylinders merge only if their radii differ by at most this fraction of the larger,
/// and by at most `t σ`: coaxial cylinders whose radii differ by more than the noise are
/// two surfaces (the outer and inner wall of a tube), even where a cylinder between them
/// with a shifted axis explains both (seen from one side, the front of the outer wall
/// and the back of the inner wall lie on one such cylinder: measured on the shared
/// mug, 40.0 and 37.3 mm walls, one 38.5 mm cylinder at 0.8 mm RMS).
const RADIUS_RATIO_GAP: f64 = 0.2;

/// Cylinders merge only if the longer one's axis passes within this fraction of the
/// larger radius of the other's axis point.
const AXIS_OFFSET_GAP: f64 = 0.2;

/// Parallel planes at most this many σ apart merge as layers of one surface (module
/// docs): the compact model's cap.
pub const LAYER_SIGMAS: f64 = crate::compact::CAP_SIGMAS;

/// A part's RMS about the union's model may exceed its own model's RMS (or its σ, if
/// larger) by at most this factor (dimensionless).
pub const MAX_RMS_GROWTH: f64 = 2.0;

/// Whether a part whose points lie at RMS `about_union` from the union's model is still
/// explained by it (module docs).
fn still_fits(part: &Part, about_union: f64, tolerance: f64) -> bool {
    about_union <= tolerance * part.sigma
        && about_union <= MAX_RMS_GROWTH * part.rms.max(part.sigma)
}

/// A segment under construction: its points (sample indices), model, noise and moments.
#[derive(Debug, Clone)]
pub struct Part {
    /// Point indices (ascending).
    pub ids: Vec<usize>,
    /// The model (`None`: clutter, never merged).
    pub model: Option<SurfaceModel>,
    /// RMS of the points from the model (scene units).
    pub rms: f64,
    /// The part's noise σ (scene units).
    pub sigma: f64,
    /// Moments of the points.
    pub moments: Moments,
}

/// Merges `parts` by the rule of the module docs; `cos_angle` is the cosine of the
/// largest angle between merged cylinder axes, `tolerance` is `t` (in σ).
pub fn merge_parts(
    mut parts: Vec<Part>,
    points: &[Point3<f64>],
    cos_angle: f64,
    tolerance: f64,
) -> Vec<Part> {
    parts.sort_by(|a, b| {
        b.ids
            .len()
            .cmp(&a.ids.len())
            .then(a.ids.first().cmp(&b.ids.first()))
    });
    loop {
        let mut merged_any = false;
        let mut i = 0;
        while i < parts.len() {
            let mut j = i + 1;
            while j < parts.len() {
                if let Some(joined) = try_merge(&parts[i], &parts[j], points, cos_angle, tolerance)
                {
                    parts[i] = joined;
                    parts.remove(j);
                    merged_any = true;
                } else {
                    j += 1;
                }
            }
            i += 1;
        }
        if !merged_any {
            return parts;
        }
    }
}

/// The union of `a` and `b` if one model explains it (module docs), else `None`.
fn try_merge(
    a: &Part,
    b: &Part,
    points: &[Point3<f64>],
    cos_angle: f64,
    tolerance: f64,
) -> Option<Part> {
    match (a.model?, b.model?) {
        (SurfaceModel::Plane { .. }, SurfaceModel::Plane { .. }) => {
            merge_planes(a, b, cos_angle, tolerance)
        }
        (SurfaceModel::Cylinder { .. }, SurfaceModel::Cylinder { .. }) => {
            merge_cylinders(a, b, points, cos_angle, tolerance)
        }
        _ => None,
    }
}

/// The union of two plane parts if its plane explains both, or if they are parallel
/// layers of one surface (module docs; O(1) by moments).
fn merge_planes(a: &Part, b: &Part, cos_angle: f64, tolerance: f64) -> Option<Part> {
    let mut union = a.moments;
    union += &b.moments;
    let fit = union.plane()?;
    let about = |p: &Part| p.moments.rms_about(&fit.point, &fit.normal);
    let explained = still_fits(a, about(a), tolerance) && still_fits(b, about(b), tolerance);
    let layers = || match (a.model, b.model) {
        (
            Some(SurfaceModel::Plane {
                point: pa,
                normal: na,
            }),
            Some(SurfaceModel::Plane {
                point: pb,
                normal: nb,
            }),
        ) => {
            // The distance between the two planes, along either normal.
            let offset = na.dot(&(pb - pa)).abs().max(nb.dot(&(pb - pa)).abs());
            na.dot(&nb).abs() >= cos_angle && offset <= LAYER_SIGMAS * a.sigma.min(b.sigma)
        }
        _ => false,
    };
    if !(explained || layers()) {
        return None;
    }
    let model = SurfaceModel::Plane {
        point: fit.point,
        normal: fit.normal,
    };
    Some(joined(a, b, model, fit.rms, union))
}

/// The union of two cylinder parts if, after the quick filters (parallel axes, close
/// radii, close axis lines), the union's refitted cylinder explains both.
fn merge_cylinders(
    a: &Part,
    b: &Part,
    points: &[Point3<f64>],
    cos_angle: f64,
    tolerance: f64,
) -> Option<Part> {
    let (
        Some(SurfaceModel::Cylinder {
            point: pa,
            axis: aa,
            radius: ra,
            length: la,
        }),
        Some(SurfaceModel::Cylinder {
            point: pb,
            axis: ab,
            radius: rb,
            length: lb,
        }),
    ) = (a.model, b.model)
    else {
        return None;
    };
    let r = ra.max(rb);
    let off = |p: &Point3<f64>, q: &Point3<f64>, axis: &nalgebra::Vector3<f64>| {
        let d = q - p;
        (d - axis * d.dot(axis)).norm()
    };
    // The longer part's axis is the better determined: a short piece's axis, tilted by
    // a fraction of a degree, misses a far neighbour's axis point.
    let offset = if la >= lb {
        off(&pa, &pb, &aa)
    } else {
        off(&pb, &pa, &ab)
    };
    if aa.dot(&ab).abs() < cos_angle
        || (ra - rb).abs() > (tolerance * a.sigma.max(b.sigma)).min(RADIUS_RATIO_GAP * r)
        || offset > AXIS_OFFSET_GAP * r
    {
        return None;
    }
    let ids = union_ids(&a.ids, &b.ids);
    let pts: Vec<Point3<f64>> = ids.iter().map(|&i| points[i]).collect();
    let start = CylinderFit {
        point: pa,
        axis: aa,
        radius: ra,
        length: la,
        rms: a.rms,
    };
    let fit = refit_cylinder(&pts, &start)?;
    let model = SurfaceModel::Cylinder {
        point: fit.point,
        axis: fit.axis,
        radius: fit.radius,
        length: fit.length,
    };
    let part_rms = |p: &Part| {
        let ss: f64 = p
            .ids
            .iter()
            .map(|&i| model.distance(&points[i]).powi(2))
            .sum();
        (ss / p.ids.len().max(1) as f64).sqrt()
    };
    if !(still_fits(a, part_rms(a), tolerance) && still_fits(b, part_rms(b), tolerance)) {
        return None;
    }
    let mut union = a.moments;
    union += &b.moments;
    Some(joined(a, b, model, fit.rms, union))
}

/// The part made of `a` and `b` with `model`.
fn joined(a: &Part, b: &Part, model: SurfaceModel, rms: f64, moments: Moments) -> Part {
    let (na, nb) = (a.ids.len() as f64, b.ids.len() as f64);
    Part {
        ids: union_ids(&a.ids, &b.ids),
        model: Some(model),
        rms,
        sigma: (a.sigma * na + b.sigma * nb) / (na + nb),
        moments,
    }
}

/// The sorted union of two ascending, disjoint index lists.
fn union_ids(a: &[usize], b: &[usize]) -> Vec<usize> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < b.len() {
        if j >= b.len() || (i < a.len() && a[i] < b[j]) {
            out.push(a[i]);
            i += 1;
        } else {
            out.push(b[j]);
            j += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;

    fn plane_part(points: &[Point3<f64>], ids: Vec<usize>, sigma: f64) -> Part {
        let moments = Moments::of(points, &ids);
        let fit = moments.plane().unwrap();
        Part {
            ids,
            model: Some(SurfaceModel::Plane {
                point: fit.point,
                normal: fit.normal,
            }),
            rms: fit.rms,
            sigma,
            moments,
        }
    }

    #[test]
    fn a_tread_of_quantised_depth_joins_its_wall_and_a_crossing_face_does_not() {
        // The plane z = 0.3 x (σ = 1 mm) for x < 0.6, and beyond it one tread of the
        // same plane seen from above with depth rounded to 3 cm: flat at z = 0.21, its
        // own normal +z, 17° off the wall's, its σ the quantisation's step/√12. With
        // them, a face x = −0.05 standing across.
        let (step, slope) = (0.03, 0.3);
        let mut pts = Vec::new();
        let (mut wall, mut tread) = (Vec::new(), Vec::new());
        for i in 0..70 {
            for j in 0..20 {
                let (x, y) = (i as f64 * 0.01, j as f64 * 0.01);
                let ripple = if (i + j) % 2 == 0 { 0.001 } else { -0.001 };
                if x < 0.6 {
                    wall.push(pts.len());
                    pts.push(Point3::new(x, y, slope * x + ripple));
                } else if (slope * x / step).round() == 7.0 {
                    tread.push(pts.len());
                    pts.push(Point3::new(x, y, 7.0 * step));
                }
            }
        }
        let face: Vec<usize> = (0..20 * 30)
            .map(|k| {
                let (y, z) = ((k % 20) as f64 * 0.01, (k / 20) as f64 * 0.01);
                pts.push(Point3::new(-0.05, y, z));
                pts.len() - 1
            })
            .collect();
        assert!(tread.len() >= 100, "{}", tread.len());
        let parts = vec![
            plane_part(&pts, wall, 0.001),
            plane_part(&pts, tread, step / 12f64.sqrt()),
            plane_part(&pts, face, 0.001),
        ];
        let merged = merge_parts(parts, &pts, 5f64.to_radians().cos(), 2.5);
        let sizes: Vec<usize> = merged.iter().map(|p| p.ids.len()).collect();
        assert_eq!(merged.len(), 2, "{sizes:?}");
        let Some(SurfaceModel::Plane { normal, .. }) = merged[0].model else {
            panic!()
        };
        let truth = Vector3::new(-slope, 0.0, 1.0).normalize();
        assert!(normal.dot(&truth).abs() > 0.999, "{normal}");
    }

    #[test]
    fn interleaved_depth_layers_merge_and_a_book_on_the_table_does_not() {
        // A wall z ≈ 0 seen face-on through quantised depth: 2 cm blobs alternate between
        // the levels z = 0 and z = q (q = 4 σ), each level flat within σ. Beside it a
        // 20 cm book whose top is 10 σ above the wall's plane.
        let (sigma, q) = (0.001, 0.004);
        let mut pts = Vec::new();
        let (mut low, mut high, mut book) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..100 {
            for j in 0..50 {
                let (x, y) = (i as f64 * 0.005, j as f64 * 0.005);
                let ripple = if (i + j) % 2 == 0 { sigma } else { -sigma };
                let level = ((i / 4) + (j / 4)) % 2;
                let list = if level == 0 { &mut low } else { &mut high };
                list.push(pts.len());
                pts.push(Point3::new(x, y, level as f64 * q + ripple));
            }
        }
        for i in 0..40 {
            for j in 0..40 {
                let (x, y) = (0.6 + i as f64 * 0.005, j as f64 * 0.005);
                let ripple = if (i + j) % 2 == 0 { sigma } else { -sigma };
                book.push(pts.len());
                pts.push(Point3::new(x, y, 10.0 * sigma + ripple));
            }
        }
        let parts = vec![
            plane_part(&pts, low, sigma),
            plane_part(&pts, high, sigma),
            plane_part(&pts, book, sigma),
        ];
        let merged = merge_parts(parts, &pts, 5f64.to_radians().cos(), 2.5);
        let sizes: Vec<usize> = merged.iter().map(|p| p.ids.len()).collect();
        assert_eq!(sizes, [5000, 1600]);
    }

    #[test]
    fn coplanar_pieces_merge_and_a_step_does_not() {
        // Three patches of z = 0 (two of them far apart) and one at z = 0.05.
        let mut pts = Vec::new();
        let patch = |pts: &mut Vec<Point3<f64>>, x0: f64, z: f64| {
            let start = pts.len();
            for i in 0..20 {
                for j in 0..20 {
                    let s = if (i + j) % 2 == 0 { 0.001 } else { -0.001 };
                    pts.push(Point3::new(x0 + i as f64 * 0.01, j as f64 * 0.01, z + s));
                }
            }
            (start..pts.len()).collect::<Vec<usize>>()
        };
        let a = patch(&mut pts, 0.0, 0.0);
        let b = patch(&mut pts, 0.2, 0.0);
        let c = patch(&mut pts, 2.0, 0.0);
        let d = patch(&mut pts, 0.4, 0.05);
        let parts: Vec<Part> = [a, b, c, d]
            .into_iter()
            .map(|ids| plane_part(&pts, ids, 0.001))
            .collect();
        let merged = merge_parts(parts, &pts, 5f64.to_radians().cos(), 2.5);
        let mut sizes: Vec<usize> = merged.iter().map(|p| p.ids.len()).collect();
        sizes.sort_unstable();
        assert_eq!(sizes, [400, 1200]);
        let big = merged.iter().find(|p| p.ids.len() == 1200).unwrap();
        let Some(SurfaceModel::Plane { normal, .. }) = big.model else {
            panic!()
        };
        assert!(normal.dot(&Vector3::z()).abs() > 1.0 - 1e-9);
        assert_eq!(union_ids(&[1, 4, 9], &[0, 5]), [0, 1, 4, 5, 9]);
    }

    fn cylinder_part(points: &mut Vec<Point3<f64>>, r: f64, phase: f64, sigma: f64) -> Part {
        let start = points.len();
        for i in 0..40 {
            for j in 0..30 {
                let phi = phase + i as f64 * 0.08;
                let s = if (i + j) % 2 == 0 { sigma } else { -sigma };
                points.push(Point3::new(
                    (r + s) * phi.cos(),
                    (r + s) * phi.sin(),
                    j as f64 * 0.003,
                ));
            }
        }
        let ids: Vec<usize> = (start..points.len()).collect();
        let model = SurfaceModel::Cylinder {
            point: Point3::new(0.0, 0.0, 0.045),
            axis: Vector3::z(),
            radius: r,
            length: 0.09,
        };
        Part {
            moments: Moments::of(points, &ids),
            ids,
            model: Some(model),
            rms: sigma,
            sigma,
        }
    }

    #[test]
    fn two_arcs_of_one_cylinder_merge_and_two_walls_do_not() {
        // One cylinder seen in two arcs: one part. The outer and inner wall of a mug
        // (r = 40 and 37 mm, σ = 0.7 mm): within t σ = 1.75 mm of a cylinder between
        // them, but each much worse explained by it than by its own.
        let mut pts = Vec::new();
        let arcs = vec![
            cylinder_part(&mut pts, 0.04, 0.0, 0.0006),
            cylinder_part(&mut pts, 0.04, 3.3, 0.0006),
        ];
        assert_eq!(
            merge_parts(arcs, &pts, 5f64.to_radians().cos(), 2.5).len(),
            1
        );
        let mut pts = Vec::new();
        let walls = vec![
            cylinder_part(&mut pts, 0.04, 0.0, 0.0007),
            cylinder_part(&mut pts, 0.037, 0.2, 0.0007),
        ];
        assert_eq!(
            merge_parts(walls, &pts, 5f64.to_radians().cos(), 2.5).len(),
            2
        );
    }
}
