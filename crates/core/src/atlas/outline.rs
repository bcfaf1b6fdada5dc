//! The outline of a set of planar points: where a bounded plane ends.
//!
//! The points (local 2-D coordinates) are binned into an occupancy grid whose cell
//! centres sit on the points' bounding box (the extreme points are cell centres), gaps
//! of up to two cells are closed (morphological closing with a 3 × 3 square), components
//! of fewer than [`MIN_COMPONENT_CELLS`] cells are dropped and holes of fewer than
//! [`MIN_HOLE_CELLS`] cells filled. Marching squares (`contour`) at iso-level ½ on the
//! 0/1 grid traces the boundary, which therefore runs along cell edges half a cell beyond
//! the outermost occupied cell centres. Each ring is then moved inward by half the
//! difference between the cell and the points' own spacing (estimated from the count of
//! points per occupied cell), so that the outline of an evenly sampled patch lies half a
//! point spacing beyond its outermost points, where the sampled surface itself ends; and
//! it is simplified (Ramer–Douglas–Peucker, `geo::Simplify`) with a tolerance of half a
//! cell.
//!
//! Bounded work: a grid of more than [`MAX_OUTLINE_CELLS`] cells is coarsened (the cell
//! is enlarged until the grid fits); the cost is linear in the points and the cells.

use std::collections::VecDeque;

use geo::{Simplify, Validation};
use nalgebra::{Point2, Vector2};

use super::plane::{signed_area, to_geo};
use crate::{Error, Result};

/// Most cells of the occupancy grid (4 Mi, 4 MiB of flags and 32 MiB of contour values);
/// a finer grid is coarsened until it fits.
pub const MAX_OUTLINE_CELLS: usize = 1 << 22;

/// Components of the closed occupancy grid with fewer cells than this are dropped
/// (stray points, a few spurious returns).
pub const MIN_COMPONENT_CELLS: usize = 6;

/// Holes with fewer cells than this are filled (missing returns inside a surface).
pub const MIN_HOLE_CELLS: usize = 4;

/// The simplification tolerance, in cells.
const SIMPLIFY_CELLS: f64 = 0.5;

/// The tolerance, in cells, that reduces straight runs of the traced outline to their
/// ends before corners are restored (small enough to keep the corner bevels).
const PRESIMPLIFY_CELLS: f64 = 0.1;

/// Halvings of the simplification tolerance tried when a simplified outline is not a
/// valid polygon, before the unsimplified one is used.
const SIMPLIFY_RETRIES: u32 = 3;

/// Edges of at least this many cells are the sides that [`square_corners`] extends.
const CORNER_LONG_CELLS: f64 = 5.0;

/// How far (cells) a restored corner may be from the rounded-off chain it replaces.
const CORNER_NEAR_CELLS: f64 = 2.5;

/// Least turn (radians) between the edges around a bevel for it to count as a corner.
const CORNER_MIN_TURN: f64 = 0.35;

/// Most vertices of an unsimplified outline that the inset is tried on (its validity
/// check is quadratic in them).
const MAX_CHECKED_VERTICES: usize = 2048;

/// Empty cells kept around the points' bounding box (room for the closing's dilation).
const MARGIN: usize = 1;

/// The longest miter of the inward offset, in offset distances (sharper corners are
/// bevelled to this length).
const MAX_MITER: f64 = 3.0;

/// A polygon as rings of local 2-D points: `(outline, holes)`, open rings.
pub(super) type Rings = (Vec<Point2<f64>>, Vec<Vec<Point2<f64>>>);

