//! Python bindings of primfit: the extension module `primfit._primfit`.
//!
//! A thin layer: argument checks and numpy conversion ([`convert`]), the GIL released
//! around every call into the core, and a per-process thread pool ([`pool`]) so forked
//! children (e.g. PyTorch data-loader workers) do not hang. The user-facing API is the
//! Python package `primfit` (`crates/py/python/primfit`), which coerces inputs to
//! C-ordered float64 and builds result objects.

mod chamfer;
mod convert;
mod fit;
mod io;
mod pool;
mod register;
mod render;
mod synth;
mod tiles;

use pyo3::prelude::*;

/// Low-level bindings; use the `primfit` package instead.
#[pymodule(gil_used = false)]
mod _primfit {
    #[pymodule_export]
    use super::chamfer::{ChamferProblem, chamfer_problems};
    #[pymodule_export]
    use super::fit::{PyFitOptions, candidates, fit, fit_problem, read_result};
    #[pymodule_export]
    use super::io::{primitives_mesh, read_mesh, read_ply, write_mesh, write_ply};
    #[pymodule_export]
    use super::register::register;
    #[pymodule_export]
    use super::render::render;
    #[pymodule_export]
    use super::synth::{
        synth_hallway, synth_nine_cylinders, synth_partial_view, synth_pipe, synth_registration,
        synth_six_in_a_row,
    };

    #[pymodule_export]
    use super::tiles::{
        fit_tile, merge_tiles, spilled_tile_points, split_survey, tile_grid_array, tile_grid_file,
        tile_points,
    };

    /// The library version.
    #[allow(non_upper_case_globals)]
    #[pymodule_export]
    const __version__: &str = primfit_core::VERSION;
}
