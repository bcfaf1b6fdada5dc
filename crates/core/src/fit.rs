//! The whole fitting pipeline: cloud → lattice → coefficients → solver → primitives.
//!
//! [`FitOptions`] holds what a user may set; [`Settings`] is every value actually used,
//! with defaults derived from the cloud ([`Settings::resolve`]):
//!
//! | setting | default |
//! |---|---|
//! | `size` | the bounding-box diagonal ÷ 8, rounded down to 1, 2 or 5 × 10^k |
//! | `spacing` | `size / 2` (the thesis's hallway: 1 m squares on a 0.5 m lattice); when `mesh` is the only type, the mesh's bounding radius (as in the registration scenes) |
//! | `radius` | `size / 10` (tube radius of cylinders and elbows) |
//! | `bend` | `spacing` (elbow centre-line radius) |
//! | `cap` | `max(spacing, 5σ)`: every point is within half a step of some lattice position, so a point farther than a whole step from every chosen primitive is treated as unexplained; on very noisy scans (noise σ, see below) a point within 5σ of a surface still counts as explained. `d_cap = cap²` |
//! | noise σ | the median off-plane spread of the flattest half of the k = 32 nearest-neighbour neighbourhoods of up to 4 000 evenly strided points ([`crate::surface::noise_level`], [`crate::surface::NOISE_MAX_POINTS`]) |
//! | `sample_spacing` | `min(size / 16, 2π·radius / 12)` but never finer than the cloud's median point spacing |
//! | `beta` | 32 candidates per point (24 was the least that recovered every synthetic pipe) |
//! | `alpha` | 10 samples per candidate (thesis §6.3), `independent` model only |
//! | frame | [`FrameChoice::Axis`] (the scene axes) in the library; the CLI defaults to `auto`: the scan's dominant axes ([`crate::frame::estimate_frame`]) |
//! | lattice origin | `axis`: the scene origin; `auto` and a given frame without origin: grid planes on the data ([`crate::frame::grid_origin`]) |
//! | refinement | off in the library (`FitOptions::refine = None`); the CLI turns it on ([`RefineOptions::default`]) |

use std::time::Instant;

use nalgebra::{Point3, UnitQuaternion};
use serde_json::{Value, json};

use crate::atlas::{MeshShape, Shape, ShapeKind, TriMesh};
use crate::chamfer::{ChamferOptions, Coefficients, Evaluator, LossValue, PointModel};
use crate::frame::{FrameChoice, FrameEstimate, estimate_frame, grid_origin, realign};
use crate::lattice::{CandidateSet, LatticeSpec};
use crate::metrics::point_to_model_distances;
use crate::progress::{Progress, Silent};
use crate::refine::{RefineContext, RefineOptions, Refined, refine};
use crate::solve::{Solution, SolverOptions, solve};
use crate::spatial::{PointIndex, median_spacing};
use crate::surface::{
    DEFAULT_MAX_POINTS, DEFAULT_NEIGHBOURS, NOISE_MAX_POINTS, local_planes, noise_level,
};
use crate::{Error, PointCloud, Primitive, Result};

/// User-facing options of [`fit`]; `None` means "derive from the cloud".
#[derive(Debug, Clone, Default)]
pub struct FitOptions {
    /// Primitive types to use (default: square).
    pub kinds: Vec<ShapeKind>,
    /// Main extent: square side, disk/sphere diameter, cylinder length.
    pub size: Option<f64>,
    /// Tube radius of cylinders and elbows.
    pub radius: Option<f64>,
    /// Elbow bend radius (centre line).
    pub bend: Option<f64>,
    /// Lattice translation step.
    pub spacing: Option<f64>,
    /// A lattice point.
    pub origin: Option<Point3<f64>>,
    /// How the lattice frame is chosen (default: the scene axes).
    pub frame: FrameChoice,
    /// Continuous refinement after the existence decision (default: none).
    pub refine: Option<RefineOptions>,
    /// Spacing of candidate surface samples.
    pub sample_spacing: Option<f64>,
    /// Point-term model.
    pub model: PointModel,
    /// α; `Some(usize::MAX)` = unlimited.
    pub alpha: Option<usize>,
    /// β; `Some(usize::MAX)` = unlimited.
    pub beta: Option<usize>,
    /// The distance whose square is `d_cap`.
    pub cap: Option<f64>,
    /// Weight of the primitive term (default 1).
    pub primitive_weight: Option<f64>,
    /// Weight of the point term (default 1).
    pub point_weight: Option<f64>,
    /// The mesh used by the `mesh` type.
    pub mesh: Option<MeshShape>,
    /// Solver settings.
    pub solver: SolverOptions,
    /// Upper bound on the estimated peak memory of the fit ([`estimate_bytes`]), bytes
    /// (default: half the machine's memory).
    pub memory_budget: Option<u64>,
    /// Seed for every random choice (the chamfer fit itself is deterministic).
    pub seed: u64,
}

