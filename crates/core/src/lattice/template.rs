//! One shape's canonical surface samples and their KD-tree in the local frame, shared by
//! every candidate of that shape.

use nalgebra::Point3;

use crate::atlas::Shape;
use crate::spatial::PointIndex;

/// One shape's canonical samples and their KD-tree, in the shape's local frame.
#[derive(Debug)]
pub struct Template {
    /// The shape.
    pub shape: Shape,
    /// Local-frame surface samples.
    pub samples: Vec<Point3<f64>>,
    /// KD-tree over `samples`.
    pub index: PointIndex,
    /// Bounding radius of the samples about the local origin.
    pub radius: f64,
    /// Bounding radius of the samples and the continuous surface together.
    pub surface_radius: f64,
}

impl Template {
    /// Samples `shape` at `sample_spacing` and indexes the samples.
    pub fn new(shape: Shape, sample_spacing: f64) -> Self {
        let samples = shape.sample_surface(sample_spacing);
        let index = PointIndex::new(&samples);
        let radius = samples.iter().map(|p| p.coords.norm()).fold(0.0, f64::max);
        let surface_radius = radius.max(shape.bounding_radius());
        Template {
            shape,
            samples,
            index,
            radius,
            surface_radius,
        }
    }
}
