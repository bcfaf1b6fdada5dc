//! Types and helpers shared by the scene generators: [`Scene`], [`LatticeHint`], the
//! noise model, area-uniform random sampling of shapes, lattice rotations.

use std::f64::consts::{FRAC_PI_2, TAU};

use nalgebra::{Matrix3, Point3, Rotation3, Unit, UnitQuaternion, Vector3};
use rand::{Rng, RngExt};
use rand_distr::StandardNormal;

use crate::atlas::{Shape, TriMesh, elbow_rotation_between};
use crate::check::non_negative;
use crate::error::Remedy;
use crate::{Error, PointCloud, Pose, Primitive, Result};

/// Bytes per point of a synthetic scene, for the memory check of [`check_scene_points`]:
/// the point (24) with room for a normal, a sensor origin or a label, and the growth of
/// the vectors that collect them.
const BYTES_PER_SCENE_POINT: f64 = 96.0;

/// Refuses, before any point is drawn, a scene of `count` points (which may be NaN or
/// infinite when computed from extreme options) that would not fit in the default
/// memory budget; `remedy` is the option that makes it smaller.
pub(crate) fn check_scene_points(what: &str, count: f64, remedy: &'static str) -> Result<usize> {
    let limit = (crate::budget::default_memory_budget() as f64 / BYTES_PER_SCENE_POINT).floor();
    crate::budget::check_count(what, count, limit, "points", vec![Remedy::Lower(remedy)])?;
    Ok(count as usize)
}

/// A synthetic scene with its ground truth.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The sampled (noisy, possibly misaligned) points.
    pub cloud: PointCloud,
    /// The true primitives, in the same (possibly misaligned) frame as the cloud.
    pub truth: Vec<Primitive>,
    /// The lattice the truth was built on (before misalignment).
    pub lattice: LatticeHint,
    /// The rigid misalignment applied to cloud and truth (identity when none):
    /// undoing it ([`Scene::aligned_truth`]) puts the truth back on [`Scene::lattice`].
    pub misalignment: Pose,
}

impl Scene {
    /// The truth with the misalignment undone: these primitives lie on [`Scene::lattice`].
    pub fn aligned_truth(&self) -> Vec<Primitive> {
        let inv = inverse_rigid(&self.misalignment);
        self.truth
            .iter()
            .map(|p| Primitive::new(p.shape.clone(), inv.compose(&p.pose)))
            .collect()
    }
}

/// Which candidate lattice the truth lives on: translations `origin + spacing·(i,j,k)`,
/// axis-aligned orientations, and the shapes (types with sizes) used.
#[derive(Debug, Clone)]
pub struct LatticeHint {
    /// Translation step (scene units).
    pub spacing: f64,
    /// Lattice origin.
    pub origin: Point3<f64>,
    /// The shapes (kind + sizes) that occur in the truth, one entry per distinct shape.
    pub shapes: Vec<Shape>,
}

impl LatticeHint {
    /// True when `p` is a lattice candidate up to `tol` (scene units): its translation is
    /// `origin + spacing·integers`, its rotation maps the coordinate axes onto signed
    /// coordinate axes, its scale is 1 and its shape is one of [`LatticeHint::shapes`]
    /// (sizes equal within 1e-9 relative).
    pub fn contains(&self, p: &Primitive, tol: f64) -> bool {
        let grid = (p.pose.translation - self.origin.coords) / self.spacing;
        let on_grid = grid
            .iter()
            .all(|g| (g - g.round()).abs() * self.spacing <= tol);
        let m = p.pose.rotation.to_rotation_matrix().into_inner();
        let axis_aligned = m
            .iter()
            .all(|v| v.abs() < 1e-9 || (v.abs() - 1.0).abs() < 1e-9);
        let shape_known = self.shapes.iter().any(|s| same_shape(s, &p.shape, 1e-9));
        on_grid && axis_aligned && (p.pose.scale - 1.0).abs() < 1e-12 && shape_known
    }
}

