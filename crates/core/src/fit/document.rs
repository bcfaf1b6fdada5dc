//! The schema of `result.json` (DESIGN §3) as serde types: [`ResultDoc`] (`primfit`,
//! `settings`, `metrics`, `primitives`) and [`SettingsDoc`], the settings of a fit.
//!
//! Written: [`super::FitResult::to_json`] and [`super::result_json`] (also used by `synth
//! --truth` and `register`, with their own settings); read back:
//! [`super::FitResult::from_json`]. The chamfer's keys (`model` … `polish`) are written
//! for the chamfer method (the compact model's without `alpha`), `ray` and `mcmc` only for
//! the mcmc method, the lattice's (`size` … `refine`) for every method but the compact
//! model, which writes `detect` instead.

use nalgebra::{Point3, UnitQuaternion};
use serde::{Deserialize, Serialize};

use super::options::{AUTO_TYPES, FitOptions, parse_types};
use super::{CompactSettings, McmcRun, McmcSettings, MethodSettings, Settings};
use crate::atlas::MeshShape;
use crate::chamfer::{ChamferOptions, PointModel};
use crate::limit::{Limit, as_count};
use crate::ray::RayModel;
use crate::refine::RefineOptions;
use crate::solve::{Parameterization, SolverOptions};
use crate::{Error, Primitive, Result, check};

/// A whole `result.json`: the version, the settings and measures (each command its own),
/// and the primitives (entries `E`: [`PrimitiveEntry`], or with more per-primitive keys).
#[derive(Debug, Serialize)]
pub struct ResultDoc<'a, S: Serialize, M: Serialize, E: Serialize = PrimitiveEntry<'a>> {
    /// The library version ([`crate::VERSION`]).
    pub primfit: &'a str,
    /// The settings used.
    pub settings: S,
    /// The measures of the result against its cloud.
    pub metrics: M,
    /// The primitives with their existence probability.
    pub primitives: Vec<E>,
}

/// One entry of `"primitives"`: the primitive's JSON and its `existence`.
#[derive(Debug, Serialize)]
pub struct PrimitiveEntry<'a> {
    /// The primitive (`type`, `size`, `pose`).
    #[serde(flatten)]
    pub primitive: &'a Primitive,
    /// Its existence probability.
    pub existence: f64,
}

/// `"settings"` of a fit: every value [`Settings`] holds that decides the result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SettingsDoc {
    /// Primitive type names (`["auto"]`: the compact model).
    pub types: Vec<String>,
    /// The lattice (every method but the compact model).
    #[serde(flatten)]
    pub lattice: Option<LatticeDoc>,
    /// [`Settings::noise`].
    pub noise: f64,
    /// [`Settings::sample_spacing`].
    pub sample_spacing: f64,
    /// [`Settings::point_spacing`].
    pub point_spacing: f64,
    /// `chamfer` or `mcmc`.
    pub method: String,
    /// The chamfer loss and its solver (the chamfer method only).
    #[serde(flatten)]
    pub chamfer: Option<ChamferDoc>,
    /// The ray model (the mcmc method only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ray: Option<RayDoc>,
    /// The sampler and what it did (the mcmc method only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mcmc: Option<McmcDoc>,
    /// What the detection found (the compact model only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detect: Option<DetectDoc>,
    /// [`Settings::seed`].
    pub seed: u64,
    /// The source of the mesh type's mesh, `null` without.
    pub mesh_model: Option<String>,
}

/// The lattice's keys of `"settings"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LatticeDoc {
    /// [`Settings::size`].
    pub size: f64,
    /// [`Settings::radius`].
    pub radius: f64,
    /// [`Settings::bend`].
    pub bend: f64,
    /// [`Settings::spacing`].
    pub spacing: f64,
    /// [`Settings::origin`].
    pub origin: [f64; 3],
    /// The lattice frame and how it was chosen.
    pub frame: FrameDoc,
    /// The refinement, `null` without.
    pub refine: Option<RefineDoc>,
}

/// `settings.detect`: the compact model's [`CompactSettings`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectDoc {
    /// [`CompactSettings::segments`].
    pub segments: usize,
    /// [`CompactSettings::proposed`].
    pub proposed: usize,
    /// [`CompactSettings::growing_noise`].
    pub growing_noise: f64,
    /// [`CompactSettings::angle_degrees`].
    pub angle_degrees: f64,
    /// [`CompactSettings::voxel`].
    pub voxel: Option<f64>,
}

/// `settings.frame`: lattice frame → scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameDoc {
    /// `axis`, `auto` or `given`.
    pub source: String,
    /// Unit quaternion `[w, x, y, z]`.
    pub rotation: [f64; 4],
    /// Share of flat normals near a frame axis (estimated frames), else `null`.
    pub support: Option<f64>,
}

