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
//! | module | concept |
//! |---|---|
//! | [`atlas`] | primitive *types*: local-frame surfaces (disk, square, cylinder, elbow, sphere, mesh, plane) |
//! | [`primitive`] | a type placed in the scene by a [`primitive::Pose`] |
//! | [`surface`] | local normals, flatness and noise level by PCA of k nearest neighbours |
//! | [`detect`] | shape detection from the data: region growing, plane / cylinder / sphere segments |
//! | [`frame`] | the lattice frame: the scan's dominant axes and a grid origin on the data |
//! | [`lattice`] | the candidate set G = types × orientations × translation grid |
//! | [`chamfer`] | the probabilistic chamfer distance: coefficients, value, gradient |
//! | [`solve`] | projected L-BFGS over existence, thresholding, discrete polish |
//! | [`ray`] | ray likelihood (thesis eq. 4.10), RayTree, Metropolis–Hastings (thesis ch. 4) |
//! | [`refine`] | continuous pose and size refinement of chosen primitives, existence re-check |
//! | [`synth`] | synthetic scenes with ground truth |
//! | [`register`] | particle-filter registration of a mesh, the chamfer as measurement |
//! | [`metrics`] | the measures of DESIGN §4 |
//! | [`render`] | pictures of a fit: a PNG and an interactive HTML page |
//! | [`io`] | PLY and JSON |
//! | [`error`], [`check`] | the typed error and the range checks that build it |
//! | [`limit`] | a count that may be unlimited (`inf`) |
//!
//! Units: every length is in the cloud's units (metres for the bundled data); distances
//! inside losses are **squared** Euclidean, as in the thesis.
//!
//! # Fitting a cloud
//!
//! [`fit::fit`] runs the whole pipeline on a [`PointCloud`]: here a small synthetic
//! hallway (floor and two walls tiled by 1 m squares, 1 cm jitter), fitted with 1 m
//! squares on a 0.5 m lattice and then refined. `FitOptions::default()` is what
//! `primfit fit` does without flags (an estimated frame, refinement); here the lattice is
//! kept on the scene axes, on which the synthetic hallway lies.
//!
//! ```
//! use primfit_core::ShapeKind;
//! use primfit_core::fit::{FitOptions, fit};
//! use primfit_core::frame::FrameChoice;
//! use primfit_core::metrics::{MetricsOptions, evaluate};
//! use primfit_core::progress::Silent;
//! use primfit_core::refine::RefineOptions;
//! use primfit_core::synth::{Density, HallwayParams, hallway};
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
//! use primfit_core::chamfer::{ChamferOptions, Coefficients, Evaluator, SampleSets};
//! use primfit_core::na::Point3;
//! use primfit_core::progress::Silent;
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
pub mod chamfer;
pub mod check;
pub mod cloud;
pub mod compact;
pub mod detect;
pub mod error;
pub mod fit;
pub mod frame;
pub mod io;
pub mod lattice;
pub mod limit;
pub mod metrics;
pub mod primitive;
pub mod progress;
pub mod ray;
pub mod refine;
pub mod register;
pub mod render;
pub mod solve;
pub mod spatial;
pub mod surface;
pub mod synth;

pub use atlas::{Shape, ShapeKind, TriMesh};
pub use cloud::PointCloud;
pub use error::{Error, Result};
pub use limit::Limit;
pub use primitive::{Hit, Pose, Primitive};

/// The library version, written into every `result.json` as `"primfit"`.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
