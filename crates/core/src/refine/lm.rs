//! The Levenberg–Marquardt fitter: one primitive `P` moved to lower
//!
//! `F(P) = w_point Σ_{y ∈ A(P)} d(y, P)² + w_s Σ_{x ∈ σ(P)} max(0, d(x, A(P)) − h)²`
//!
//! (scene units²), `A(P)` the points `P` owns ([`super::ownership`]), `σ(P)` its surface
//! samples, `h` the cloud's point spacing; the weights are [`Weights`]. Why this cost
//! and not the plain chamfer is in `docs/refine.md`.
//!
//! **Parameters**: a small rotation `ω` (applied on the left, about `P`'s origin), a
//! translation `τ`, and `η_k = ln s_k` for each size `s_k` ([`Shape::sizes`]), clamped to
//! the primitive's size limits. Squares and disks do not turn about their normal
//! ([`locked_axis`]). Meshes refine their pose only.
//!
//! **Jacobians** in closed form from the exact closest point `c`: a point residual
//! `r = |y − c|`, `n = (y − c)/r`, has `∂r/∂θ = −n · ∂x/∂θ` (envelope theorem), with
//! `∂x/∂ω = −[x − t]ₓ`, `∂x/∂τ = I` and `∂x/∂η_k` from [`Shape::size_tangents`] rotated
//! into the scene; a sample residual `r = |x − q| − h > 0` (`q` its nearest owned point)
//! has `∂r/∂θ = m · ∂x/∂θ`, `m = (x − q)/|x − q|`.
//!
//! **Steps** solve `(JᵀWJ + λ (diag JᵀWJ + ε I)) δ = −JᵀWr` and are kept only if `F`
//! decreases by a relative [`MIN_DECREASE`] and more than numerical noise.

use nalgebra::{DMatrix, DVector, Point3, SMatrix, SVector, UnitQuaternion, Vector3};

use super::RefineContext;
use crate::atlas::Shape;
use crate::spatial::{BoxTree, Hint};
use crate::{Pose, Primitive};

/// An LM step is kept only if it lowers the cost by at least this fraction.
pub const MIN_DECREASE: f64 = 1e-9;

/// At most this many of a primitive's assigned points enter its LM problem (evenly
/// strided, each weighted by `assigned / used`): the sum over all of them is estimated
/// well by a few thousand, and refinement time stays independent of the cloud's density.
pub const MAX_FIT_POINTS: usize = 4096;

/// Fewer points than this (owned by a primitive) do not constrain a fit: the fitter
/// leaves the primitive as it is and re-typing skips it. Three points span a plane.
pub(super) const MIN_FIT_POINTS: usize = 3;

/// Residuals below this (relative to the primitive's size) carry no direction and are skipped.
const TINY: f64 = 1e-12;

/// Pose parameters of one primitive: 3 rotation (`ω`, rows 0–2 of a Jacobian row) and
/// 3 translation (`τ`, rows 3–5); the sizes `η` follow.
const POSE_PARAMS: usize = 6;

/// Most parameters of one primitive: 3 rotation + 3 translation + 2 sizes.
const MAX_PARAMS: usize = 8;

/// The damping `λ` of the first step (dimensionless, relative to the diagonal of
/// `JᵀWJ`): small, so the first step is close to Gauss–Newton, the usual LM start.
const INITIAL_DAMPING: f64 = 1e-3;

/// `λ` is multiplied by this after a rejected step: a rejection costs more damping
/// than an acceptance takes away (÷ [`DAMPING_DECREASE`]).
const DAMPING_INCREASE: f64 = 4.0;

/// `λ` is divided by this after an accepted step.
const DAMPING_DECREASE: f64 = 3.0;

/// `λ` never falls below this (dimensionless), so a long run of accepted steps cannot
/// damp the system to nothing.
const MIN_DAMPING: f64 = 1e-9;

/// Damped steps tried per iteration (each rejection raises `λ` by [`DAMPING_INCREASE`])
/// before the fit stops: `4⁶ ≈ 4000` times the damping.
const MAX_STEP_TRIALS: usize = 6;