/// True when two shapes have the same kind and sizes within `rel` relative
/// (meshes: same source string and the same mesh allocation or equal meshes).
pub(crate) fn same_shape(a: &Shape, b: &Shape, rel: f64) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= rel * x.abs().max(y.abs());
    match (a, b) {
        (Shape::Disk { diameter: x }, Shape::Disk { diameter: y })
        | (Shape::Sphere { diameter: x }, Shape::Sphere { diameter: y })
        | (Shape::Square { side: x }, Shape::Square { side: y }) => close(*x, *y),
        (
            Shape::Cylinder {
                length: l1,
                radius: r1,
            },
            Shape::Cylinder {
                length: l2,
                radius: r2,
            },
        ) => close(*l1, *l2) && close(*r1, *r2),
        (
            Shape::Elbow {
                bend: b1,
                radius: r1,
            },
            Shape::Elbow {
                bend: b2,
                radius: r2,
            },
        ) => close(*b1, *b2) && close(*r1, *r2),
        (Shape::Mesh(m1), Shape::Mesh(m2)) => {
            m1.source == m2.source
                && (std::sync::Arc::ptr_eq(&m1.mesh, &m2.mesh) || m1.mesh == m2.mesh)
        }
        (Shape::Plane(p1), Shape::Plane(p2)) => p1 == p2,
        _ => false,
    }
}

/// How many points to draw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Density {
    /// Expected points per unit area (points / scene unit²); the count is
    /// `round(density × total area)`.
    PerArea(f64),
    /// Exactly this many points in total, spread area-uniformly.
    Total(usize),
}

impl Density {
    /// The number of points for a total area (scene units²).
    pub fn count(&self, area: f64) -> Result<usize> {
        match *self {
            Density::PerArea(d) => {
                non_negative("density", d)?;
                let what = format!("a density of {d} points per unit area over {area}");
                check_scene_points(&what, (d * area).round(), "density")
            }
            Density::Total(n) => check_scene_points("the scene", n as f64, "points"),
        }
    }
}

/// Per-point and per-piece Gaussian noise (standard deviations, scene units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Noise {
    /// σ of the isotropic per-point offset.
    pub jitter: f64,
    /// σ of the isotropic per-piece (per-primitive or per-surface) offset.
    pub drift: f64,
}

impl Noise {
    /// Checks both σ are finite and ≥ 0.
    pub fn validate(&self) -> Result<()> {
        non_negative("jitter", self.jitter)?;
        non_negative("drift", self.drift)
    }
}

/// A random rigid motion applied to cloud and truth (zero by default).
///
/// The translation has a uniformly random direction and a length uniform in
/// `[0, offset × spacing]`; the rotation is about a uniformly random axis through the
/// centroid of the truth centres, by an angle uniform in `[0, angle]`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Misalignment {
    /// Largest translation, as a fraction of the lattice spacing (dimensionless, ≥ 0).
    pub offset: f64,
    /// Largest rotation angle (radians, ≥ 0).
    pub angle: f64,
}

impl Misalignment {
    /// Checks both bounds are finite and ≥ 0.
    pub fn validate(&self) -> Result<()> {
        non_negative("offset", self.offset)?;
        non_negative("angle", self.angle)
    }

    /// Draws the motion (as a [`Pose`]) for a lattice `spacing` and rotation `pivot`.
    /// Draws nothing (and returns the identity) when both bounds are zero.
    pub(crate) fn draw<R: Rng>(&self, rng: &mut R, spacing: f64, pivot: Point3<f64>) -> Pose {
        if self.offset == 0.0 && self.angle == 0.0 {
            return Pose::identity();
        }
        let t = random_unit(rng) * (rng.random::<f64>() * self.offset * spacing);
        let axis = Unit::new_normalize(random_unit(rng));
        let rot = UnitQuaternion::from_axis_angle(&axis, rng.random::<f64>() * self.angle);
        Pose::new(rot, pivot.coords - rot * pivot.coords + t)
    }
}

/// The rotation mapping local z onto the coordinate axis `axis` (0 = x, 1 = y, 2 = z);
/// used for squares/disks (normal) and cylinders (axis). Local x maps onto the next
/// axis cyclically, so the result is a signed permutation.
pub fn axis_rotation(axis: usize) -> UnitQuaternion<f64> {
    let e = |i: usize| Vector3::ith(i % 3, 1.0);
    let (x, y, z) = (e(axis + 1), e(axis + 2), e(axis));
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::from_columns(
        &[x, y, z],
    )))
}

/// The rotation of an elbow whose centre line enters with tangent `d_in` and leaves with
/// tangent `d_out` (both unit coordinate axes, perpendicular). With this rotation and the
/// torus centre at `entry + bend·d_out`, the arc runs from `entry` to
/// `entry + bend·(d_in + d_out)`. The rotation is canonical: the plane normal (image of
/// local z) is a *positive* axis, so equal quarter tori get equal rotations.
pub fn elbow_rotation(d_in: &Vector3<f64>, d_out: &Vector3<f64>) -> Result<UnitQuaternion<f64>> {
    let unit_axis = |v: &Vector3<f64>| {
        (v.norm() - 1.0).abs() < 1e-9 && v.iter().filter(|c| c.abs() > 1e-9).count() == 1
    };
    if !unit_axis(d_in) || !unit_axis(d_out) || d_in.dot(d_out).abs() > 1e-9 {
        return Err(Error::invalid(format!(
            "elbow directions must be perpendicular unit axes, got {d_in:?} and {d_out:?}"
        )));
    }
    // The same quarter torus traversed the other way (entering along −d_out, leaving
    // along −d_in) when that makes the plane normal a positive axis.
    if (-d_out).cross(d_in).sum() < 0.0 {
        Ok(elbow_rotation_between(&-d_out, &-d_in))
    } else {
        Ok(elbow_rotation_between(d_in, d_out))
    }
}

