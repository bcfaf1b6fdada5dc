//! The overlap of a model with itself: how much of its area another of its primitives
//! also lies on (issue 14: "no surface is covered twice").
//!
//! Both measures sample every primitive area-uniformly ([`Primitive::sample_surface`] at
//! `spacing`), weight each sample by its primitive's area ÷ its sample count, and return
//! the weighted share of samples that another primitive covers:
//!
//! - [`overlap_share`]: a sample is covered when another primitive's surface lies within
//!   `h` of it. This is the literal "share of model area within `h` of another
//!   primitive". It also counts the band along an edge where two primitives meet (a
//!   wall and the floor, two abutting tiles): a band of width `h` on each side, so a
//!   model whose faces meet along edges of total length `L` scores about `2 h L / A`
//!   (`A` its area) even when no surface is covered twice — 2 % for a 5 × 4 × 2.5 m room
//!   of floor and walls at `h` = 3 cm.
//! - [`double_cover_share`]: a sample is covered only when the nearest point of the
//!   other primitive is within `h`, lies along the sample's own normal (within
//!   [`DOUBLE_COVER_MAX_ANGLE_DEG`]) or coincides with it, **and** the other surface is
//!   parallel to this one there (normals within the same angle): the other surface runs
//!   over or under this one (two stacked or coplanar overlapping patches), not beside it
//!   (a coplanar tile abutting it) nor across it (a perpendicular face meeting it at an
//!   edge, or ending just short of it). This is the share of area covered twice.
//!
//! Neighbours are found through bounding balls (a kd-tree over centres per radius class,
//! as [`crate::spatial::PrimitiveIndex`]), so only primitives whose balls come within `h`
//! of each other are compared: near-linear in the model size for compact scenes.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::spatial::PointIndex;
use crate::{Primitive, Result, check};

/// The largest angle (degrees) between a sample's normal and the direction to the
/// nearest point of another primitive, and between the two surfaces' normals, for
/// [`double_cover_share`] to count the sample as covered twice. 45° splits "over or
/// under, parallel" (0°, stacked patches) from "beside" or "across" (90°, faces meeting
/// at an edge) evenly.
pub const DOUBLE_COVER_MAX_ANGLE_DEG: f64 = 45.0;

/// Distances below this many sample spacings count as coincident surfaces for
/// [`double_cover_share`] (no direction to test).
const COINCIDENT_SPACINGS: f64 = 1e-6;

/// Step of the numeric normal probe, relative to a primitive's size.
const NORMAL_PROBE: f64 = 1e-6;

/// Share of `model`'s area (in `[0, 1]`) within `h` (scene units) of another of its
/// primitives' surfaces, from area-uniform samples `spacing` apart (scene units); 0 for a
/// model with no area. Counts the band of width `h` where two primitives meet at an
/// edge (see the module docs). Errs when `h < 0` or `spacing ≤ 0`.
pub fn overlap_share(model: &[Primitive], h: f64, spacing: f64) -> Result<f64> {
    covered_share(model, h, spacing, Cover::Near)
}

/// Share of `model`'s area (in `[0, 1]`) that another of its primitives covers too: the
/// other's nearest surface point is within `h` (scene units) along the sample's normal,
/// and the other surface parallel to it there (both within
/// [`DOUBLE_COVER_MAX_ANGLE_DEG`]), from area-uniform samples `spacing` apart
/// (scene units); 0 for a model with no area. Faces meeting at an edge do not count
/// (see the module docs). Errs when `h < 0` or `spacing ≤ 0`.
pub fn double_cover_share(model: &[Primitive], h: f64, spacing: f64) -> Result<f64> {
    covered_share(model, h, spacing, Cover::Along)
}

/// When a sample counts as covered by another primitive.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Cover {
    /// The other surface is within `h`.
    Near,
    /// The other surface is within `h` along the sample's normal.
    Along,
}