/// The inference method of a fit (`--method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Probabilistic chamfer + L-BFGS over existence (thesis ch. 6).
    #[default]
    Chamfer,
    /// Ray likelihood + Metropolis–Hastings over existence (thesis ch. 4, [`crate::ray`]).
    Mcmc,
}

impl Method {
    /// The CLI/JSON name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Chamfer => "chamfer",
            Method::Mcmc => "mcmc",
        }
    }
}

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
    /// Budget for the estimated peak memory of a fit, bytes ([`estimate_bytes`]).
    pub memory_budget: u64,
    /// Mesh source, if the mesh type is used.
    pub mesh: Option<MeshShape>,
    /// The inference method.
    pub method: Method,
    /// Settings specific to the method, merged into [`Settings::to_json`] (e.g. the ray
    /// model and sampler of `mcmc`).
    pub method_settings: serde_json::Map<String, Value>,
}

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

fn limit(v: Option<usize>, default: usize) -> Option<usize> {
    match v {
        None => Some(default),
        Some(usize::MAX) => None,
        Some(n) => Some(n),
    }
}

/// Physical memory in bytes (Linux `/proc/meminfo`), or 8 GiB when unknown.
fn physical_memory() -> u64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("MemTotal:"))?;
            line.split_whitespace()
                .nth(1)?
                .parse::<u64>()
                .ok()
                .map(|kb| kb * 1024)
        })
        .unwrap_or(8 << 30)
}

fn positive(name: &str, v: f64) -> Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(Error::invalid(format!(
            "--{name} must be a positive length, got {v}"
        )))
    }
}

