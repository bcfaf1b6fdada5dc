//! Which surface explains a segment: a plane, a cylinder, a sphere, or none (clutter).
//!
//! **Rule.** Let `σ` be the segment's noise (the detection's floored σ, or the median
//! local residual of the segment's points where that is larger) and `t` the tolerance
//! (in σ, [`super::DEFAULT_TOLERANCE`]).
//!
//! 1. The least-squares plane ([`super::plane`]) with RMS `≤ 2 σ_fine`
//!    ([`CURVED_MIN_PLANE_SIGMAS`]; `σ_fine ≤ σ` the median residual of the segment's
//!    neighbourhoods off a height quadric, which the surface's curvature does not
//!    inflate: on a 10 cm pipe sampled every 1.7 cm a plane's residual is mostly the
//!    pipe's sagitta, and a strip of it judged by that residual passed for a plane)
//!    explains the segment:
//!    a **plane** (the simplest model is tried first; a gently curved surface that a
//!    plane explains within the noise *is* a plane at this noise level, and no curved
//!    model could halve an RMS already near σ).
//! 2. Otherwise a **cylinder** ([`super::cylinder`]) and, when enabled, a **sphere**
//!    ([`super::sphere`]) are fitted; one is accepted if its RMS is `≤ t σ` **and** at
//!    most [`CURVED_GAIN`] times the plane's RMS (it must explain the points markedly
//!    better than the plane, not merely absorb noise with its extra parameters). Of two
//!    accepted, the lower RMS wins.
//! 3. Otherwise the plane, if its RMS is `≤ t σ` (a curved surface the noise estimate
//!    absorbed is caught by step 2 first: [`CURVED_MIN_PLANE_SIGMAS`]).
//! 4. Otherwise the segment is **clutter**: no model of the three explains it.

use nalgebra::{Point3, Vector3};

use super::SurfaceModel;
use super::cylinder::fit_cylinder;
use super::plane::Moments;
use super::sphere::fit_sphere;

/// A curved model must have at most this fraction of the plane's RMS (dimensionless):
/// halving the residual is far beyond what the 2–3 extra parameters of a cylinder or
/// sphere gain on truly planar noise.
pub const CURVED_GAIN: f64 = 0.5;

/// A plane within this many σ (at the finest scale) is kept without trying curved
/// models: no curved model can have less RMS than the noise, so none can halve this
/// ([`CURVED_GAIN`]). A plane that passes the tolerance with more RMS may be a curved
/// surface whose curvature the coarse noise estimate has absorbed (curvature inflates
/// the residuals of wide neighbourhoods: a pole seen by a depth camera), and is a
/// cylinder or sphere when one explains it markedly better.
pub const CURVED_MIN_PLANE_SIGMAS: f64 = 1.0 / CURVED_GAIN;

/// A curved model's radius must be at most this multiple of the segment's extent (its
/// largest RMS spread along a principal direction): larger radii describe surfaces that
/// are flat at the segment's scale, whose radius the data cannot pin down.
pub const MAX_RADIUS_PER_EXTENT: f64 = 20.0;

/// A classified segment: its model (`None`: clutter) and the RMS of its points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Classified {
    /// The accepted model, `None` for clutter.
    pub model: Option<SurfaceModel>,
    /// RMS distance of the points from the model (from the plane for clutter), scene units.
    pub rms: f64,
}

/// Classifies the points `points[i]`, `i ∈ ids`, with unit normals `normals[i]`, at
/// noise `sigma` and tolerance `tolerance` (in σ); `spheres` enables the sphere model.
/// `fine` is the segment's noise at the finest scale (the median residual of its own
/// neighbourhoods off a height quadric, scene units), free of curvature: a plane within
/// [`CURVED_MIN_PLANE_SIGMAS`] of it is kept without trying curved models.
pub fn classify(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    ids: &[usize],
    (sigma, fine): (f64, f64),
    tolerance: f64,
    spheres: bool,
) -> Classified {
    let limit = tolerance * sigma;
    let moments = Moments::of(points, ids);
    let Some(plane) = moments.plane() else {
        return Classified {
            model: None,
            rms: f64::INFINITY,
        };
    };
    let as_plane = Classified {
        model: Some(SurfaceModel::Plane {
            point: plane.point,
            normal: plane.normal,
        }),
        rms: plane.rms,
    };
    if plane.rms <= limit && plane.rms <= CURVED_MIN_PLANE_SIGMAS * fine {
        return as_plane;
    }
    let pts: Vec<Point3<f64>> = ids.iter().map(|&i| points[i]).collect();
    let ns: Vec<Vector3<f64>> = ids.iter().map(|&i| normals[i]).collect();
    let extent = spread(&pts);
    let accept = |rms: f64, radius: f64| {
        rms <= limit && rms <= CURVED_GAIN * plane.rms && radius <= MAX_RADIUS_PER_EXTENT * extent
    };
    // The two curved fits are independent: on two threads the sphere's runs beside the
    // cylinder's (the same models on any thread count).
    let (cylinder, sphere) = rayon::join(
        || fit_cylinder(&pts, &ns),
        || spheres.then(|| fit_sphere(&pts)).flatten(),
    );
    let mut best: Option<Classified> = None;
    if let Some(c) = cylinder.filter(|c| accept(c.rms, c.radius)) {
        best = Some(Classified {
            model: Some(SurfaceModel::Cylinder {
                point: c.point,
                axis: c.axis,
                radius: c.radius,
                length: c.length,
            }),
            rms: c.rms,
        });
    }
    if let Some(s) = sphere.filter(|s| accept(s.rms, s.radius))
        && best.is_none_or(|b| s.rms < b.rms)
    {
        best = Some(Classified {
            model: Some(SurfaceModel::Sphere {
                centre: s.centre,
                radius: s.radius,
            }),
            rms: s.rms,
        });
    }
    match best {
        Some(curved) => curved,
        None if plane.rms <= limit => as_plane,
        None => Classified {
            model: None,
            rms: plane.rms,
        },
    }
}

/// The largest RMS spread of `pts` along a principal direction (scene units).
fn spread(pts: &[Point3<f64>]) -> f64 {
    spreads(pts)[0]
}

/// The RMS spreads of `pts` along their three principal directions, largest first
/// (scene units): a plane segment is a strip when the middle one is small.
pub(super) fn spreads(pts: &[Point3<f64>]) -> [f64; 3] {
    let ids: Vec<usize> = (0..pts.len()).collect();
    let m = Moments::of(pts, &ids);
    let c = m.centroid().unwrap_or_else(Point3::origin);
    let cov = pts
        .iter()
        .map(|p| (p - c) * (p - c).transpose())
        .sum::<nalgebra::Matrix3<f64>>()
        / pts.len().max(1) as f64;
    let mut e: Vec<f64> = cov
        .symmetric_eigenvalues()
        .iter()
        .map(|v| v.max(0.0).sqrt())
        .collect();
    e.sort_by(|a, b| b.total_cmp(a));
    [e[0], e[1], e[2]]
}
