//! [`Settings`] (every value a fit uses) and [`Settings::resolve`], which derives the
//! defaults that depend on the cloud from [`FitOptions`] (what a user may set; its
//! `Default` is the table of the fixed defaults).
//!
//! Resolved settings are not changed afterwards: a stage that needs other values makes
//! its own ([`Settings::finer`], [`Settings::realigned`]).

use nalgebra::{Point3, UnitQuaternion};
use serde_json::Value;

use super::document::SettingsDoc;
use super::options::{FitOptions, McmcFitOptions, MethodOptions};
use crate::atlas::{MeshShape, Shape, ShapeKind};
use crate::chamfer::{ChamferOptions, PointModel};
use crate::frame::{FrameChoice, FrameEstimate, estimate_frame, grid_origin};
use crate::lattice::LatticeSpec;
use crate::ray::RayModel;
use crate::refine::RefineOptions;
use crate::solve::SolverOptions;
use crate::spatial::PointIndex;
use crate::surface::{
    DEFAULT_MAX_POINTS, DEFAULT_NEIGHBOURS, NOISE_MAX_POINTS, local_planes, noise_level,
};
use crate::{Error, PointCloud, Result, check};

use super::options::DEFAULT_KIND;

/// Every setting of a fit, defaults resolved.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Primitive types.
    pub kinds: Vec<ShapeKind>,
    /// See [`FitOptions::size`].
    pub size: f64,
    /// See [`FitOptions::radius`].
    pub radius: f64,
    /// See [`FitOptions::bend`].
    pub bend: f64,
    /// See [`FitOptions::spacing`].
    pub spacing: f64,
    /// See [`FitOptions::origin`].
    pub origin: Point3<f64>,
    /// Lattice frame → scene.
    pub frame: UnitQuaternion<f64>,
    /// How the frame was chosen: `axis`, `auto` or `given`.
    pub frame_source: &'static str,
    /// Share of flat normals within ≈ 14° of a frame axis (estimated frames only).
    pub frame_support: Option<f64>,
    /// The cloud's estimated noise σ (scene units; see the module docs), 0 if unknown.
    pub noise: f64,
    /// Refinement options, if refinement runs.
    pub refine: Option<RefineOptions>,
    /// See [`FitOptions::sample_spacing`].
    pub sample_spacing: f64,
    /// The cloud's median nearest-neighbour distance.
    pub point_spacing: f64,
    /// The distance whose square is `d_cap`.
    pub cap: f64,
    /// Loss options.
    pub chamfer: ChamferOptions,
    /// Solver options.
    pub solver: SolverOptions,
    /// Seed.
    pub seed: u64,
    /// Budget for the estimated peak memory of a fit, bytes ([`super::estimate_bytes`]).
    pub memory_budget: u64,
    /// Budget for the estimated work of a lattice pass, nearest-neighbour queries per point
    /// ([`super::estimate_work`]).
    pub work_budget: f64,
    /// Mesh source, if the mesh type is used.
    pub mesh: Option<MeshShape>,
    /// Whether rays charge the candidates they cross in front of their points
    /// ([`crate::ray::FreeSpace`]): [`FitOptions::free_space`] resolved against the
    /// cloud's sensor origins.
    pub free_space: bool,
    /// The inference method and the settings only it has.
    pub method: MethodSettings,
}

/// The inference method of resolved [`Settings`] with its own settings.
#[derive(Debug, Clone, PartialEq)]
pub enum MethodSettings {
    /// Probabilistic chamfer + L-BFGS over existence (the chamfer settings are
    /// [`Settings::chamfer`], [`Settings::solver`], [`Settings::cap`]).
    Chamfer,
    /// Ray likelihood + Metropolis–Hastings (thesis ch. 4).
    Mcmc(McmcSettings),
    /// The probabilistic chamfer over candidates detected in the data (`types` auto,
    /// [`crate::compact`]); the lattice settings (size, spacing, frame, …) play no part.
    Compact(CompactSettings),
}

