//! Tiled fitting of surveys too large for one fit: the xy box is cut into square tiles,
//! each tile is fitted with a halo of its neighbours' points, every primitive is owned by
//! the tile whose core holds its centre, and the owned primitives are merged across the
//! seams (issue 18).
//!
//! | step | file | what it does |
//! |---|---|---|
//! | partition | `grid.rs` | [`TileGrid`]: tiles, cores, haloed boxes, owners, seam bands |
//! | read | `stream.rs` | [`read_tile`]: one tile's haloed points from a LAS/LAZ file in chunks ([`survey_bounds`] from the header) |
//! | split | `split.rs` | [`split_survey`]: one pass over a LAS/LAZ file (or a range of its points) into per-tile spill files; [`read_spilled_tile`] |
//! | fit a tile | `mod.rs` | [`fit_tile`]: the ordinary [`fit`] of the tile's points, the primitives whose centres lie in its core, its seam points |
//! | merge | `merge.rs` | [`merge_tiles`]: coplanar plane pieces and collinear cylinders across seams joined, duplicates dropped by an existence re-check on the seam points |
//!
//! [`fit_tiled`] runs all of it in one process, tile after tile (`primfit fit --tiles`);
//! the Python package runs [`fit_tile`] on Dask workers and [`merge_tiles`] on the
//! coordinator (`primfit.dask.fit_tiled`). Nothing about fitting itself is tiled: each
//! tile is an ordinary fit, so its result is what a fit of that region gives.

mod grid;
mod merge;
mod split;
mod stream;
#[cfg(test)]
mod tests;

pub use grid::{MAX_TILES, SEAM_BAND_SHARE, TileGrid};
pub use merge::{
    DUPLICATE_SHARE, MERGE_ANGLE_DEG, MERGE_RADIUS_RATIO, MergeTolerance, Piece, dedup_on_seams,
    merge_pieces, merge_two,
};
pub use split::{SPILL_BUFFER_POINTS, read_spilled_tile, spill_path, split_survey};
pub use stream::{read_tile, survey_bounds};

use nalgebra::Point3;
use serde_json::{Value, json};

use crate::atlas::MeshShape;
use crate::fit::{FitOptions, FitResult, FitStats, fit};
use crate::metrics::{Metrics, MetricsOptions, evaluate};
use crate::progress::Progress;
use crate::{Error, PointCloud, Result};

/// A tile's halo as a share of the tile size when none is given: wide enough that a
/// primitive crossing the seam is seen whole-enough on both sides to be fitted there.
pub const DEFAULT_HALO_SHARE: f64 = 0.1;

/// Tiles with fewer points than this are not fitted (nothing to detect in them).
pub const MIN_TILE_POINTS: usize = 100;

/// Points a tile holds, about, when no tile size is given ([`default_tile_size`]): a fit
/// of this many points stays within a few hundred MiB.
pub const DEFAULT_TILE_POINTS: f64 = 500_000.0;

/// The tile side (scene units) at which a survey of `points` points over the xy box of
/// `lo..hi` has about [`DEFAULT_TILE_POINTS`] per tile (points spread evenly in xy),
/// rounded up to a whole number of scene units.
pub fn default_tile_size(lo: &Point3<f64>, hi: &Point3<f64>, points: u64) -> f64 {
    let area = ((hi.x - lo.x) * (hi.y - lo.y)).max(f64::MIN_POSITIVE);
    let side = (area * DEFAULT_TILE_POINTS / (points.max(1) as f64)).sqrt();
    side.ceil().max(1.0)
}

/// The halo (scene units) of tiles of side `tile_size` when `halo` is `None`.
pub fn default_halo(tile_size: f64, halo: Option<f64>) -> f64 {
    halo.unwrap_or(DEFAULT_HALO_SHARE * tile_size)
}

/// What one tile's fit hands to the merge.
#[derive(Debug, Clone)]
pub struct TileFit {
    /// The tile's index in the grid.
    pub tile: usize,
    /// The fit of the tile's haloed points, its primitives only those it owns (centre in
    /// its core); `None` for a tile with fewer than [`MIN_TILE_POINTS`] points.
    pub result: Option<FitResult>,
    /// The tile's core points that lie in a seam band ([`TileGrid::is_seam`]).
    pub seam: Vec<Point3<f64>>,
    /// Points of the tile's core.
    pub core_points: usize,
    /// The measures of the tile's core points against the tile's whole model (before
    /// ownership); `None` with no fit.
    pub metrics: Option<Metrics>,
}

