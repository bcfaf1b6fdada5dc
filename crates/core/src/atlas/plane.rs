//! The `Plane` type: a bounded planar patch, one or more disjoint polygons (each an outer
//! ring and optional holes) in the plane z = 0 of its local frame, normal +z. Unlike the
//! square and the disk its extent is free-form, so a plane can end where its points end;
//! its in-plane orientation is whatever frame the polygon was built in (see
//! [`super::fit_plane`], which takes it from the points).
//!
//! A plane of several **parts** is one surface seen in pieces: a floor cut by the
//! occlusion shadows of the furniture on it, a table top split by a mug's shadow. It is
//! one primitive (one pose, one existence), as a user counts surfaces.
//!
//! Queries are exact: a point's projection is inside the plane by the even–odd rule over
//! all rings (holes and other parts included: parts are disjoint), otherwise its closest
//! point lies on a ring edge. The inside test looks at the edges of the horizontal slab
//! of the projection (`edge_slabs.rs`), the closest boundary point is found through a
//! hierarchy over the triangulation (`bvh.rs`): neither scans every edge.

use std::sync::Arc;

use geo::{LineString, Polygon, TriangulateEarcut, Validation};
use nalgebra::{Point2, Point3, Vector3};
use serde_json::Value;

use super::TriMesh;
use super::bvh::TriangleBvh;
use super::edge_slabs::EdgeSlabs;
use super::planar::plane_ray;
use crate::error::Unit;
use crate::{Error, Result};

/// A polygon as rings of local 2-D points: `(outline, holes)`, each ring open (first
/// vertex not repeated).
pub type Rings = (Vec<Point2<f64>>, Vec<Vec<Point2<f64>>>);

/// Most vertices a plane may have over all its rings: the validity check of a polygon
/// is quadratic in them (16 Ki vertices, about 10⁸ segment tests).
pub const MAX_PLANE_VERTICES: usize = 1 << 14;

/// Most sample rows [`PlaneShape`] sampling scans: a spacing finer than the polygon's
/// bounding-box extent ÷ this is raised to it, so a thin sliver cannot make the scan
/// unbounded (the sample count itself is capped by [`super::Shape::MAX_SAMPLES`]).
const MAX_SAMPLE_ROWS: f64 = (1u64 << 20) as f64;

/// Relative mismatch allowed between the triangulation's area and the polygon's
/// (shoelace) area before the triangulation is declared failed.
const TRIANGULATION_AREA_TOLERANCE: f64 = 1e-9;

/// A bounded planar polygon in the plane z = 0 (local frame, local units).
///
/// Build it with [`PlaneShape::new`] (checked rings) or from points with
/// [`PlaneShape::from_points`]; clones share the rings and the triangulation.
#[derive(Clone)]
pub struct PlaneShape {
    inner: Arc<PlaneData>,
}

/// The immutable data of a [`PlaneShape`].
struct PlaneData {
    /// The disjoint parts, largest area first: each an outer ring, counter-clockwise seen
    /// from +z, and its holes, clockwise; rings not closed (first ≠ last).
    parts: Vec<Rings>,
    /// Every ring edge `[a, b]` (outlines and holes of every part).
    edges: Vec<[Point2<f64>; 2]>,
    /// Triangulation in z = 0, faces counter-clockwise seen from +z.
    mesh: TriMesh,
    /// Polygon area (outlines minus holes, over every part), local units².
    area: f64,
    /// Largest outline vertex distance from the local origin, local units.
    bounding_radius: f64,
    /// Axis-aligned bounds of the outlines: `(min, max)`.
    bounds: (Point2<f64>, Point2<f64>),
    /// `edges` by horizontal slab, for the inside test.
    slabs: EdgeSlabs,
    /// A hierarchy over `mesh`'s triangles, for the closest point outside.
    bvh: TriangleBvh,
}

impl std::fmt::Debug for PlaneShape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PlaneShape")
            .field("parts", &self.inner.parts.len())
            .field("vertices", &self.vertex_count())
            .field("area", &self.inner.area)
            .finish()
    }
}

impl PartialEq for PlaneShape {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.inner, &other.inner) || self.inner.parts == other.inner.parts
    }
}

impl PlaneShape {
    /// A plane bounded by `outline` with `holes` (local 2-D coordinates, local units; a
    /// ring may repeat its first vertex at the end; either orientation).
    ///
    /// Errors: a ring with fewer than 3 vertices ([`Error::OutOfRange`]), a non-finite
    /// vertex ([`Error::NonFinite`]), more than [`MAX_PLANE_VERTICES`] vertices
    /// ([`Error::OverLimit`]), rings that are not a valid polygon (self-intersecting, a
    /// hole outside the outline or crossing another ring: [`Error::InvalidArgument`]), or
    /// no area.
    pub fn new(outline: Vec<Point2<f64>>, holes: Vec<Vec<Point2<f64>>>) -> Result<PlaneShape> {
        Self::from_parts(vec![(outline, holes)])
    }

