//! Where the picture is seen from: a [`View`] (azimuth and elevation, degrees) about an
//! orbit frame, the default frame from the cloud's principal axes, and the orthographic
//! [`Projection`] that fits the scene into the image.

use std::str::FromStr;

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

use crate::{Error, Result};

/// A viewing direction: the camera looks at the scene from `azimuth` degrees about the
/// orbit frame's up axis (0 = from its first horizontal axis, 90 = from its second)
/// and `elevation` degrees above its horizontal plane (90 = from straight above).
///
/// With `--view` (an explicit view) the orbit frame is the scene's: up = +z, azimuth 0
/// = from +x, 90 = from +y, as in matplotlib's `view_init(elev, azim)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Degrees about the up axis.
    pub azimuth: f64,
    /// Degrees above the horizontal plane, in [−90, 90].
    pub elevation: f64,
}

impl FromStr for View {
    type Err = Error;

    /// Parses `azimuth,elevation` in degrees (`30,20`, `-60,45`).
    fn from_str(s: &str) -> Result<View> {
        let bad = || {
            Error::out_of_range(
                "view",
                format!("{s:?}"),
                "two numbers azimuth,elevation in degrees, elevation in [-90, 90]",
            )
        };
        let parts: Vec<f64> = s
            .split(',')
            .map(|t| t.trim().parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| bad())?;
        match parts[..] {
            [azimuth, elevation] if azimuth.is_finite() && (-90.0..=90.0).contains(&elevation) => {
                Ok(View { azimuth, elevation })
            }
            _ => Err(bad()),
        }
    }
}

/// The frame a [`View`] is measured in: an up axis and a first horizontal axis
/// (orthonormal), and the point looked at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitFrame {
    /// Up (elevation 90 looks down along −`up`).
    pub up: Vector3<f64>,
    /// Azimuth 0, elevation 0 looks along −`front`.
    pub front: Vector3<f64>,
    /// The point the camera looks at (scene coordinates).
    pub target: Point3<f64>,
}

impl OrbitFrame {
    /// The scene's frame: up = +z, front = +x, looking at `target`.
    pub fn scene(target: Point3<f64>) -> OrbitFrame {
        OrbitFrame {
            up: Vector3::z(),
            front: Vector3::x(),
            target,
        }
    }

    /// A frame from the cloud's shape: up along the principal axis of least spread,
    /// signed toward the scene origin when that is the sensor of a camera-frame scan
    /// (outside the points, within 100 spreads of their centroid and at least 6° off
    /// their main plane), else so that the points' third moment along it is positive
    /// (objects standing on a main surface are above it), else toward +z. Front: toward
    /// the scene origin across `up` or, when it is at the centroid, the middle principal
    /// axis. Looks at the centroid.
    pub fn principal(points: &[Point3<f64>]) -> OrbitFrame {
        let n = points.len().max(1) as f64;
        let centroid = Point3::from(points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n);
        let cov = points.iter().fold(Matrix3::zeros(), |m, p| {
            let d = p - centroid;
            m + d * d.transpose()
        }) / n;
        if points.len() < 3 || !cov.iter().all(|c| c.is_finite()) {
            return OrbitFrame::scene(centroid);
        }
        let eigen = SymmetricEigen::new(cov);
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
        let mut up: Vector3<f64> = eigen.eigenvectors.column(order[0]).into();
        let sigma = eigen.eigenvalues[order[0]].max(0.0).sqrt();
        let spread = eigen.eigenvalues[order[2]].max(0.0).sqrt();
        let to_origin = -centroid.coords;
        let distance = to_origin.norm();
        let sensor = to_origin.dot(&up) / distance;
        let skew = points
            .iter()
            .map(|p| (p - centroid).dot(&up).powi(3))
            .sum::<f64>()
            / n;
        let flip = if distance > spread && distance < 100.0 * spread && sensor.abs() > 0.1 {
            sensor < 0.0
        } else if skew.abs() > 0.1 * sigma.powi(3) {
            skew < 0.0
        } else {
            up.z < 0.0
        };
        if flip {
            up = -up;
        }
        let horizontal = to_origin - up * up.dot(&to_origin);
        let front = if horizontal.norm() > 1e-6 * spread.max(f64::MIN_POSITIVE) {
            horizontal.normalize()
        } else {
            eigen.eigenvectors.column(order[1]).into()
        };
        OrbitFrame {
            up,
            front,
            target: centroid,
        }
    }

    /// The camera basis of `view` in this frame.
    pub fn camera(&self, view: View) -> Camera {
        let (az, el) = (view.azimuth.to_radians(), view.elevation.to_radians());
        let side = self.up.cross(&self.front);
        let horizontal = self.front * az.cos() + side * az.sin();
        let back = horizontal * el.cos() + self.up * el.sin();
        let right = side * az.cos() - self.front * az.sin();
        Camera {
            right,
            up: back.cross(&right),
            back,
        }
    }
}