/// One area-uniform random point on `shape`'s surface, in its local frame.
///
/// Meshes pick a face with probability ∝ area (O(faces) per call; generators prepare a
/// table once instead).
pub fn sample_shape_local<R: Rng>(shape: &Shape, rng: &mut R) -> Point3<f64> {
    match shape {
        Shape::Mesh(m) => {
            let cdf = mesh_cdf(&m.mesh);
            sample_mesh(&m.mesh, &cdf, rng)
        }
        Shape::Plane(p) => {
            let cdf = mesh_cdf(p.mesh());
            sample_mesh(p.mesh(), &cdf, rng)
        }
        _ => sample_analytic(shape, rng),
    }
}

/// Area-uniform point on a non-mesh shape (local frame).
fn sample_analytic<R: Rng>(shape: &Shape, rng: &mut R) -> Point3<f64> {
    let u = |rng: &mut R| rng.random::<f64>();
    match *shape {
        Shape::Square { side } => Point3::new((u(rng) - 0.5) * side, (u(rng) - 0.5) * side, 0.0),
        Shape::Disk { diameter } => {
            let (r, t) = (0.5 * diameter * u(rng).sqrt(), TAU * u(rng));
            Point3::new(r * t.cos(), r * t.sin(), 0.0)
        }
        Shape::Cylinder { length, radius } => {
            let t = TAU * u(rng);
            Point3::new(radius * t.cos(), radius * t.sin(), (u(rng) - 0.5) * length)
        }
        Shape::Elbow { bend, radius } => {
            // Area element ∝ (bend + radius·cos ψ): rejection-sample the tube angle ψ.
            let psi = loop {
                let psi = TAU * u(rng);
                if u(rng) * (bend + radius) <= bend + radius * psi.cos() {
                    break psi;
                }
            };
            let phi = FRAC_PI_2 * u(rng);
            let rho = bend + radius * psi.cos();
            Point3::new(rho * phi.cos(), rho * phi.sin(), radius * psi.sin())
        }
        Shape::Sphere { diameter } => Point3::from(random_unit(rng) * (0.5 * diameter)),
        Shape::Mesh(_) | Shape::Plane(_) => {
            unreachable!("meshes and planes are sampled with a prepared table")
        }
    }
}

/// Cumulative face areas of a mesh (last entry = total area).
pub(crate) fn mesh_cdf(mesh: &TriMesh) -> Vec<f64> {
    let mut acc = 0.0;
    mesh.faces
        .iter()
        .map(|f| {
            acc += mesh.triangle_area(f);
            acc
        })
        .collect()
}

/// Area-uniform point on a mesh given its [`mesh_cdf`].
pub(crate) fn sample_mesh<R: Rng>(mesh: &TriMesh, cdf: &[f64], rng: &mut R) -> Point3<f64> {
    let total = cdf.last().copied().unwrap_or(0.0);
    let target = rng.random::<f64>() * total;
    let i = cdf
        .partition_point(|&c| c <= target)
        .min(cdf.len().saturating_sub(1));
    let [a, b, c] = mesh.faces[i].map(|k| mesh.vertices[k as usize]);
    let (mut s, mut t) = (rng.random::<f64>(), rng.random::<f64>());
    if s + t > 1.0 {
        (s, t) = (1.0 - s, 1.0 - t);
    }
    a + (b - a) * s + (c - a) * t
}

/// A uniformly random unit vector.
pub(crate) fn random_unit<R: Rng>(rng: &mut R) -> Vector3<f64> {
    loop {
        let v = Vector3::new(gauss(rng), gauss(rng), gauss(rng));
        let n = v.norm();
        if n > 1e-12 {
            return v / n;
        }
    }
}

/// Samples of `primitives` at `spacing` (scene units), each moved along a random
/// direction by a normal draw of deviation `sigma`, from the RNG seeded with `seed`.
#[cfg(test)]
pub(crate) fn jittered_samples(
    primitives: &[Primitive],
    spacing: f64,
    sigma: f64,
    seed: u64,
) -> Vec<Point3<f64>> {
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (primitives.iter())
        .flat_map(|p| p.sample_surface(spacing))
        .map(|p| p + random_unit(&mut rng) * (sigma * gauss(&mut rng)))
        .collect()
}