    /// A plane of one or more disjoint `parts`, each `(outline, holes)` as in
    /// [`PlaneShape::new`]. Errors as there, and [`Error::InvalidArgument`] when parts
    /// overlap or touch; no parts is [`Error::OutOfRange`].
    pub fn from_parts(parts: Vec<Rings>) -> Result<PlaneShape> {
        crate::check::at_least("plane parts", parts.len(), 1)?;
        let parts = check_parts(parts)?;
        let polygons: Vec<Polygon<f64>> = parts.iter().map(|(o, h)| to_geo(o, h)).collect();
        if let Err(e) = geo::MultiPolygon::new(polygons).check_validation() {
            return Err(Error::invalid(format!(
                "plane outline is not a valid polygon: {e}"
            )));
        }
        Self::from_valid_parts(parts)
    }

    /// [`PlaneShape::from_parts`] without the quadratic validity check, for disjoint parts
    /// that are valid polygons by construction (closed-free, finite, ≥ 3 vertices each).
    /// Parts are put largest first.
    pub(super) fn from_valid_parts(parts: Vec<Rings>) -> Result<PlaneShape> {
        let mut parts: Vec<(Rings, f64)> = parts
            .into_iter()
            .map(|(outline, holes)| {
                let outline = oriented(outline, true);
                let holes: Vec<_> = holes.into_iter().map(|h| oriented(h, false)).collect();
                let area =
                    signed_area(&outline) + holes.iter().map(|h| signed_area(h)).sum::<f64>();
                ((outline, holes), area)
            })
            .collect();
        parts.sort_by(|a, b| b.1.total_cmp(&a.1));
        let area: f64 = parts.iter().map(|p| p.1).sum();
        if parts.iter().any(|p| p.1.is_nan() || p.1 <= 0.0) || area.is_nan() {
            return Err(Error::invalid("plane outline has no area"));
        }
        let parts: Vec<Rings> = parts.into_iter().map(|p| p.0).collect();
        let mut mesh = TriMesh::default();
        for (outline, holes) in &parts {
            mesh.append(&triangulate(outline, holes));
        }
        if (mesh.area() - area).abs() > TRIANGULATION_AREA_TOLERANCE * area {
            return Err(Error::invalid(format!(
                "plane outline could not be triangulated (mesh area {} of polygon area {area})",
                mesh.area()
            )));
        }
        let edges: Vec<[Point2<f64>; 2]> = parts
            .iter()
            .flat_map(|(o, h)| std::iter::once(o).chain(h))
            .flat_map(|ring| ring_edges(ring))
            .collect();
        let outlines = || parts.iter().flat_map(|(o, _)| o.iter());
        let bounding_radius = outlines().map(|v| v.coords.norm()).fold(0.0, f64::max);
        let bounds = outlines().fold(
            (
                Point2::from([f64::INFINITY; 2]),
                Point2::from([f64::NEG_INFINITY; 2]),
            ),
            |(lo, hi), v| (lo.inf(v), hi.sup(v)),
        );
        let slabs = EdgeSlabs::new(&edges, bounds.0.y, bounds.1.y);
        let bvh = TriangleBvh::new(&mesh);
        let inner = PlaneData {
            parts,
            edges,
            mesh,
            area,
            bounding_radius,
            bounds,
            slabs,
            bvh,
        };
        Ok(PlaneShape {
            inner: Arc::new(inner),
        })
    }

    /// The outer ring of the largest part, counter-clockwise seen from +z, first vertex
    /// not repeated (local units).
    pub fn outline(&self) -> &[Point2<f64>] {
        &self.inner.parts[0].0
    }

    /// The holes of the largest part, each clockwise seen from +z, first vertex not
    /// repeated (local units).
    pub fn holes(&self) -> &[Vec<Point2<f64>>] {
        &self.inner.parts[0].1
    }

    /// Every part `(outline, holes)`, largest area first (the first is
    /// [`PlaneShape::outline`] and [`PlaneShape::holes`]).
    pub fn parts(&self) -> &[Rings] {
        &self.inner.parts
    }

    /// The number of vertices over all rings of all parts.
    pub fn vertex_count(&self) -> usize {
        self.inner
            .parts
            .iter()
            .map(|(o, h)| o.len() + h.iter().map(Vec::len).sum::<usize>())
            .sum()
    }