/// The size of a residual change that is numerical noise, relative to the primitive's
/// bounding radius: a step must lower `F` by more than such residuals would.
const NOISE_RESIDUAL: f64 = 1e-9;

/// The number of sample residuals the noise floor charges at the sample weight (a
/// nominal count of a primitive's samples, dimensionless).
const NOISE_SAMPLES: f64 = 1e3;

/// The `ε` of the damped system relative to the mean diagonal of `JᵀWJ`: keeps it
/// positive definite when a parameter has no gradient (all its Jacobian entries zero).
const DIAGONAL_FLOOR: f64 = 1e-9;

/// Weights of the refinement cost (module docs): `point` per squared point residual,
/// `sample` per squared sample residual, and the `slack` subtracted from a sample's
/// distance to the cloud.
#[derive(Debug, Clone, Copy)]
pub(super) struct Weights {
    pub(super) point: f64,
    pub(super) sample: f64,
    pub(super) slack: f64,
}

impl Weights {
    /// `point = w_point`; `sample = w_prim · s² J / A` for sample spacing `s`, `J` points
    /// and the total area `A` of `prims`, so that the samples count as if the surfaces
    /// carried as many samples as the cloud has points (the balance of the DESIGN §4
    /// chamfer); `slack` = the cloud's point spacing.
    pub(super) fn new(ctx: &RefineContext<'_>, prims: &[Primitive]) -> Self {
        let area: f64 = prims.iter().map(Primitive::area).sum();
        Weights {
            point: ctx.chamfer.point_weight,
            sample: ctx.chamfer.primitive_weight
                * ctx.sample_spacing.powi(2)
                * ctx.points.len() as f64
                / area.max(f64::MIN_POSITIVE),
            slack: ctx.point_spacing.max(0.0),
        }
    }

    /// The residual of a sample at squared distance `d2` from the cloud: `max(0, d − slack)`.
    #[inline]
    fn sample_residual(&self, d2: f64) -> f64 {
        (d2.sqrt() - self.slack).max(0.0)
    }
}

/// The scene axis a primitive may not turn about: a square's or disk's normal, so that a
/// patch tilts onto its points but keeps its in-plane orientation from the lattice frame
/// (for a disk that turn is a symmetry; for a square it is all but unconstrained inside
/// the data, and left free the patches of a plane spin to all angles). A bounded plane's
/// in-plane orientation came from its points with its outline, so it is locked too.
fn locked_axis(p: &Primitive) -> Option<Vector3<f64>> {
    match p.shape {
        Shape::Square { .. } | Shape::Disk { .. } | Shape::Plane(_) => {
            Some(p.pose.rotation * Vector3::z())
        }
        _ => None,
    }
}

/// A Jacobian row, zero-padded to [`MAX_PARAMS`] (kept on the stack).
type Row = SVector<f64, MAX_PARAMS>;

/// Normal equations `A = Σ w JᵀJ`, `g = Σ w Jᵀr`, and the cost `F = Σ w r²`.
struct Normal {
    /// `Σ w JᵀJ` (top-left `m × m` used).
    a: SMatrix<f64, MAX_PARAMS, MAX_PARAMS>,
    /// `Σ w Jᵀr` (first `m` used).
    g: Row,
    /// `Σ w r²`.
    cost: f64,
    /// Parameters in use.
    m: usize,
}

impl Normal {
    fn new(m: usize) -> Self {
        Normal {
            a: SMatrix::zeros(),
            g: Row::zeros(),
            cost: 0.0,
            m,
        }
    }
    fn add(&mut self, w: f64, r: f64, row: &Row) {
        self.a += (w * row) * row.transpose();
        self.g += (w * r) * row;
        self.cost += w * r * r;
    }
}

/// The LM problem of one primitive: its assigned points, the cloud for its samples, size bounds.
pub(super) struct Fitter<'a> {
    ctx: &'a RefineContext<'a>,
    weights: &'a Weights,
    /// All assigned points: the samples' distances are measured to these.
    own: &'a [Point3<f64>],
    /// Box tree over `own`: most samples a refinement measures lie off the data, where
    /// it opens fewer nodes than a kd-tree (`spatial/box_tree.rs`).
    own_index: BoxTree,
    /// The assigned points, strided to at most [`MAX_FIT_POINTS`].
    points: Vec<Point3<f64>>,
    /// Weight of one squared point residual: `w_point · assigned / used`.
    point_weight: f64,
    limits: &'a [(f64, f64)],
}