impl Settings {
    /// Resolves every default from the cloud (see the module docs) and validates.
    pub fn resolve(cloud: &PointCloud, index: &PointIndex, o: &FitOptions) -> Result<Settings> {
        let (lo, hi) = cloud
            .bounds()
            .ok_or_else(|| Error::invalid("the cloud is empty"))?;
        let diagonal = (hi - lo).norm();
        if diagonal.is_nan() || diagonal <= 0.0 {
            return Err(Error::invalid(
                "the cloud has no extent (all points coincide)",
            ));
        }
        let point_spacing = median_spacing(&cloud.points, index, 2000).unwrap_or(diagonal / 100.0);
        let noise = noise_level(&local_planes(
            &cloud.points,
            index,
            DEFAULT_NEIGHBOURS,
            NOISE_MAX_POINTS,
        ))
        .unwrap_or(0.0);

        let kinds = if o.kinds.is_empty() {
            vec![ShapeKind::Square]
        } else {
            o.kinds.clone()
        };
        let size = positive("size", o.size.unwrap_or_else(|| nice_floor(diagonal / 8.0)))?;
        let default_spacing = match &o.mesh {
            Some(m) if kinds.iter().all(|k| *k == ShapeKind::Mesh) => m.bounding_radius(),
            _ => size / 2.0,
        };
        let spacing = positive("spacing", o.spacing.unwrap_or(default_spacing))?;
        let radius = positive("radius", o.radius.unwrap_or(size / 10.0))?;
        let bend = positive("bend", o.bend.unwrap_or(spacing))?;
        let cap = o.cap.unwrap_or(spacing.max(5.0 * noise));
        if !(cap.is_finite() && cap >= 0.0) {
            return Err(Error::invalid(format!(
                "--cap must be a finite distance ≥ 0, got {cap}"
            )));
        }
        let tubes = kinds
            .iter()
            .any(|k| matches!(k, ShapeKind::Cylinder | ShapeKind::Elbow));
        let mut sample_spacing = size / 16.0;
        if tubes {
            sample_spacing = sample_spacing.min(std::f64::consts::TAU * radius / 12.0);
        }
        let sample_spacing = positive(
            "sample-spacing",
            o.sample_spacing
                .unwrap_or(sample_spacing.max(point_spacing)),
        )?;
        if kinds.contains(&ShapeKind::Mesh) && o.mesh.is_none() {
            return Err(Error::invalid(
                "the mesh type needs a mesh (--mesh-model FILE.ply)",
            ));
        }
        let chamfer = ChamferOptions {
            model: o.model,
            alpha: match o.model {
                PointModel::Independent => limit(o.alpha, 10),
                PointModel::Existence => None,
            },
            beta: limit(o.beta, 32),
            cap: cap * cap,
            surface_distance: o.model == PointModel::Existence,
            primitive_weight: o.primitive_weight.unwrap_or(1.0),
            point_weight: o.point_weight.unwrap_or(1.0),
        };
        chamfer.validate()?;
        if let Some(r) = &o.refine {
            r.validate()?;
        }
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
            memory_budget: o.memory_budget.unwrap_or(physical_memory() / 2),
            mesh: o.mesh.clone(),
            method: Method::Chamfer,
            method_settings: serde_json::Map::new(),
        })
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

    /// Every setting as JSON (`result.json`'s `"settings"`).
    pub fn to_json(&self) -> Value {
        let lim = |v: Option<usize>| v.map_or(Value::from("inf"), Value::from);
        let frame = FrameEstimate {
            rotation: self.frame,
            support: self.frame_support.unwrap_or(f64::NAN),
        }
        .to_json(self.frame_source);
        let refine = self.refine.as_ref().map(|r| {
            json!({ "rounds": r.rounds, "iterations": r.iterations, "trim": r.trim.unwrap_or(self.cap),
                    "max_growth": r.max_growth, "recheck": r.recheck, "merge": r.merge, "fill": r.fill,
                    "retype": r.retype })
        });
        let mut doc = json!({
            "types": self.kinds.iter().map(|k| k.name()).collect::<Vec<_>>(),
            "size": self.size,
            "radius": self.radius,
            "bend": self.bend,
            "spacing": self.spacing,
            "origin": [self.origin.x, self.origin.y, self.origin.z],
            "frame": frame,
            "noise": self.noise,
            "refine": refine,
            "sample_spacing": self.sample_spacing,
            "point_spacing": self.point_spacing,
            "model": self.chamfer.model.name(),
            "alpha": lim(self.chamfer.alpha),
            "beta": lim(self.chamfer.beta),
            "cap": self.cap,
            "weights": [self.chamfer.primitive_weight, self.chamfer.point_weight],
            "parameterization": self.solver.parameterization.name(),
            "max_iterations": self.solver.max_iterations,
            "search_points": self.solver.search_points,
            "threshold": self.solver.threshold,
            "polish": self.solver.polish,
            "method": self.method.name(),
            "seed": self.seed,
            "mesh_model": self.mesh.as_ref().map(|m| m.source.clone()),
        });
        if let Value::Object(m) = &mut doc {
            if self.method != Method::Chamfer {
                // The chamfer loss and its solver play no part in other methods.
                for key in [
                    "model",
                    "alpha",
                    "beta",
                    "cap",
                    "weights",
                    "parameterization",
                    "max_iterations",
                    "search_points",
                    "threshold",
                    "polish",
                ] {
                    m.remove(key);
                }
            }
            m.extend(self.method_settings.clone());
        }
        doc
    }
}