/// `settings.refine`: [`RefineOptions`] with the trim distance resolved.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RefineDoc {
    /// [`RefineOptions::rounds`].
    pub rounds: usize,
    /// [`RefineOptions::iterations`].
    pub iterations: usize,
    /// The trim distance (scene units): [`RefineOptions::trim`], or the cap.
    pub trim: f64,
    /// [`RefineOptions::max_growth`].
    pub max_growth: f64,
    /// [`RefineOptions::recheck`].
    pub recheck: bool,
    /// [`RefineOptions::merge`].
    pub merge: bool,
    /// [`RefineOptions::fill`].
    pub fill: bool,
    /// [`RefineOptions::retype`].
    pub retype: bool,
}

/// The chamfer method's keys of `"settings"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChamferDoc {
    /// `existence` or `independent`.
    pub model: String,
    /// α (`"inf"`: all); not written by the compact model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<Limit>,
    /// β (`"inf"`: all).
    pub beta: Limit,
    /// [`Settings::cap`] (a distance, not squared).
    pub cap: f64,
    /// `[primitive_weight, point_weight]`.
    pub weights: [f64; 2],
    /// `box` or `logit`.
    pub parameterization: String,
    /// [`SolverOptions::max_iterations`].
    pub max_iterations: usize,
    /// [`SolverOptions::search_points`] (no limit: the largest count).
    #[serde(with = "as_count")]
    pub search_points: Limit,
    /// [`SolverOptions::threshold`].
    pub threshold: f64,
    /// [`SolverOptions::polish`].
    pub polish: bool,
    /// [`Settings::free_space`] (absent in older results: off).
    #[serde(default)]
    pub free_space: bool,
}

/// `settings.ray`: the mcmc method's [`RayModel`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RayDoc {
    /// [`RayModel::rate`].
    pub rate: f64,
    /// [`RayModel::sigma`].
    pub sigma: f64,
    /// [`RayModel::min_cos`].
    pub min_cos: f64,
}

/// `settings.mcmc`: the sampler's settings and, in a result, its run ([`McmcRun`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct McmcDoc {
    /// [`McmcSettings::prior`].
    pub prior: f64,
    /// Proposals after burn-in (the run's; `null` before a run when derived).
    pub steps: Option<usize>,
    /// Proposals before counting (as `steps`).
    pub burn_in: Option<usize>,
    /// [`McmcSettings::flips_per_step`].
    pub flips_per_step: f64,
    /// [`McmcSettings::decay`].
    pub decay: f64,
    /// What the run did, in a result.
    #[serde(flatten)]
    pub run: Option<McmcRunDoc>,
}

/// The [`McmcRun`] keys of `settings.mcmc` besides `steps` and `burn_in`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct McmcRunDoc {
    /// [`McmcRun::accepted`].
    pub accepted: usize,
    /// [`McmcRun::polish_flips`].
    pub polish_flips: usize,
    /// [`McmcRun::log_likelihood`].
    pub log_likelihood: f64,
    /// [`McmcRun::log_posterior`].
    pub log_posterior: f64,
    /// [`McmcRun::frames`].
    pub frames: usize,
    /// [`McmcRun::skipped_points`].
    pub skipped_points: usize,
}

impl SettingsDoc {
    /// The document of `s`, with the mcmc `run` when there was one.
    pub fn new(s: &Settings, run: Option<&McmcRun>) -> Self {
        let q = s.frame.quaternion();
        let lattice = LatticeDoc {
            size: s.size,
            radius: s.radius,
            bend: s.bend,
            spacing: s.spacing,
            origin: s.origin.coords.into(),
            frame: FrameDoc {
                source: s.frame_source.to_owned(),
                rotation: [q.w, q.i, q.j, q.k],
                support: s.frame_support.filter(|v| v.is_finite()),
            },
            refine: s.refine.as_ref().map(|r| RefineDoc::new(r, s.cap)),
        };
        let mut doc = SettingsDoc {
            types: s.kinds.iter().map(|k| k.name().to_owned()).collect(),
            lattice: Some(lattice),
            noise: s.noise,
            sample_spacing: s.sample_spacing,
            point_spacing: s.point_spacing,
            method: s.method.name().to_owned(),
            chamfer: Some(ChamferDoc::new(s)),
            ray: None,
            mcmc: None,
            detect: None,
            seed: s.seed,
            mesh_model: s.mesh.as_ref().map(|m| m.source.clone()),
        };
        match &s.method {
            MethodSettings::Chamfer => {}
            MethodSettings::Mcmc(m) => {
                // The chamfer loss and its solver play no part.
                doc.chamfer = None;
                doc.ray = Some(RayDoc::from(m.ray));
                doc.mcmc = Some(McmcDoc::new(m, run));
            }
            MethodSettings::Compact(c) => {
                // No lattice: its sizes, frame and refinement play no part.
                doc.types = vec![AUTO_TYPES.to_owned()];
                doc.lattice = None;
                if let Some(chamfer) = &mut doc.chamfer {
                    chamfer.alpha = None;
                }
                doc.detect = Some(DetectDoc::from(c));
            }
        }
        doc
    }