impl<'a> Fitter<'a> {
    pub(super) fn new(
        ctx: &'a RefineContext<'a>,
        weights: &'a Weights,
        assigned: &'a [Point3<f64>],
        limits: &'a [(f64, f64)],
    ) -> Self {
        let stride = assigned.len().div_ceil(MAX_FIT_POINTS).max(1);
        let points: Vec<Point3<f64>> = assigned.iter().step_by(stride).copied().collect();
        let point_weight = weights.point * assigned.len() as f64 / points.len().max(1) as f64;
        Fitter {
            ctx,
            weights,
            own: assigned,
            own_index: BoxTree::new(assigned),
            points,
            point_weight,
            limits,
        }
    }

    /// The residual of the sample `x`, `d(x, A(P)) − h` (module docs; the whole cloud
    /// stands in for `A(P)` when that is empty), and the point it is measured to; `None`
    /// when the sample lies within `h` of those points.
    fn sample_residual(&self, x: &Point3<f64>, hint: &mut Hint) -> Option<(f64, Point3<f64>)> {
        let (q, d2) = if self.own.is_empty() {
            let (j, d2) = self.ctx.index.nearest(x)?;
            (self.ctx.points[j as usize], d2)
        } else {
            self.own_index.nearest_point(x, hint)?
        };
        let r = self.weights.sample_residual(d2);
        (r > 0.0).then_some((r, q))
    }

    /// The refinement cost `F` of `p` on this problem's points.
    pub(super) fn cost(&self, p: &Primitive) -> f64 {
        self.normal(p, false).cost
    }

    /// The Jacobian row of a residual with direction `dir` (`∂r/∂x = dir`) at scene
    /// point `x` whose local point is `local`.
    fn row(&self, p: &Primitive, x: &Point3<f64>, local: &Point3<f64>, dir: &Vector3<f64>) -> Row {
        let tangents = p.shape.size_tangents(local);
        let mut row = Row::zeros();
        let lever = x.coords - p.pose.translation;
        let mut spin = lever.cross(dir);
        if let Some(n) = locked_axis(p) {
            spin -= n * spin.dot(&n);
        }
        row.fixed_rows_mut::<3>(0).copy_from(&spin);
        row.fixed_rows_mut::<3>(3).copy_from(dir);
        for (k, t) in tangents.iter().enumerate().take(MAX_PARAMS - POSE_PARAMS) {
            row[POSE_PARAMS + k] = dir.dot(&(p.pose.rotation * t * p.pose.scale));
        }
        row
    }

    /// Cost and (when `jacobian`) normal equations of `p`: the point term, then the
    /// sample term.
    fn normal(&self, p: &Primitive, jacobian: bool) -> Normal {
        let m = POSE_PARAMS + p.shape.sizes().len();
        let mut out = Normal::new(m);
        let tiny = TINY * p.bounding_radius().max(1.0);
        self.add_point_terms(&mut out, p, jacobian, tiny);
        self.add_sample_terms(&mut out, p, jacobian, tiny);
        out
    }

    /// Adds `w_point r²` (and its rows) for each of the problem's points.
    fn add_point_terms(&self, out: &mut Normal, p: &Primitive, jacobian: bool, tiny: f64) {
        let w_point = self.point_weight;
        for y in &self.points {
            let c = p.closest_point(y);
            let r = (y - c).norm();
            if r <= tiny {
                continue;
            }
            if jacobian {
                let n = (y - c) / r;
                let row = self.row(p, &c, &p.pose.to_local(&c), &(-n));
                out.add(w_point, r, &row);
            } else {
                out.cost += w_point * r * r;
            }
        }
    }