/// The outlines of `points` at occupancy cell `cell` (see the module docs), one polygon
/// per connected component of the cleaned grid, largest area first, each a valid
/// polygon; and the cell actually used (larger than `cell` when the grid was coarsened).
///
/// Errors: no points ([`Error::EmptyCloud`]), a non-finite point ([`Error::NonFinite`]),
/// `cell` not positive and finite ([`Error::OutOfRange`]), or no component large enough
/// ([`Error::InvalidArgument`]).
pub(super) fn outlines(points: &[Point2<f64>], cell: f64) -> Result<(Vec<Rings>, f64)> {
    crate::check::positive("plane outline cell", cell)?;
    if points.is_empty() {
        return Err(Error::EmptyCloud);
    }
    if let Some(index) = points
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return Err(Error::NonFinite {
            what: "plane point".into(),
            index,
        });
    }
    let mut grid = Grid::new(points, cell);
    grid.close();
    grid.drop_small_components();
    grid.fill_small_holes();
    let step = grid.step.x.min(grid.step.y);
    let inset = grid.inset(points.len());
    let mut polygons: Vec<Rings> = grid
        .rings()
        .into_iter()
        .filter_map(|rings| finish(rings, step, inset))
        .collect();
    if polygons.is_empty() {
        return Err(Error::invalid(format!(
            "plane points cover no {MIN_COMPONENT_CELLS} connected cells of {cell}"
        )));
    }
    polygons.sort_by(|a, b| signed_area(&b.0).abs().total_cmp(&signed_area(&a.0).abs()));
    Ok((polygons, step))
}

/// Simplified, inset, valid rings of one component (`None` if nothing valid is left).
/// Simplification falls back to smaller tolerances and finally to the traced rings
/// (valid by construction); the inset is skipped where it would make the polygon
/// invalid.
fn finish(rings: Rings, step: f64, inset: f64) -> Option<Rings> {
    let simplified = (0..=SIMPLIFY_RETRIES)
        .map(|k| SIMPLIFY_CELLS * step / 2f64.powi(k as i32))
        .find_map(|eps| simplify(&rings, eps, step).filter(is_valid));
    let (base, checkable) = match simplified {
        Some(s) => (s, true),
        None => {
            let small =
                rings.0.len() + rings.1.iter().map(Vec::len).sum::<usize>() <= MAX_CHECKED_VERTICES;
            (rings, small)
        }
    };
    if inset > 0.0 && checkable {
        let shrunk = offset_rings(&base, inset);
        if is_valid(&shrunk) && signed_area(&shrunk.0).abs() > 0.0 {
            return Some(shrunk);
        }
    }
    Some(base)
}

/// The rings simplified with tolerance `eps`, holes smaller than [`MIN_HOLE_CELLS`]
/// cells (or degenerate) dropped; `None` if the outline degenerates.
fn simplify((outline, holes): &Rings, eps: f64, step: f64) -> Option<Rings> {
    let min_hole = MIN_HOLE_CELLS as f64 * step * step;
    let rdp = |ring: &[Point2<f64>], eps: f64| -> Vec<Point2<f64>> {
        let ring = start_at_extreme(ring);
        let poly = to_geo(&ring, &[]).simplify(eps);
        let mut out: Vec<Point2<f64>> = poly
            .exterior()
            .coords()
            .map(|c| Point2::new(c.x, c.y))
            .collect();
        if out.len() > 1 && out.first() == out.last() {
            out.pop();
        }
        out
    };
    // Straight runs first (a tolerance that keeps the corner bevels), then the corners,
    // then the full tolerance.
    let one = |ring: &[Point2<f64>]| {
        let runs = rdp(ring, PRESIMPLIFY_CELLS * step);
        rdp(&square_corners(runs, step), eps)
    };
    let outline = one(outline);
    if outline.len() < 3 || signed_area(&outline).abs() < min_hole {
        return None;
    }
    let holes = holes
        .iter()
        .map(|h| one(h))
        .filter(|h| h.len() >= 3 && signed_area(h).abs() >= min_hole)
        .collect();
    Some((outline, holes))
}

