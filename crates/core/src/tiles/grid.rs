//! [`TileGrid`]: the partition of a survey's xy bounding box into square tiles, each
//! fitted with a halo of its neighbours' points around it.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::{Error, Result, check};

/// The most tiles a grid may have: beyond this a tile is so small against the survey
/// that the per-tile overhead dominates; the error asks for a larger tile.
pub const MAX_TILES: usize = 1_000_000;

/// The seam band's half width as a share of the halo: the points the coordinator keeps
/// are those this close to a seam (a quarter of the halo: the band where pieces of the
/// two sides overlap most), so it holds about `2 · SEAM_BAND_SHARE · halo / tile_size`
/// of the survey per seam direction.
pub const SEAM_BAND_SHARE: f64 = 0.25;

/// A grid of `nx × ny` square tiles of side `tile_size` (scene units) covering the xy
/// bounding box of a survey from `origin` (the box's minimum corner). Tile `t` is column
/// `t % nx`, row `t / nx`; its **core** is its square, its **haloed box** the core grown
/// by `halo` (scene units) on every side. Every point lies in exactly one core (points
/// on the far edge of the box belong to the last column or row).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TileGrid {
    /// The xy minimum corner of the survey (scene units).
    pub origin: [f64; 2],
    /// Side of a tile's core (scene units).
    pub tile_size: f64,
    /// Width of the band of neighbouring points a tile is fitted with (scene units).
    pub halo: f64,
    /// Columns (along x).
    pub nx: usize,
    /// Rows (along y).
    pub ny: usize,
}

impl TileGrid {
    /// The grid of tiles of side `tile_size` with halos `halo` (scene units) over the xy
    /// box of `lo..hi`. Errs when `tile_size ≤ 0`, `halo < 0`, `halo ≥ tile_size`, a
    /// value is not finite, or the grid would exceed [`MAX_TILES`].
    pub fn new(lo: &Point3<f64>, hi: &Point3<f64>, tile_size: f64, halo: f64) -> Result<Self> {
        check::positive("tile_size", tile_size)?;
        check::non_negative("halo", halo)?;
        if halo >= tile_size {
            return Err(Error::out_of_range(
                "halo",
                halo,
                format!("smaller than the tile size {tile_size}"),
            ));
        }
        for c in lo.coords.iter().chain(hi.coords.iter()) {
            if !c.is_finite() {
                return Err(Error::invalid("the survey's bounds are not finite"));
            }
        }
        let count = |span: f64| ((span / tile_size).floor() as usize).saturating_add(1);
        let (nx, ny) = (count(hi.x - lo.x), count(hi.y - lo.y));
        let tiles = nx.saturating_mul(ny);
        if tiles > MAX_TILES {
            return Err(Error::out_of_range(
                "tile_size",
                tile_size,
                format!("large enough for at most {MAX_TILES} tiles (this gives {tiles})"),
            ));
        }
        Ok(TileGrid {
            origin: [lo.x, lo.y],
            tile_size,
            halo,
            nx,
            ny,
        })
    }

    /// Number of tiles.
    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    /// Always false: a grid has at least one tile.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The column or row of coordinate `v` (scene units) from `origin` along one axis of
    /// `n` cells, clamped to the grid.
    fn cell(&self, v: f64, origin: f64, n: usize) -> usize {
        let c = ((v - origin) / self.tile_size).floor();
        if c.is_nan() || c < 0.0 {
            0
        } else {
            (c as usize).min(n - 1)
        }
    }

    /// The tile whose core holds the xy position `(x, y)` (scene units); positions
    /// outside the grid go to the nearest tile.
    pub fn owner(&self, x: f64, y: f64) -> usize {
        let i = self.cell(x, self.origin[0], self.nx);
        let j = self.cell(y, self.origin[1], self.ny);
        j * self.nx + i
    }

    /// The core of tile `t`: its xy minimum and maximum corners (scene units).
    pub fn core(&self, t: usize) -> ([f64; 2], [f64; 2]) {
        let (i, j) = ((t % self.nx) as f64, (t / self.nx) as f64);
        let lo = [
            self.origin[0] + i * self.tile_size,
            self.origin[1] + j * self.tile_size,
        ];
        (lo, [lo[0] + self.tile_size, lo[1] + self.tile_size])
    }

    /// Whether `(x, y)` lies in tile `t`'s haloed box (its core grown by the halo; a
    /// tile on the grid's border reaches to infinity outwards, so points just outside a
    /// header's bounds are still read by a tile).
    pub fn in_haloed(&self, t: usize, x: f64, y: f64) -> bool {
        self.in_grown(t, x, y, self.halo)
    }

