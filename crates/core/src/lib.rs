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
//! | [`atlas`] | primitive *types*: local-frame surfaces (disk, square, cylinder, elbow, sphere, mesh) |
//! | [`primitive`] | a type placed in the scene by a [`primitive::Pose`] |
//! | [`surface`] | local normals, flatness and noise level by PCA of k nearest neighbours |
//! | [`frame`] | the lattice frame: the scan's dominant axes and a grid origin on the data |
//! | [`lattice`] | the candidate set G = types × orientations × translation grid |
//! | [`chamfer`] | the probabilistic chamfer distance: coefficients, value, gradient |
//! | [`solve`] | projected L-BFGS over existence, thresholding, discrete polish |
//! | [`ray`] | ray likelihood (thesis eq. 4.10), RayTree, Metropolis–Hastings (thesis ch. 4) |
//! | [`refine`] | continuous pose and size refinement of chosen primitives, existence re-check |
//! | [`synth`] | synthetic scenes with ground truth |
//! | [`register`] | particle-filter registration of a mesh, the chamfer as measurement |
//! | [`metrics`] | the measures of DESIGN §4 |
//! | [`io`] | PLY and JSON |
//!
//! Units: every length is in the cloud's units (metres for the bundled data); distances
//! inside losses are **squared** Euclidean, as in the thesis.
#![forbid(unsafe_code)]

pub use nalgebra as na;

pub mod atlas;
pub mod chamfer;
pub mod cloud;
pub mod error;
pub mod fit;
pub mod frame;
pub mod io;
pub mod lattice;
pub mod metrics;
pub mod primitive;
pub mod progress;
pub mod ray;
pub mod refine;
pub mod register;
pub mod solve;
pub mod spatial;
pub mod surface;
pub mod synth;

pub use atlas::{Shape, ShapeKind, TriMesh};
pub use cloud::PointCloud;
pub use error::{Error, Result};
pub use primitive::{Hit, Pose, Primitive};

/// The library version, written into every `result.json` as `"primfit"`.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