/// Restores the corners the box average rounded off: between two consecutive edges of
/// at least [`CORNER_LONG_CELLS`] cells, a chain of shorter edges no longer than twice
/// [`CORNER_NEAR_CELLS`] cells is replaced by the point where the two long edges' lines
/// meet, when they turn by more than [`CORNER_MIN_TURN`] and the point is within
/// [`CORNER_NEAR_CELLS`] cells of the chain's mean vertex.
fn square_corners(ring: Vec<Point2<f64>>, step: f64) -> Vec<Point2<f64>> {
    let n = ring.len();
    let (long, near) = (CORNER_LONG_CELLS * step, CORNER_NEAR_CELLS * step);
    let at = |k: usize| ring[k % n];
    let length = |k: usize| (at(k + 1) - at(k)).norm();
    let longs: Vec<usize> = (0..n).filter(|&k| length(k) >= long).collect();
    if n < 4 || longs.len() < 2 {
        return ring;
    }
    let mut out = Vec::with_capacity(n);
    for (k, &e1) in longs.iter().enumerate() {
        let e2 = longs[(k + 1) % longs.len()];
        // The chain: vertices e1 + 1 ..= e2 (cyclically), joined by short edges.
        let count = (e2 + n - e1 - 1) % n + 1;
        let chain: Vec<Point2<f64>> = (1..=count).map(|j| at(e1 + j)).collect();
        let chain_length: f64 = (1..count).map(|j| length(e1 + j)).sum();
        let mean = chain.iter().map(|v| v.coords).sum::<Vector2<f64>>() / count as f64;
        let corner = (count > 1 && chain_length <= 2.0 * near)
            .then(|| line_meet(&at(e1), &at(e1 + 1), &at(e2), &at(e2 + 1)))
            .flatten()
            .filter(|x| (x.coords - mean).norm() <= near);
        match corner {
            Some(x) => out.push(x),
            None => out.extend(chain),
        }
    }
    // The first chain may have started before index 0: rotation only, same ring.
    if out.len() < 3 { ring } else { out }
}

/// Where the line through `p, q` meets the line through `r, s` (`None` when they turn
/// by less than [`CORNER_MIN_TURN`]).
fn line_meet(
    p: &Point2<f64>,
    q: &Point2<f64>,
    r: &Point2<f64>,
    s: &Point2<f64>,
) -> Option<Point2<f64>> {
    let cross = |u: Vector2<f64>, v: Vector2<f64>| u.x * v.y - u.y * v.x;
    let (d1, d2) = (q - p, s - r);
    let denom = cross(d1, d2);
    if denom.abs() <= CORNER_MIN_TURN.sin() * d1.norm() * d2.norm() {
        return None;
    }
    Some(p + d1 * (cross(r - p, d2) / denom))
}

/// The ring rotated to start at its vertex farthest from the vertex mean: an extreme
/// point every simplification keeps, so the fixed start of Ramer–Douglas–Peucker does
/// not leave a spurious vertex in the middle of an edge.
fn start_at_extreme(ring: &[Point2<f64>]) -> Vec<Point2<f64>> {
    let mean = ring.iter().map(|v| v.coords).sum::<Vector2<f64>>() / ring.len() as f64;
    let far = (0..ring.len())
        .max_by(|&a, &b| {
            let d = |i: usize| (ring[i].coords - mean).norm_squared();
            d(a).total_cmp(&d(b))
        })
        .unwrap_or(0);
    ring[far..].iter().chain(&ring[..far]).copied().collect()
}

/// Whether the rings form a valid polygon (`geo::Validation`).
fn is_valid((outline, holes): &Rings) -> bool {
    outline.len() >= 3 && to_geo(outline, holes).is_valid()
}

/// Every ring moved by `d` into the polygon's material (outline inward, holes outward):
/// each edge shifted along its normal, vertices at the shifted edges' intersections,
/// miters longer than [`MAX_MITER`]·d cut to that length.
fn offset_rings((outline, holes): &Rings, d: f64) -> Rings {
    let left = |ring: &[Point2<f64>], ccw: bool| {
        let ring: Vec<Point2<f64>> = if (signed_area(ring) > 0.0) == ccw {
            ring.to_vec()
        } else {
            ring.iter().rev().copied().collect()
        };
        offset_left(&ring, d)
    };
    (
        left(outline, true),
        holes.iter().map(|h| left(h, false)).collect(),
    )
}