/// What the compact model ([`crate::compact`]) found and used, for `result.json`.
#[derive(Debug, Clone, PartialEq)]
pub struct CompactSettings {
    /// Detected segments (planes, cylinders, spheres).
    pub segments: usize,
    /// Candidates proposed from them.
    pub proposed: usize,
    /// Noise σ at the fine scale the region growing used (scene units).
    pub growing_noise: f64,
    /// The region-growing angle (degrees).
    pub angle_degrees: f64,
    /// Voxel edge of the detection's subsampling (scene units), if any.
    pub voxel: Option<f64>,
}

impl MethodSettings {
    /// The CLI/JSON name: `chamfer` or `mcmc`.
    pub fn name(&self) -> &'static str {
        match self {
            MethodSettings::Chamfer => "chamfer",
            MethodSettings::Mcmc(_) => "mcmc",
            MethodSettings::Compact(_) => "chamfer",
        }
    }
}

/// The settings of the `mcmc` method ([`McmcFitOptions`] resolved).
#[derive(Debug, Clone, PartialEq)]
pub struct McmcSettings {
    /// The measurement model (noise rate, σ, `|cos θ|` floor).
    pub ray: RayModel,
    /// `p(φ_i = 1)` of supported candidates.
    pub prior: f64,
    /// Proposals after burn-in; `None`: derived from the number of supported candidates
    /// when they are known (a result's settings hold the value used).
    pub steps: Option<usize>,
    /// Proposals before counting; `None`: `steps / 5`.
    pub burn_in: Option<usize>,
    /// Expected flips per proposal.
    pub flips_per_step: f64,
    /// Flip-rate factor per frame of age.
    pub decay: f64,
}

impl McmcSettings {
    /// `o` with the ray model's defaults: rate `1 / diagonal` (`diagonal` of the cloud's
    /// bounding box, at least the spacing) and σ = `spacing / 10`.
    fn resolve(o: &McmcFitOptions, diagonal: f64, spacing: f64) -> Result<Self> {
        let ray = RayModel {
            rate: o.rate.unwrap_or(1.0 / diagonal.max(spacing)),
            sigma: o.sigma.unwrap_or(spacing / MCMC_SIGMA_PER_SPACING),
            min_cos: o.min_cos,
        };
        ray.validate()?;
        o.validate()?;
        Ok(McmcSettings {
            ray,
            prior: o.prior,
            steps: o.steps,
            burn_in: o.burn_in,
            flips_per_step: o.flips_per_step,
            decay: o.decay,
        })
    }
}

/// The default `mcmc` σ is the spacing divided by this.
const MCMC_SIGMA_PER_SPACING: f64 = 10.0;

/// `x` rounded down to 1, 2 or 5 × 10^k.
fn nice_floor(x: f64) -> f64 {
    let e = 10f64.powf(x.log10().floor());
    let m = x / e;
    e * if m >= 5.0 {
        5.0
    } else if m >= 2.0 {
        2.0
    } else {
        1.0
    }
}

/// The default `size` is the cloud's bounding-box diagonal divided by this (then rounded
/// down to 1, 2 or 5 × 10^k).
const DIAGONALS_PER_SIZE: f64 = 8.0;
/// The default `spacing` is `size` divided by this (the thesis's hallway: 1 m squares on a
/// 0.5 m lattice).
const SIZES_PER_SPACING: f64 = 2.0;
/// The default tube `radius` is `size` divided by this.
const SIZES_PER_RADIUS: f64 = 10.0;
/// The default `cap` is at least this many noise σ.
const CAP_NOISE_SIGMAS: f64 = 5.0;
/// The default `sample_spacing` is at most `size` divided by this …
const SAMPLES_PER_SIZE: f64 = 16.0;
/// … and, with tubes, at most their circumference divided by this.
const SAMPLES_PER_CIRCUMFERENCE: f64 = 12.0;
/// Points probed for the cloud's median point spacing.
const SPACING_PROBES: usize = 2000;
/// Without a measurable point spacing it is taken as the diagonal divided by this.
const DIAGONALS_PER_POINT_SPACING: f64 = 100.0;