impl TileFit {
    /// The tile as JSON for another process (a Dask worker to the coordinator): `tile`,
    /// `core_points`, `result` (the tile's `result.json` with its measures, or null) and
    /// `seam` (`[[x, y, z], …]`, scene units).
    pub fn to_json(&self) -> Value {
        let result = match (&self.result, &self.metrics) {
            (Some(r), Some(m)) => r.to_json(m.to_json()),
            _ => Value::Null,
        };
        let seam: Vec<[f64; 3]> = self.seam.iter().map(|p| [p.x, p.y, p.z]).collect();
        json!({"tile": self.tile, "core_points": self.core_points, "result": result, "seam": seam})
    }

    /// Reads back [`TileFit::to_json`]; `load` gives the mesh of a mesh source.
    pub fn from_json(doc: &Value, load: &dyn Fn(&str) -> Result<MeshShape>) -> Result<TileFit> {
        let count = |key: &str| {
            doc.get(key)
                .and_then(Value::as_u64)
                .ok_or_else(|| Error::json(key, "a count"))
        };
        let (tile, core_points) = (count("tile")? as usize, count("core_points")? as usize);
        let (result, metrics) = match doc.get("result") {
            Some(Value::Null) | None => (None, None),
            Some(r) => {
                let (r, m) = FitResult::from_json(r, load)?;
                (Some(r), Some(m))
            }
        };
        let seam: Vec<[f64; 3]> =
            serde_json::from_value(doc.get("seam").cloned().unwrap_or(Value::Null))
                .map_err(|e| Error::json("seam", format!("[[x, y, z], …]: {e}")))?;
        Ok(TileFit {
            tile,
            result,
            seam: seam.into_iter().map(Point3::from).collect(),
            core_points,
            metrics,
        })
    }
}

/// A [`Progress`] for the fit of one tile: messages and cancellation go through, stages
/// do not (the caller's bar counts tiles).
struct Inner<'a>(&'a dyn Progress);

impl Progress for Inner<'_> {
    fn message(&self, text: &str) {
        self.0.message(text);
    }
    fn cancelled(&self) -> bool {
        self.0.cancelled()
    }
}

