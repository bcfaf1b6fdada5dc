//! A bounded plane from 3-D points: the plane by principal components (or a given
//! normal), the in-plane axes from the points' minimum-area enclosing rectangle, the
//! local origin at their centroid, and the outline from [`PlaneShape::from_points`].

use geo::{MinimumRotatedRect, MultiPoint};
use nalgebra::{Matrix3, Point2, Point3, Rotation3, UnitQuaternion, Vector3};

use super::{PlaneShape, Shape};
use crate::{Error, Pose, Primitive, Result};

impl PlaneShape {
    /// The outline of `points` (local 2-D coordinates, local units) at occupancy cell
    /// `cell` (same units; pass a few point spacings): the largest connected part, see
    /// [`PlaneShape::parts_from_points`] for how it is traced. The plane's coordinates are
    /// the points' own.
    pub fn from_points(points: &[Point2<f64>], cell: f64) -> Result<PlaneShape> {
        Self::parts_from_points(points, cell)?
            .into_iter()
            .next()
            .ok_or_else(|| Error::invalid("plane points have no outline"))
    }

    /// One plane per connected part of `points` (local 2-D coordinates, local units),
    /// largest area first, traced on an occupancy grid of cell `cell` (same units; pass
    /// a few point spacings; the steps are documented in `atlas/outline.rs`): gaps up to two cells wide
    /// closed, parts of fewer than [`crate::atlas::MIN_COMPONENT_CELLS`] cells dropped,
    /// holes of fewer than [`crate::atlas::MIN_HOLE_CELLS`] cells filled, the boundary
    /// simplified to within about half a cell and ending half a point spacing beyond the
    /// outermost points. A grid of more than [`crate::atlas::MAX_OUTLINE_CELLS`] cells is
    /// coarsened until it fits (the outline is then correspondingly coarser, and points
    /// sparse at the coarser cell may leave no part); an outline that simplifies to more
    /// than 2048 vertices (points much sparser than the cell) is traced again at twice
    /// the cell, up to three times. Linear in points and cells.
    ///
    /// Errors: no points ([`Error::EmptyCloud`]), a non-finite point
    /// ([`Error::NonFinite`]), `cell` not positive and finite ([`Error::OutOfRange`]),
    /// no part of at least the minimum size ([`Error::InvalidArgument`]), or an outline
    /// still too complex at the coarsest cell tried ([`Error::OverLimit`]).
    pub fn parts_from_points(points: &[Point2<f64>], cell: f64) -> Result<Vec<PlaneShape>> {
        let (polygons, _cell) = super::outline::outlines(points, cell)?;
        polygons
            .into_iter()
            .map(|part| {
                check_vertex_count(std::slice::from_ref(&part))?;
                PlaneShape::from_valid_parts(vec![part])
            })
            .collect()
    }

    /// One plane whose parts are every connected part of `points`, traced as in
    /// [`PlaneShape::parts_from_points`]: a surface seen in pieces (occlusion shadows,
    /// sensor holes) as one primitive. Errors as there, counting the vertices of all
    /// parts together against [`super::MAX_PLANE_VERTICES`].
    pub fn whole_from_points(points: &[Point2<f64>], cell: f64) -> Result<PlaneShape> {
        let (parts, _cell) = super::outline::outlines(points, cell)?;
        check_vertex_count(&parts)?;
        PlaneShape::from_valid_parts(parts)
    }
}

/// [`Error::OverLimit`] when `parts` have more than [`super::MAX_PLANE_VERTICES`]
/// vertices together.
fn check_vertex_count(parts: &[super::Rings]) -> Result<()> {
    let n: usize = parts
        .iter()
        .map(|(outline, holes)| outline.len() + holes.iter().map(Vec::len).sum::<usize>())
        .sum();
    if n > super::MAX_PLANE_VERTICES {
        return Err(Error::OverLimit {
            what: "a plane outline".into(),
            need: n as f64,
            limit: super::MAX_PLANE_VERTICES as f64,
            unit: crate::error::Unit::Count("vertices"),
            remedies: vec![crate::error::Remedy::Raise("cell")],
        });
    }
    Ok(())
}

