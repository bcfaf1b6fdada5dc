//! Registration scenes (thesis §6.3.3): points from a randomly posed mesh plus uniform
//! outliers; and a small procedural asymmetric test object.

use std::sync::Arc;

use nalgebra::{Point3, Unit, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::common::{
    Density, LatticeHint, Noise, Piece, Scene, check_scene_points, random_unit, sample_pieces,
};
use crate::atlas::{MeshShape, Shape, TriMesh};
use crate::check::{self, non_negative, positive};
use crate::{PointCloud, Pose, Primitive, Result};

/// Parameters of [`registration`]. Lengths in the mesh's units.
#[derive(Debug, Clone, PartialEq)]
pub struct RegistrationParams {
    /// Number of inlier points N drawn on the posed mesh (thesis: 100).
    pub inliers: usize,
    /// Number of uniform outliers M (thesis: 1900, i.e. 95 %).
    pub outliers: usize,
    /// Largest translation per axis: the translation is uniform in `[-t, t]³`
    /// (0 = rotation only, as in thesis figure 6-8).
    pub translation: f64,
    /// Scale range `(lo, hi)`, drawn uniformly; `None` = scale 1.
    pub scale: Option<(f64, f64)>,
    /// Half-side of the outlier cube, in units of the posed mesh's bounding radius; the
    /// cube is centred on the posed mesh's origin.
    pub outlier_box: f64,
    /// Per-point jitter on the inliers (drift is ignored: there is one object).
    pub noise: Noise,
    /// Number of objects K (thesis figure 6-9), each with its own random pose and
    /// `inliers` points; object k is centred at `(k − (K−1)/2) · 2.5 r` along x (r = the
    /// mesh's largest posed bounding radius) plus its random translation.
    pub objects: usize,
    /// RNG seed.
    pub seed: u64,
}

impl Default for RegistrationParams {
    fn default() -> Self {
        RegistrationParams {
            inliers: 100,
            outliers: 1900,
            translation: 0.0,
            scale: None,
            outlier_box: 1.0,
            noise: Noise::default(),
            objects: 1,
            seed: 0,
        }
    }
}

/// A uniformly random rotation (quaternion from a uniform point on S³).
pub(super) fn random_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    let axis = Unit::new_normalize(random_unit(rng));
    // Haar measure: angle density ∝ sin²(θ/2) on [0, π]; sample by rejection.
    let angle = loop {
        let a = std::f64::consts::PI * rng.random::<f64>();
        if rng.random::<f64>() <= (a / 2.0).sin().powi(2) {
            break a;
        }
    };
    UnitQuaternion::from_axis_angle(&axis, angle)
}

/// `inliers` points from the surface of `mesh` under a random pose, followed by
/// `outliers` points uniform in a cube around it (half-side `outlier_box` × the posed
/// bounding radius, centred on the pose's translation). The cloud lists the inliers
/// first. The truth is the posed mesh primitive; the lattice hint is informational
/// (spacing = the posed bounding radius, origin 0).
///
/// With `objects` = K > 1: K posed meshes side by side along x, `inliers` points on
/// each (object by object), then `outliers` points uniform in the bounding box of the K
/// cubes.
pub fn registration(mesh: &MeshShape, params: &RegistrationParams) -> Result<Scene> {
    let shape = Shape::Mesh(mesh.clone());
    shape.validate()?;
    non_negative("translation", params.translation)?;
    positive("outlier_box", params.outlier_box)?;
    params.noise.validate()?;
    if let Some(range) = params.scale {
        check::positive_range("scale", range)?;
    }
    check::at_least("objects", params.objects, 1)?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let k = params.objects;
    let largest = params.scale.map_or(1.0, |s| s.1) * mesh.bounding_radius();
    let mut truth = Vec::with_capacity(k);
    for i in 0..k {
        let rotation = random_rotation(&mut rng);
        let t = params.translation;
        let offset = Vector3::x() * ((i as f64 - (k - 1) as f64 / 2.0) * 2.5 * largest);
        let translation = offset + Vector3::from_fn(|_, _| (2.0 * rng.random::<f64>() - 1.0) * t);
        let scale = params
            .scale
            .map_or(1.0, |(lo, hi)| lo + (hi - lo) * rng.random::<f64>());
        truth.push(Primitive::new(
            shape.clone(),
            Pose {
                rotation,
                translation,
                scale,
            },
        ));
    }
    let noise = Noise {
        jitter: params.noise.jitter,
        drift: 0.0,
    };
    let total = k as f64 * params.inliers as f64 + params.outliers as f64;
    let remedy = if params.outliers > params.inliers {
        "outliers"
    } else {
        "inliers"
    };
    check_scene_points("the registration scene", total, remedy)?;
    let mut points = Vec::with_capacity(total as usize);
    for t in &truth {
        points.extend(sample_pieces(
            &[Piece::Prim(t.clone())],
            Density::Total(params.inliers),
            noise,
            &mut rng,
        )?);
    }
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for t in &truth {
        let half = Vector3::repeat(params.outlier_box * t.bounding_radius());
        lo = lo.inf(&(t.pose.translation - half));
        hi = hi.sup(&(t.pose.translation + half));
    }
    points.extend((0..params.outliers).map(|_| {
        Point3::from(lo + Vector3::from_fn(|a, _| (hi[a] - lo[a]) * rng.random::<f64>()))
    }));
    Ok(Scene {
        cloud: PointCloud::from_points(points),
        lattice: LatticeHint {
            spacing: truth[0].bounding_radius(),
            origin: Point3::origin(),
            shapes: vec![truth[0].shape.clone()],
        },
        truth,
        misalignment: Pose::identity(),
    })
}

/// A closed, lumpy, asymmetric test body (320 triangles, 162 vertices, about 1 unit
/// across): a twice-subdivided icosphere, stretched to (1.0, 0.7, 0.5) semi-axes and
/// pushed out by three Gaussian bumps of different heights at non-symmetric directions,
/// so no rotation other than the identity maps it onto itself. Star-shaped about the
/// origin (hence not self-intersecting); faces are counter-clockwise seen from outside.
pub fn asymmetric_object() -> MeshShape {
    let TriMesh {
        mut vertices,
        faces,
    } = TriMesh::unit_icosphere(2);
    let bumps = [
        (Vector3::new(1.0, 0.3, 0.2).normalize(), 0.35),
        (Vector3::new(-0.2, 1.0, 0.6).normalize(), 0.2),
        (Vector3::new(0.3, -0.5, -1.0).normalize(), 0.12),
    ];
    for v in &mut vertices {
        let u = v.coords.normalize();
        let r = 1.0
            + bumps
                .iter()
                .map(|(d, h)| h * (-(u - d).norm_squared() / 0.3).exp())
                .sum::<f64>();
        let s = u * r;
        *v = Point3::new(s.x, 0.7 * s.y, 0.5 * s.z) * 0.5;
    }
    // A closed icosphere with finite vertices always has faces of positive area.
    MeshShape::new("asymmetric_object", Arc::new(TriMesh { vertices, faces }))
        .expect("procedural mesh is valid")
}
