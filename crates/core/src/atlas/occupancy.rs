//! The occupancy grid of a plane's points ([`super::outline`]): binning, morphological
//! closing, connected parts and holes, and the iso-½ rings that bound it.

use std::collections::VecDeque;

use nalgebra::{Point2, Vector2};

use super::plane::{Rings, signed_area};

/// Most cells of the occupancy grid (4 Mi, 4 MiB of flags and 32 MiB of contour values);
/// a finer grid is coarsened until it fits.
pub const MAX_OUTLINE_CELLS: usize = 1 << 22;

/// Components of the closed occupancy grid with fewer cells than this are dropped
/// (stray points, a few spurious returns).
pub const MIN_COMPONENT_CELLS: usize = 6;

/// Holes with fewer cells than this are filled (missing returns inside a surface).
pub const MIN_HOLE_CELLS: usize = 4;

/// Empty cells kept around the points' bounding box (room for the closing's dilation).
const MARGIN: usize = 1;

/// The occupancy grid: cell `(i, j)` has its centre at `origin + (i·step.x, j·step.y)`.
pub(super) struct Grid {
    /// Cells along x and y (margins included).
    nx: usize,
    ny: usize,
    /// The centre of cell (0, 0).
    origin: Point2<f64>,
    /// Cell pitch along x and y.
    pub(super) step: Vector2<f64>,
    /// Occupancy, row-major (`j·nx + i`).
    occupied: Vec<bool>,
    /// Cells holding at least one point (before closing).
    raw_count: usize,
}

impl Grid {
    /// Bins `points` into cells of about `cell` (coarsened to fit [`MAX_OUTLINE_CELLS`]).
    pub(super) fn new(points: &[Point2<f64>], cell: f64) -> Grid {
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
    pub(super) fn close(&mut self) {
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
    pub(super) fn drop_small_components(&mut self) {
        for (cells, _) in self.components(true) {
            if cells.len() < MIN_COMPONENT_CELLS {
                cells.iter().for_each(|&c| self.occupied[c] = false);
            }
        }
    }

    /// Fills enclosed empty regions of fewer than [`MIN_HOLE_CELLS`] cells.
    pub(super) fn fill_small_holes(&mut self) {
        for (cells, border) in self.components(false) {
            if !border && cells.len() < MIN_HOLE_CELLS {
                cells.iter().for_each(|&c| self.occupied[c] = true);
            }
        }
    }

    /// How far to move the traced outline inward: half of (cell − point spacing), the
    /// spacing estimated as `√(occupied area / points)`; never negative, at most half a
    /// cell.
    pub(super) fn inset(&self, points: usize) -> f64 {
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
    pub(super) fn rings(&self) -> Vec<Rings> {
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