/// Size and timing facts of a fit, for the summary and the benchmark table.
#[derive(Debug, Clone, Default)]
pub struct FitStats {
    /// Input points J.
    pub points: usize,
    /// Lattice candidates near the data (after the occupancy prior).
    pub lattice_candidates: usize,
    /// Candidates N the solver saw: those not dominated (`chamfer::dominance`).
    pub candidates: usize,
    /// (point, candidate) entries of the point term.
    pub entries: usize,
    /// Bytes per entry.
    pub bytes_per_entry: usize,
    /// Bytes held by the coefficients.
    pub coefficient_bytes: usize,
    /// The peak estimate checked against the memory budget ([`estimate_bytes`]).
    pub estimated_bytes: u64,
    /// Seconds spent building the lattice.
    pub lattice_seconds: f64,
    /// Seconds spent building coefficients.
    pub coefficient_seconds: f64,
    /// Seconds spent in L-BFGS, thresholding and polish.
    pub solve_seconds: f64,
    /// Seconds spent refining (0 without refinement).
    pub refine_seconds: f64,
    /// Primitives the post-refinement existence check removed.
    pub refine_dropped: usize,
    /// Lattice passes run (2 when the lattice was re-aligned to a first refined fit).
    pub passes: usize,
    /// Primitives proposed by the coarse-to-fine gap filling (before merging).
    pub filled: usize,
}

/// The result of [`fit`].
#[derive(Debug, Clone)]
pub struct FitResult {
    /// Settings used.
    pub settings: Settings,
    /// The chosen primitives.
    pub primitives: Vec<Primitive>,
    /// The continuous existence probability of each chosen primitive.
    pub existence: Vec<f64>,
    /// Solver output over all candidates.
    pub solution: Solution,
    /// Sizes and timings.
    pub stats: FitStats,
}

impl FitResult {
    /// `result.json` (DESIGN §3); `metrics` is inserted as given.
    pub fn to_json(&self, metrics: Value) -> Value {
        result_json(
            self.settings.to_json(),
            metrics,
            &self.primitives,
            &self.existence,
        )
    }

    /// All primitives as one mesh, with the primitive index of every face.
    pub fn mesh(&self) -> (TriMesh, Vec<i32>) {
        primitives_mesh(&self.primitives)
    }
}

/// The `result.json` document shared by `fit`, `synth --truth` and `register`.
pub fn result_json(
    settings: Value,
    metrics: Value,
    primitives: &[Primitive],
    existence: &[f64],
) -> Value {
    let list: Vec<Value> = primitives
        .iter()
        .zip(existence)
        .map(|(p, e)| {
            let mut v = p.to_json();
            v["existence"] = json!(e);
            v
        })
        .collect();
    json!({ "primfit": crate::VERSION, "settings": settings, "metrics": metrics, "primitives": list })
}

/// One triangle mesh of all `primitives`, and the index of the primitive of every face.
pub fn primitives_mesh(primitives: &[Primitive]) -> (TriMesh, Vec<i32>) {
    let mut mesh = TriMesh::default();
    let mut owner = Vec::new();
    for (k, p) in primitives.iter().enumerate() {
        let range = mesh.append(&p.triangulate());
        owner.extend(std::iter::repeat_n(k as i32, range.len()));
    }
    (mesh, owner)
}

/// Estimated **peak** bytes of a fit of `points` points under `chamfer` with `candidates`
/// candidates (at most `max_samples` samples each), for the memory-budget check.
///
/// Per point, with `E` entries (`β`, or `β·α` for the independent model) and `U ≤ β`
/// distinct candidates:
///
/// * the coefficients themselves: `12·E + 8` bytes ([`Coefficients::BYTES_PER_ENTRY`]
///   plus a row offset), held from the build to the end;
/// * plus the larger of two transients: the build's per-chunk rows, copied into the
///   final arrays (`12·E`, plus 16 bytes per point saying where each row lies), and the
///   polish's per-candidate transpose (16 bytes per distinct (point, candidate): `16·U`);
/// * plus [`BYTES_PER_POINT`] for the cloud, its KD-tree and per-point solver state.
///
/// The benchmark table (`scripts/bench.sh`) prints this estimate next to the measured
/// peak RSS of every scene.
pub fn estimate_bytes(
    points: usize,
    candidates: usize,
    max_samples: usize,
    chamfer: &ChamferOptions,
) -> u64 {
    let distinct = chamfer.beta.unwrap_or(candidates).min(candidates) as u64;
    let entries = distinct
        * match chamfer.model {
            PointModel::Existence => 1,
            PointModel::Independent => chamfer.alpha.unwrap_or(max_samples).min(max_samples) as u64,
        };
    let per_entry = Coefficients::BYTES_PER_ENTRY as u64;
    let coefficients = entries * per_entry + 8;
    let transient = (entries * per_entry + 16).max(16 * distinct);
    points as u64 * (coefficients + transient + BYTES_PER_POINT)
}

