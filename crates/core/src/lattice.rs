//! The candidate set G = types × orientations × translation grid (thesis §3.2), pruned by
//! an occupancy prior.
//!
//! Every candidate of one shape shares a single [`Template`]: the shape's surface samples
//! and a KD-tree over them **in the local frame** (thesis §6.2 footnote). A query point is
//! mapped into a candidate's local frame instead of building a tree per candidate.

use std::collections::HashSet;

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use crate::atlas::{Shape, ShapeKind};
use crate::chamfer::CandidateGeometry;
use crate::error::{Remedy, Unit};
use crate::spatial::PointIndex;
use crate::{Error, PointCloud, Pose, Primitive, Result, check};

/// What the lattice is made of. All lengths in scene units.
#[derive(Debug, Clone)]
pub struct LatticeSpec {
    /// The primitive types with their sizes; one template each.
    pub shapes: Vec<Shape>,
    /// Translation step of the grid.
    pub spacing: f64,
    /// A point of the grid (translations are `origin + frame · spacing · (i, j, k)`).
    pub origin: Point3<f64>,
    /// Rotation of the lattice frame relative to the scene axes (identity = axis-aligned).
    pub frame: UnitQuaternion<f64>,
    /// Spacing of each candidate's surface samples σ_i.
    pub sample_spacing: f64,
}

impl LatticeSpec {
    /// Checks sizes and spacings.
    pub fn validate(&self) -> Result<()> {
        if self.shapes.is_empty() {
            return Err(Error::Missing {
                what: "at least one primitive type".into(),
                needed_by: "the lattice",
            });
        }
        for s in &self.shapes {
            s.validate()?;
        }
        check::positive("spacing", self.spacing)?;
        check::positive("sample_spacing", self.sample_spacing)?;
        check::finite("origin", self.origin.coords.as_slice())
    }
}

/// The orientation set of a type, in the lattice frame: the distinct axis-aligned
/// placements of the shape (symmetric duplicates removed).
///
/// - square, disk: normal along z, x or y (3);
/// - cylinder: axis along z, x or y (3);
/// - elbow: plane normal along z, x or y, times the 4 quadrants (12);
/// - sphere, mesh: the identity (1).
pub fn orientations(kind: ShapeKind) -> Vec<UnitQuaternion<f64>> {
    use std::f64::consts::FRAC_PI_2;
    let axes = [
        UnitQuaternion::identity(), // local z → z
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), FRAC_PI_2), // local z → x
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -FRAC_PI_2), // local z → y
    ];
    match kind {
        ShapeKind::Square | ShapeKind::Disk | ShapeKind::Cylinder => axes.to_vec(),
        ShapeKind::Elbow => axes
            .iter()
            .flat_map(|a| {
                (0..4).map(move |q| {
                    a * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), q as f64 * FRAC_PI_2)
                })
            })
            .collect(),
        ShapeKind::Sphere | ShapeKind::Mesh => vec![UnitQuaternion::identity()],
    }
}

/// One shape's canonical samples and their KD-tree, in the shape's local frame.
#[derive(Debug)]
pub struct Template {
    /// The shape.
    pub shape: Shape,
    /// Local-frame surface samples.
    pub samples: Vec<Point3<f64>>,
    /// KD-tree over `samples`.
    pub index: PointIndex,
    /// Bounding radius of the samples about the local origin.
    pub radius: f64,
    /// Bounding radius of the samples and the continuous surface together.
    pub surface_radius: f64,
}

impl Template {
    /// Samples `shape` at `sample_spacing` and indexes the samples.
    pub fn new(shape: Shape, sample_spacing: f64) -> Self {
        let samples = shape.sample_surface(sample_spacing);
        let index = PointIndex::new(&samples);
        let radius = samples.iter().map(|p| p.coords.norm()).fold(0.0, f64::max);
        let surface_radius = radius.max(shape.bounding_radius());
        Template {
            shape,
            samples,
            index,
            radius,
            surface_radius,
        }
    }
}

/// A finite set of candidate primitives sharing templates: the thesis's G.
#[derive(Debug)]
pub struct CandidateSet {
    /// One template per shape.
    pub templates: Vec<Template>,
    /// Template of each candidate.
    pub template_of: Vec<u32>,
    /// Pose of each candidate (scale 1 on a lattice).
    pub poses: Vec<Pose>,
}

