//! Which surface explains a segment: a plane, a cylinder, a sphere, or none (clutter).
//!
//! **Rule.** Let `σ` be the segment's noise (the detection's floored σ, or the median
//! local residual of the segment's points where that is larger) and `t` the tolerance
//! (in σ, [`super::DEFAULT_TOLERANCE`]).
//!
//! 1. The least-squares plane ([`super::plane`]) whose normals agree with the points'
//!    (below) and with RMS `≤ 2 σ_fine`
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
//!    better than the plane, not merely absorb noise with its extra parameters); a
//!    cylinder is also accepted with RMS `≤ t σ` when its normals agree with the
//!    points' where the plane's do not, if it is at least [`TUBE_MIN_ASPECT`] times as
//!    long as its radius (a tube's strip). Of two accepted, the lower RMS wins.
//! 3. Otherwise the plane, if its RMS is `≤ t σ` (a curved surface the noise estimate
//!    absorbed is caught by step 2 first: [`CURVED_MIN_PLANE_SIGMAS`]).
//! 4. Otherwise the segment is **clutter**: no model of the three explains it.
//!
//! **Normals.** A model's normals agree with the points' when at least
//! [`NORMALS_AGREE_SHARE`] of the points (with a normal) have theirs within their growing
//! angle of the model's surface normal there. Distances alone cannot tell a strip of a
//! thin tube from a plane: growing creeps around a tube in small steps, and a strip of
//! 70° of a 6 cm tube is flat within 2 σ at 2 mm noise (its sagitta is 1 cm, its RMS off
//! a plane 3–4 mm), while its normals fan out by ±35° about the plane's.

use nalgebra::{Point3, Vector3};

use super::SurfaceModel;
use super::cylinder::{CylinderFit, fit_cylinder};
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

/// A model's normals agree with a segment's when at least this share of its points have
/// their normal within their growing angle of the model's (module docs). A half: on a
/// plane the noise tilts fewer normals than that past the growing angle, which is
/// derived from that noise, and a region that crept a little over a crease keeps its
/// plane.
pub const NORMALS_AGREE_SHARE: f64 = 0.5;

/// A cylinder that wins over a plane by its normals alone (module docs) is at least this
/// many times as long as its radius (dimensionless).
pub const TUBE_MIN_ASPECT: f64 = 2.0;

/// A classified segment: its model (`None`: clutter) and the RMS of its points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Classified {
    /// The accepted model, `None` for clutter.
    pub model: Option<SurfaceModel>,
    /// RMS distance of the points from the model (from the plane for clutter), scene units.
    pub rms: f64,
}

/// The points' surface: their positions, unit normals (zero where unknown) and the
/// `cos` of each one's growing angle, all indexed alike.
#[derive(Debug, Clone, Copy)]
pub struct Oriented<'a> {
    /// The points.
    pub points: &'a [Point3<f64>],
    /// Their unit normals, sign arbitrary; zero where the neighbourhood is degenerate.
    pub normals: &'a [Vector3<f64>],
    /// Per point: `cos` of its growing angle.
    pub cos_angle: &'a [f64],
}

impl Oriented<'_> {
    /// Whether the normals of at least [`NORMALS_AGREE_SHARE`] of the points `ids` (of
    /// those with a normal) are within their growing angle of `model_normal` at the
    /// point (unit or zero; either sign).
    pub fn normals_agree(
        &self,
        ids: &[usize],
        model_normal: impl Fn(&Point3<f64>) -> Vector3<f64>,
    ) -> bool {
        let (mut with_normal, mut agree) = (0usize, 0usize);
        for &i in ids {
            let n = self.normals[i];
            if n == Vector3::zeros() {
                continue;
            }
            with_normal += 1;
            if n.dot(&model_normal(&self.points[i])).abs() >= self.cos_angle[i] {
                agree += 1;
            }
        }
        agree as f64 >= NORMALS_AGREE_SHARE * with_normal as f64
    }
}