/// The default view in a [`OrbitFrame::principal`] frame: from above and a little to
/// the side of the front.
pub const DEFAULT_VIEW: View = View {
    azimuth: 25.0,
    elevation: 40.0,
};

/// An orthonormal camera basis: image right, image up, and `back` (from the scene
/// toward the camera; the camera looks along −`back`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Image x.
    pub right: Vector3<f64>,
    /// Image y (upward).
    pub up: Vector3<f64>,
    /// Toward the camera.
    pub back: Vector3<f64>,
}

/// An orthographic projection of scene points to pixels of a `width × height` image.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Projection {
    pub camera: Camera,
    /// Scene point at the image centre.
    centre: Point3<f64>,
    /// Pixels per scene unit.
    zoom: f64,
    half: [f64; 2],
}

impl Projection {
    /// The projection that fits every point of `points` into the image with a margin
    /// of 5 % on each side, looking along −`camera.back`.
    pub fn fit(camera: Camera, points: &[Point3<f64>], width: u32, height: u32) -> Projection {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in points {
            let v = p.coords;
            for (k, axis) in [camera.right, camera.up].iter().enumerate() {
                let c = v.dot(axis);
                lo[k] = lo[k].min(c);
                hi[k] = hi[k].max(c);
            }
        }
        if !lo[0].is_finite() {
            lo = [0.0; 2];
            hi = [1.0; 2];
        }
        let extent = [(hi[0] - lo[0]).max(1e-12), (hi[1] - lo[1]).max(1e-12)];
        let zoom = (0.9 * f64::from(width) / extent[0]).min(0.9 * f64::from(height) / extent[1]);
        let mid = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        let centre = Point3::from(camera.right * mid[0] + camera.up * mid[1]);
        Projection {
            camera,
            centre,
            zoom,
            half: [f64::from(width) / 2.0, f64::from(height) / 2.0],
        }
    }

    /// Pixel coordinates (x right, y down, pixel centres at +0.5) and depth (larger
    /// is nearer the camera, scene units) of `p`.
    pub fn project(&self, p: &Point3<f64>) -> [f64; 3] {
        let d = p - self.centre;
        [
            self.half[0] + self.zoom * d.dot(&self.camera.right),
            self.half[1] - self.zoom * d.dot(&self.camera.up),
            d.dot(&self.camera.back),
        ]
    }

    /// Pixels per scene unit.
    pub fn zoom(&self) -> f64 {
        self.zoom
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_parse_and_bad_ones_name_the_option() {
        let v: View = "30,-20".parse().expect("parse");
        assert_eq!((v.azimuth, v.elevation), (30.0, -20.0));
        for bad in ["", "30", "30,20,10", "a,b", "0,91", "nan,0", "inf,3"] {
            let e = bad.parse::<View>().expect_err(bad).to_string();
            assert!(e.starts_with("view must be"), "{e}");
        }
    }

    #[test]
    fn camera_bases_are_right_handed_and_match_matplotlib() {
        let frame = OrbitFrame::scene(Point3::origin());
        let c = frame.camera(View {
            azimuth: 0.0,
            elevation: 0.0,
        });
        assert!((c.back - Vector3::x()).norm() < 1e-12);
        assert!((c.right - Vector3::y()).norm() < 1e-12);
        assert!((c.up - Vector3::z()).norm() < 1e-12);
        let top = frame.camera(View {
            azimuth: 30.0,
            elevation: 90.0,
        });
        assert!((top.back - Vector3::z()).norm() < 1e-12);
        assert!((top.right.cross(&top.up) - top.back).norm() < 1e-12);
    }

    #[test]
    fn the_principal_frame_stands_a_table_upright() {
        // A flat 2 × 1 table top in the plane y = 1 (camera frame: y down) with a post
        // standing on it (toward −y), seen from the origin.
        let mut points = Vec::new();
        for i in 0..40 {
            for k in 0..20 {
                points.push(Point3::new(
                    f64::from(i) / 20.0 - 1.0,
                    1.0,
                    f64::from(k) / 20.0 + 2.0,
                ));
            }
        }
        for i in 0..200 {
            let t = f64::from(i) / 200.0;
            points.push(Point3::new(0.1 * t, 1.0 - 0.3 * t, 2.5));
        }
        let frame = OrbitFrame::principal(&points);
        assert!(frame.up.y < -0.99, "{}", frame.up);
        assert!(frame.front.z < -0.99, "{}", frame.front);
        // Centred on the origin, there is no sensor to go by: the post stands up.
        let centroid = points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64;
        let centred: Vec<Point3<f64>> = points.iter().map(|p| p - centroid).collect();
        assert!(OrbitFrame::principal(&centred).up.y < -0.99);
    }
}
