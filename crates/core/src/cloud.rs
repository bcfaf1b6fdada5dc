//! [`PointCloud`]: the input scan as plain arrays.

use nalgebra::{Point3, Vector3};

/// A point cloud: positions plus optional per-point attributes, all of equal length.
///
/// Coordinates are in the scan's units (metres for the bundled data).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    /// Point positions.
    pub points: Vec<Point3<f64>>,
    /// Unit normals, if the file has `nx, ny, nz`.
    pub normals: Option<Vec<Vector3<f64>>>,
    /// RGB colours, if the file has `red, green, blue`.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Semantic labels (0 unknown, 1 ground, 2 wall, 3 door, other: other classes).
    pub labels: Option<Vec<i32>>,
    /// Each point's sensor origin (`sensor_x, sensor_y, sensor_z`), for ray likelihoods.
    pub sensors: Option<Vec<Point3<f64>>>,
}

impl PointCloud {
    /// A cloud of bare positions.
    pub fn from_points(points: Vec<Point3<f64>>) -> Self {
        PointCloud {
            points,
            ..Default::default()
        }
    }
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }
    /// True when the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
    /// Axis-aligned bounds `(min, max)`, or `None` for an empty cloud.
    pub fn bounds(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        bounds_of(&self.points)
    }
}

/// Axis-aligned bounds `(min, max)` of a point slice, or `None` when empty.
pub fn bounds_of(points: &[Point3<f64>]) -> Option<(Point3<f64>, Point3<f64>)> {
    let first = points.first()?;
    let (mut lo, mut hi) = (*first, *first);
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    Some((lo, hi))
}