/// Shifts every edge of `ring` by `d` to its left.
fn offset_left(ring: &[Point2<f64>], d: f64) -> Vec<Point2<f64>> {
    let n = ring.len();
    let normal = |i: usize| {
        let e = ring[(i + 1) % n] - ring[i];
        Vector2::new(-e.y, e.x)
            .try_normalize(0.0)
            .unwrap_or_else(Vector2::zeros)
    };
    (0..n)
        .map(|i| {
            let (n1, n2) = (normal((i + n - 1) % n), normal(i));
            let denom = 1.0 + n1.dot(&n2);
            let miter = if denom > 2.0 / (MAX_MITER * MAX_MITER) {
                (n1 + n2) / denom
            } else {
                (n1 + n2).try_normalize(0.0).unwrap_or(n2) * MAX_MITER
            };
            ring[i] + miter * d
        })
        .collect()
}

/// The occupancy grid: cell `(i, j)` has its centre at `origin + (i·step.x, j·step.y)`.
struct Grid {
    /// Cells along x and y (margins included).
    nx: usize,
    ny: usize,
    /// The centre of cell (0, 0).
    origin: Point2<f64>,
    /// Cell pitch along x and y.
    step: Vector2<f64>,
    /// Occupancy, row-major (`j·nx + i`).
    occupied: Vec<bool>,
    /// Cells holding at least one point (before closing).
    raw_count: usize,
}

impl Grid {
    /// Bins `points` into cells of about `cell` (coarsened to fit [`MAX_OUTLINE_CELLS`]).
    fn new(points: &[Point2<f64>], cell: f64) -> Grid {
        let (lo, hi) = points.iter().fold(
            (
                Point2::from([f64::INFINITY; 2]),
                Point2::from([f64::NEG_INFINITY; 2]),
            ),
            |(lo, hi), p| (lo.inf(p), hi.sup(p)),
        );
        let extent = hi - lo;
        let max = MAX_OUTLINE_CELLS as f64;
        let mut cell = cell.max(extent.x.max(extent.y) / max);
        let centres = |len: f64, cell: f64| (len / cell).round() + 1.0;
        let margin = 2.0 * MARGIN as f64;
        loop {
            let total = (centres(extent.x, cell) + margin) * (centres(extent.y, cell) + margin);
            if total <= max {
                break;
            }
            cell *= 1.01 * (total / max).sqrt();
        }
        let (cx, cy) = (
            centres(extent.x, cell) as usize,
            centres(extent.y, cell) as usize,
        );
        let step = |len: f64, n: usize| if n > 1 { len / (n - 1) as f64 } else { cell };
        let step = Vector2::new(step(extent.x, cx), step(extent.y, cy));
        let (nx, ny) = (cx + 2 * MARGIN, cy + 2 * MARGIN);
        let origin = lo - step * MARGIN as f64;
        let mut occupied = vec![false; nx * ny];
        for p in points {
            let i = (((p.x - lo.x) / step.x).round() as usize).min(cx - 1) + MARGIN;
            let j = (((p.y - lo.y) / step.y).round() as usize).min(cy - 1) + MARGIN;
            occupied[j * nx + i] = true;
        }
        let raw_count = occupied.iter().filter(|&&o| o).count();
        Grid {
            nx,
            ny,
            origin,
            step,
            occupied,
            raw_count,
        }
    }

    /// Morphological closing with a 3 × 3 square (dilation, then erosion with the
    /// outside of the grid empty): fills gaps up to two cells wide.
    fn close(&mut self) {
        let dilated = self.spread(&self.occupied, true);
        self.occupied = self.spread(&dilated, false);
    }

    /// 3 × 3 dilation (`any`) or erosion (`!any`: every neighbour set, outside empty),
    /// as two separable 3-cell passes.
    fn spread(&self, cells: &[bool], any: bool) -> Vec<bool> {
        let (nx, ny) = (self.nx, self.ny);
        let pass = |src: &[bool], di: usize, dj: usize| -> Vec<bool> {
            let at = |i: isize, j: isize| {
                let inside = i >= 0 && j >= 0 && (i as usize) < nx && (j as usize) < ny;
                inside && src[j as usize * nx + i as usize]
            };
            let mut out = vec![false; nx * ny];
            for j in 0..ny as isize {
                for i in 0..nx as isize {
                    let (a, b) = (
                        (i - di as isize, j - dj as isize),
                        (i + di as isize, j + dj as isize),
                    );
                    let trio = [at(a.0, a.1), at(i, j), at(b.0, b.1)];
                    out[j as usize * nx + i as usize] = if any {
                        trio.iter().any(|&c| c)
                    } else {
                        trio.iter().all(|&c| c)
                    };
                }
            }
            out
        };
        pass(&pass(cells, 1, 0), 0, 1)
    }

