//! `primfit`: represent a whole 3D point cloud with geometric primitives only.
//!
//! This umbrella crate re-exports [`primfit_core`]; it exists so that the workspace's
//! top-level `tests/`, `benches/` and `examples/` folders belong to a package.
pub use primfit_core::*;