impl CandidateSet {
    /// A set from explicit `(template, pose)` pairs.
    pub fn from_parts(
        templates: Vec<Template>,
        template_of: Vec<u32>,
        poses: Vec<Pose>,
    ) -> Result<Self> {
        check::same_len("template ids", template_of.len(), "poses", poses.len())?;
        if let Some(k) = template_of
            .iter()
            .position(|t| *t as usize >= templates.len())
        {
            return Err(Error::IndexOutOfRange {
                what: format!("template_of[{k}]"),
                index: template_of[k] as usize,
                item: "template",
                count: templates.len(),
            });
        }
        Ok(CandidateSet {
            templates,
            template_of,
            poses,
        })
    }

    /// A set holding exactly `primitives` (one template per distinct shape, samples at
    /// `sample_spacing`), e.g. to score a ground truth with the fitter's loss.
    pub fn from_primitives(primitives: &[Primitive], sample_spacing: f64) -> Result<Self> {
        let mut templates: Vec<Template> = Vec::new();
        let mut template_of = Vec::with_capacity(primitives.len());
        for p in primitives {
            p.shape.validate()?;
            let same = |t: &Template| {
                t.shape.sizes_json() == p.shape.sizes_json() && t.shape.kind() == p.shape.kind()
            };
            let t = match templates.iter().position(same) {
                Some(t) => t,
                None => {
                    templates.push(Template::new(p.shape.clone(), sample_spacing));
                    templates.len() - 1
                }
            };
            template_of.push(t as u32);
        }
        let poses = primitives.iter().map(|p| p.pose).collect();
        Self::from_parts(templates, template_of, poses)
    }

    /// Builds the lattice of `spec` around `cloud`, keeping a candidate only when input
    /// points occupy a lattice cell within its reach (its bounding radius plus half a cell
    /// diagonal) — the occupancy prior of thesis §6.
    pub fn build(spec: &LatticeSpec, cloud: &PointCloud) -> Result<Self> {
        spec.validate()?;
        if cloud.is_empty() {
            return Err(Error::EmptyCloud);
        }
        check_template_sizes(spec)?;
        check_grid_extent(spec, cloud)?;
        let templates: Vec<Template> = spec
            .shapes
            .par_iter()
            .map(|s| Template::new(s.clone(), spec.sample_spacing))
            .collect();
        let occupied = occupied_nodes(spec, &cloud.points);
        let mut template_of = Vec::new();
        let mut poses = Vec::new();
        for (t, template) in templates.iter().enumerate() {
            let reach = template.radius / spec.spacing + 0.5 * 3f64.sqrt();
            let rotations = orientations(template.shape.kind());
            check_dilation(spec, &template.shape, &occupied, reach, rotations.len())?;
            let nodes = dilate(&occupied, reach);
            for node in &nodes {
                let translation = node_position(spec, node).coords;
                for r in &rotations {
                    template_of.push(t as u32);
                    poses.push(Pose::new(spec.frame * r, translation));
                }
            }
        }
        Ok(CandidateSet {
            templates,
            template_of,
            poses,
        })
    }

    /// Number of candidates N.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// True when there are no candidates.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// The template of candidate `i`.
    #[inline]
    pub fn template(&self, i: usize) -> &Template {
        &self.templates[self.template_of[i] as usize]
    }

    /// Candidate `i` as a [`Primitive`].
    pub fn primitive(&self, i: usize) -> Primitive {
        Primitive::new(self.template(i).shape.clone(), self.poses[i])
    }

    /// For each candidate: does one of its surface samples lie within `distance` of an
    /// input point? Conservative (cells of size `distance`, so a few candidates up to
    /// `2√3 · distance` away also pass); never drops a candidate that is within `distance`.
    ///
    /// A candidate whose surface has no input point within the cap distance explains no
    /// point better than `d_cap` and adds a positive primitive term, so it can only make
    /// the loss worse: the fitter drops such candidates before building coefficients.
    pub fn near_data(&self, cloud: &[Point3<f64>], distance: f64) -> Vec<bool> {
        if !(distance.is_finite() && distance > 0.0) {
            return vec![true; self.len()];
        }
        let cell = |p: &Point3<f64>| (p.coords / distance).map(|c| c.floor() as i64);
        let occupied: HashSet<nalgebra::Vector3<i64>> = cloud.iter().map(cell).collect();
        let near: HashSet<nalgebra::Vector3<i64>> = occupied
            .iter()
            .flat_map(|c| {
                (-1..=1).flat_map(move |i| {
                    (-1..=1).flat_map(move |j| {
                        (-1..=1).map(move |k| c + nalgebra::Vector3::new(i, j, k))
                    })
                })
            })
            .collect();
        (0..self.len())
            .into_par_iter()
            .map(|i| {
                let pose = &self.poses[i];
                self.template(i)
                    .samples
                    .iter()
                    .any(|x| near.contains(&cell(&pose.to_scene(x))))
            })
            .collect()
    }

