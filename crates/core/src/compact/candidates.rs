//! Candidates proposed from a [`Detection`]: each planar segment becomes one bounded
//! `plane` whose parts are the connected parts of its points (the outline ends where its
//! points end; a surface cut by occlusion shadows stays one primitive), each cylinder or
//! sphere segment its bounded primitive.

use nalgebra::{Point2, Point3};
use rayon::prelude::*;

use super::tube_lattice::TubeLattice;
use crate::atlas::{PlaneShape, plane_frame};
use crate::detect::{Detection, Segment, SurfaceModel};
use crate::spatial::{PointIndex, strided_median};
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

/// Neighbours first fetched from the cloud to find a probe's nearest point of its own
/// segment; four times as many at each retry, up to [`MAX_MEMBER_NEIGHBOURS`].
const MEMBER_NEIGHBOURS: usize = 8;

/// See [`MEMBER_NEIGHBOURS`]: a probe whose 512 nearest points hold no other point of
/// its segment is left out of the median.
const MAX_MEMBER_NEIGHBOURS: usize = 512;

/// One proposed candidate and the detected segment it comes from.
#[derive(Debug, Clone)]
pub struct Proposal {
    /// The candidate primitive.
    pub primitive: Primitive,
    /// Index of its segment in [`Detection::segments`].
    pub segment: usize,
}