    /// Whether `(x, y)` lies in tile `t`'s core grown by `h` (scene units), border tiles
    /// unbounded outwards.
    fn in_grown(&self, t: usize, x: f64, y: f64, h: f64) -> bool {
        let (lo, hi) = self.core(t);
        let (i, j) = (t % self.nx, t / self.nx);
        let inside = |v: f64, lo: f64, hi: f64, first: bool, last: bool| {
            (first || v >= lo - h) && (last || v <= hi + h)
        };
        inside(x, lo[0], hi[0], i == 0, i + 1 == self.nx)
            && inside(y, lo[1], hi[1], j == 0, j + 1 == self.ny)
    }

    /// The tiles whose haloed boxes hold `(x, y)`: its owner and up to 8 neighbours.
    pub fn tiles_of(&self, x: f64, y: f64) -> Vec<usize> {
        self.tiles_within(x, y, self.halo)
    }

    /// The tiles whose cores come within `h` (scene units, at most the halo) of `(x, y)`.
    fn tiles_within(&self, x: f64, y: f64, h: f64) -> Vec<usize> {
        // One cell wider each way than `x ± h` reaches, so that a point exactly on a
        // haloed box's edge (which `in_grown` counts in) is not missed by the rounding.
        let (i0, i1) = (
            self.cell(x - h, self.origin[0], self.nx).saturating_sub(1),
            (self.cell(x + h, self.origin[0], self.nx) + 1).min(self.nx - 1),
        );
        let (j0, j1) = (
            self.cell(y - h, self.origin[1], self.ny).saturating_sub(1),
            (self.cell(y + h, self.origin[1], self.ny) + 1).min(self.ny - 1),
        );
        let mut out = Vec::with_capacity(4);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let t = j * self.nx + i;
                if self.in_grown(t, x, y, h) {
                    out.push(t);
                }
            }
        }
        out
    }

    /// Whether `(x, y)` lies within [`SEAM_BAND_SHARE`] of the halo of a seam between
    /// two tiles: the coordinator keeps such points for the existence re-check of
    /// primitives crossing the seam.
    pub fn is_seam(&self, x: f64, y: f64) -> bool {
        self.tiles_within(x, y, SEAM_BAND_SHARE * self.halo).len() > 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> TileGrid {
        TileGrid::new(
            &Point3::new(0.0, 0.0, 0.0),
            &Point3::new(25.0, 9.0, 3.0),
            10.0,
            1.0,
        )
        .unwrap()
    }

    #[test]
    fn every_point_has_one_owner_and_its_owner_sees_it() {
        let g = grid();
        assert_eq!((g.nx, g.ny, g.len()), (3, 1, 3));
        for k in 0..=250 {
            let x = k as f64 * 0.1;
            let t = g.owner(x, 4.0);
            let (lo, hi) = g.core(t);
            assert!(x >= lo[0] && (x < hi[0] || t == g.nx - 1), "x {x} tile {t}");
            assert!(g.tiles_of(x, 4.0).contains(&t));
        }
        assert_eq!(g.owner(-5.0, -5.0), 0);
        assert_eq!(g.owner(100.0, 100.0), 2);
        assert!(g.in_haloed(2, 100.0, 100.0) && g.in_haloed(0, -5.0, 4.0));
        assert!(!g.in_haloed(0, 12.0, 4.0));
    }

    #[test]
    fn halo_points_go_to_both_sides_of_a_seam() {
        let g = grid();
        assert_eq!(g.tiles_of(9.5, 4.0), vec![0, 1]);
        assert_eq!(g.tiles_of(10.5, 4.0), vec![0, 1]);
        assert_eq!(g.tiles_of(5.0, 4.0), vec![0]);
        assert!(g.is_seam(10.2, 4.0));
        assert!(!g.is_seam(10.9, 4.0));
        assert!(!g.is_seam(15.0, 4.0));
    }

    #[test]
    fn bad_sizes_are_refused() {
        let (lo, hi) = (Point3::origin(), Point3::new(1.0, 1.0, 1.0));
        assert!(TileGrid::new(&lo, &hi, 0.0, 0.0).is_err());
        assert!(TileGrid::new(&lo, &hi, 1.0, 1.0).is_err());
        assert!(TileGrid::new(&lo, &hi, 1.0, -0.1).is_err());
        assert!(TileGrid::new(&lo, &hi, f64::NAN, 0.0).is_err());
        assert!(TileGrid::new(&lo, &Point3::new(1e9, 1e9, 0.0), 1e-3, 0.0).is_err());
    }
}