    /// Polygon area: outlines minus holes, over every part (local units²).
    pub fn area(&self) -> f64 {
        self.inner.area
    }

    /// Radius of a ball about the local origin containing the polygon (local units).
    pub fn bounding_radius(&self) -> f64 {
        self.inner.bounding_radius
    }

    /// The precomputed triangulation (z = 0, faces counter-clockwise seen from +z).
    pub fn mesh(&self) -> &TriMesh {
        &self.inner.mesh
    }

    /// Whether the local 2-D point `(x, y)` is inside the polygon (even–odd rule over all
    /// rings; points on an edge may go either way).
    pub fn contains(&self, x: f64, y: f64) -> bool {
        let mut inside = false;
        for &e in self.inner.slabs.near(y) {
            let [a, b] = &self.inner.edges[e as usize];
            if (a.y > y) != (b.y > y) && x < a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y) {
                inside = !inside;
            }
        }
        inside
    }

    /// The closest point of the polygon to `p` (local frame): its projection onto z = 0
    /// when that is inside, otherwise the closest point of the closest ring edge.
    pub fn closest_point(&self, p: &Point3<f64>) -> Point3<f64> {
        if self.contains(p.x, p.y) {
            return Point3::new(p.x, p.y, 0.0);
        }
        // Outside, the closest point lies on the boundary, which is the boundary of the
        // triangulation: its hierarchy finds it in logarithmic time, near or far.
        let q = Point3::new(p.x, p.y, 0.0);
        let c = self.inner.bvh.closest_point(&q).unwrap_or(q);
        Point3::new(c.x, c.y, 0.0)
    }

    /// The first hit of the ray `o + t·d` (local frame, `t ≥ 0` in units of `d`) with the
    /// polygon; a ray lying in the plane z = 0 hits where it first enters the polygon.
    pub fn ray_intersect(&self, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
        plane_ray(o, d, |x, y| self.contains(x, y), |o, d| self.entry(o, d))
    }

    /// The first `t ≥ 0` at which the 2-D ray `o + t·d` is in the polygon (inside or on
    /// an edge).
    fn entry(&self, o: [f64; 2], d: [f64; 2]) -> Option<f64> {
        if self.contains(o[0], o[1]) {
            return Some(0.0);
        }
        let (o, d) = (Point2::from(o), nalgebra::Vector2::from(d));
        self.inner
            .edges
            .iter()
            .filter_map(|[a, b]| ray_segment(&o, &d, a, b))
            .reduce(f64::min)
    }

    /// Area-uniform samples: the centres of a square grid of pitch `spacing` laid over
    /// the polygon's bounding box (centred on it) that fall inside the polygon, row by
    /// row; about `area / spacing²` points, at least one (an interior point when the
    /// grid misses a polygon smaller than a cell). `spacing` must be positive and finite.
    pub(super) fn sample(&self, spacing: f64) -> Vec<Point3<f64>> {
        let (lo, hi) = self.inner.bounds;
        let extent = hi - lo;
        let spacing = spacing.max(extent.x.max(extent.y) / MAX_SAMPLE_ROWS);
        let (nx, ny) = (cells(extent.x, spacing), cells(extent.y, spacing));
        let centre = nalgebra::center(&lo, &hi);
        let x0 = centre.x - (nx - 1) as f64 * spacing / 2.0;
        let y0 = centre.y - (ny - 1) as f64 * spacing / 2.0;
        let mut out = Vec::new();
        let mut crossings = Vec::new();
        for j in 0..ny {
            let y = y0 + j as f64 * spacing;
            crossings.clear();
            crossings.extend(
                self.inner
                    .edges
                    .iter()
                    .filter(|[a, b]| (a.y > y) != (b.y > y))
                    .map(|[a, b]| a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y)),
            );
            crossings.sort_by(f64::total_cmp);
            for span in crossings.chunks_exact(2) {
                // Columns i with x0 + i·spacing in [span[0], span[1]).
                let first = ((span[0] - x0) / spacing).ceil().max(0.0) as usize;
                let mut i = first;
                while i < nx && x0 + i as f64 * spacing < span[1] {
                    out.push(Point3::new(x0 + i as f64 * spacing, y, 0.0));
                    i += 1;
                }
            }
        }
        if out.is_empty() {
            out.push(self.interior_point());
        }
        out
    }

    /// A point inside the polygon: the centroid of its largest triangle.
    fn interior_point(&self) -> Point3<f64> {
        let mesh = &self.inner.mesh;
        let largest = mesh
            .faces
            .iter()
            .max_by(|f, g| mesh.triangle_area(f).total_cmp(&mesh.triangle_area(g)))
            .expect("a plane has at least one face with area");
        let [a, b, c] = largest.map(|i| mesh.vertices[i as usize].coords);
        Point3::from((a + b + c) / 3.0)
    }

    /// The rings as JSON: `(outline, holes, more_parts)` with `outline = [[x, y], …]`
    /// and `holes = [[[x, y], …], …]` of the largest part, and `more_parts` the other
    /// parts as `[{"outline": …, "holes": …}, …]` (`None` for a plane of one part); local
    /// units, first vertex not repeated.
    pub fn rings_json(&self) -> (Value, Value, Option<Value>) {
        let ring =
            |r: &[Point2<f64>]| Value::from(r.iter().map(|v| vec![v.x, v.y]).collect::<Vec<_>>());
        let holes =
            |h: &[Vec<Point2<f64>>]| Value::from(h.iter().map(|r| ring(r)).collect::<Vec<_>>());
        let (outline, first_holes) = &self.inner.parts[0];
        let more = &self.inner.parts[1..];
        let more = (!more.is_empty()).then(|| {
            Value::from(
                more.iter()
                    .map(|(o, h)| serde_json::json!({ "outline": ring(o), "holes": holes(h) }))
                    .collect::<Vec<_>>(),
            )
        });
        (ring(outline), holes(first_holes), more)
    }

    /// A plane from the JSON fields of [`PlaneShape::rings_json`]: `outline` required,
    /// `holes` and `more_parts` optional (absent or `null`: none). Errors name the field
    /// ([`Error::Json`]) or the polygon's fault (see [`PlaneShape::from_parts`]).
    pub fn from_rings_json(
        outline: Option<&Value>,
        holes: Option<&Value>,
        more_parts: Option<&Value>,
    ) -> Result<PlaneShape> {
        let mut parts = vec![part_from_json(outline, holes, "")?];
        match more_parts {
            None | Some(Value::Null) => {}
            Some(Value::Array(list)) => {
                for (k, part) in list.iter().enumerate() {
                    let at = format!("more_parts[{k}].");
                    parts.push(part_from_json(part.get("outline"), part.get("holes"), &at)?);
                }
            }
            Some(_) => {
                return Err(Error::json(
                    "more_parts",
                    "an array of parts {\"outline\": …, \"holes\": …}",
                ));
            }
        }
        PlaneShape::from_parts(parts)
    }
}