/// The candidates of every segment of `detection` over `points` (indexed by `index`),
/// in segment order.
/// Segments whose points give no outline (too few, degenerate) propose nothing.
pub fn propose(points: &[Point3<f64>], index: &PointIndex, detection: &Detection) -> Vec<Proposal> {
    let per_segment: Vec<Vec<Proposal>> = detection
        .segments
        .par_iter()
        .enumerate()
        .map(|(s, segment)| {
            segment_candidates(points, index, segment, detection.spacing)
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
    index: &PointIndex,
    segment: &Segment,
    fallback_spacing: f64,
) -> Vec<Primitive> {
    match segment.model {
        SurfaceModel::Plane { normal, .. } => {
            let own: Vec<Point3<f64>> = segment.points.iter().map(|&i| points[i]).collect();
            let cell = outline_cell(points, index, &segment.points, fallback_spacing);
            bounded_planes(&own, normal, cell)
        }
        _ => segment.primitive().into_iter().collect(),
    }
}

/// The outline cell of the plane of `members` (ascending indices into `points`):
/// [`OUTLINE_CELLS_PER_SPACING`] of their own median spacing, or of `fallback_spacing`
/// when theirs cannot be measured (scene units).
pub(super) fn outline_cell(
    points: &[Point3<f64>],
    index: &PointIndex,
    members: &[usize],
    fallback_spacing: f64,
) -> f64 {
    OUTLINE_CELLS_PER_SPACING * own_spacing(points, index, members).unwrap_or(fallback_spacing)
}

/// The median nearest-neighbour distance among the points `members` (ascending
/// indices into `points`), over up to [`SPACING_PROBES`] evenly strided members; the
/// neighbours come from `index`, the whole cloud's, filtered to the members: the same
/// answer as a kd-tree of the members' own, without building one over a wall of
/// millions of points for a few hundred probes.
fn own_spacing(points: &[Point3<f64>], index: &PointIndex, members: &[usize]) -> Option<f64> {
    if members.len() < 2 {
        return None;
    }
    strided_median(members.len(), SPACING_PROBES, |k| {
        second_member(points, index, members, &points[members[k]])
    })
}

/// The distance from `q` (a member) to the second nearest member, the first being `q`
/// itself or a duplicate, by (distance, index); `None` when the nearest
/// [`MAX_MEMBER_NEIGHBOURS`] points of the cloud hold fewer than two members.
fn second_member(
    points: &[Point3<f64>],
    index: &PointIndex,
    members: &[usize],
    q: &Point3<f64>,
) -> Option<f64> {
    let mut k = MEMBER_NEIGHBOURS;
    loop {
        let hits = index.nearest_n(q, k.min(points.len()));
        let mut found = hits
            .iter()
            .filter(|(j, _)| members.binary_search(&(*j as usize)).is_ok());
        if let (Some(_), Some(second)) = (found.next(), found.next()) {
            return Some(second.1.sqrt());
        }
        if k >= MAX_MEMBER_NEIGHBOURS || hits.len() < k {
            return None;
        }
        k *= 4;
    }
}

/// The bounded plane of `points` (all on the plane of `normal`), one part per connected
/// part of them. When the parts together are too complex for one plane
/// ([`crate::atlas::MAX_PLANE_VERTICES`]: a large, much fragmented surface), one plane
/// per part instead, so that no surface is lost; none when they give no outline.
pub(super) fn bounded_planes(
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

/// How the loss sees one candidate: the samples of its primitive term, the area each
/// stands for, and whether they cover only part of its surface.
#[derive(Debug, Clone)]
pub struct CandidateSamples {
    /// Surface samples (scene coordinates).
    pub points: Vec<Point3<f64>>,
    /// The weight of each sample's squared distance in the primitive term: the area it
    /// stands for over `s²`, `s` the sample spacing of the fit (1: sampled at `s`).
    pub weight: f64,
    /// The factor on the whole primitive term: [`sparse_surface_scale`] for a surface
    /// sparser than the scan, 1 otherwise.
    pub sparse_scale: f64,
    /// Whether the samples cover only part of the surface (a tube seen from one side):
    /// the candidate is then judged by them in the point term too.
    pub partial: bool,
    /// The lattice of a partial tube's samples, for its nearest-sample queries.
    pub tube: Option<TubeLattice>,
}

/// The samples by which a candidate is judged, about `spacing` apart: all of a plane's
/// or a sphere's; of a cylinder, those in the angular sectors around its axis where its
/// segment's points (`segment` indices into `points`) lie, with one sector of margin
/// ([`TUBE_SECTORS`]). Never empty for a valid primitive.
///
/// A plane or sphere that would have more than `max_samples` samples is sampled more
/// coarsely, at `s' = spacing √(planned / max_samples)`, and each sample weighted by
/// `(s' / spacing)²`: the same area integral of squared distances (the primitive term,
/// thesis eq. 6.1) estimated from `max_samples` samples instead of millions. Its point
/// term uses the exact surface, so only the estimate's variance changes.
pub fn judged_samples(
    primitive: &Primitive,
    segment: &[usize],
    points: &[Point3<f64>],
    spacing: f64,
    max_samples: f64,
) -> CandidateSamples {
    let fine = primitive.area() / (spacing * spacing);
    let own = if planned_samples(primitive, spacing, max_samples) < fine {
        spacing * (fine / max_samples).sqrt()
    } else {
        spacing
    };
    let (points, partial, tube) = supported_samples(primitive, segment, points, own);
    CandidateSamples {
        points,
        weight: (own / spacing).powi(2),
        sparse_scale: 1.0,
        partial,
        tube,
    }
}

/// The factor on the primitive term of a candidate whose segment's points (`segment`,
/// ascending indices into `points`, indexed by `index`) lie farther apart than the scan's
/// median spacing `spacing`: `(spacing / s_seg)⁴` where their own median spacing `s_seg`
/// ([`own_spacing`]) is larger, else 1.
///
/// The primitive term samples every candidate at the scan's spacing and charges each
/// sample its squared distance to the nearest point (about `(s/2)²` on a surface sampled
/// at `s`). A surface sampled `k` times more sparsely is, up to scale, the same surface:
/// it has `k²` times the samples per point and each distance is `k` times longer, so it
/// is charged `k⁴` times what its points can save, and a floor at 3 cm under a pipe at
/// 1.2 cm is dropped whole. Scaled back, a hole is charged by its size in the surface's
/// own spacings.
pub fn sparse_surface_scale(
    points: &[Point3<f64>],
    index: &PointIndex,
    segment: &[usize],
    spacing: f64,
) -> f64 {
    match own_spacing(points, index, segment) {
        Some(own) if own > spacing && spacing > 0.0 => (spacing / own).powi(4),
        _ => 1.0,
    }
}

/// About how many samples [`judged_samples`] gives `primitive` (its area over the
/// spacing squared, at most `max_samples` for a plane or a sphere).
pub fn planned_samples(primitive: &Primitive, spacing: f64, max_samples: f64) -> f64 {
    let fine = primitive.area() / (spacing * spacing);
    match primitive.shape {
        Shape::Cylinder { .. } => fine,
        _ => fine.min(max_samples),
    }
}

/// [`judged_samples`] at `spacing` without coarsening, whether they are a part of the
/// surface's, and for such a tube the lattice of its kept samples.
fn supported_samples(
    primitive: &Primitive,
    segment: &[usize],
    points: &[Point3<f64>],
    spacing: f64,
) -> (Vec<Point3<f64>>, bool, Option<TubeLattice>) {
    let local = primitive.shape.sample_surface(spacing);
    let keep = match primitive.shape {
        Shape::Cylinder { .. } => Some(in_occupied_sectors(primitive, segment, points, &local)),
        _ => None,
    };
    let to_scene = |p: &Point3<f64>| primitive.pose.to_scene(p);
    match keep {
        Some(keep) if keep.contains(&true) && keep.contains(&false) => {
            let kept = local.iter().zip(&keep).filter(|(_, k)| **k);
            let kept = kept.map(|(p, _)| to_scene(p)).collect();
            // Every ring has the first one's angles; the lattice checks it.
            let ring = local.iter().take_while(|p| p.z == local[0].z).count();
            let lattice = TubeLattice::new(primitive.pose, &local, &keep[..ring]);
            (kept, true, lattice)
        }
        _ => (local.iter().map(to_scene).collect(), false, None),
    }
}

/// Per local sample of a cylinder, whether it lies in one of the angular sectors (or
/// next to one, [`TUBE_SECTORS`]) that hold its segment's points.
fn in_occupied_sectors(
    primitive: &Primitive,
    segment: &[usize],
    points: &[Point3<f64>],
    local: &[Point3<f64>],
) -> Vec<bool> {
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
    local.iter().map(|p| near(sector(p))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_surface_twice_as_sparse_as_the_scan_is_charged_a_sixteenth() {
        // A 1 cm grid (the scan's spacing) and, apart from it, a 2 cm grid.
        let grid = |origin: f64, step: f64, n: usize| {
            (0..n * n).map(move |k| {
                Point3::new(origin + step * (k / n) as f64, step * (k % n) as f64, 0.0)
            })
        };
        let mut points: Vec<Point3<f64>> = grid(0.0, 0.01, 50).collect();
        let dense: Vec<usize> = (0..points.len()).collect();
        points.extend(grid(1.0, 0.02, 20));
        let sparse: Vec<usize> = (dense.len()..points.len()).collect();
        let index = PointIndex::new(&points);
        assert_eq!(sparse_surface_scale(&points, &index, &dense, 0.01), 1.0);
        let scale = sparse_surface_scale(&points, &index, &sparse, 0.01);
        assert!((scale - 1.0 / 16.0).abs() < 1e-6, "{scale}");
    }

    #[test]
    fn own_spacing_through_the_cloud_index_is_the_members_own_tree_median() {
        // Two interleaved grids: a coarse one (the members) and a fine one between
        // them, whose points are nearer than any other member.
        let mut points = Vec::new();
        let mut members = Vec::new();
        for i in 0..60 {
            for j in 0..40 {
                let (x, y) = (
                    i as f64 * 0.1,
                    j as f64 * 0.1 + 0.003 * ((i * 7 + j) % 5) as f64,
                );
                members.push(points.len());
                points.push(Point3::new(x, y, 0.0));
                points.push(Point3::new(x + 0.031, y + 0.017, 0.001));
                points.push(Point3::new(x + 0.052, y + 0.049, -0.001));
            }
        }
        let index = PointIndex::new(&points);
        let own: Vec<Point3<f64>> = members.iter().map(|&i| points[i]).collect();
        let expected = PointIndex::new(&own).median_spacing(&own, SPACING_PROBES);
        assert_eq!(own_spacing(&points, &index, &members), expected);
        assert!(expected.unwrap() > 0.09, "{expected:?}");
        assert_eq!(own_spacing(&points, &index, &members[..1]), None);
    }

    /// A tube seen from one side keeps the samples of its occupied sectors, as a lattice
    /// whose nearest-sample answers are those of a search over the kept samples; a tube
    /// seen all round keeps every sample and needs no lattice.
    #[test]
    fn a_tube_seen_from_one_side_is_judged_by_a_lattice_of_its_kept_samples() {
        use nalgebra::{UnitQuaternion, Vector3};
        let pose = crate::Pose::new(
            UnitQuaternion::from_euler_angles(0.4, 0.2, -0.7),
            Vector3::new(1.0, 2.0, 0.5),
        );
        let tube = Primitive::new(
            Shape::Cylinder {
                length: 0.3,
                radius: 0.05,
            },
            pose,
        );
        let around = |from: f64, to: f64| -> Vec<Point3<f64>> {
            (0..400)
                .map(|k| {
                    let t = from + (to - from) * (k % 20) as f64 / 20.0;
                    let z = 0.3 * ((k / 20) as f64 / 20.0 - 0.5);
                    pose.to_scene(&Point3::new(0.05 * t.cos(), 0.05 * t.sin(), z))
                })
                .collect()
        };
        let front = around(0.0, 1.5);
        let segment: Vec<usize> = (0..front.len()).collect();
        let judged = judged_samples(&tube, &segment, &front, 0.004, 1e6);
        assert!(judged.partial);
        let lattice = judged
            .tube
            .as_ref()
            .expect("a lattice for the partial tube");
        let all = tube.shape.sample_surface(0.004).len();
        assert!(
            judged.points.len() < all / 2,
            "{} of {all}",
            judged.points.len()
        );
        for y in front.iter().step_by(7).chain(&around(3.0, 6.0)) {
            let y = y + Vector3::new(0.01, -0.02, 0.03);
            let brute = judged
                .points
                .iter()
                .map(|q| (q - y).norm_squared())
                .fold(f64::INFINITY, f64::min);
            let got = lattice.nearest(&judged.points, &y).1;
            assert!(
                (got - brute).abs() <= 1e-12 * brute.max(1e-12),
                "{got} vs {brute}"
            );
        }
        let whole = judged_samples(&tube, &segment, &around(0.0, 6.3), 0.004, 1e6);
        assert!(!whole.partial && whole.tube.is_none());
        assert_eq!(whole.points.len(), all);
    }
}