/// The area-weighted share of samples covered by another primitive.
fn covered_share(model: &[Primitive], h: f64, spacing: f64, cover: Cover) -> Result<f64> {
    check::non_negative("h", h)?;
    check::positive("spacing", spacing)?;
    let near = ball_neighbours(model, h)?;
    let per: Vec<(f64, f64)> = model
        .par_iter()
        .enumerate()
        .map(|(i, a)| {
            let samples = a.sample_surface(spacing);
            if samples.is_empty() || near[i].is_empty() {
                return (a.area(), 0.0);
            }
            let hits = samples
                .par_iter()
                .filter(|x| {
                    let others = near[i].iter().map(|&j| &model[j]);
                    is_covered(a, x, others, h, spacing, cover)
                })
                .count();
            (a.area(), a.area() * hits as f64 / samples.len() as f64)
        })
        .collect();
    let total: f64 = per.iter().map(|p| p.0).sum();
    let covered: f64 = per.iter().map(|p| p.1).sum();
    Ok(if total > 0.0 { covered / total } else { 0.0 })
}

/// Whether one of `others` covers the sample `x` of `a`.
fn is_covered<'a>(
    a: &Primitive,
    x: &Point3<f64>,
    others: impl Iterator<Item = &'a Primitive>,
    h: f64,
    spacing: f64,
    cover: Cover,
) -> bool {
    let mut normal: Option<Vector3<f64>> = None;
    for b in others {
        if (x - b.center()).norm() - b.bounding_radius() > h {
            continue;
        }
        match cover {
            Cover::Near => {
                if b.distance(x) <= h {
                    return true;
                }
            }
            Cover::Along => {
                let n = *normal.get_or_insert_with(|| surface_normal(a, x, spacing));
                if covers_along(x, &n, b, h, spacing) {
                    return true;
                }
            }
        }
    }
    false
}

/// Whether `b` runs over or under the surface point `x` (unit normal `n`), the test of
/// [`double_cover_share`]: `b`'s nearest point is within `h` (scene units) along `n`
/// (within [`DOUBLE_COVER_MAX_ANGLE_DEG`]) or coincides with `x`, and `b`'s surface is
/// parallel to `n`'s there, within the same angle; `spacing` (scene units) scales the
/// coincidence and the normal probe.
pub(crate) fn covers_along(
    x: &Point3<f64>,
    n: &Vector3<f64>,
    b: &Primitive,
    h: f64,
    spacing: f64,
) -> bool {
    let cos_max = DOUBLE_COVER_MAX_ANGLE_DEG.to_radians().cos();
    let y = b.closest_point(x);
    let offset = y - x;
    let d = offset.norm();
    if d > h {
        return false;
    }
    let along = d <= COINCIDENT_SPACINGS * spacing || offset.dot(n).abs() >= cos_max * d;
    along && surface_normal(b, &y, spacing).dot(n).abs() >= cos_max
}

/// The unit normal of `p` at its surface point `x`: the offset from a probe point just
/// off `x` to its closest surface point is along the normal there. Of the three probes
/// along the coordinate axes the one with the longest offset is used (at least `1/√3`
/// of the step for any normal).
pub(crate) fn surface_normal(p: &Primitive, x: &Point3<f64>, spacing: f64) -> Vector3<f64> {
    let step = NORMAL_PROBE * p.bounding_radius().max(spacing);
    (0..3)
        .map(|k| {
            let q = x + Vector3::ith(k, step);
            q - p.closest_point(&q)
        })
        .max_by(|u, v| u.norm_squared().total_cmp(&v.norm_squared()))
        .and_then(|v| v.try_normalize(0.0))
        .unwrap_or_else(Vector3::z)
}