/// One part's rings from JSON (`at` prefixes the field names in errors).
fn part_from_json(outline: Option<&Value>, holes: Option<&Value>, at: &str) -> Result<Rings> {
    let outline = ring_from_json(outline, &format!("{at}outline"))?;
    let holes = match holes {
        None | Some(Value::Null) => Vec::new(),
        Some(Value::Array(list)) => list
            .iter()
            .enumerate()
            .map(|(k, h)| ring_from_json(Some(h), &format!("{at}holes[{k}]")))
            .collect::<Result<_>>()?,
        Some(_) => {
            return Err(Error::json(
                format!("{at}holes"),
                "an array of rings [[x, y], …]",
            ));
        }
    };
    Ok((outline, holes))
}

/// `ceil(length / spacing)` sample columns, at least 1.
fn cells(length: f64, spacing: f64) -> usize {
    ((length / spacing).ceil() as usize).max(1)
}

/// One ring from JSON: an array of at least 3 `[x, y]` number pairs.
fn ring_from_json(v: Option<&Value>, field: &str) -> Result<Vec<Point2<f64>>> {
    let expected = "an array of [x, y] number pairs";
    let list = v
        .and_then(Value::as_array)
        .ok_or_else(|| Error::json(field, expected))?;
    list.iter()
        .enumerate()
        .map(|(k, xy)| match xy.as_array().map(Vec::as_slice) {
            Some([x, y]) => match (x.as_f64(), y.as_f64()) {
                (Some(x), Some(y)) => Ok(Point2::new(x, y)),
                _ => Err(Error::json(
                    format!("{field}[{k}]"),
                    "a pair of numbers [x, y]",
                )),
            },
            _ => Err(Error::json(
                format!("{field}[{k}]"),
                "a pair of numbers [x, y]",
            )),
        })
        .collect()
}