    /// The settings this document describes; `load` gives the mesh of `mesh_model`. What
    /// `result.json` does not hold (the solver's tolerances, the memory budget, for the
    /// mcmc method the chamfer's settings) takes the defaults of [`FitOptions`]. Also
    /// returns the mcmc run it records.
    pub fn to_settings(
        &self,
        load: &dyn Fn(&str) -> Result<MeshShape>,
    ) -> Result<(Settings, Option<McmcRun>)> {
        let kinds = parse_types(&self.types)?;
        let defaults = FitOptions::default();
        let cap = self.chamfer.as_ref().map_or(0.0, |c| c.cap);
        let (chamfer, solver) = match (&self.chamfer, self.method.as_str()) {
            (Some(c), _) => c.options()?,
            (None, "mcmc") => (ChamferOptions::default(), defaults.solver.clone()),
            (None, _) => return Err(Error::json("settings.model", "the chamfer's settings")),
        };
        let (method, run) = self.method_settings()?;
        // The compact model has no lattice (it writes none; here it is zero, as in a fit).
        let lattice = match (&self.lattice, &method) {
            (Some(l), _) => l.clone(),
            (None, MethodSettings::Compact(_)) => LatticeDoc::none(),
            (None, _) => return Err(Error::json("settings.size", "the lattice's settings")),
        };
        let settings = Settings {
            kinds,
            size: lattice.size,
            radius: lattice.radius,
            bend: lattice.bend,
            spacing: lattice.spacing,
            origin: Point3::from(lattice.origin),
            frame: lattice.frame.rotation()?,
            frame_source: lattice.frame.source()?,
            frame_support: lattice.frame.support,
            noise: self.noise,
            refine: lattice.refine.as_ref().map(|r| r.options(cap)),
            sample_spacing: self.sample_spacing,
            point_spacing: self.point_spacing,
            cap,
            chamfer,
            solver,
            seed: self.seed,
            memory_budget: crate::budget::default_memory_budget(),
            work_budget: super::DEFAULT_WORK_PER_POINT,
            mesh: self.mesh_model.as_deref().map(load).transpose()?,
            free_space: self.chamfer.as_ref().is_some_and(|c| c.free_space),
            method,
        };
        Ok((settings, run))
    }

    /// The method's settings and the mcmc run.
    fn method_settings(&self) -> Result<(MethodSettings, Option<McmcRun>)> {
        match (self.method.as_str(), &self.ray, &self.mcmc) {
            ("chamfer", _, _) => Ok((
                self.detect.as_ref().map_or(MethodSettings::Chamfer, |d| {
                    MethodSettings::Compact(d.to_settings())
                }),
                None,
            )),
            ("mcmc", Some(ray), Some(m)) => {
                let settings = McmcSettings {
                    ray: RayModel {
                        rate: ray.rate,
                        sigma: ray.sigma,
                        min_cos: ray.min_cos,
                    },
                    prior: m.prior,
                    steps: m.steps,
                    burn_in: m.burn_in,
                    flips_per_step: m.flips_per_step,
                    decay: m.decay,
                };
                let run = match (&m.run, m.steps, m.burn_in) {
                    (Some(r), Some(steps), Some(burn_in)) => Some(McmcRun {
                        steps,
                        burn_in,
                        accepted: r.accepted,
                        polish_flips: r.polish_flips,
                        log_likelihood: r.log_likelihood,
                        log_posterior: r.log_posterior,
                        frames: r.frames,
                        skipped_points: r.skipped_points,
                    }),
                    _ => None,
                };
                Ok((MethodSettings::Mcmc(settings), run))
            }
            ("mcmc", _, _) => Err(Error::json("settings.ray", "the mcmc method's ray model")),
            (other, _, _) => Err(Error::Unknown {
                what: "method",
                value: other.into(),
                expected: "chamfer or mcmc",
            }),
        }
    }
}

impl LatticeDoc {
    /// The lattice settings of a fit without one (the compact model): zero sizes, the
    /// scene axes.
    fn none() -> Self {
        LatticeDoc {
            size: 0.0,
            radius: 0.0,
            bend: 0.0,
            spacing: 0.0,
            origin: [0.0; 3],
            frame: FrameDoc {
                source: "auto".into(),
                rotation: [1.0, 0.0, 0.0, 0.0],
                support: None,
            },
            refine: None,
        }
    }
}