/// A standard normal draw.
pub(crate) fn gauss<R: Rng>(rng: &mut R) -> f64 {
    rng.sample(StandardNormal)
}

/// A surface piece points are drawn from: a primitive, or a rectangle
/// `corner + a·u + b·v`, a, b ∈ [0, 1] (hallway walls).
#[derive(Debug, Clone)]
pub(crate) enum Piece {
    /// A primitive's surface.
    Prim(Primitive),
    /// A parallelogram spanned by two edge vectors from a corner.
    Rect {
        /// One corner.
        corner: Point3<f64>,
        /// First edge vector.
        u: Vector3<f64>,
        /// Second edge vector.
        v: Vector3<f64>,
    },
}

impl Piece {
    fn area(&self) -> f64 {
        match self {
            Piece::Prim(p) => p.area(),
            Piece::Rect { u, v, .. } => u.cross(v).norm(),
        }
    }
}

/// Draws points area-uniformly on the union of `pieces` (each piece counted with its
/// full area), adds per-piece drift and per-point jitter.
pub(crate) fn sample_pieces<R: Rng>(
    pieces: &[Piece],
    density: Density,
    noise: Noise,
    rng: &mut R,
) -> Result<Vec<Point3<f64>>> {
    noise.validate()?;
    let areas: Vec<f64> = pieces.iter().map(Piece::area).collect();
    let total: f64 = areas.iter().sum();
    let n = density.count(total)?;
    if n > 0 && !(total > 0.0 && total.is_finite()) {
        return Err(Error::invalid(
            "cannot sample points: the surfaces have no area",
        ));
    }
    let drifts: Vec<Vector3<f64>> = pieces
        .iter()
        .map(|_| Vector3::new(gauss(rng), gauss(rng), gauss(rng)) * noise.drift)
        .collect();
    let mesh_cdfs: Vec<Option<Vec<f64>>> = pieces
        .iter()
        .map(|p| match p {
            Piece::Prim(Primitive {
                shape: Shape::Mesh(m),
                ..
            }) => Some(mesh_cdf(&m.mesh)),
            Piece::Prim(Primitive {
                shape: Shape::Plane(p),
                ..
            }) => Some(mesh_cdf(p.mesh())),
            _ => None,
        })
        .collect();
    let mut cdf = areas.clone();
    for i in 1..cdf.len() {
        cdf[i] += cdf[i - 1];
    }
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let target = rng.random::<f64>() * total;
        let i = cdf.partition_point(|&c| c <= target).min(pieces.len() - 1);
        let p = match &pieces[i] {
            Piece::Prim(prim) => {
                let local = match (&prim.shape, &mesh_cdfs[i]) {
                    (Shape::Mesh(m), Some(c)) => sample_mesh(&m.mesh, c, rng),
                    (Shape::Plane(p), Some(c)) => sample_mesh(p.mesh(), c, rng),
                    (shape, _) => sample_analytic(shape, rng),
                };
                prim.pose.to_scene(&local)
            }
            Piece::Rect { corner, u, v } => {
                corner + u * rng.random::<f64>() + v * rng.random::<f64>()
            }
        };
        let jitter = Vector3::new(gauss(rng), gauss(rng), gauss(rng)) * noise.jitter;
        out.push(p + drifts[i] + jitter);
    }
    Ok(out)
}

/// Draws `mis` about the centroid of the truth centres and applies it to points and truth.
pub(crate) fn misalign<R: Rng>(
    mis: &Misalignment,
    rng: &mut R,
    spacing: f64,
    points: &mut [Point3<f64>],
    truth: &mut [Primitive],
) -> Result<Pose> {
    mis.validate()?;
    let pivot = if truth.is_empty() {
        Point3::origin()
    } else {
        Point3::from(
            truth
                .iter()
                .map(|p| p.center().coords)
                .sum::<Vector3<f64>>()
                / truth.len() as f64,
        )
    };
    let pose = mis.draw(rng, spacing, pivot);
    for p in points.iter_mut() {
        *p = pose.to_scene(p);
    }
    for t in truth.iter_mut() {
        t.pose = pose.compose(&t.pose);
    }
    Ok(pose)
}

/// The inverse of a rigid (scale-1) pose.
pub(crate) fn inverse_rigid(p: &Pose) -> Pose {
    let r = p.rotation.inverse();
    Pose::new(r, -(r * p.translation))
}