/// `v`, checked to be a positive finite length named `name`.
fn positive(name: &str, v: f64) -> Result<f64> {
    check::positive(name, v)?;
    Ok(v)
}

/// The lengths of [`Settings`] with their defaults from the cloud (see the module docs
/// of [`super`]), checked.
struct Lengths {
    size: f64,
    spacing: f64,
    radius: f64,
    bend: f64,
    cap: f64,
    sample_spacing: f64,
}

impl Lengths {
    /// The lengths of `o` for a cloud of bounding-box `diagonal`, median point spacing
    /// `point_spacing` and noise σ `noise`.
    fn resolve(o: &FitOptions, diagonal: f64, point_spacing: f64, noise: f64) -> Result<Self> {
        let size = o
            .size
            .unwrap_or_else(|| nice_floor(diagonal / DIAGONALS_PER_SIZE));
        let size = positive("size", size)?;
        let default_spacing = match &o.mesh {
            Some(m) if o.kinds.iter().all(|k| *k == ShapeKind::Mesh) => m.bounding_radius(),
            _ => size / SIZES_PER_SPACING,
        };
        let spacing = positive("spacing", o.spacing.unwrap_or(default_spacing))?;
        let radius = positive("radius", o.radius.unwrap_or(size / SIZES_PER_RADIUS))?;
        let bend = positive("bend", o.bend.unwrap_or(spacing))?;
        let cap = o.cap.unwrap_or(spacing.max(CAP_NOISE_SIGMAS * noise));
        check::non_negative("cap", cap)?;
        let tubes = o
            .kinds
            .iter()
            .any(|k| matches!(k, ShapeKind::Cylinder | ShapeKind::Elbow));
        let mut sample_spacing = size / SAMPLES_PER_SIZE;
        if tubes {
            let circumference = std::f64::consts::TAU * radius;
            sample_spacing = sample_spacing.min(circumference / SAMPLES_PER_CIRCUMFERENCE);
        }
        let sample_spacing = o
            .sample_spacing
            .unwrap_or(sample_spacing.max(point_spacing));
        let sample_spacing = positive("sample_spacing", sample_spacing)?;
        Ok(Lengths {
            size,
            spacing,
            radius,
            bend,
            cap,
            sample_spacing,
        })
    }
}

/// The loss options of `o` with `d_cap = cap²`, checked.
fn chamfer_options(o: &FitOptions, cap: f64) -> Result<ChamferOptions> {
    let chamfer = ChamferOptions {
        model: o.model,
        alpha: match o.model {
            PointModel::Independent => o.alpha.get(),
            PointModel::Existence => None,
        },
        beta: o.beta.get(),
        cap: cap * cap,
        surface_distance: o.model == PointModel::Existence,
        primitive_weight: o.primitive_weight,
        point_weight: o.point_weight,
    };
    chamfer.validate()?;
    Ok(chamfer)
}

/// The bounding-box diagonal of a non-empty cloud whose points do not all coincide.
fn extent(cloud: &PointCloud) -> Result<f64> {
    let (lo, hi) = cloud.bounds().ok_or(Error::EmptyCloud)?;
    let diagonal = (hi - lo).norm();
    if diagonal.is_nan() || diagonal <= 0.0 {
        let expected = "positive: the points must not all coincide";
        let name = "the cloud's extent (bounding-box diagonal)";
        return Err(Error::out_of_range(name, diagonal, expected));
    }
    Ok(diagonal)
}

/// The work budget of `o` (per point), checked positive.
pub(super) fn work_budget(o: &FitOptions) -> Result<f64> {
    let budget = o.work_budget.unwrap_or(super::DEFAULT_WORK_PER_POINT);
    check::positive("work_budget", budget)?;
    Ok(budget)
}