    /// Keeps only the candidates for which `keep(i)` is true (order preserved).
    pub fn retain(&mut self, keep: &[bool]) {
        let mut k = keep.iter();
        self.template_of.retain(|_| *k.next().unwrap_or(&false));
        let mut k = keep.iter();
        self.poses.retain(|_| *k.next().unwrap_or(&false));
    }
}

impl CandidateGeometry for CandidateSet {
    fn len(&self) -> usize {
        self.poses.len()
    }
    fn sample_count(&self, i: usize) -> usize {
        self.template(i).samples.len()
    }
    fn scene_samples(&self, i: usize, out: &mut Vec<Point3<f64>>) {
        let pose = &self.poses[i];
        out.clear();
        out.extend(self.template(i).samples.iter().map(|p| pose.to_scene(p)));
    }
    fn bounding_ball(&self, i: usize) -> (Point3<f64>, f64) {
        let pose = &self.poses[i];
        (
            Point3::from(pose.translation),
            self.template(i).surface_radius * pose.scale,
        )
    }
    #[inline]
    fn nearest_sample(&self, i: usize, y: &Point3<f64>) -> (u32, f64) {
        let pose = &self.poses[i];
        let local = pose.to_local(y);
        let (k, d2) = self
            .template(i)
            .index
            .nearest(&local)
            .unwrap_or((0, f64::INFINITY));
        (k, d2 * pose.scale * pose.scale)
    }
    #[inline]
    fn surface_distance(&self, i: usize, y: &Point3<f64>) -> f64 {
        let pose = &self.poses[i];
        let d = self.template(i).shape.distance(&pose.to_local(y)) * pose.scale;
        d * d
    }
    fn nearest_samples(
        &self,
        i: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    ) {
        let pose = &self.poses[i];
        let local = pose.to_local(y);
        let s2 = pose.scale * pose.scale;
        let template = self.template(i);
        out.clear();
        match k {
            Some(k) if k < template.samples.len() => {
                out.extend(
                    template
                        .index
                        .nearest_n(&local, k)
                        .into_iter()
                        .map(|(j, d)| (j, d * s2)),
                );
            }
            _ => {
                out.extend(
                    template
                        .samples
                        .iter()
                        .enumerate()
                        .map(|(j, x)| (j as u32, (x - local).norm_squared() * s2)),
                );
                out.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            }
        }
    }
}

type Node = [i32; 3];

/// The most surface samples one template may have.
const MAX_TEMPLATE_SAMPLES: f64 = 1e7;
/// The most lattice cells from the origin to a point along any axis (grid coordinates
/// are `i32`, and dilation offsets are added to them).
const MAX_CELLS_PER_AXIS: f64 = (1u32 << 24) as f64;
/// The most candidates a lattice may have (about 80 bytes each before any coefficient).
const MAX_CANDIDATES: f64 = (1u64 << 27) as f64;

/// Fails (instead of exhausting memory) when a template would have absurdly many
/// samples: a sample spacing far finer than the shape.
fn check_template_sizes(spec: &LatticeSpec) -> Result<()> {
    for s in &spec.shapes {
        let n = s.area() / (spec.sample_spacing * spec.sample_spacing);
        if n.is_nan() || n > MAX_TEMPLATE_SAMPLES {
            return Err(Error::OverLimit {
                what: format!(
                    "a {} of area {:.3e} sampled every {}",
                    s.kind().name(),
                    s.area(),
                    spec.sample_spacing
                ),
                need: n,
                limit: MAX_TEMPLATE_SAMPLES,
                unit: Unit::Count("samples"),
                remedies: vec![Remedy::Raise("sample_spacing")],
            });
        }
    }
    Ok(())
}