/// For every primitive, the others whose bounding balls come within `h` of its own
/// (ascending indices). Primitives are grouped by bounding radius (classes a factor 2
/// apart) so one large primitive does not widen every search. Errs on a non-finite
/// bounding ball.
fn ball_neighbours(model: &[Primitive], h: f64) -> Result<Vec<Vec<usize>>> {
    for (i, p) in model.iter().enumerate() {
        let (c, r) = (p.center(), p.bounding_radius());
        if !(c.coords.iter().all(|v| v.is_finite()) && r.is_finite()) {
            return Err(crate::Error::NonFinite {
                what: "the bounding sphere of primitive".into(),
                index: i,
            });
        }
    }
    let class_of = |r: f64| {
        if r > 0.0 {
            r.log2().floor() as i32
        } else {
            i32::MIN
        }
    };
    let mut keys: Vec<i32> = model
        .iter()
        .map(|p| class_of(p.bounding_radius()))
        .collect();
    keys.sort_unstable();
    keys.dedup();
    let classes: Vec<(PointIndex, Vec<usize>, f64)> = keys
        .iter()
        .map(|&k| {
            let ids: Vec<usize> = (0..model.len())
                .filter(|&i| class_of(model[i].bounding_radius()) == k)
                .collect();
            let centres: Vec<Point3<f64>> = ids.iter().map(|&i| model[i].center()).collect();
            let max_r = ids
                .iter()
                .map(|&i| model[i].bounding_radius())
                .fold(0.0, f64::max);
            (PointIndex::new(&centres), ids, max_r)
        })
        .collect();
    Ok(model
        .par_iter()
        .enumerate()
        .map(|(i, a)| {
            let (c, r) = (a.center(), a.bounding_radius());
            let mut out: Vec<usize> = classes
                .iter()
                .flat_map(|(tree, ids, max_r)| {
                    let reach = r + max_r + h;
                    tree.within(&c, reach * reach)
                        .into_iter()
                        .map(|(k, d2)| (ids[k as usize], d2.sqrt()))
                })
                .filter(|&(j, d)| j != i && d <= r + model[j].bounding_radius() + h)
                .map(|(j, _)| j)
                .collect();
            out.sort_unstable();
            out
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point2, UnitQuaternion};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::atlas::PlaneShape;
    use crate::{Pose, Shape};

    /// A square of `side` centred at `(x, y, z)` with normal +z.
    fn square(side: f64, x: f64, y: f64, z: f64) -> Primitive {
        let pose = Pose::new(UnitQuaternion::identity(), Vector3::new(x, y, z));
        Primitive::new(Shape::Square { side }, pose)
    }

    /// Both shares of `model` at `h`, samples 1 cm apart.
    fn shares(model: &[Primitive], h: f64) -> (f64, f64) {
        (
            overlap_share(model, h, 0.01).unwrap(),
            double_cover_share(model, h, 0.01).unwrap(),
        )
    }

    #[test]
    fn disjoint_squares_do_not_overlap_and_identical_ones_overlap_entirely() {
        let apart = [square(1.0, 0.0, 0.0, 0.0), square(1.0, 3.0, 0.0, 0.0)];
        assert_eq!(shares(&apart, 0.05), (0.0, 0.0));
        let same = [square(1.0, 0.0, 0.0, 0.0), square(1.0, 0.0, 0.0, 0.0)];
        assert_eq!(shares(&same, 0.05), (1.0, 1.0));
        assert_eq!(shares(&[], 0.05), (0.0, 0.0));
        assert_eq!(shares(&apart[..1], 0.05), (0.0, 0.0));
    }

    #[test]
    fn squares_overlapping_by_half_share_half_their_area() {
        // Coplanar, shifted by half a side: half of each lies on the other. The literal
        // share adds the band of width h beside the other's edge; the double cover not.
        let h = 0.02;
        let half = [square(1.0, 0.0, 0.0, 0.0), square(1.0, 0.5, 0.0, 0.0)];
        let (near, double) = shares(&half, h);
        assert!((near - (0.5 + h)).abs() < 0.011, "{near}");
        assert!((double - 0.5).abs() < 0.011, "{double}");
        // Stacked 1 cm apart, half over half: covered within 2 cm, not within 5 mm.
        let stacked = [square(1.0, 0.0, 0.0, 0.0), square(1.0, 0.5, 0.0, 0.01)];
        assert!((shares(&stacked, 0.02).1 - 0.5).abs() < 0.011);
        assert_eq!(shares(&stacked, 0.005), (0.0, 0.0));
    }

    #[test]
    fn faces_meeting_at_an_edge_are_a_band_but_no_double_cover() {
        // A floor and a wall meeting along the floor's edge x = 0.5.
        let wall_pose = Pose::new(
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2),
            Vector3::new(0.5, 0.0, 0.5),
        );
        let model = [
            square(1.0, 0.0, 0.0, 0.0),
            Primitive::new(Shape::Square { side: 1.0 }, wall_pose),
        ];
        let h = 0.05;
        let (near, double) = shares(&model, h);
        assert!((near - h).abs() < 0.011, "a band h wide on each: {near}");
        assert_eq!(double, 0.0);
        // Both ending 2 cm short of the edge: the other face is diagonally within h of
        // a band of each, but across it, not over it.
        let short_pose = Pose::new(wall_pose.rotation, Vector3::new(0.5, 0.0, 0.51));
        let short = [
            square(0.98, -0.01, 0.0, 0.0),
            Primitive::new(Shape::Square { side: 0.98 }, short_pose),
        ];
        let (near, double) = shares(&short, h);
        assert!(near > 0.02, "{near}");
        assert_eq!(double, 0.0);
    }

    #[test]
    fn a_plane_on_a_cylinder_is_covered_where_it_touches() {
        // A bounded plane (a 1 × 0.4 m rectangle) tangent to a cylinder of radius 0.1
        // lying along x beneath it: within h = 1 cm the plane is covered on the strip
        // |y| < √(2 r h) ≈ 4.5 cm (share of both areas ≈ 2 × 0.045 / (0.4 + 2π r)).
        let rect = PlaneShape::new(
            vec![
                Point2::new(-0.5, -0.2),
                Point2::new(0.5, -0.2),
                Point2::new(0.5, 0.2),
                Point2::new(-0.5, 0.2),
            ],
            vec![],
        )
        .unwrap();
        let plane = Primitive::new(Shape::Plane(rect), Pose::identity());
        let tube = Primitive::new(
            Shape::Cylinder {
                length: 1.0,
                radius: 0.1,
            },
            Pose::new(
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2),
                Vector3::new(0.0, 0.0, -0.1),
            ),
        );
        let (near, double) = shares(&[plane, tube], 0.01);
        let strip = (2.0f64 * 0.1 * 0.01).sqrt();
        let expected = (2.0 * strip + 2.0 * strip) / (0.4 + std::f64::consts::TAU * 0.1);
        assert!(
            (near - expected).abs() < 0.2 * expected,
            "{near} vs {expected}"
        );
        assert!(double > 0.5 * expected && double <= near, "{double}");
    }

    #[test]
    fn the_neighbour_search_is_exact_against_brute_force() {
        // Sixty random squares of mixed sizes: every sample's verdict over the ball
        // neighbours equals the verdict over all other primitives.
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let model: Vec<Primitive> = (0..60)
            .map(|_| {
                let side = [0.05, 0.3, 1.5][rng.random_range(0..3)];
                let rot = UnitQuaternion::from_euler_angles(
                    rng.random::<f64>() * 3.0,
                    rng.random::<f64>() * 3.0,
                    0.0,
                );
                let t = Vector3::new(rng.random(), rng.random(), rng.random()) * 3.0;
                Primitive::new(Shape::Square { side }, Pose::new(rot, t))
            })
            .collect();
        let (h, spacing) = (0.04, 0.05);
        let near = ball_neighbours(&model, h).unwrap();
        for cover in [Cover::Near, Cover::Along] {
            let (mut fast, mut slow) = (0.0, 0.0);
            for (i, a) in model.iter().enumerate() {
                let samples = a.sample_surface(spacing);
                let w = a.area() / samples.len() as f64;
                for x in &samples {
                    let pruned = near[i].iter().map(|&j| &model[j]);
                    let all = model.iter().enumerate().filter(|(j, _)| *j != i);
                    fast += w * is_covered(a, x, pruned, h, spacing, cover) as u8 as f64;
                    slow += w * is_covered(a, x, all.map(|p| p.1), h, spacing, cover) as u8 as f64;
                }
            }
            assert!(slow > 0.0);
            assert_eq!(fast, slow, "{cover:?}");
            let total: f64 = model.iter().map(Primitive::area).sum();
            let share = covered_share(&model, h, spacing, cover).unwrap();
            assert!((share - fast / total).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_arguments_are_errors() {
        let one = [square(1.0, 0.0, 0.0, 0.0)];
        assert!(overlap_share(&one, -1.0, 0.01).is_err());
        assert!(overlap_share(&one, 0.1, 0.0).is_err());
        assert!(double_cover_share(&one, 0.1, f64::NAN).is_err());
    }
}
