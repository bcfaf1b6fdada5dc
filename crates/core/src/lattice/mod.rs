//! The candidate set G = types × orientations × translation grid (thesis §3.2), pruned by
//! an occupancy prior.
//!
//! Every candidate of one shape shares a single [`Template`]: the shape's surface samples
//! and a KD-tree over them **in the local frame** (thesis §6.2 footnote). A query point is
//! mapped into a candidate's local frame instead of building a tree per candidate.

use std::collections::HashSet;

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use crate::atlas::Shape;
use crate::chamfer::CandidateGeometry;
use crate::error::{Remedy, Unit};
use crate::{Error, PointCloud, Pose, Primitive, Result, check};

mod orientation;
mod template;
#[cfg(test)]
mod tests;

#[cfg(test)]
impl CandidateSet {
    /// Tests' lattice: 1 m squares on a 0.5 m axis-aligned grid through the origin,
    /// samples 0.1 m apart, near the points of `cloud`.
    pub(crate) fn unit_squares(cloud: &PointCloud) -> CandidateSet {
        let spec = LatticeSpec {
            shapes: vec![Shape::Square { side: 1.0 }],
            spacing: 0.5,
            origin: Point3::origin(),
            frame: UnitQuaternion::identity(),
            sample_spacing: 0.1,
        };
        CandidateSet::build(&spec, cloud).expect("a valid lattice near the cloud")
    }
}

pub use orientation::orientations;
pub use template::Template;

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
    /// `sample_spacing`), e.g. to score a ground truth with the fitter's loss. Planes
    /// share a template only when their polygons are equal.
    pub fn from_primitives(primitives: &[Primitive], sample_spacing: f64) -> Result<Self> {
        let mut shapes: Vec<&Shape> = Vec::new();
        let mut template_of = Vec::with_capacity(primitives.len());
        for p in primitives {
            p.shape.validate()?;
            let same = |t: &&Shape| match (t, &p.shape) {
                (Shape::Plane(a), Shape::Plane(b)) => a == b,
                _ => t.sizes_json() == p.shape.sizes_json() && t.kind() == p.shape.kind(),
            };
            let t = match shapes.iter().position(same) {
                Some(t) => t,
                None => {
                    shapes.push(&p.shape);
                    shapes.len() - 1
                }
            };
            template_of.push(t as u32);
        }
        // Sampling and indexing each distinct shape is the work: in parallel.
        let templates: Vec<Template> = shapes
            .par_iter()
            .map(|&shape| Template::new(shape.clone(), sample_spacing))
            .collect();
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
/// The most (occupied node, offset) pairs the dilation may enumerate: a few seconds of
/// hashing. Each occupied node is dilated by the ball of lattice offsets within a
/// candidate's reach, whose size grows with (size / spacing)³.
const MAX_DILATION_STEPS: f64 = 2e8;

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
/// [`MAX_CANDIDATES`] candidates of `shape`, or would visit more than
/// [`MAX_DILATION_STEPS`] offsets (a spacing far finer than the shape).
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
    let steps = occupied.len() as f64 * ball;
    let bound = steps.min(boxed) * rotations as f64;
    let what = format!(
        "a {} of radius {:.3e} on a lattice of spacing {}",
        shape.kind().name(),
        shape.bounding_radius(),
        spec.spacing
    );
    let over = |need: f64, limit: f64, unit: &'static str| Error::OverLimit {
        what: what.clone(),
        need,
        limit,
        unit: Unit::Count(unit),
        remedies: vec![Remedy::Raise("spacing")],
    };
    if !(ball <= MAX_CANDIDATES && bound <= MAX_CANDIDATES) {
        return Err(over(bound.max(ball), MAX_CANDIDATES, "candidates"));
    }
    if steps > MAX_DILATION_STEPS {
        return Err(over(steps, MAX_DILATION_STEPS, "lattice offsets to visit"));
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