    /// Components of cells whose flag equals `value` (4-connected for occupied cells, as
    /// marching squares separates diagonal neighbours; 8-connected for empty ones), each
    /// as its cell indices and whether it touches the grid's border.
    fn components(&self, value: bool) -> Vec<(Vec<usize>, bool)> {
        let (nx, ny) = (self.nx, self.ny);
        let mut seen = vec![false; nx * ny];
        let mut out = Vec::new();
        let steps: &[(isize, isize)] = if value {
            &[(1, 0), (-1, 0), (0, 1), (0, -1)]
        } else {
            &[
                (1, 0),
                (-1, 0),
                (0, 1),
                (0, -1),
                (1, 1),
                (1, -1),
                (-1, 1),
                (-1, -1),
            ]
        };
        for start in 0..nx * ny {
            if seen[start] || self.occupied[start] != value {
                continue;
            }
            let (mut cells, mut border, mut queue) = (Vec::new(), false, VecDeque::from([start]));
            seen[start] = true;
            while let Some(c) = queue.pop_front() {
                let (i, j) = ((c % nx) as isize, (c / nx) as isize);
                border |= i == 0 || j == 0 || i as usize == nx - 1 || j as usize == ny - 1;
                cells.push(c);
                for (di, dj) in steps {
                    let (a, b) = (i + di, j + dj);
                    if a < 0 || b < 0 || a as usize >= nx || b as usize >= ny {
                        continue;
                    }
                    let n = b as usize * nx + a as usize;
                    if !seen[n] && self.occupied[n] == value {
                        seen[n] = true;
                        queue.push_back(n);
                    }
                }
            }
            out.push((cells, border));
        }
        out
    }

    /// The 3 × 3 mean of the occupancy (outside the grid empty), as contour values.
    fn box_average(&self) -> Vec<f64> {
        let (nx, ny) = (self.nx, self.ny);
        let mut out = vec![0.0; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                let mut sum = 0u32;
                for b in j.saturating_sub(1)..(j + 2).min(ny) {
                    for a in i.saturating_sub(1)..(i + 2).min(nx) {
                        sum += u32::from(self.occupied[b * nx + a]);
                    }
                }
                out[j * nx + i] = f64::from(sum) / 9.0;
            }
        }
        out
    }

    /// Clears components of fewer than [`MIN_COMPONENT_CELLS`] cells.
    fn drop_small_components(&mut self) {
        for (cells, _) in self.components(true) {
            if cells.len() < MIN_COMPONENT_CELLS {
                cells.iter().for_each(|&c| self.occupied[c] = false);
            }
        }
    }

    /// Fills enclosed empty regions of fewer than [`MIN_HOLE_CELLS`] cells.
    fn fill_small_holes(&mut self) {
        for (cells, border) in self.components(false) {
            if !border && cells.len() < MIN_HOLE_CELLS {
                cells.iter().for_each(|&c| self.occupied[c] = true);
            }
        }
    }

    /// How far to move the traced outline inward: half of (cell − point spacing), the
    /// spacing estimated as `√(occupied area / points)`; never negative, at most half a
    /// cell.
    fn inset(&self, points: usize) -> f64 {
        let cell_area = self.step.x * self.step.y;
        let spacing = (self.raw_count as f64 * cell_area / points.max(1) as f64).sqrt();
        let cell = cell_area.sqrt();
        ((cell - spacing) / 2.0).clamp(0.0, cell / 2.0)
    }

    /// The iso-½ rings of the grid's 3 × 3 box average (`contour::ContourBuilder`, with
    /// linear interpolation), grouped into polygons: each outer ring with the holes it is
    /// the innermost outer ring around. On a straight run of cells the iso-line is the
    /// cells' edge; the average turns the staircase of an edge oblique to the grid into a
    /// nearly straight line, which the simplification then reduces to a few vertices.
    fn rings(&self) -> Vec<Rings> {
        let values = self.box_average();
        // `contour` puts value (i, j) at (i + ½, j + ½) of its own coordinates.
        let builder = contour::ContourBuilder::new(self.nx, self.ny, true)
            .x_origin(self.origin.x - 0.5 * self.step.x)
            .y_origin(self.origin.y - 0.5 * self.step.y)
            .x_step(self.step.x)
            .y_step(self.step.y);
        let rings: Vec<Vec<Point2<f64>>> = builder
            .lines(&values, &[0.5])
            .unwrap_or_default()
            .into_iter()
            .flat_map(|line| line.into_inner().0.0)
            .map(|ring| ring.0.iter().map(|c| Point2::new(c.x, c.y)).collect())
            .collect();
        let (mut outers, mut holes) = (Vec::new(), Vec::new());
        for mut ring in rings {
            if ring.len() > 1 && ring.first() == ring.last() {
                ring.pop();
            }
            if ring.len() < 3 {
                continue;
            }
            // `contour` traces outer rings clockwise and holes counter-clockwise.
            if signed_area(&ring) < 0.0 {
                outers.push((ring, Vec::new()));
            } else {
                holes.push(ring);
            }
        }
        for hole in holes {
            let around = outers
                .iter()
                .enumerate()
                .filter(|(_, (o, _))| ring_contains(o, &hole[0]))
                .min_by(|(_, (a, _)), (_, (b, _))| {
                    signed_area(a).abs().total_cmp(&signed_area(b).abs())
                })
                .map(|(k, _)| k);
            if let Some(k) = around {
                outers[k].1.push(hole);
            }
        }
        outers
    }
}

