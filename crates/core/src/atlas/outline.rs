//! The outline of a set of planar points: where a bounded plane ends.
//!
//! 1. The points (local 2-D coordinates) are binned into an occupancy grid
//!    ([`super::occupancy`]) whose cell centres sit on the points' bounding box (the
//!    extreme points are cell centres).
//! 2. Gaps up to two cells wide are closed (morphological closing with a 3 × 3 square),
//!    4-connected parts of fewer than [`MIN_COMPONENT_CELLS`] cells dropped, holes of
//!    fewer than [`MIN_HOLE_CELLS`] cells filled.
//! 3. Marching squares (`contour`, linear interpolation) traces the iso-½ line of the
//!    grid's 3 × 3 box average: along a straight run of cells that is the cells' edge,
//!    half a cell beyond the outermost occupied cell centres; across an edge oblique to
//!    the grid the average turns the staircase into a nearly straight line.
//! 4. Each ring is simplified: straight runs to their ends (a tenth of a cell), corners
//!    the average rounded off restored where two long sides meet, then
//!    Ramer–Douglas–Peucker (`geo::Simplify`) at half a cell; smaller tolerances, and
//!    finally the traced rings, are used where the result is not a valid polygon.
//! 5. The rings are moved inward by half of (cell − point spacing), the spacing
//!    estimated from the count of points per occupied cell, so that the outline of an
//!    evenly sampled patch lies half a point spacing beyond its outermost points, where
//!    the sampled surface itself ends (no overhang); skipped where it would make the
//!    polygon invalid.
//!
//! Bounded work: a grid of more than [`crate::atlas::MAX_OUTLINE_CELLS`] cells is coarsened (the cell
//! is enlarged until the grid fits); the cost is linear in the points and the cells,
//! plus the validity checks of the simplified rings (quadratic in their few vertices).

use geo::{Simplify, Validation};
use nalgebra::{Point2, Vector2};

use super::occupancy::{Grid, MIN_COMPONENT_CELLS, MIN_HOLE_CELLS};
use super::plane::{Rings, signed_area, to_geo};
use crate::error::{Remedy, Unit};
use crate::{Error, Result};

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
const CORNER_NEAR_CELLS: f64 = 2.0;

/// Least turn (radians) between the edges around a bevel for it to count as a corner.
const CORNER_MIN_TURN: f64 = 0.75;

/// Most vertices of a simplified outline (all rings): its validity check is quadratic
/// in them. A more complex outline is traced again at twice the cell.
pub(super) const MAX_CHECKED_VERTICES: usize = 2048;

/// Doublings of the cell tried when an outline has more than [`MAX_CHECKED_VERTICES`]
/// vertices.
const COARSEN_RETRIES: u32 = 3;

/// The longest miter of the inward offset, in offset distances (sharper corners are
/// bevelled to this length).
const MAX_MITER: f64 = 3.0;

/// The outlines of `points` at occupancy cell `cell` (see the module docs), one polygon
/// per connected component of the cleaned grid, largest area first, each a valid
/// polygon; and the cell actually used: larger than `cell` when the grid was coarsened
/// to fit [`crate::atlas::MAX_OUTLINE_CELLS`], or doubled (up to [`COARSEN_RETRIES`]
/// times) when a simplified outline still had more than [`MAX_CHECKED_VERTICES`]
/// vertices (points much sparser than the cell leave a speckled outline).
///
/// Errors: no points ([`Error::EmptyCloud`]), a non-finite point ([`Error::NonFinite`]),
/// `cell` not positive and finite ([`Error::OutOfRange`]), no component large enough
/// ([`Error::InvalidArgument`]), or an outline too complex even at the coarsest cell
/// ([`Error::OverLimit`]).
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
    let mut try_cell = cell;
    let mut need = 0;
    for _ in 0..=COARSEN_RETRIES {
        match trace(points, try_cell)? {
            Ok(done) => return Ok(done),
            Err(vertices) => need = vertices,
        }
        try_cell *= 2.0;
    }
    Err(Error::OverLimit {
        what: format!(
            "the outline of {} plane points at cell {cell}",
            points.len()
        ),
        need: need as f64,
        limit: MAX_CHECKED_VERTICES as f64,
        unit: Unit::Count("outline vertices"),
        remedies: vec![Remedy::Raise("cell")],
    })
}

/// One attempt of [`outlines`] at `cell`: `Ok(Err(n))` when a simplified outline has
/// `n` > [`MAX_CHECKED_VERTICES`] vertices.
fn trace(points: &[Point2<f64>], cell: f64) -> Result<Result<(Vec<Rings>, f64), usize>> {
    let mut grid = Grid::new(points, cell);
    grid.close();
    grid.drop_small_components();
    grid.fill_small_holes();
    let step = grid.step.x.min(grid.step.y);
    let inset = grid.inset(points.len());
    let mut polygons = Vec::new();
    for rings in grid.rings() {
        match finish(rings, step, inset) {
            Ok(p) => polygons.push(p),
            Err(n) => return Ok(Err(n)),
        }
    }
    if polygons.is_empty() {
        return Err(Error::invalid(format!(
            "plane points leave no outline at cell {cell}: no part covers \
             {MIN_COMPONENT_CELLS} connected cells and is two cells wide"
        )));
    }
    polygons.sort_by(|a, b| signed_area(&b.0).abs().total_cmp(&signed_area(&a.0).abs()));
    Ok(Ok((polygons, step)))
}

/// The number of vertices over all rings.
fn vertex_count((outline, holes): &Rings) -> usize {
    outline.len() + holes.iter().map(Vec::len).sum::<usize>()
}

/// Simplified, inset, valid rings of one component, or `Err(n)` when the simplified
/// rings have `n` > [`MAX_CHECKED_VERTICES`] vertices (too many to check). The
/// simplification falls back to smaller tolerances and finally to the traced rings
/// (valid by construction); the inset is skipped where it would make the polygon
/// invalid.
fn finish(rings: Rings, step: f64, inset: f64) -> Result<Rings, usize> {
    let mut simplified = None;
    for k in 0..=SIMPLIFY_RETRIES {
        let eps = SIMPLIFY_CELLS * step / 2f64.powi(k as i32);
        let Some(candidate) = simplify(&rings, eps, step) else {
            continue;
        };
        let n = vertex_count(&candidate);
        if n > MAX_CHECKED_VERTICES {
            return Err(n);
        }
        if is_valid(&candidate) {
            simplified = Some(candidate);
            break;
        }
    }
    let (base, checkable) = match simplified {
        Some(s) => (s, true),
        None => {
            let small = vertex_count(&rings) <= MAX_CHECKED_VERTICES;
            (rings, small)
        }
    };
    if inset > 0.0 && checkable {
        let shrunk = offset_rings(&base, inset);
        if is_valid(&shrunk) && signed_area(&shrunk.0).abs() > 0.0 {
            return Ok(shrunk);
        }
    }
    Ok(base)
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
