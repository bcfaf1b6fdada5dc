//! `primfit fit --tiles`: the survey fitted tile after tile in this process
//! ([`primfit_core::tiles::fit_tiled`]), or, with `--scheduler`, handed to the Python
//! package's Dask driver (`python3 -m primfit.dask`).

use std::path::Path;
use std::process::Command;

use anyhow::{Context, Result, bail};
use clap::Args;

/// The Python interpreter `--scheduler` runs, unless `PRIMFIT_PYTHON` names another.
const PYTHON: &str = "python3";

/// Tiled fitting of surveys larger than one fit (issue 18).
#[derive(Debug, Args)]
pub struct TileArgs {
    /// Fit the scan in square xy tiles with halos, one after another, each with every
    /// core, and merge the tiles' primitives across the seams (primitives are owned by
    /// the tile holding their centre; coplanar planes and collinear cylinders crossing
    /// a seam are joined, duplicates dropped by an existence re-check on seam points).
    #[arg(long)]
    pub tiles: bool,
    /// Tile side in scene units [default: about 500 000 points per tile].
    #[arg(long, requires = "tiles", allow_hyphen_values = true)]
    pub tile_size: Option<f64>,
    /// Halo: neighbouring points a tile is fitted with, scene units [default: tile size / 10].
    #[arg(long, requires = "tiles", allow_hyphen_values = true)]
    pub halo: Option<f64>,
    /// Run the tiles on the Dask cluster at this scheduler address (`tcp://host:8786`;
    /// `local` starts a LocalCluster with one worker per core). Needs the Python package
    /// with its dask extra (`pip install primfit[dask]`): this hands the job to
    /// `python3 -m primfit.dask` (`PRIMFIT_PYTHON` to use another interpreter).
    #[arg(long, requires = "tiles", value_name = "ADDRESS")]
    pub scheduler: Option<String>,
}

/// Runs `python3 -m primfit.dask` for `--scheduler`, with the scene, the tile options
/// and the outputs; the Python driver writes the same result JSON and mesh.
pub fn hand_off(
    tiles: &TileArgs,
    scheduler: &str,
    scene: &Path,
    output: Option<&Path>,
    mesh: Option<&Path>,
    quiet: bool,
) -> Result<()> {
    let python = std::env::var("PRIMFIT_PYTHON").unwrap_or_else(|_| PYTHON.to_string());
    let mut cmd = Command::new(&python);
    cmd.args(["-m", "primfit.dask"]).arg(scene);
    cmd.args(["--scheduler", scheduler]);
    if let Some(s) = tiles.tile_size {
        cmd.arg("--tile-size").arg(s.to_string());
    }
    if let Some(h) = tiles.halo {
        cmd.arg("--halo").arg(h.to_string());
    }
    if let Some(o) = output {
        cmd.arg("-o").arg(o);
    }
    if let Some(m) = mesh {
        cmd.arg("--mesh").arg(m);
    }
    if quiet {
        cmd.arg("--quiet");
    }
    let status = cmd.status().with_context(|| {
        format!(
            "--scheduler runs `{python} -m primfit.dask`, which could not start: install the \
             Python package with its dask extra (pip install primfit[dask])"
        )
    })?;
    if !status.success() {
        bail!("`{python} -m primfit.dask` failed ({status})");
    }
    Ok(())
}