impl From<&CompactSettings> for DetectDoc {
    fn from(c: &CompactSettings) -> Self {
        DetectDoc {
            segments: c.segments,
            proposed: c.proposed,
            growing_noise: c.growing_noise,
            angle_degrees: c.angle_degrees,
            voxel: c.voxel,
        }
    }
}

impl DetectDoc {
    /// The compact model's settings this entry was written from.
    fn to_settings(&self) -> CompactSettings {
        CompactSettings {
            segments: self.segments,
            proposed: self.proposed,
            growing_noise: self.growing_noise,
            angle_degrees: self.angle_degrees,
            voxel: self.voxel,
        }
    }
}

impl FrameDoc {
    /// The rotation (normalised; a zero quaternion is an error).
    fn rotation(&self) -> Result<UnitQuaternion<f64>> {
        check::unit_quaternion("frame.rotation", self.rotation)
    }

    /// The source as [`Settings::frame_source`] holds it.
    fn source(&self) -> Result<&'static str> {
        match self.source.as_str() {
            "axis" => Ok("axis"),
            "auto" => Ok("auto"),
            "given" => Ok("given"),
            other => Err(Error::Unknown {
                what: "frame source",
                value: other.into(),
                expected: "axis, auto or given",
            }),
        }
    }
}

impl RefineDoc {
    /// The document of `r` under a fit with `cap` (the default trim).
    fn new(r: &RefineOptions, cap: f64) -> Self {
        RefineDoc {
            rounds: r.rounds,
            iterations: r.iterations,
            trim: r.trim.unwrap_or(cap),
            max_growth: r.max_growth,
            recheck: r.recheck,
            merge: r.merge,
            fill: r.fill,
            retype: r.retype,
        }
    }

    /// The options; a trim equal to `cap` is the default (`None`).
    fn options(&self, cap: f64) -> RefineOptions {
        RefineOptions {
            rounds: self.rounds,
            iterations: self.iterations,
            trim: (self.trim != cap).then_some(self.trim),
            max_growth: self.max_growth,
            recheck: self.recheck,
            merge: self.merge,
            fill: self.fill,
            retype: self.retype,
        }
    }
}

impl ChamferDoc {
    /// The chamfer keys of `s`.
    fn new(s: &Settings) -> Self {
        let c = &s.chamfer;
        ChamferDoc {
            model: c.model.name().to_owned(),
            alpha: Some(Limit::from_bound(c.alpha)),
            beta: Limit::from_bound(c.beta),
            cap: s.cap,
            weights: [c.primitive_weight, c.point_weight],
            parameterization: s.solver.parameterization.name().to_owned(),
            max_iterations: s.solver.max_iterations,
            search_points: s.solver.search_points,
            threshold: s.solver.threshold,
            polish: s.solver.polish,
            free_space: s.free_space,
        }
    }

    /// The loss and solver options (the solver's tolerances: defaults).
    fn options(&self) -> Result<(ChamferOptions, SolverOptions)> {
        let model = PointModel::parse(&self.model)?;
        let chamfer = ChamferOptions {
            model,
            alpha: self.alpha.and_then(Limit::get),
            beta: self.beta.get(),
            cap: self.cap * self.cap,
            surface_distance: model == PointModel::Existence,
            primitive_weight: self.weights[0],
            point_weight: self.weights[1],
        };
        let solver = SolverOptions {
            parameterization: Parameterization::parse(&self.parameterization)?,
            max_iterations: self.max_iterations,
            search_points: self.search_points,
            threshold: self.threshold,
            polish: self.polish,
            ..SolverOptions::default()
        };
        Ok((chamfer, solver))
    }
}

impl From<RayModel> for RayDoc {
    fn from(r: RayModel) -> Self {
        RayDoc {
            rate: r.rate,
            sigma: r.sigma,
            min_cos: r.min_cos,
        }
    }
}

impl McmcDoc {
    /// The sampler's keys of `m`, with the `run`'s steps and record when there was one.
    fn new(m: &McmcSettings, run: Option<&McmcRun>) -> Self {
        McmcDoc {
            prior: m.prior,
            steps: run.map(|r| r.steps).or(m.steps),
            burn_in: run.map(|r| r.burn_in).or(m.burn_in),
            flips_per_step: m.flips_per_step,
            decay: m.decay,
            run: run.map(|r| McmcRunDoc {
                accepted: r.accepted,
                polish_flips: r.polish_flips,
                log_likelihood: r.log_likelihood,
                log_posterior: r.log_posterior,
                frames: r.frames,
                skipped_points: r.skipped_points,
            }),
        }
    }
}