/// Classifies the points `surface.points[i]`, `i ∈ ids`, at noise `sigma` and tolerance
/// `tolerance` (in σ); `spheres` enables the sphere model. `fine` is the segment's noise
/// at the finest scale (the median residual of its own neighbourhoods off a height
/// quadric, scene units), free of curvature: a plane within [`CURVED_MIN_PLANE_SIGMAS`]
/// of it whose normals agree with the points' is kept without trying curved models.
pub fn classify(
    surface: Oriented,
    ids: &[usize],
    (sigma, fine): (f64, f64),
    tolerance: f64,
    spheres: bool,
) -> Classified {
    let (points, normals) = (surface.points, surface.normals);
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
    let plane_agrees = surface.normals_agree(ids, |_| plane.normal);
    if plane.rms <= limit && plane.rms <= CURVED_MIN_PLANE_SIGMAS * fine && plane_agrees {
        return as_plane;
    }
    let pts: Vec<Point3<f64>> = ids.iter().map(|&i| points[i]).collect();
    let ns: Vec<Vector3<f64>> = ids.iter().map(|&i| normals[i]).collect();
    let extent = spread(&pts);
    let accept = |rms: f64, radius: f64| {
        rms <= limit && rms <= CURVED_GAIN * plane.rms && radius <= MAX_RADIUS_PER_EXTENT * extent
    };
    // A tube's strip beats the plane by its normals where the plane's disagree with the
    // points' (module docs); only a tube at least [`TUBE_MIN_ASPECT`] times as long as its
    // radius, whose axis its strip pins down: a short wide band of an organic shape
    // (a bunny's flank) would become a whole ring far from its points.
    let tube_strip = |c: &CylinderFit| {
        !plane_agrees
            && c.rms <= limit
            && c.length >= TUBE_MIN_ASPECT * c.radius
            && surface.normals_agree(ids, |p| {
                c.off_axis(p).try_normalize(0.0).unwrap_or_default()
            })
    };
    // The two curved fits are independent: on two threads the sphere's runs beside the
    // cylinder's (the same models on any thread count).
    let (cylinder, sphere) = rayon::join(
        || fit_cylinder(&pts, &ns),
        || spheres.then(|| fit_sphere(&pts)).flatten(),
    );
    let mut best: Option<Classified> = None;
    if let Some(c) = cylinder.filter(|c| accept(c.rms, c.radius) || tube_strip(c)) {
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

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    use super::super::{DEFAULT_TOLERANCE, MIN_ANGLE_DEG};
    use super::*;

    const NOISE: f64 = 0.002;
    /// The growing angle of a quiet scan: its floor.
    const ANGLE_DEG: f64 = MIN_ANGLE_DEG;

    /// Points on `arc` radians of a tube of `radius` about the z axis, `length` long,
    /// with Gaussian noise along the radius; their normals radial, tilted by up to a
    /// tenth of the growing angle (estimation noise).
    fn tube_strip(
        radius: f64,
        arc: f64,
        length: f64,
        n: usize,
    ) -> (Vec<Point3<f64>>, Vec<Vector3<f64>>) {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let tilt = 0.1 * ANGLE_DEG.to_radians();
        (0..n)
            .map(|_| {
                let a = (rng.random::<f64>() - 0.5) * arc;
                let z = rng.random::<f64>() * length;
                let r = radius + NOISE * rng.sample::<f64, _>(StandardNormal);
                let radial = Vector3::new(a.cos(), a.sin(), 0.0);
                let normal =
                    (radial + Vector3::z() * tilt * (rng.random::<f64>() - 0.5)).normalize();
                (Point3::new(r * a.cos(), r * a.sin(), z), normal)
            })
            .unzip()
    }

    fn classified(points: &[Point3<f64>], normals: &[Vector3<f64>]) -> Option<SurfaceModel> {
        let cos_angle = vec![ANGLE_DEG.to_radians().cos(); points.len()];
        let surface = Oriented {
            points,
            normals,
            cos_angle: &cos_angle,
        };
        let ids: Vec<usize> = (0..points.len()).collect();
        // The judged σ a little above the noise, the fine one at it (as detection has
        // them on a quiet scan).
        let sigma = (1.3 * NOISE, 1.25 * NOISE);
        classify(surface, &ids, sigma, DEFAULT_TOLERANCE, true).model
    }

    #[test]
    fn a_strip_of_a_thin_tube_flat_within_the_noise_is_a_cylinder_by_its_normals() {
        // 70° of a 6 cm tube: its sagitta is 1.1 cm, its RMS off a plane under twice
        // the fine σ, but its normals fan out by ±35° about the plane's.
        let (points, normals) = tube_strip(0.06, 70f64.to_radians(), 0.5, 1500);
        let plane = Moments::of(&points, &(0..points.len()).collect::<Vec<_>>())
            .plane()
            .unwrap();
        assert!(plane.rms < 2.0 * 1.25 * NOISE, "plane RMS {}", plane.rms);
        match classified(&points, &normals) {
            Some(SurfaceModel::Cylinder { radius, .. }) => {
                assert!((radius - 0.06).abs() < 0.006, "radius {radius}");
            }
            other => panic!("expected a cylinder, got {other:?}"),
        }
    }

    #[test]
    fn a_short_wide_band_and_a_flat_patch_stay_planes() {
        // The same arc of a 20 cm tube only 5 cm long: a band the normals alone must not
        // turn into a whole ring (shorter than twice its radius).
        let (points, normals) = tube_strip(0.2, 20f64.to_radians(), 0.05, 800);
        assert!(
            matches!(
                classified(&points, &normals),
                Some(SurfaceModel::Plane { .. })
            ),
            "band"
        );
        // A flat patch whose normals agree with its plane.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (points, normals): (Vec<_>, Vec<_>) = (0..1000)
            .map(|_| {
                let (x, y) = (rng.random::<f64>(), rng.random::<f64>() * 0.1);
                let z = NOISE * rng.sample::<f64, _>(StandardNormal);
                let tilt = 0.5 * ANGLE_DEG.to_radians() * (rng.random::<f64>() - 0.5);
                (
                    Point3::new(x, y, z),
                    Vector3::new(tilt.sin(), 0.0, tilt.cos()),
                )
            })
            .unzip();
        assert!(
            matches!(
                classified(&points, &normals),
                Some(SurfaceModel::Plane { .. })
            ),
            "patch"
        );
    }
}