/// Even–odd point-in-ring test.
fn ring_contains(ring: &[Point2<f64>], p: &Point2<f64>) -> bool {
    let n = ring.len();
    let mut inside = false;
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y) {
            inside = !inside;
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_is_capped_and_centres_sit_on_the_extreme_points() {
        let points = [
            Point2::new(-3.0, 1.0),
            Point2::new(7.0, 2.5),
            Point2::new(0.0, 1.5),
        ];
        let grid = Grid::new(&points, 1e-9);
        assert!(
            grid.nx * grid.ny <= MAX_OUTLINE_CELLS,
            "{} × {}",
            grid.nx,
            grid.ny
        );
        assert!(
            grid.nx * grid.ny > MAX_OUTLINE_CELLS / 2,
            "coarsened no more than needed"
        );
        let centre = |i: usize, j: usize| {
            grid.origin + Vector2::new(i as f64 * grid.step.x, j as f64 * grid.step.y)
        };
        let first = centre(MARGIN, MARGIN);
        let last = centre(grid.nx - 1 - MARGIN, grid.ny - 1 - MARGIN);
        assert!((first - Point2::new(-3.0, 1.0)).norm() < 1e-9);
        assert!((last - Point2::new(7.0, 2.5)).norm() < 1e-9);
        assert_eq!(grid.raw_count, 3);
    }

    #[test]
    fn closing_fills_gaps_and_keeps_concave_corners() {
        // An L of cells with a one-cell gap across one arm.
        let mut points = Vec::new();
        for j in 0..10 {
            for i in 0..10 {
                if (i < 4 || j < 4) && i != 7 {
                    points.push(Point2::new(i as f64, j as f64));
                }
            }
        }
        let mut grid = Grid::new(&points, 1.0);
        grid.close();
        let at = |g: &Grid, i: usize, j: usize| g.occupied[(j + MARGIN) * g.nx + i + MARGIN];
        assert!((0..4).all(|j| at(&grid, 7, j)), "gap closed");
        assert!(!at(&grid, 4, 4) && !at(&grid, 5, 5), "concave corner kept");
        assert!(at(&grid, 9, 0) && at(&grid, 0, 9) && !at(&grid, 9, 9));
        assert_eq!(grid.components(true).len(), 1);
    }
}