/// The cheap checks of [`PlaneShape::from_parts`]; returns the rings without a closing
/// vertex.
fn check_parts(parts: Vec<Rings>) -> Result<Vec<Rings>> {
    let parts: Vec<Rings> = parts
        .into_iter()
        .map(|(o, h)| (open(o), h.into_iter().map(open).collect()))
        .collect();
    let total: usize = parts
        .iter()
        .map(|(o, h)| o.len() + h.iter().map(Vec::len).sum::<usize>())
        .sum();
    if total > MAX_PLANE_VERTICES {
        return Err(Error::OverLimit {
            what: "a plane outline".into(),
            need: total as f64,
            limit: MAX_PLANE_VERTICES as f64,
            unit: Unit::Count("vertices"),
            remedies: Vec::new(),
        });
    }
    let rings = parts.iter().flat_map(|(outline, holes)| {
        std::iter::once(("plane outline", outline)).chain(holes.iter().map(|h| ("plane hole", h)))
    });
    for (name, ring) in rings {
        crate::check::at_least(&format!("{name} vertices"), ring.len(), 3)?;
        if let Some(index) = ring
            .iter()
            .position(|v| !(v.x.is_finite() && v.y.is_finite()))
        {
            return Err(Error::NonFinite {
                what: format!("{name} vertex"),
                index,
            });
        }
    }
    Ok(parts)
}

/// The ring without its closing vertex (when the last equals the first).
fn open(mut ring: Vec<Point2<f64>>) -> Vec<Point2<f64>> {
    if ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    ring
}

/// Shoelace signed area of an open ring: positive when counter-clockwise (y up).
pub(super) fn signed_area(ring: &[Point2<f64>]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
        / 2.0
}

/// The ring turned counter-clockwise (`ccw`) or clockwise.
fn oriented(mut ring: Vec<Point2<f64>>, ccw: bool) -> Vec<Point2<f64>> {
    if (signed_area(&ring) > 0.0) != ccw {
        ring.reverse();
    }
    ring
}

/// The edges `[v_i, v_{i+1}]` of an open ring, closing edge included.
fn ring_edges(ring: &[Point2<f64>]) -> impl Iterator<Item = [Point2<f64>; 2]> + '_ {
    (0..ring.len()).map(move |i| [ring[i], ring[(i + 1) % ring.len()]])
}

/// The rings as a `geo` polygon (closed line strings).
pub(super) fn to_geo(outline: &[Point2<f64>], holes: &[Vec<Point2<f64>>]) -> Polygon<f64> {
    let line =
        |r: &[Point2<f64>]| LineString::from(r.iter().map(|v| (v.x, v.y)).collect::<Vec<_>>());
    Polygon::new(line(outline), holes.iter().map(|h| line(h)).collect())
}

/// Ear-cutting triangulation (`geo::TriangulateEarcut`), faces turned counter-clockwise
/// seen from +z and zero-area faces dropped.
fn triangulate(outline: &[Point2<f64>], holes: &[Vec<Point2<f64>>]) -> TriMesh {
    let raw = to_geo(outline, holes).earcut_triangles_raw();
    let vertices: Vec<Point3<f64>> = raw
        .vertices
        .iter()
        .map(|[x, y]| Point3::new(*x, *y, 0.0))
        .collect();
    let faces = raw
        .triangle_indices
        .chunks_exact(3)
        .filter_map(|t| {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| vertices[i]);
            let turn = (b - a).cross(&(c - a)).z;
            let face = [t[0], t[1], t[2]].map(|i| i as u32);
            match turn.partial_cmp(&0.0) {
                Some(std::cmp::Ordering::Greater) => Some(face),
                Some(std::cmp::Ordering::Less) => Some([face[0], face[2], face[1]]),
                _ => None,
            }
        })
        .collect();
    TriMesh { vertices, faces }
}

/// The first `t ≥ 0` at which the 2-D ray `o + t·d` touches segment `ab`.
fn ray_segment(
    o: &Point2<f64>,
    d: &nalgebra::Vector2<f64>,
    a: &Point2<f64>,
    b: &Point2<f64>,
) -> Option<f64> {
    let cross = |u: &nalgebra::Vector2<f64>, v: &nalgebra::Vector2<f64>| u.x * v.y - u.y * v.x;
    let (e, w) = (b - a, a - o);
    let denom = cross(d, &e);
    if denom == 0.0 {
        // Parallel: a hit only if collinear; then at the nearer end ahead (or at 0 if
        // the origin lies on the segment).
        if cross(&w, d) != 0.0 {
            return None;
        }
        let len2 = d.norm_squared();
        let (ta, tb) = (w.dot(d) / len2, (b - o).dot(d) / len2);
        let (lo, hi) = (ta.min(tb), ta.max(tb));
        return if hi < 0.0 { None } else { Some(lo.max(0.0)) };
    }
    let t = cross(&w, &e) / denom;
    let u = cross(&w, d) / denom;
    (t >= 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
}
