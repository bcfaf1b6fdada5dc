//! Fitting a cloud far from the origin (georeferenced LAS/LAZ/E57 scans: eastings and
//! northings of 10⁵–10⁷ m) in a local frame, and handing the result back in the
//! input's frame.
//!
//! An `f64` resolves 10⁻⁹ m at 10⁷ m, but the pipeline's sums of squares (the PCA of
//! neighbourhoods, normal equations of the refinement) cancel most of that: a pipe moved
//! by 6·10⁶ m was refined to measurably different primitives (test
//! `large_coordinates`). So a cloud whose bounding-box centre lies farther than
//! [`LOCAL_FRAME_BEYOND`] from the origin is moved by that centre rounded to whole
//! metres (so that the subtraction is exact for points near it), fitted, and every
//! output position (primitive translations, the lattice origin) is moved back.
//! Positions in the options move with the cloud; a lattice anchored at the scene origin
//! (frame `Axis` without an origin) stays anchored there. Clouds nearer the origin are
//! fitted as they are, bit for bit as before.

use nalgebra::{Point3, Vector3};

use super::{FitOptions, FitResult};
use crate::cloud::bounds_of;
use crate::frame::FrameChoice;
use crate::progress::Progress;
use crate::{PointCloud, Result};

/// Clouds whose bounding-box centre is farther than this from the origin (m) are fitted
/// in a local frame. Beyond any object or room scan; below every projected coordinate.
pub(super) const LOCAL_FRAME_BEYOND: f64 = 1e4;

/// The shift to a local frame for `cloud`, or `None` when it is near the origin.
pub(super) fn local_shift(cloud: &PointCloud) -> Option<Vector3<f64>> {
    let (lo, hi) = bounds_of(&cloud.points)?;
    let centre = nalgebra::center(&lo, &hi).coords;
    (centre.norm() > LOCAL_FRAME_BEYOND).then(|| centre.map(f64::round))
}

/// Fits `cloud` moved by `-shift` with `options` moved likewise, then moves the result
/// back by `shift`.
pub(super) fn fit_shifted(
    cloud: &PointCloud,
    options: &FitOptions,
    progress: &dyn Progress,
    shift: Vector3<f64>,
) -> Result<FitResult> {
    progress.message(&format!(
        "fitting in a local frame: coordinates minus {:?}",
        shift.as_slice()
    ));
    let local = PointCloud {
        points: cloud.points.iter().map(|p| p - shift).collect(),
        sensors: cloud
            .sensors
            .as_ref()
            .map(|s| s.iter().map(|p| p - shift).collect()),
        ..cloud.clone()
    };
    let mut result = super::fit(&local, &shifted_options(options, shift), progress)?;
    for p in &mut result.primitives {
        p.pose.translation += shift;
    }
    result.settings.origin += shift;
    Ok(result)
}

/// `options` with every position moved by `-shift`; a lattice anchored at the scene
/// origin is given that origin explicitly (moved).
fn shifted_options(options: &FitOptions, shift: Vector3<f64>) -> FitOptions {
    let moved = |p: Point3<f64>| p - shift;
    let mut o = options.clone();
    o.origin = options.origin.map(moved);
    match &mut o.frame {
        FrameChoice::Given { origin, .. } => *origin = origin.map(moved),
        FrameChoice::Axis if o.origin.is_none() => o.origin = Some(moved(Point3::origin())),
        FrameChoice::Axis | FrameChoice::Auto => {}
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_far_clouds_are_moved_by_a_whole_metre_shift() {
        let near = PointCloud::from_points(vec![Point3::new(5.3, -2.0, 1.0)]);
        assert_eq!(local_shift(&near), None);
        let far = PointCloud::from_points(vec![
            Point3::new(1e6 + 0.4, 2e6 - 3.7, 100.2),
            Point3::new(1e6 + 2.0, 2e6 - 1.0, 101.0),
        ]);
        let shift = local_shift(&far).expect("far");
        assert_eq!(shift, Vector3::new(1_000_001.0, 1_999_998.0, 101.0));
    }

    #[test]
    fn positions_in_options_move_with_the_cloud() {
        let d = Vector3::new(100.0, 200.0, 3.0);
        let axis = shifted_options(&FitOptions::lattice(), d);
        assert_eq!(axis.origin, Some(Point3::new(-100.0, -200.0, -3.0)));
        let given = FitOptions {
            origin: Some(Point3::new(101.0, 202.0, 3.5)),
            frame: FrameChoice::Auto,
            ..Default::default()
        };
        assert_eq!(
            shifted_options(&given, d).origin,
            Some(Point3::new(1.0, 2.0, 0.5))
        );
        let auto = FitOptions {
            frame: FrameChoice::Auto,
            ..Default::default()
        };
        assert_eq!(shifted_options(&auto, d).origin, None);
    }
}
