//! [`FitOptions`]: what a user may set, and the one table of defaults.
//!
//! `FitOptions::default()` is `primfit fit` without flags and `primfit.fit(points)`
//! without keywords: the CLI and the Python package take every default from here. A
//! field that is an `Option` is derived from the cloud when `None`
//! ([`super::Settings::resolve`] documents how); every other default is a constant
//! below, or the `Default` of the option's own type ([`RefineOptions`],
//! [`SolverOptions`]).

use nalgebra::Point3;

use crate::atlas::{MeshShape, ShapeKind};
use crate::chamfer::PointModel;
use crate::frame::FrameChoice;
use crate::refine::RefineOptions;
use crate::solve::SolverOptions;
use crate::{Error, Limit, Result, check};

pub use crate::solve::{DEFAULT_MAX_ITERATIONS, DEFAULT_SEARCH_POINTS};

/// The primitive type of the lattice when none is named ([`FitOptions::lattice`]).
pub const DEFAULT_KIND: ShapeKind = ShapeKind::Square;
/// The name of "the types the data supports" (`--types auto`, the default): an empty
/// [`FitOptions::kinds`], the compact model of [`crate::compact`].
pub const AUTO_TYPES: &str = "auto";

/// The primitive types of `names` (`square`, `cylinder`, …); `["auto"]` (or nothing) is
/// the empty list: the types the data supports ([`AUTO_TYPES`]).
pub fn parse_types<S: AsRef<str>>(names: &[S]) -> Result<Vec<ShapeKind>> {
    let names: Vec<&str> = names.iter().map(|n| n.as_ref().trim()).collect();
    if names.is_empty() || names == [AUTO_TYPES] {
        return Ok(Vec::new());
    }
    names.iter().map(|n| ShapeKind::parse(n)).collect()
}
/// Default lattice frame: the scan's dominant axes, the grid on the data.
pub const DEFAULT_FRAME: FrameChoice = FrameChoice::Auto;
/// Default α (samples per candidate and point, `independent` model only; thesis §6.3).
pub const DEFAULT_ALPHA: Limit = Limit::At(10);
/// Default β (candidates per point): 24 was the least that recovered every synthetic
/// pipe.
pub const DEFAULT_BETA: Limit = Limit::At(32);
/// Default weight of the primitive term and of the point term.
pub const DEFAULT_WEIGHT: f64 = 1.0;
/// Default seed of every random choice.
pub const DEFAULT_SEED: u64 = 0;
/// Default `p(φ_i = 1)` of a candidate the `mcmc` prior supports (thesis §4.2.1).
pub const DEFAULT_PRIOR: f64 = 0.1;
/// Default floor of `|cos θ|` of the `mcmc` ray model (the along-ray deviation is at most
/// 5 σ).
pub const DEFAULT_MIN_COS: f64 = 0.2;
/// Default expected flips per `mcmc` proposal.
pub const DEFAULT_FLIPS_PER_STEP: f64 = 1.0;
/// Default `mcmc` flip-rate factor per frame of age.
pub const DEFAULT_DECAY: f64 = 0.9;
pub use crate::budget::DEFAULT_MEMORY_SHARE;

/// User-facing options of [`super::fit`]; `None` means "derive from the cloud"
/// ([`super::Settings::resolve`]). The `Default` is `primfit fit`'s.
#[derive(Debug, Clone)]
pub struct FitOptions {
    /// Primitive types to use (default: [`DEFAULT_KIND`]); at least one.
    pub kinds: Vec<ShapeKind>,
    /// Main extent: square side, disk/sphere diameter, cylinder length (scene units).
    pub size: Option<f64>,
    /// Tube radius of cylinders and elbows (scene units).
    pub radius: Option<f64>,
    /// Elbow bend radius (centre line, scene units).
    pub bend: Option<f64>,
    /// Lattice translation step (scene units).
    pub spacing: Option<f64>,
    /// A lattice point (scene coordinates).
    pub origin: Option<Point3<f64>>,
    /// How the lattice frame is chosen (default: [`DEFAULT_FRAME`]).
    pub frame: FrameChoice,
    /// Continuous refinement after the existence decision, `None` for none (default:
    /// [`RefineOptions::default`]).
    pub refine: Option<RefineOptions>,
    /// Spacing of candidate surface samples (scene units).
    pub sample_spacing: Option<f64>,
    /// Point-term model (default: [`PointModel::Existence`]).
    pub model: PointModel,
    /// α: samples per candidate and point, `independent` model only (default
    /// [`DEFAULT_ALPHA`]).
    pub alpha: Limit,
    /// β: candidates per point (default [`DEFAULT_BETA`]).
    pub beta: Limit,
    /// The distance whose square is `d_cap` (scene units).
    pub cap: Option<f64>,
    /// Weight of the primitive term (default [`DEFAULT_WEIGHT`]).
    pub primitive_weight: f64,
    /// Weight of the point term (default [`DEFAULT_WEIGHT`]).
    pub point_weight: f64,
    /// The mesh used by the `mesh` type.
    pub mesh: Option<MeshShape>,
    /// Solver settings (default: [`SolverOptions::default`]).
    pub solver: SolverOptions,
    /// The inference method and its own options (default: the chamfer).
    pub method: MethodOptions,
    /// Upper bound on the estimated peak memory of the fit ([`super::estimate_bytes`]),
    /// bytes (default: [`DEFAULT_MEMORY_SHARE`] of the machine's memory).
    pub memory_budget: Option<u64>,
    /// Upper bound on the estimated work of a lattice pass ([`super::estimate_work`]),
    /// nearest-neighbour queries per input point (default: [`super::DEFAULT_WORK_PER_POINT`]).
    pub work_budget: Option<f64>,
    /// Charge candidates for the rays that cross them in front of their points
    /// ([`crate::ray::FreeSpace`]); `None` (default): on exactly when the cloud has
    /// sensor origins; `Some(true)` without them is an error.
    pub free_space: Option<bool>,
    /// Seed for every random choice (the chamfer fit itself is deterministic).
    pub seed: u64,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            kinds: Vec::new(),
            size: None,
            radius: None,
            bend: None,
            spacing: None,
            origin: None,
            frame: DEFAULT_FRAME,
            refine: Some(RefineOptions::default()),
            sample_spacing: None,
            model: PointModel::default(),
            alpha: DEFAULT_ALPHA,
            beta: DEFAULT_BETA,
            cap: None,
            primitive_weight: DEFAULT_WEIGHT,
            point_weight: DEFAULT_WEIGHT,
            mesh: None,
            solver: SolverOptions::default(),
            method: MethodOptions::default(),
            memory_budget: None,
            work_budget: None,
            free_space: None,
            seed: DEFAULT_SEED,
        }
    }
}