/// `1.3 GiB`, `250 MiB`, `12 KiB`.
fn human_bytes(b: u64) -> String {
    let b = b as f64;
    if b >= (1u64 << 30) as f64 {
        format!("{:.1} GiB", b / (1u64 << 30) as f64)
    } else if b >= (1u64 << 20) as f64 {
        format!("{:.0} MiB", b / (1u64 << 20) as f64)
    } else {
        format!("{:.0} KiB", b / 1024.0)
    }
}

/// Bytes per input point besides the coefficients in [`estimate_bytes`]: the cloud
/// (24), the KD-tree built over it (~28, shared by the settings and the primitive term),
/// the build's cell order (12), and the polish's per-point owner and cost (12), rounded
/// up.
pub const BYTES_PER_POINT: u64 = 96;

/// The exact binary chamfer of a primitive set against `cloud` under `settings` (samples
/// at `settings.sample_spacing`, all primitives existing, no α/β truncation):
/// `w_prim Σ_i g_i + w_point Σ_y min_i d_i(y)`, or `d_cap` per point for an empty set.
/// Used to compare a fit with a ground truth on the fitter's own terms.
pub fn binary_chamfer(
    cloud: &PointCloud,
    primitives: &[Primitive],
    settings: &Settings,
) -> Result<LossValue> {
    let set = CandidateSet::from_primitives(primitives, settings.sample_spacing)?;
    let options = ChamferOptions {
        alpha: None,
        beta: None,
        ..settings.chamfer.clone()
    };
    let coeffs = Coefficients::build(&cloud.points, &set, &options, &Silent)?;
    Ok(Evaluator::new(&coeffs).binary_value(&vec![true; set.len()]))
}

/// Fits primitives to `cloud`: a lattice pass (candidates, coefficients, L-BFGS, polish),
/// then, with [`FitOptions::refine`], continuous refinement ([`crate::refine`]). With an
/// estimated frame (`auto`) and refinement, the lattice is then re-aligned to the refined
/// primitives ([`crate::frame::realign`]: their axes and the grid phase of their centres)
/// and fitted and refined once more; the pass with the lower binary chamfer is kept.
pub fn fit(cloud: &PointCloud, options: &FitOptions, progress: &dyn Progress) -> Result<FitResult> {
    if cloud.is_empty() {
        return Err(Error::invalid("the cloud is empty"));
    }
    if cloud
        .points
        .iter()
        .any(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(Error::invalid("the cloud has non-finite coordinates"));
    }
    let index = PointIndex::new(&cloud.points);
    let settings = Settings::resolve(cloud, &index, options)?;
    progress.message(&format!("settings: {}", settings.to_json()));
    let first = fill_gaps(
        cloud,
        &index,
        fit_pass(cloud, &index, settings, progress)?,
        progress,
    )?;
    let realign_pass = first.settings.refine.is_some()
        && first.settings.frame_source == "auto"
        && !first.primitives.is_empty();
    if !realign_pass {
        return Ok(first);
    }
    let (frame, origin) = realign(
        &first.primitives,
        &first.settings.frame,
        first.settings.spacing,
    );
    let mut settings = first.settings.clone();
    settings.frame = frame;
    settings.origin = origin;
    progress.message(&format!(
        "re-aligned lattice: frame {:?}, origin {origin:?}",
        frame.quaternion().coords
    ));
    let second = fill_gaps(
        cloud,
        &index,
        fit_pass(cloud, &index, settings, progress)?,
        progress,
    )?;
    let loss = |r: &FitResult| binary_chamfer(cloud, &r.primitives, &r.settings).map(|l| l.total);
    let (a, b) = (loss(&first)?, loss(&second)?);
    progress.message(&format!(
        "binary chamfer: first pass {a:.6}, re-aligned pass {b:.6}"
    ));
    let mut best = if b <= a { second } else { first };
    best.stats.passes = 2;
    Ok(best)
}