/// Fails when the cloud spans more lattice cells than grid coordinates can hold: a
/// spacing absurdly fine for the cloud's extent (or a cloud far from the origin).
fn check_grid_extent(spec: &LatticeSpec, cloud: &PointCloud) -> Result<()> {
    let far = cloud
        .points
        .iter()
        .map(|p| (p - spec.origin).norm())
        .fold(0.0, f64::max);
    let cells = far / spec.spacing;
    if cells.is_nan() || cells > MAX_CELLS_PER_AXIS {
        return Err(Error::OverLimit {
            what: format!("a lattice spacing of {}", spec.spacing),
            need: cells,
            limit: MAX_CELLS_PER_AXIS,
            unit: Unit::Count("cells between the lattice origin and the cloud"),
            remedies: vec![Remedy::Raise("spacing"), Remedy::Nearer("origin")],
        });
    }
    Ok(())
}

/// Fails when dilating the `occupied` nodes by `reach` cells could give more than
/// [`MAX_CANDIDATES`] candidates of `shape` (a spacing far finer than the shape).
fn check_dilation(
    spec: &LatticeSpec,
    shape: &Shape,
    occupied: &[Node],
    reach: f64,
    rotations: usize,
) -> Result<()> {
    let k = reach.floor();
    let ball = (2.0 * k + 1.0).powi(3);
    // Nodes: at most every offset of every occupied node, and at most every cell of
    // the occupied bounding box grown by `k`.
    let mut boxed = 1.0;
    for axis in 0..3 {
        let lo = occupied.iter().map(|n| n[axis]).min().unwrap_or(0);
        let hi = occupied.iter().map(|n| n[axis]).max().unwrap_or(0);
        boxed *= f64::from(hi) - f64::from(lo) + 1.0 + 2.0 * k;
    }
    let bound = (occupied.len() as f64 * ball).min(boxed) * rotations as f64;
    if !(ball <= MAX_CANDIDATES && bound <= MAX_CANDIDATES) {
        return Err(Error::OverLimit {
            what: format!(
                "a {} of radius {:.3e} on a lattice of spacing {}",
                shape.kind().name(),
                shape.bounding_radius(),
                spec.spacing
            ),
            need: bound.max(ball),
            limit: MAX_CANDIDATES,
            unit: Unit::Count("candidates"),
            remedies: vec![Remedy::Raise("spacing")],
        });
    }
    Ok(())
}

/// Grid coordinates of the lattice node nearest to `p`.
fn node_of(spec: &LatticeSpec, p: &Point3<f64>) -> Node {
    let local = spec.frame.inverse_transform_vector(&(p - spec.origin)) / spec.spacing;
    [
        local.x.round() as i32,
        local.y.round() as i32,
        local.z.round() as i32,
    ]
}

/// Scene position of a lattice node.
fn node_position(spec: &LatticeSpec, n: &Node) -> Point3<f64> {
    let v = Vector3::new(n[0] as f64, n[1] as f64, n[2] as f64) * spec.spacing;
    spec.origin + spec.frame * v
}

/// The set of nodes whose cell holds at least one input point, sorted for determinism.
fn occupied_nodes(spec: &LatticeSpec, points: &[Point3<f64>]) -> Vec<Node> {
    let mut nodes: Vec<Node> = points.par_iter().map(|p| node_of(spec, p)).collect();
    nodes.par_sort_unstable();
    nodes.dedup();
    nodes
}