/// A lattice type sized by `size` (all but the elbow and the mesh) smaller than the
/// cloud's median point spacing holds about one point: its existence cannot be
/// measured, and the fit would only multiply candidates.
fn check_size_against_spacing(kinds: &[ShapeKind], size: f64, point_spacing: f64) -> Result<()> {
    let sized = kinds.iter().any(|k| {
        matches!(
            k,
            ShapeKind::Square | ShapeKind::Disk | ShapeKind::Sphere | ShapeKind::Cylinder
        )
    });
    if sized && size < point_spacing {
        let expected = format!("at least the cloud's median point spacing {point_spacing:.4}");
        return Err(Error::out_of_range("size", size, expected));
    }
    Ok(())
}

/// The lattice frame, the frame estimate's support and the grid origin of `o.frame`:
/// given values as they are, otherwise estimated from local planes of the cloud.
fn resolve_frame(
    cloud: &PointCloud,
    index: &PointIndex,
    o: &FitOptions,
    spacing: f64,
    size: f64,
) -> (UnitQuaternion<f64>, Option<f64>, Point3<f64>) {
    let given_origin = match &o.frame {
        FrameChoice::Given {
            origin: Some(p), ..
        } => Some(*p),
        _ => o.origin,
    };
    // The frame and the grid origin need more neighbourhoods than the noise level;
    // they are estimated only when not given.
    let estimated = matches!(o.frame, FrameChoice::Auto)
        || (given_origin.is_none() && !matches!(o.frame, FrameChoice::Axis));
    let planes = if estimated {
        local_planes(&cloud.points, index, DEFAULT_NEIGHBOURS, DEFAULT_MAX_POINTS)
    } else {
        Vec::new()
    };
    let (frame, frame_support) = match &o.frame {
        FrameChoice::Axis => (UnitQuaternion::identity(), None),
        FrameChoice::Given { rotation, .. } => (*rotation, None),
        FrameChoice::Auto => match estimate_frame(&planes, o.seed) {
            Some(FrameEstimate { rotation, support }) => (rotation, Some(support)),
            None => (UnitQuaternion::identity(), None),
        },
    };
    let origin = match (given_origin, &o.frame) {
        (Some(p), _) => p,
        (None, FrameChoice::Axis) => Point3::origin(),
        (None, _) => grid_origin(&planes, &cloud.points, &frame, spacing, size),
    };
    (frame, frame_support, origin)
}

/// Whether a fit of `cloud` charges free space: asked for (`Some`), or by default
/// (`None`) exactly when the cloud has sensor origins. Asking for it without them is an
/// error naming what is missing.
pub(crate) fn resolve_free_space(asked: Option<bool>, cloud: &PointCloud) -> Result<bool> {
    match (asked, cloud.sensors.is_some()) {
        (Some(true), false) => Err(Error::Missing {
            what: "each point's sensor origin (PLY vertex properties sensor_x, sensor_y, \
                   sensor_z)"
                .into(),
            needed_by: "the free-space cost (free_space)",
        }),
        (Some(on), _) => Ok(on),
        (None, has_sensors) => Ok(has_sensors),
    }
}