impl FitOptions {
    /// The plain lattice pipeline (`primfit fit --frame axis --no-refine`): the scene
    /// axes and origin, no continuous refinement; everything else as [`Default`].
    pub fn lattice() -> Self {
        FitOptions {
            kinds: vec![DEFAULT_KIND],
            frame: FrameChoice::Axis,
            refine: None,
            ..Default::default()
        }
    }
}

/// The inference method of a fit (`--method`) with the options only it has.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum MethodOptions {
    /// Probabilistic chamfer + L-BFGS over existence (thesis ch. 6).
    #[default]
    Chamfer,
    /// Ray likelihood + Metropolis–Hastings over existence (thesis ch. 4,
    /// [`crate::ray`]); needs each point's sensor origin.
    Mcmc(McmcFitOptions),
}

impl MethodOptions {
    /// The CLI/JSON name: `chamfer` or `mcmc`.
    pub fn name(&self) -> &'static str {
        match self {
            MethodOptions::Chamfer => "chamfer",
            MethodOptions::Mcmc(_) => "mcmc",
        }
    }

    /// The method called `name`, with its default options.
    pub fn parse(name: &str) -> Result<Self> {
        match name.trim() {
            "chamfer" => Ok(MethodOptions::Chamfer),
            "mcmc" => Ok(MethodOptions::Mcmc(McmcFitOptions::default())),
            o => Err(Error::Unknown {
                what: "method",
                value: o.into(),
                expected: "chamfer or mcmc",
            }),
        }
    }
}

/// Options of the `mcmc` method on top of [`FitOptions`] (sizes, lattice, seed); `None`
/// means "derive" (see [`super::Settings::resolve`]).
#[derive(Debug, Clone, PartialEq)]
pub struct McmcFitOptions {
    /// Noise rate `r` (1 / scene unit) [default: 1 / the bounding-box diagonal].
    pub rate: Option<f64>,
    /// Surface deviation σ (scene units) [default: spacing / 10].
    pub sigma: Option<f64>,
    /// Floor of `|cos θ|` in the projected deviation (default [`DEFAULT_MIN_COS`]).
    pub min_cos: f64,
    /// `p(φ_i = 1)` of supported candidates (default [`DEFAULT_PRIOR`]).
    pub prior: f64,
    /// Proposals after burn-in [default: `max(1000, 20 N)` for N supported candidates].
    pub steps: Option<usize>,
    /// Proposals before counting [default: `steps / 5`].
    pub burn_in: Option<usize>,
    /// Expected flips per proposal (default [`DEFAULT_FLIPS_PER_STEP`]).
    pub flips_per_step: f64,
    /// Flip-rate factor per frame of age (default [`DEFAULT_DECAY`]).
    pub decay: f64,
}

/// The most `mcmc` proposals (steps, and burn-in): 100× the default of a 5 000-candidate
/// lattice, minutes of sampling at most.
pub const MAX_MCMC_STEPS: usize = 10_000_000;

impl McmcFitOptions {
    /// Checks the counts, which need no cloud ([`MAX_MCMC_STEPS`]).
    pub fn validate(&self) -> Result<()> {
        if let Some(steps) = self.steps {
            check::at_most("steps", steps, MAX_MCMC_STEPS)?;
        }
        if let Some(burn_in) = self.burn_in {
            check::at_most("burn_in", burn_in, MAX_MCMC_STEPS)?;
        }
        Ok(())
    }
}

impl Default for McmcFitOptions {
    fn default() -> Self {
        McmcFitOptions {
            rate: None,
            sigma: None,
            min_cos: DEFAULT_MIN_COS,
            prior: DEFAULT_PRIOR,
            steps: None,
            burn_in: None,
            flips_per_step: DEFAULT_FLIPS_PER_STEP,
            decay: DEFAULT_DECAY,
        }
    }
}