/// Coarse to fine: when a refined fit leaves points unexplained (farther than
/// `max(4σ̂, h / 2)` from every primitive, at least 1 % of the points and 20 of them),
/// fits a lattice of half the spacing to those points alone, adds what it finds to the
/// model and refines the union (with merging) on the whole cloud. The result is kept
/// only if its binary chamfer is lower. Returns `result` unchanged without refinement.
///
/// `σ̂ = 1.4826 · median` of the point→model distances is the noise the refined model
/// sees (a robust σ of the residuals), `h` the point spacing. The cloud's own noise
/// estimate ([`Settings::noise`]) is no good here: on tubes thinner than its
/// neighbourhoods it measures their curvature (σ ≈ 0.02 for a 0.1 radius pipe with
/// 5 mm of noise), and a threshold of 4 of it hides a whole missing elbow.
fn fill_gaps(
    cloud: &PointCloud,
    index: &PointIndex,
    result: FitResult,
    progress: &dyn Progress,
) -> Result<FitResult> {
    let Some(options) = result.settings.refine.clone() else {
        return Ok(result);
    };
    if !options.fill || result.primitives.is_empty() {
        return Ok(result);
    }
    let s = &result.settings;
    let distances = point_to_model_distances(&cloud.points, &result.primitives)?;
    let threshold = (4.0 * robust_sigma(&distances)).max(s.point_spacing / 2.0);
    let residual: Vec<Point3<f64>> = cloud
        .points
        .iter()
        .zip(&distances)
        .filter(|(_, d)| **d > threshold)
        .map(|(p, _)| *p)
        .collect();
    if residual.len() < 20 || residual.len() * 100 < cloud.len() {
        return Ok(result);
    }
    let mut fine = s.clone();
    fine.spacing = s.spacing / 2.0;
    fine.refine = None;
    let sub = PointCloud::from_points(residual);
    let sub_index = PointIndex::new(&sub.points);
    let Ok(extra) = fit_pass(&sub, &sub_index, fine, progress) else {
        return Ok(result);
    };
    if extra.primitives.is_empty() {
        return Ok(result);
    }
    let mut union = result.primitives.clone();
    union.extend(extra.primitives.iter().cloned());
    let mut existence = result.existence.clone();
    existence.extend(extra.existence.iter().copied());
    let shapes = s.shapes();
    let ctx = refine_context(cloud, index, s, &shapes);
    let refined = refine(&ctx, &union, &options)?;
    let before = binary_chamfer(cloud, &result.primitives, s)?.total;
    progress.message(&format!(
        "coarse to fine: {} unexplained points, {} primitives added, binary chamfer {before:.6} → {:.6}",
        sub.len(),
        extra.primitives.len(),
        refined.loss_after
    ));
    if refined.loss_after >= before {
        return Ok(result);
    }
    let mut out = result;
    out.existence = refined.source.iter().map(|&i| existence[i]).collect();
    out.primitives = refined.primitives;
    out.stats.refine_seconds += refined.seconds + extra.stats.solve_seconds;
    out.stats.filled += extra.primitives.len();
    Ok(out)
}

/// `1.4826 · median` of the finite `distances` (0 when there are none): the σ of a
/// normal residual whose absolute values these are.
fn robust_sigma(distances: &[f64]) -> f64 {
    let mut d: Vec<f64> = distances
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * d[mid]
}

/// What [`refine`] needs from a fit under `settings` (`shapes` = `settings.shapes()`).
fn refine_context<'a>(
    cloud: &'a PointCloud,
    index: &'a PointIndex,
    settings: &'a Settings,
    shapes: &'a [Shape],
) -> RefineContext<'a> {
    RefineContext {
        points: &cloud.points,
        index,
        point_spacing: settings.point_spacing,
        sample_spacing: settings.sample_spacing,
        chamfer: &settings.chamfer,
        shapes,
        frame: settings.frame,
    }
}