impl Settings {
    /// Resolves every default from the cloud (see the module docs) and validates.
    pub fn resolve(cloud: &PointCloud, index: &PointIndex, o: &FitOptions) -> Result<Settings> {
        let diagonal = extent(cloud)?;
        let point_spacing = index
            .median_spacing(&cloud.points, SPACING_PROBES)
            .unwrap_or(diagonal / DIAGONALS_PER_POINT_SPACING);
        let noise = noise_level(&local_planes(
            &cloud.points,
            index,
            DEFAULT_NEIGHBOURS,
            NOISE_MAX_POINTS,
        ))
        .unwrap_or(0.0);
        // No types named: the lattice methods (here: `mcmc`; the chamfer goes to the
        // compact model first, see `super::fit`) use the default lattice type.
        let kinds = if o.kinds.is_empty() {
            vec![DEFAULT_KIND]
        } else {
            o.kinds.clone()
        };
        let Lengths {
            size,
            spacing,
            radius,
            bend,
            cap,
            sample_spacing,
        } = Lengths::resolve(o, diagonal, point_spacing, noise)?;
        if kinds.contains(&ShapeKind::Mesh) && o.mesh.is_none() {
            return Err(Error::Missing {
                what: "a mesh (the `mesh` option)".into(),
                needed_by: "the mesh primitive type",
            });
        }
        check_size_against_spacing(&kinds, size, point_spacing)?;
        let chamfer = chamfer_options(o, cap)?;
        if let Some(r) = &o.refine {
            r.validate()?;
        }
        let method = match &o.method {
            MethodOptions::Chamfer => MethodSettings::Chamfer,
            MethodOptions::Mcmc(m) => {
                MethodSettings::Mcmc(McmcSettings::resolve(m, diagonal, spacing)?)
            }
        };
        let (frame, frame_support, origin) = resolve_frame(cloud, index, o, spacing, size);
        Ok(Settings {
            kinds,
            size,
            radius,
            bend,
            spacing,
            origin,
            frame,
            frame_source: o.frame.name(),
            frame_support,
            noise,
            refine: o.refine.clone(),
            sample_spacing,
            point_spacing,
            cap,
            chamfer,
            solver: o.solver.clone(),
            seed: o.seed,
            memory_budget: o
                .memory_budget
                .unwrap_or_else(crate::budget::default_memory_budget),
            work_budget: work_budget(o)?,
            mesh: o.mesh.clone(),
            // The mcmc method's ray likelihood holds free space already.
            free_space: matches!(o.method, MethodOptions::Chamfer)
                && resolve_free_space(o.free_space, cloud)?,
            method,
        })
    }

    /// The settings of the coarse-to-fine pass ([`super::fit`]): half the spacing, no
    /// refinement; everything else as here.
    pub fn finer(&self) -> Settings {
        Settings {
            spacing: self.spacing / 2.0,
            refine: None,
            ..self.clone()
        }
    }

    /// These settings on another lattice frame (lattice → scene) and grid origin (the
    /// re-aligned pass of [`super::fit`]).
    pub fn realigned(&self, frame: UnitQuaternion<f64>, origin: Point3<f64>) -> Settings {
        Settings {
            frame,
            origin,
            ..self.clone()
        }
    }

    /// These settings with the method's settings `method` (the mcmc sampler's length is
    /// known only once its candidates are).
    pub fn with_method(&self, method: MethodSettings) -> Settings {
        Settings {
            method,
            ..self.clone()
        }
    }

    /// The shape of each selected type at the configured sizes.
    pub fn shapes(&self) -> Vec<Shape> {
        self.kinds
            .iter()
            .filter_map(|k| {
                Some(match k {
                    ShapeKind::Square => Shape::Square { side: self.size },
                    ShapeKind::Disk => Shape::Disk {
                        diameter: self.size,
                    },
                    ShapeKind::Sphere => Shape::Sphere {
                        diameter: self.size,
                    },
                    ShapeKind::Cylinder => Shape::Cylinder {
                        length: self.size,
                        radius: self.radius,
                    },
                    ShapeKind::Elbow => Shape::Elbow {
                        bend: self.bend,
                        radius: self.radius,
                    },
                    ShapeKind::Mesh => Shape::Mesh(self.mesh.clone()?),
                    ShapeKind::Plane => return None,
                })
            })
            .collect()
    }

    /// The lattice these settings describe.
    pub fn lattice(&self) -> LatticeSpec {
        LatticeSpec {
            shapes: self.shapes(),
            spacing: self.spacing,
            origin: self.origin,
            frame: self.frame,
            sample_spacing: self.sample_spacing,
        }
    }

    /// Every setting as JSON (`result.json`'s `"settings"`; its schema is in
    /// `fit/document.rs`).
    pub fn to_json(&self) -> Value {
        serde_json::to_value(SettingsDoc::new(self, None)).unwrap_or(Value::Null)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_floor_rounds_down_to_1_2_5() {
        assert_eq!(nice_floor(1.3), 1.0);
        assert_eq!(nice_floor(0.31), 0.2);
        assert_eq!(nice_floor(7.0), 5.0);
        assert!((nice_floor(0.05) - 0.05).abs() < 1e-15);
    }
}