/// The local frame of a plane through `points` (scene coordinates): origin at their
/// centroid, local z the plane's unit normal (`normal_hint` if given, oriented as
/// given; otherwise the direction of least variance, its largest component made
/// positive), local x along the longer side of the minimum-area rectangle enclosing the
/// projected points. Unit scale.
///
/// Errors: no points ([`Error::EmptyCloud`]), a non-finite point ([`Error::NonFinite`])
/// or a zero or non-finite hint ([`Error::OutOfRange`]).
pub fn plane_frame(points: &[Point3<f64>], normal_hint: Option<Vector3<f64>>) -> Result<Pose> {
    if points.is_empty() {
        return Err(Error::EmptyCloud);
    }
    if let Some(index) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(Error::NonFinite {
            what: "point".into(),
            index,
        });
    }
    let centroid = points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64;
    let normal = match normal_hint {
        Some(n) => n
            .try_normalize(f64::MIN_POSITIVE)
            .filter(|n| n.iter().all(|c| c.is_finite()))
            .ok_or_else(|| {
                Error::out_of_range("normal_hint", format!("{n:?}"), "a non-zero finite vector")
            })?,
        None => least_variance_direction(points, &centroid),
    };
    // A first in-plane basis, then turned so that x follows the enclosing rectangle.
    let helper = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u0 = normal.cross(&helper).normalize();
    let v0 = normal.cross(&u0);
    let projected: MultiPoint<f64> = points
        .iter()
        .map(|p| {
            let d = p.coords - centroid;
            (d.dot(&u0), d.dot(&v0))
        })
        .collect::<Vec<_>>()
        .into();
    let angle = projected
        .minimum_rotated_rect()
        .map(|rect| longer_side_angle(rect.exterior().0.as_slice()))
        .unwrap_or(0.0);
    let u = u0 * angle.cos() + v0 * angle.sin();
    let v = normal.cross(&u);
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[u, v, normal]));
    Ok(Pose::new(
        UnitQuaternion::from_rotation_matrix(&rotation),
        centroid,
    ))
}

/// The plane of `points` and its outline at occupancy cell `cell` (scene units; pass a
/// few point spacings): the frame of [`plane_frame`] and the largest part of
/// [`PlaneShape::from_points`] of the points in it. The points' distances from the
/// plane are ignored (the outline is of their projections).
pub fn fit_plane(
    points: &[Point3<f64>],
    normal_hint: Option<Vector3<f64>>,
    cell: f64,
) -> Result<(Pose, PlaneShape)> {
    let pose = plane_frame(points, normal_hint)?;
    let local: Vec<Point2<f64>> = points
        .iter()
        .map(|p| {
            let q = pose.to_local(p);
            Point2::new(q.x, q.y)
        })
        .collect();
    Ok((pose, PlaneShape::from_points(&local, cell)?))
}

/// The bounded plane primitive of `points` (scene coordinates): [`fit_plane`] as a
/// [`Primitive`] of type `plane`.
pub fn fit_plane_primitive(
    points: &[Point3<f64>],
    normal_hint: Option<Vector3<f64>>,
    cell: f64,
) -> Result<Primitive> {
    let (pose, shape) = fit_plane(points, normal_hint, cell)?;
    Ok(Primitive::new(Shape::Plane(shape), pose))
}

/// The unit eigenvector of the points' covariance with the least eigenvalue, its largest
/// component made positive (a deterministic sign).
fn least_variance_direction(points: &[Point3<f64>], centroid: &Vector3<f64>) -> Vector3<f64> {
    let cov = points.iter().fold(Matrix3::zeros(), |acc, p| {
        let d = p.coords - centroid;
        acc + d * d.transpose()
    });
    let eigen = cov.symmetric_eigen();
    let k = eigen.eigenvalues.imin();
    let n: Vector3<f64> = eigen.eigenvectors.column(k).into_owned();
    let n = n
        .try_normalize(f64::MIN_POSITIVE)
        .unwrap_or_else(Vector3::z);
    if n[n.iamax()] < 0.0 { -n } else { n }
}

/// The direction angle (radians) of the longer side of a rectangle given as a closed
/// ring of its corners.
fn longer_side_angle(corners: &[geo::Coord<f64>]) -> f64 {
    if corners.len() < 3 {
        return 0.0;
    }
    let side = |a: geo::Coord<f64>, b: geo::Coord<f64>| (b.x - a.x, b.y - a.y);
    let (s1, s2) = (side(corners[0], corners[1]), side(corners[1], corners[2]));
    let longer = if s1.0.hypot(s1.1) >= s2.0.hypot(s2.1) {
        s1
    } else {
        s2
    };
    longer.1.atan2(longer.0)
}
