//! The axis-aligned orientations of each primitive type in the lattice frame.

use nalgebra::{UnitQuaternion, Vector3};

use crate::atlas::ShapeKind;

/// The orientation set of a type, in the lattice frame: the distinct axis-aligned
/// placements of the shape (symmetric duplicates removed).
///
/// - square, disk: normal along z, x or y (3);
/// - cylinder: axis along z, x or y (3);
/// - elbow: plane normal along z, x or y, times the 4 quadrants (12);
/// - sphere, mesh: the identity (1);
/// - plane: none: a plane's orientation comes from its points, not from the lattice
///   frame, so it is never a lattice candidate.
pub fn orientations(kind: ShapeKind) -> Vec<UnitQuaternion<f64>> {
    use std::f64::consts::FRAC_PI_2;
    let axes = [
        UnitQuaternion::identity(), // local z → z
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), FRAC_PI_2), // local z → x
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -FRAC_PI_2), // local z → y
    ];
    match kind {
        ShapeKind::Square | ShapeKind::Disk | ShapeKind::Cylinder => axes.to_vec(),
        ShapeKind::Elbow => axes
            .iter()
            .flat_map(|a| {
                (0..4).map(move |q| {
                    a * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), q as f64 * FRAC_PI_2)
                })
            })
            .collect(),
        ShapeKind::Sphere | ShapeKind::Mesh => vec![UnitQuaternion::identity()],
        ShapeKind::Plane => Vec::new(),
    }
}
