//! # primfit-core
//!
//! Represent a whole 3D point cloud with geometric primitives only, by inferring which
//! members of a large, fixed, discrete set of candidate primitives **exist**
//! (Jared Glover-style discretisation of the reference thesis, `shared/reference/thesis.txt`).
//!
//! Data flows one way:
//!
//! ```text
//! file ─► PointCloud ─► Lattice (candidates) ─► chamfer::Coefficients ─► solve ─► existence
//!      ─► primitives ─► outputs (JSON, mesh PLY, metrics)
//! ```
//!
//! # The public surface
//!
//! The crate root re-exports what a user calls; the modules below group the rest of a
//! coherent API each. Everything else is private: the local-surface PCA (`surface`), the
//! lattice frame (`frame`; its [`fit::FrameChoice`] is a fit option), the kd-trees
//! (`spatial`; [`PointIndex`] is re-exported), running uneven jobs on all cores
//! (`schedule`), and the small modules behind the root re-exports
//! (`cloud`, `primitive`, `error`, `check`, `limit`, `progress`).
//!
//! | at the root | what it is |
//! |---|---|
//! | [`fit()`], [`FitOptions`], [`FitResult`] | the whole pipeline: a cloud in, primitives and their existence out |
//! | [`register()`], [`RegisterOptions`], [`Registration`] | particle-filter registration of a mesh in a cloud |
//! | [`evaluate`], [`Metrics`], [`MetricsOptions`] | the measures of a model against its cloud (DESIGN §4) |
//! | [`read_cloud`], [`read_mesh`], [`write_mesh`] | files: clouds of every accepted format, PLY meshes |
//! | [`PointCloud`], [`bounds_of`], [`PointIndex`] | a cloud (points, optional normals, colours, sensor origins), its bounds, a kd-tree over it |
//! | [`Primitive`], [`Pose`], [`Hit`] | a shape placed in the scene, its pose, a ray's first hit on it |
//! | [`Shape`], [`ShapeKind`], [`MeshShape`], [`TriMesh`] | primitive types in their local frame, a triangle mesh |
//! | [`Progress`], [`Silent`] | how long stages report progress |
//! | [`StageTimes`], [`Stopwatch`] | wall time per stage of a run (`primfit fit -v`, `--timings`) |
//! | [`Error`], [`Result`], [`Unit`], [`Remedy`], [`Limit`] | the typed error, what its amounts count and what would fix it; a count that may be unlimited |
//! | [`VERSION`], [`na`] | the library version; nalgebra, whose points and rotations the API uses |
//!
//! | module | concept |
//! |---|---|
//! | [`mod@fit`] | the pipeline's options, defaults, resolved settings and result (`result.json`) |
//! | [`atlas`] | primitive *types*: local-frame surfaces (disk, square, cylinder, elbow, sphere, mesh, plane) |
//! | [`lattice`] | the candidate set G = types × orientations × translation grid |
//! | [`chamfer`] | the probabilistic chamfer distance: coefficients, value, gradient |
//! | [`solve`] | projected L-BFGS over existence, thresholding, discrete polish |
//! | [`refine`] | continuous pose and size refinement of chosen primitives, existence re-check |
//! | [`detect`] | shape detection from the data: plane / cylinder / sphere segments |
//! | [`compact`] | the compact model (the default [`fit()`]): detected shapes as candidates, kept by the chamfer with a description length |
//! | [`ray`] | ray likelihood (thesis eq. 4.10), RayTree, Metropolis–Hastings (thesis ch. 4) |
//! | [`mod@register`] | registration of a mesh: the entry point, its options, the report, the pose scoring |
//! | [`synth`] | synthetic scenes with ground truth |
//! | [`metrics`] | the measures of DESIGN §4 and their parts |
//! | [`render`] | pictures of a fit: a PNG and an interactive HTML page |
//! | [`budget`] | up-front limits of memory, threads and work that every entry point checks before it allocates |
//! | [`io`] | cloud readers (PLY, PCD, LAS/LAZ, E57, text), mesh writers (PLY, OBJ, GLB), atomic writes |
//!
//! Units: every length is in the cloud's units (metres for the bundled data); distances
//! inside losses are **squared** Euclidean, as in the thesis.
//!
//! # Fitting a cloud
//!
//! [`fit()`] runs the whole pipeline on a [`PointCloud`]: here a small synthetic
//! hallway (floor and two walls tiled by 1 m squares, 1 cm jitter), fitted with 1 m
//! squares on a 0.5 m lattice and then refined. `FitOptions::default()` is what
//! `primfit fit` does without flags (an estimated frame, refinement); here the lattice is
//! kept on the scene axes, on which the synthetic hallway lies.
//!
//! ```
//! use primfit_core::fit::FrameChoice;
//! use primfit_core::refine::RefineOptions;
//! use primfit_core::synth::{Density, HallwayParams, hallway};
//! use primfit_core::{FitOptions, MetricsOptions, ShapeKind, Silent, evaluate, fit};
//!
//! let scene = hallway(&HallwayParams {
//!     length: 2.0,
//!     density: Density::PerArea(30.0), // points per m²
//!     ..Default::default()
//! })?;
//! let options = FitOptions {
//!     kinds: vec![ShapeKind::Square],
//!     size: Some(1.0),
//!     spacing: Some(0.5),
//!     frame: FrameChoice::Axis,
//!     refine: Some(RefineOptions::default()),
//!     ..Default::default()
//! };
//! let result = fit(&scene.cloud, &options, &Silent)?;
//! let points = &scene.cloud.points;
//! let metrics = evaluate(points, &result.primitives, None, &MetricsOptions::default())?;
//! assert!(metrics.coverage > 0.99); // share of points near a fitted surface
//! assert!(metrics.point_to_model_mean < 0.025); // metres
//! let json = result.to_json(metrics.to_json()); // what `primfit fit -o result.json` writes
//! assert_eq!(json["primitives"].as_array().unwrap().len(), result.primitives.len());
//! # Ok::<(), primfit_core::Error>(())
//! ```
//!
//! # The probabilistic chamfer
//!
//! The loss over existence probabilities `p` ([`chamfer`]): its coefficients are built
//! once for a cloud and a candidate set, then [`chamfer::Evaluator`] gives the value and
//! the gradient at any `p`. Here the candidates are given by explicit surface samples
//! ([`chamfer::SampleSets`]); the fitter uses a lattice ([`lattice::CandidateSet`]).
//!
//! ```
//! use primfit_core::Silent;
//! use primfit_core::chamfer::{ChamferOptions, Coefficients, Evaluator, SampleSets};
//! use primfit_core::na::Point3;
//!
//! // Five points on the x axis; candidate 0 is sampled on them, candidate 1 a metre above.
//! let on_line = |z: f64| (0..5).map(move |i| Point3::new(i as f64, 0.0, z));
//! let cloud: Vec<Point3<f64>> = on_line(0.0).collect();
//! let samples: Vec<Point3<f64>> = on_line(0.0).chain(on_line(1.0)).collect();
//! let owner = [0, 0, 0, 0, 0, 1, 1, 1, 1, 1];
//! let candidates = SampleSets::new(&samples, &owner, 2)?;
//! let options = ChamferOptions { cap: 4.0, ..Default::default() };
//! let coefficients = Coefficients::build(&cloud, &candidates, &options, &Silent)?;
//! // Primitive term g_i: each sample's squared distance to the nearest point, summed.
//! assert_eq!(coefficients.g, [0.0, 5.0]);
//!
//! let mut loss = Evaluator::new(&coefficients);
//! let mut grad = [0.0; 2];
//! assert_eq!(loss.evaluate(&[1.0, 0.0], &mut grad).total, 0.0); // the right one exists
//! assert_eq!(loss.evaluate(&[0.0, 1.0], &mut grad).total, 10.0); // 5 (g_1) + 5 × 1²
//! assert_eq!(loss.evaluate(&[0.0, 0.0], &mut grad).total, 20.0); // every point pays the cap
//! assert!(grad[0] < grad[1]); // descending the gradient turns candidate 0 on first
//! # Ok::<(), primfit_core::Error>(())
//! ```
#![forbid(unsafe_code)]

pub use nalgebra as na;

pub mod atlas;
pub mod budget;
pub mod chamfer;
mod check;
mod cloud;
pub mod compact;
pub mod detect;
mod error;
pub mod fit;
mod frame;
pub mod io;
pub mod lattice;
mod limit;
pub mod metrics;
mod primitive;
mod progress;
pub mod ray;
pub mod refine;
pub mod register;
pub mod render;
mod schedule;
pub mod solve;
mod spatial;
mod surface;
pub mod synth;
pub mod tiles;
mod timing;

pub use atlas::{MeshShape, Shape, ShapeKind, TriMesh};
pub use cloud::{PointCloud, bounds_of};
pub use error::{Error, Remedy, Result, Unit};
pub use fit::{FitOptions, FitResult, fit, fit_indexed};
pub use io::{read_cloud, read_mesh, write_mesh};
pub use limit::Limit;
pub use metrics::{Metrics, MetricsOptions, evaluate};
pub use primitive::{Hit, Pose, Primitive};
pub use progress::{Progress, Silent};
pub use register::{RegisterOptions, Registration, register};
pub use spatial::PointIndex;
pub use timing::{StageTimes, Stopwatch};

/// The library version, written into every `result.json` as `"primfit"`.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