/// Every node within Euclidean grid distance `reach` (in cells) of an occupied node, sorted.
fn dilate(occupied: &[Node], reach: f64) -> Vec<Node> {
    let k = reach.floor() as i32;
    let offsets: Vec<Node> = (-k..=k)
        .flat_map(|i| (-k..=k).flat_map(move |j| (-k..=k).map(move |l| [i, j, l])))
        .filter(|o| ((o[0] * o[0] + o[1] * o[1] + o[2] * o[2]) as f64) <= reach * reach)
        .collect();
    let set: HashSet<Node> = occupied
        .iter()
        .flat_map(|n| {
            offsets
                .iter()
                .map(move |o| [n[0] + o[0], n[1] + o[1], n[2] + o[2]])
        })
        .collect();
    let mut nodes: Vec<Node> = set.into_iter().collect();
    nodes.sort_unstable();
    nodes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> LatticeSpec {
        LatticeSpec {
            shapes: vec![Shape::Square { side: 1.0 }],
            spacing: 0.5,
            origin: Point3::origin(),
            frame: UnitQuaternion::identity(),
            sample_spacing: 0.1,
        }
    }

    #[test]
    fn orientation_counts() {
        assert_eq!(orientations(ShapeKind::Square).len(), 3);
        assert_eq!(orientations(ShapeKind::Elbow).len(), 12);
        assert_eq!(orientations(ShapeKind::Sphere).len(), 1);
        // Square normals cover the three axes.
        let normals: Vec<Vector3<f64>> = orientations(ShapeKind::Square)
            .iter()
            .map(|r| r * Vector3::z())
            .collect();
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            assert!(normals.iter().any(|n| (n - axis).norm() < 1e-12));
        }
    }

    #[test]
    fn elbow_orientations_are_distinct() {
        let elbow = Shape::Elbow {
            bend: 0.5,
            radius: 0.1,
        };
        let probe = [Point3::new(0.5, 0.0, 0.1), Point3::new(0.3, 0.4, 0.0)];
        let images: Vec<Vec<Point3<f64>>> = orientations(elbow.kind())
            .iter()
            .map(|r| probe.iter().map(|p| r * p).collect())
            .collect();
        for a in 0..images.len() {
            for b in a + 1..images.len() {
                let same = images[a]
                    .iter()
                    .zip(&images[b])
                    .all(|(p, q)| (p - q).norm() < 1e-9);
                assert!(!same, "orientations {a} and {b} coincide");
            }
        }
    }

    #[test]
    fn occupancy_keeps_only_candidates_near_points() {
        let cloud = PointCloud::from_points(vec![Point3::new(0.1, 0.1, 0.0)]);
        let set = CandidateSet::build(&spec(), &cloud).unwrap();
        assert!(!set.is_empty());
        let reach = set.templates[0].radius + 0.5 * 0.5 * 3f64.sqrt();
        for p in &set.poses {
            // Node of the point is the origin; every kept centre is within reach of it.
            assert!(p.translation.norm() <= reach + 1e-9);
            // Translations lie on the grid.
            for c in p.translation.iter() {
                assert!(((c / 0.5).round() * 0.5 - c).abs() < 1e-12);
            }
        }
        // A far-away node is never a candidate.
        assert!(set.poses.iter().all(|p| p.translation.norm() < 2.0));
    }

    /// The point term's β candidates per point equal a brute-force ranking of every
    /// candidate, with surface or sample distances, for squares, cylinders and elbows
    /// (whose surfaces reach beyond their samples' bounding radius).
    #[test]
    fn beta_rows_match_a_brute_force_ranking() {
        use crate::chamfer::{ChamferOptions, Coefficients};
        use crate::progress::Silent;
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let points: Vec<Point3<f64>> = (0..300)
            .map(|_| {
                Point3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-0.3..0.3),
                )
            })
            .collect();
        let cloud = PointCloud::from_points(points.clone());
        let shapes = vec![
            Shape::Square { side: 1.0 },
            Shape::Cylinder {
                length: 1.0,
                radius: 0.1,
            },
            Shape::Elbow {
                bend: 0.5,
                radius: 0.1,
            },
        ];
        let set = CandidateSet::build(&LatticeSpec { shapes, ..spec() }, &cloud).unwrap();
        for surface_distance in [true, false] {
            for beta in [1, 7, 40] {
                let o = ChamferOptions {
                    beta: Some(beta),
                    cap: 0.01,
                    surface_distance,
                    ..Default::default()
                };
                let c = Coefficients::build(&points, &set, &o, &Silent).unwrap();
                for (j, y) in points.iter().enumerate() {
                    let mut all: Vec<(f64, u32)> = (0..set.len())
                        .map(|i| {
                            let d = if surface_distance {
                                set.surface_distance(i, y)
                            } else {
                                set.nearest_sample(i, y).1
                            };
                            (d, i as u32)
                        })
                        .collect();
                    all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                    all.truncate(beta);
                    let r = c.row(j);
                    let got: Vec<(f64, u32)> = c.dist[r.clone()]
                        .iter()
                        .copied()
                        .zip(c.cand[r].iter().copied())
                        .collect();
                    assert_eq!(
                        got, all,
                        "point {j}, β = {beta}, surface {surface_distance}"
                    );
                }
            }
        }
    }

    #[test]
    fn nearest_sample_matches_scene_brute_force() {
        let cloud =
            PointCloud::from_points(vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.3, 0.2)]);
        let set = CandidateSet::build(&spec(), &cloud).unwrap();
        let y = Point3::new(0.37, -0.21, 0.13);
        let mut buf = Vec::new();
        for i in 0..set.len() {
            set.scene_samples(i, &mut buf);
            let brute = buf
                .iter()
                .map(|x| (x - y).norm_squared())
                .fold(f64::INFINITY, f64::min);
            let (_, d) = set.nearest_sample(i, &y);
            assert!((d - brute).abs() < 1e-12);
            let mut all = Vec::new();
            set.nearest_samples(i, &y, None, &mut all);
            assert!((all[0].1 - brute).abs() < 1e-12);
            assert_eq!(all.len(), buf.len());
        }
    }

    #[test]
    fn surface_distances_remove_the_reward_for_redundant_copies() {
        use crate::chamfer::{ChamferOptions, Coefficients, Evaluator};
        use crate::progress::Silent;
        // A dense patch on z = 0 and two candidates covering it: the square at the origin
        // and a copy shifted by less than the sample spacing.
        let pts: Vec<Point3<f64>> = (0..20)
            .flat_map(|i| {
                (0..20).map(move |j| {
                    Point3::new(i as f64 * 0.05 - 0.475, j as f64 * 0.05 - 0.475, 0.0)
                })
            })
            .collect();
        let cloud = PointCloud::from_points(pts);
        let template = Template::new(Shape::Square { side: 1.0 }, 0.1);
        let poses = vec![
            Pose::identity(),
            Pose::new(UnitQuaternion::identity(), Vector3::new(0.025, 0.025, 0.0)),
        ];
        let set = CandidateSet::from_parts(vec![template], vec![0, 0], poses).unwrap();
        let loss = |surface_distance: bool, exists: &[bool]| {
            let o = ChamferOptions {
                cap: 0.01,
                surface_distance,
                ..Default::default()
            };
            let c = Coefficients::build(&cloud.points, &set, &o, &Silent).unwrap();
            Evaluator::new(&c).binary_value(exists).point
        };
        // With sample distances the copy lowers the point term (its samples interleave)…
        assert!(loss(false, &[true, true]) < loss(false, &[true, false]) - 1e-6);
        // …with surface distances it explains nothing new.
        assert!((loss(true, &[true, true]) - loss(true, &[true, false])).abs() < 1e-12);
        // And the surface distance is the exact one.
        let y = Point3::new(0.7, 0.2, 0.3);
        let exact = set.primitive(1).distance(&y);
        assert!((set.surface_distance(1, &y) - exact * exact).abs() < 1e-12);
    }

    #[test]
    fn near_data_keeps_every_candidate_within_the_distance() {
        let cloud =
            PointCloud::from_points(vec![Point3::new(0.1, 0.1, 0.0), Point3::new(3.0, 0.2, 0.0)]);
        let set = CandidateSet::build(&spec(), &cloud).unwrap();
        let distance = 0.3;
        let keep = set.near_data(&cloud.points, distance);
        let mut buf = Vec::new();
        for (i, k) in keep.iter().enumerate() {
            set.scene_samples(i, &mut buf);
            let nearest = buf
                .iter()
                .flat_map(|x| cloud.points.iter().map(move |y| (x - y).norm()))
                .fold(f64::INFINITY, f64::min);
            if nearest <= distance {
                assert!(*k, "candidate {i} at {nearest} dropped");
            }
            if nearest > 2.0 * 3f64.sqrt() * distance {
                assert!(!*k, "candidate {i} at {nearest} kept");
            }
        }
        assert!(keep.iter().any(|k| !k), "nothing was far enough to drop");
    }

    #[test]
    fn bad_specs_are_errors() {
        let cloud = PointCloud::from_points(vec![Point3::origin()]);
        let mut s = spec();
        s.spacing = 0.0;
        let e = CandidateSet::build(&s, &cloud).expect_err("zero spacing");
        assert!(
            matches!(&e, Error::OutOfRange { name, .. } if name == "spacing"),
            "{e}"
        );
        let mut s = spec();
        s.shapes = vec![Shape::Square { side: -1.0 }];
        assert!(CandidateSet::build(&s, &cloud).is_err());
        let e = CandidateSet::build(&spec(), &PointCloud::default()).expect_err("empty");
        assert!(matches!(e, Error::EmptyCloud), "{e}");
    }
}
