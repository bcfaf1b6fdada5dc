//! The hallway scene (thesis §6.3.2): floor, two walls, optional ceiling, tiled by squares.

use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::common::{
    Density, LatticeHint, Misalignment, Noise, Piece, Scene, axis_rotation, misalign, sample_pieces,
};
use crate::atlas::Shape;
use crate::check::{self, positive};
use crate::error::{Remedy, Unit};
use crate::{Error, PointCloud, Pose, Primitive, Result};

/// The most squares a hallway may have.
const MAX_HALLWAY_SQUARES: f64 = 1e7;

/// Parameters of [`hallway`]. Lengths in metres (scene units).
///
/// The hallway runs along +x from x = 0 to `length`; the floor is z = 0, the walls are
/// y = 0 and y = `width`, the optional ceiling is z = `height`. The lattice spacing is
/// `side / 2` with origin 0.
#[derive(Debug, Clone, PartialEq)]
pub struct HallwayParams {
    /// Length along x (any positive value).
    pub length: f64,
    /// Width along y (a multiple of `side / 2`).
    pub width: f64,
    /// Height along z (a multiple of `side / 2`).
    pub height: f64,
    /// Side of the square tiles.
    pub side: f64,
    /// Whether there is a ceiling.
    pub ceiling: bool,
    /// How many points.
    pub density: Density,
    /// Per-point jitter and per-surface drift.
    pub noise: Noise,
    /// Optional rigid misalignment.
    pub misalignment: Misalignment,
    /// RNG seed.
    pub seed: u64,
}

impl Default for HallwayParams {
    fn default() -> Self {
        HallwayParams {
            length: 10.0,
            width: 2.0,
            height: 2.5,
            side: 1.0,
            ceiling: false,
            density: Density::PerArea(100.0),
            noise: Noise {
                jitter: 0.01,
                drift: 0.0,
            },
            misalignment: Misalignment::default(),
            seed: 0,
        }
    }
}

/// Tile centres along `[0, extent]` for tiles of `side` on a grid of step `side/2`:
/// `side/2, 3·side/2, …`, then one last tile whose centre is the first grid point at or
/// beyond `extent − side/2` (it overlaps its neighbour when `extent` is not a multiple of
/// `side`, and overhangs the end by less than `side/2` when `extent` is not a multiple
/// of `side/2`). Returns grid indices (centre = index × side/2).
fn tile_indices(extent: f64, side: f64) -> Vec<i64> {
    let s = side / 2.0;
    let last = (((extent - s) / s) - 1e-9).ceil().max(1.0) as i64;
    let mut out: Vec<i64> = (0..).map(|k| 1 + 2 * k).take_while(|&i| i < last).collect();
    out.push(last);
    out
}

/// A hallway tiled with squares of side `side` whose centres lie on the lattice of
/// spacing `side/2`; points are drawn on the true (untiled) surfaces.
pub fn hallway(params: &HallwayParams) -> Result<Scene> {
    let HallwayParams {
        length,
        width,
        height,
        side,
        ..
    } = *params;
    positive("length", length)?;
    positive("width", width)?;
    positive("height", height)?;
    positive("side", side)?;
    let s = side / 2.0;
    for (name, v) in [("width", width), ("height", height)] {
        check::multiple_of(name, v, s, "side / 2")?;
    }
    for (name, v) in [("length", length), ("width", width), ("height", height)] {
        if v < side - 1e-12 {
            return Err(Error::out_of_range(
                name,
                v,
                format!("at least side = {side}"),
            ));
        }
    }
    // Squares: about (length / s) × (floor, ceiling and walls) / s.
    let tiles = (length / s) * ((2.0 * width + 2.0 * height) / s);
    if tiles > MAX_HALLWAY_SQUARES {
        return Err(Error::OverLimit {
            what: format!("a {length} × {width} × {height} hallway of squares of side {side}"),
            need: tiles,
            limit: MAX_HALLWAY_SQUARES,
            unit: Unit::Count("squares"),
            remedies: vec![Remedy::Raise("side")],
        });
    }
    let (ix, iy, iz) = (
        tile_indices(length, side),
        tile_indices(width, side),
        tile_indices(height, side),
    );
    let (ny, nz) = ((width / s).round() as i64, (height / s).round() as i64);
    let shape = Shape::Square { side };
    let tile = |axis: usize, g: [i64; 3]| {
        let t = Vector3::new(g[0] as f64, g[1] as f64, g[2] as f64) * s;
        Primitive::new(shape.clone(), Pose::new(axis_rotation(axis), t))
    };
    let mut truth = Vec::new();
    let mut pieces = Vec::new();
    let (lx, ly, lz) = (
        Vector3::x() * length,
        Vector3::y() * width,
        Vector3::z() * height,
    );
    // Floor (normal z) and optional ceiling.
    let mut horizontals = vec![0];
    if params.ceiling {
        horizontals.push(nz);
    }
    for &k in &horizontals {
        truth.extend(
            ix.iter()
                .flat_map(|&i| iy.iter().map(move |&j| (i, j)))
                .map(|(i, j)| tile(2, [i, j, k])),
        );
        pieces.push(Piece::Rect {
            corner: Point3::new(0.0, 0.0, k as f64 * s),
            u: lx,
            v: ly,
        });
    }
    // Walls (normal y) at y = 0 and y = width.
    for j in [0, ny] {
        truth.extend(
            ix.iter()
                .flat_map(|&i| iz.iter().map(move |&k| (i, k)))
                .map(|(i, k)| tile(1, [i, j, k])),
        );
        pieces.push(Piece::Rect {
            corner: Point3::new(0.0, j as f64 * s, 0.0),
            u: lx,
            v: lz,
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut points = sample_pieces(&pieces, params.density, params.noise, &mut rng)?;
    let misalignment = misalign(&params.misalignment, &mut rng, s, &mut points, &mut truth)?;
    Ok(Scene {
        cloud: PointCloud::from_points(points),
        truth,
        lattice: LatticeHint {
            spacing: s,
            origin: Point3::origin(),
            shapes: vec![shape],
        },
        misalignment,
    })
}

#[cfg(test)]
mod tests {
    use super::tile_indices;

    #[test]
    fn tile_indices_cover_with_overlap_at_end() {
        assert_eq!(
            tile_indices(10.0, 1.0),
            vec![1, 3, 5, 7, 9, 11, 13, 15, 17, 19]
        );
        assert_eq!(tile_indices(2.5, 1.0), vec![1, 3, 4]);
        assert_eq!(tile_indices(1.0, 1.0), vec![1]);
        // 10.3 m: last centre at 10 m (grid point ≥ 9.8), overhang 0.2 m.
        assert_eq!(tile_indices(10.3, 1.0).last(), Some(&20));
    }
}