/// One lattice fit under `settings`, refined when `settings.refine` is set.
fn fit_pass(
    cloud: &PointCloud,
    index: &PointIndex,
    settings: Settings,
    progress: &dyn Progress,
) -> Result<FitResult> {
    let t0 = Instant::now();
    let mut candidates = CandidateSet::build(&settings.lattice(), cloud)?;
    // Exact in effect: a candidate with no point within the cap of its surface can only
    // raise the loss (see `CandidateSet::near_data`).
    if settings.cap > 0.0 {
        let keep = candidates.near_data(&cloud.points, settings.cap + settings.sample_spacing);
        candidates.retain(&keep);
    }
    let lattice_seconds = t0.elapsed().as_secs_f64();
    if candidates.is_empty() {
        return Err(Error::invalid(
            "the lattice has no candidates near the cloud",
        ));
    }
    let max_samples = candidates
        .templates
        .iter()
        .map(|t| t.samples.len())
        .max()
        .unwrap_or(1);
    let need = estimate_bytes(
        cloud.len(),
        candidates.len(),
        max_samples,
        &settings.chamfer,
    );
    if need > settings.memory_budget {
        return Err(Error::TooLarge(format!(
            "{} points × {} candidates (β = {}) would need about {} at peak, over the \
             memory budget of {} (by default half the machine's memory); lower --beta, \
             use a coarser --spacing, subsample the cloud, or raise the budget \
             (memory_budget in the Python API)",
            cloud.len(),
            candidates.len(),
            settings
                .chamfer
                .beta
                .map_or("all".to_string(), |b| b.to_string()),
            human_bytes(need),
            human_bytes(settings.memory_budget)
        )));
    }
    progress.message(&format!(
        "{} candidates, {} samples per template at most",
        candidates.len(),
        max_samples
    ));

    let t1 = Instant::now();
    // Exact: a dominated candidate has p = 0 at every minimum (`chamfer::dominance`).
    let reduced = Coefficients::build_reduced(
        &cloud.points,
        index,
        &candidates,
        &settings.chamfer,
        progress,
    )?;
    let lattice_candidates = candidates.len();
    candidates.retain(&reduced.keep_mask(lattice_candidates));
    let coeffs = reduced.coefficients;
    let coefficient_seconds = t1.elapsed().as_secs_f64();
    progress.message(&format!(
        "{} of {lattice_candidates} candidates can exist (the rest are dominated); \
         {} entries ({} bytes each, {:.1} MiB in all)",
        candidates.len(),
        coeffs.entries(),
        Coefficients::BYTES_PER_ENTRY,
        coeffs.bytes() as f64 / (1 << 20) as f64
    ));

    let t2 = Instant::now();
    let solution = solve(&coeffs, &settings.solver, progress)?;
    let solve_seconds = t2.elapsed().as_secs_f64();

    let chosen: Vec<usize> = (0..candidates.len())
        .filter(|&i| solution.exists[i])
        .collect();
    let mut primitives: Vec<Primitive> = chosen.iter().map(|&i| candidates.primitive(i)).collect();
    let mut existence: Vec<f64> = chosen.iter().map(|&i| solution.probability[i]).collect();
    let mut refined = None;
    if let Some(options) = &settings.refine {
        let shapes = settings.shapes();
        let ctx = refine_context(cloud, index, &settings, &shapes);
        let r: Refined = refine(&ctx, &primitives, options)?;
        progress.message(&format!(
            "refinement: binary chamfer {:.6} → {:.6}, {} primitives dropped, {:.2} s",
            r.loss_before, r.loss_after, r.dropped, r.seconds
        ));
        existence = r.source.iter().map(|&i| existence[i]).collect();
        primitives = r.primitives.clone();
        refined = Some(r);
    }
    let stats = FitStats {
        points: cloud.len(),
        lattice_candidates,
        candidates: candidates.len(),
        entries: coeffs.entries(),
        bytes_per_entry: Coefficients::BYTES_PER_ENTRY,
        coefficient_bytes: coeffs.bytes(),
        estimated_bytes: need,
        lattice_seconds,
        coefficient_seconds,
        solve_seconds,
        refine_seconds: refined.as_ref().map_or(0.0, |r| r.seconds),
        refine_dropped: refined.as_ref().map_or(0, |r| r.dropped),
        passes: 1,
        filled: 0,
    };
    Ok(FitResult {
        settings,
        primitives,
        existence,
        solution,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::Silent;

    #[test]
    fn nice_floor_rounds_down_to_1_2_5() {
        assert_eq!(nice_floor(1.3), 1.0);
        assert_eq!(nice_floor(0.31), 0.2);
        assert_eq!(nice_floor(7.0), 5.0);
        assert!((nice_floor(0.05) - 0.05).abs() < 1e-15);
    }

    /// A floor patch 2 m × 2 m at z = 0 and a wall at x = 0, aligned with a 0.5 m lattice.
    fn corner() -> PointCloud {
        let mut pts = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let (a, b) = (i as f64 * 0.05 + 0.025, j as f64 * 0.05 + 0.025);
                pts.push(Point3::new(a, b, 0.0));
                pts.push(Point3::new(0.0, a, b));
            }
        }
        PointCloud::from_points(pts)
    }

    #[test]
    fn fits_an_aligned_corner_with_squares() {
        let options = FitOptions {
            size: Some(1.0),
            ..Default::default()
        };
        let result = fit(&corner(), &options, &Silent).unwrap();
        assert_eq!(result.settings.spacing, 0.5);
        // Every input point is on a chosen square (within the sample spacing).
        for p in corner().points.iter().step_by(7) {
            let d = result
                .primitives
                .iter()
                .map(|q| q.distance(p))
                .fold(f64::INFINITY, f64::min);
            assert!(d < 1e-9, "point {p:?} is {d} from the model");
        }
        // Two 2 m × 2 m faces need at least 4 squares each, and the polish leaves no
        // square that is off the data.
        assert!(result.primitives.len() >= 8, "{}", result.primitives.len());
        for q in &result.primitives {
            let c = q.center();
            assert!(
                c.z.abs() < 1e-12 || c.x.abs() < 1e-12,
                "stray square at {c:?}"
            );
        }
    }

    #[test]
    fn bad_options_are_errors() {
        let c = corner();
        let bad = FitOptions {
            size: Some(-1.0),
            ..Default::default()
        };
        assert!(fit(&c, &bad, &Silent).is_err());
        let bad = FitOptions {
            cap: Some(f64::NAN),
            ..Default::default()
        };
        assert!(fit(&c, &bad, &Silent).is_err());
        assert!(fit(&PointCloud::default(), &FitOptions::default(), &Silent).is_err());
        let tiny = FitOptions {
            memory_budget: Some(10),
            ..Default::default()
        };
        assert!(matches!(fit(&c, &tiny, &Silent), Err(Error::TooLarge(_))));
    }

    #[test]
    fn memory_budget_covers_the_peak_and_names_the_settings() {
        let existence = ChamferOptions {
            beta: Some(32),
            ..Default::default()
        };
        // 12 B per entry + 8 B offset, plus the polish transpose (16 B per candidate).
        let base = BYTES_PER_POINT;
        assert_eq!(
            estimate_bytes(1, 5000, 256, &existence),
            32 * 12 + 8 + 32 * 16 + base
        );
        let independent = ChamferOptions {
            model: PointModel::Independent,
            alpha: Some(10),
            ..existence.clone()
        };
        // 320 entries: the build's copy of them (and where each row lies) outweighs the
        // transpose.
        assert_eq!(
            estimate_bytes(1, 5000, 256, &independent),
            320 * 12 + 8 + (320 * 12 + 16) + base
        );
        // Fewer candidates than β: every candidate is an entry.
        assert_eq!(
            estimate_bytes(2, 3, 256, &existence),
            2 * (3 * 12 + 8 + (3 * 12 + 16) + base)
        );

        let c = corner();
        let fitted = fit(&c, &FitOptions::default(), &Silent).unwrap();
        let need = fitted.stats.estimated_bytes;
        assert!(need >= fitted.stats.coefficient_bytes as u64);
        let just_under = FitOptions {
            memory_budget: Some(need - 1),
            ..Default::default()
        };
        let Err(Error::TooLarge(msg)) = fit(&c, &just_under, &Silent) else {
            panic!("a budget below the estimate must refuse");
        };
        for hint in [
            "--beta",
            "--spacing",
            "subsample",
            "memory_budget",
            "budget",
        ] {
            assert!(msg.contains(hint), "{msg:?} does not mention {hint}");
        }
        let exact = FitOptions {
            memory_budget: Some(need),
            ..Default::default()
        };
        assert!(fit(&c, &exact, &Silent).is_ok());
    }
}