/// Fits tile `tile` of `grid` from `points`, which must hold (at least) every point of
/// its haloed box; points outside it are ignored.
pub fn fit_tile(
    points: &[Point3<f64>],
    grid: &TileGrid,
    tile: usize,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<TileFit> {
    if tile >= grid.len() {
        return Err(Error::out_of_range(
            "tile",
            tile,
            format!("below the grid's {} tiles", grid.len()),
        ));
    }
    let mine: Vec<Point3<f64>> = points
        .iter()
        .filter(|p| grid.in_haloed(tile, p.x, p.y))
        .copied()
        .collect();
    let core: Vec<Point3<f64>> = mine
        .iter()
        .filter(|p| grid.owner(p.x, p.y) == tile)
        .copied()
        .collect();
    let seam = core
        .iter()
        .filter(|p| grid.is_seam(p.x, p.y))
        .copied()
        .collect();
    let core_points = core.len();
    if mine.len() < MIN_TILE_POINTS || core_points == 0 {
        return Ok(TileFit {
            tile,
            result: None,
            seam,
            core_points,
            metrics: None,
        });
    }
    let cloud = PointCloud::from_points(mine);
    let mut result = fit(&cloud, options, &Inner(progress)).map_err(|e| e.in_item("tile", tile))?;
    let metrics = evaluate(&core, &result.primitives, None, &MetricsOptions::default())?;
    let owned: Vec<bool> = result
        .primitives
        .iter()
        .map(|p| {
            let c = p.center();
            grid.owner(c.x, c.y) == tile
        })
        .collect();
    result.primitives = owned_only(std::mem::take(&mut result.primitives), &owned);
    result.existence = owned_only(std::mem::take(&mut result.existence), &owned);
    Ok(TileFit {
        tile,
        result: Some(result),
        seam,
        core_points,
        metrics: Some(metrics),
    })
}

/// The items of `v` whose `owned` flag is set.
fn owned_only<T>(v: Vec<T>, owned: &[bool]) -> Vec<T> {
    v.into_iter()
        .zip(owned)
        .filter_map(|(x, &o)| o.then_some(x))
        .collect()
}

/// Joins the fits of the tiles into one result (`merge.rs`): the settings are those of
/// the tile with the most points, the primitives the merged and de-duplicated pieces.
/// Also returns the tiles' measures joined ([`joined_metrics`]). Errs when no tile had
/// enough points to fit.
pub fn merge_tiles(tiles: Vec<TileFit>) -> Result<(FitResult, Metrics)> {
    let points: usize = tiles.iter().map(|t| t.core_points).sum();
    let measured: Vec<&Metrics> = tiles.iter().filter_map(|t| t.metrics.as_ref()).collect();
    let mut metrics = joined_metrics(&measured);
    let mut seam = Vec::new();
    let mut pieces = Vec::new();
    let mut best: Option<FitResult> = None;
    for t in tiles {
        seam.extend(t.seam);
        let Some(r) = t.result else { continue };
        for (p, e) in r.primitives.iter().zip(&r.existence) {
            pieces.push(Piece {
                primitive: p.clone(),
                existence: *e,
                tiles: vec![t.tile],
            });
        }
        if best
            .as_ref()
            .is_none_or(|b| b.stats.points < r.stats.points)
        {
            best = Some(r);
        }
    }
    let Some(mut result) = best else {
        return Err(Error::invalid(format!(
            "no tile has {MIN_TILE_POINTS} points or more: use a larger tile size"
        )));
    };
    let tol = MergeTolerance {
        distance: result.settings.cap,
        noise: result.settings.noise,
        points,
    };
    let pieces = dedup_on_seams(merge_pieces(pieces, &tol), &seam, &tol)?;
    result.primitives = pieces.iter().map(|p| p.primitive.clone()).collect();
    result.existence = pieces.iter().map(|p| p.existence).collect();
    result.stats = FitStats {
        points,
        passes: 1,
        ..result.stats
    };
    metrics.points = points;
    metrics.primitives = result.primitives.len();
    Ok((result, metrics))
}

/// The measures of tiles joined without the points: means weighted by each tile's
/// points, the p95 and maximum the largest of the tiles' (an upper bound), the chamfer
/// summed. Each tile is measured against its own model, so these describe the tiled fit
/// as the tiles saw it; a caller holding the whole cloud measures the merged model
/// instead ([`evaluate`]).
pub fn joined_metrics(tiles: &[&Metrics]) -> Metrics {
    let n: usize = tiles.iter().map(|m| m.points).sum();
    let w = |f: fn(&Metrics) -> f64| {
        tiles.iter().map(|m| f(m) * m.points as f64).sum::<f64>() / (n.max(1) as f64)
    };
    let top = |f: fn(&Metrics) -> f64| tiles.iter().map(|m| f(m)).fold(0.0, f64::max);
    Metrics {
        points: n,
        primitives: tiles.iter().map(|m| m.primitives).sum(),
        point_to_model_mean: w(|m| m.point_to_model_mean),
        point_to_model_p95: top(|m| m.point_to_model_p95),
        point_to_model_max: top(|m| m.point_to_model_max),
        model_to_point_mean: w(|m| m.model_to_point_mean),
        coverage: w(|m| m.coverage),
        coverage_tau: top(|m| m.coverage_tau),
        chamfer: tiles.iter().map(|m| m.chamfer).sum(),
        compactness: w(|m| m.compactness),
        sample_spacing: top(|m| m.sample_spacing),
        truth: None,
    }
}

/// Fits `cloud` tile after tile on a grid of `tile_size` with `halo` (scene units; `None`:
/// [`DEFAULT_HALO_SHARE`] of the tile size; `tile_size` `None`: [`default_tile_size`]) and merges the tiles; `progress` counts tiles.
pub fn fit_tiled(
    cloud: &PointCloud,
    options: &FitOptions,
    tile_size: Option<f64>,
    halo: Option<f64>,
    progress: &dyn Progress,
) -> Result<FitResult> {
    let (lo, hi) = cloud.bounds().ok_or(Error::EmptyCloud)?;
    let tile_size = tile_size.unwrap_or_else(|| default_tile_size(&lo, &hi, cloud.len() as u64));
    let grid = TileGrid::new(&lo, &hi, tile_size, default_halo(tile_size, halo))?;
    // Bucket the points once per tile (a point in a halo goes to every tile that sees it).
    let mut buckets: Vec<Vec<Point3<f64>>> = vec![Vec::new(); grid.len()];
    for p in &cloud.points {
        for t in grid.tiles_of(p.x, p.y) {
            buckets[t].push(*p);
        }
    }
    progress.start("tiles", grid.len() as u64);
    let mut fits = Vec::with_capacity(grid.len());
    for (t, bucket) in buckets.into_iter().enumerate() {
        progress.checkpoint()?;
        fits.push(fit_tile(&bucket, &grid, t, options, progress)?);
        progress.advance(1);
    }
    progress.finish();
    Ok(merge_tiles(fits)?.0)
}