    /// Adds `w_s r²` (and its rows) for each of `p`'s surface samples off the data.
    fn add_sample_terms(&self, out: &mut Normal, p: &Primitive, jacobian: bool, tiny: f64) {
        let w_prim = self.weights.sample;
        let spacing = self.ctx.sample_spacing / p.pose.scale;
        let mut hint = Hint::default();
        for local in p.shape.sample_surface(spacing) {
            let x = p.pose.to_scene(&local);
            let Some((r, q)) = self.sample_residual(&x, &mut hint) else {
                continue;
            };
            if r <= tiny {
                continue;
            }
            if jacobian {
                let row = self.row(p, &x, &local, &((x - q) / (x - q).norm()));
                out.add(w_prim, r, &row);
            } else {
                out.cost += w_prim * r * r;
            }
        }
    }

    /// `p` moved by the step `delta` (ω, τ, η), or `None` when the result is invalid.
    fn apply(&self, p: &Primitive, delta: &DVector<f64>) -> Option<Primitive> {
        let mut omega = Vector3::new(delta[0], delta[1], delta[2]);
        if let Some(n) = locked_axis(p) {
            omega -= n * omega.dot(&n);
        }
        let tau = Vector3::new(delta[3], delta[4], delta[5]);
        let s: Vec<f64> = p
            .shape
            .sizes()
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let (lo, hi) = self.limits.get(k).copied().unwrap_or((0.0, f64::INFINITY));
                (s * delta[POSE_PARAMS + k].exp()).clamp(lo, hi)
            })
            .collect();
        let shape = p.shape.with_sizes(&s);
        shape.validate().ok()?;
        let pose = Pose {
            rotation: UnitQuaternion::from_scaled_axis(omega) * p.pose.rotation,
            translation: p.pose.translation + tau,
            scale: p.pose.scale,
        };
        let finite = pose.translation.iter().all(|v| v.is_finite())
            && pose.rotation.coords.iter().all(|v| v.is_finite());
        finite.then(|| Primitive::new(shape, pose))
    }

    /// Up to `iterations` accepted LM steps from `p`.
    pub(super) fn run(&self, mut p: Primitive, iterations: usize) -> Primitive {
        if self.points.len() < MIN_FIT_POINTS {
            return p;
        }
        let mut lambda = INITIAL_DAMPING;
        let mut normal = self.normal(&p, true);
        // A step must lower F by a relative MIN_DECREASE, and by more than residuals of
        // NOISE_RESIDUAL of the primitive's size would: where the dead zone leaves F flat
        // (a square over exact data), the damped system's tiny gradient would otherwise
        // buy huge steps for numerically zero gains, and sizes would drift to their limits.
        let floor = (NOISE_RESIDUAL * p.bounding_radius()).powi(2)
            * (self.point_weight * self.points.len() as f64 + self.weights.sample * NOISE_SAMPLES);
        for _ in 0..iterations {
            let mut accepted = false;
            for _ in 0..MAX_STEP_TRIALS {
                let Some(delta) = self.step(&normal, lambda) else {
                    break;
                };
                let Some(trial) = self.apply(&p, &delta) else {
                    lambda *= DAMPING_INCREASE;
                    continue;
                };
                let cost = self.normal(&trial, false).cost;
                if cost < normal.cost * (1.0 - MIN_DECREASE) - floor {
                    p = trial;
                    lambda = (lambda / DAMPING_DECREASE).max(MIN_DAMPING);
                    accepted = true;
                    break;
                }
                lambda *= DAMPING_INCREASE;
            }
            if !accepted {
                break;
            }
            normal = self.normal(&p, true);
        }
        p
    }

    /// The damped Gauss–Newton step, or `None` if the system cannot be solved.
    fn step(&self, n: &Normal, lambda: f64) -> Option<DVector<f64>> {
        let m = n.m;
        let mut a: DMatrix<f64> = n.a.view((0, 0), (m, m)).clone_owned();
        let eps = DIAGONAL_FLOOR * (a.trace() / m as f64).max(f64::MIN_POSITIVE);
        for i in 0..m {
            a[(i, i)] += lambda * (a[(i, i)] + eps) + eps;
        }
        let g: DVector<f64> = n.g.rows(0, m).clone_owned();
        let delta = a.cholesky()?.solve(&(-g));
        delta.iter().all(|v| v.is_finite()).then_some(delta)
    }
}
