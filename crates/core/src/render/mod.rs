//! Pictures of a fit: a still PNG ([`render`], `primfit render`) and a self-contained
//! interactive HTML page ([`write_html`], `primfit view`).
//!
//! Both show the scan's points coloured by their distance to the fitted model on the
//! viridis scale (dark violet = on a surface, yellow = at or beyond the top of the
//! scale: by default the 95th percentile of the distances, [`distances_and_scale`])
//! together with the primitives' triangle meshes in their palette colours
//! ([`crate::io::palette_color`]).
//!
//! | file | concept |
//! |---|---|
//! | `camera` | [`View`] (azimuth, elevation in degrees), the orbit frame, the orthographic projection |
//! | `colormap` | the distance colour scale, the scale's top, point subsampling |
//! | `raster` | a z-buffered triangle and point rasteriser |
//! | `legend` | the colour bar with its two labels |
//! | `html` | the WebGL viewer page (`assets/viewer.html`, `assets/viewer.js`) |
//!
//! The still picture is an orthographic view fitted to the points' extent. Without a
//! [`View`] it looks from above and to the front of the cloud's principal frame
//! ([`OrbitFrame::principal`], [`DEFAULT_VIEW`]); with one, from that azimuth and
//! elevation about the scene's +z axis. Primitives are shaded with a Lambert term
//! (two-sided: a light near the camera, 30 % ambient); points are drawn after them as
//! small squares (1 pixel up to 1350-pixel images), slightly toward the camera so that
//! points lying on a surface show.

mod camera;
mod colormap;
mod html;
mod legend;
mod raster;

use std::path::Path;

use nalgebra::Point3;

pub use camera::{Camera, DEFAULT_VIEW, OrbitFrame, View};
pub use colormap::{distances_and_scale, subsample, viridis};
pub use html::{DEFAULT_HTML_POINTS, HtmlOptions, HtmlSummary, write_html};

use self::camera::Projection;
use self::raster::Canvas;
use crate::io::{palette_color, write_atomic};
use crate::{Error, Primitive, Result, check};

/// Background of the still picture.
const BACKGROUND: [u8; 3] = [246, 246, 246];

/// The largest image side accepted, pixels.
pub const MAX_SIDE: u32 = 8192;

/// Options of [`render`].
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    /// Image width in pixels (16 ‥ [`MAX_SIDE`]; named `image_width` in errors).
    pub width: u32,
    /// Image height in pixels (16 ‥ [`MAX_SIDE`]; named `image_height` in errors).
    pub height: u32,
    /// Where to look from; `None`: the default view (see the module docs).
    pub view: Option<View>,
    /// The distance at the top of the colour scale (scene units, positive; named
    /// `color_scale` in errors); `None`: the 95th percentile of the drawn points'
    /// distances.
    pub scale: Option<f64>,
    /// The most points drawn (an even subsample beyond); `None`: a twelfth of the
    /// image's pixels, so that the shaded surfaces show between the points.
    pub max_points: Option<usize>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 1200,
            height: 900,
            view: None,
            scale: None,
            max_points: None,
        }
    }
}

/// A rendered picture.
#[derive(Debug, Clone, PartialEq)]
pub struct Picture {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// 8-bit RGB, row-major, top row first (`3 × width × height` bytes).
    pub rgb: Vec<u8>,
    /// The distance at the top of the colour scale, scene units.
    pub scale: f64,
    /// The points drawn (after subsampling).
    pub points_drawn: usize,
}

impl Picture {
    /// The picture as PNG bytes (8-bit RGB).
    pub fn encode_png(&self) -> std::result::Result<Vec<u8>, png::EncodingError> {
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, self.width, self.height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&self.rgb)?;
        writer.finish()?;
        Ok(out)
    }

    /// Writes the picture to `path` as PNG, atomically (nothing is left on error).
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let bytes = self
            .encode_png()
            .map_err(|e| Error::io(path, std::io::Error::other(e)))?;
        write_atomic(path, |w| {
            w.write_all(&bytes).map_err(|e| Error::io(path, e))
        })
    }
}

/// Checks an image side.
fn check_side(name: &str, side: u32) -> Result<()> {
    if (16..=MAX_SIDE).contains(&side) {
        Ok(())
    } else {
        Err(Error::out_of_range(
            name,
            side,
            format!("in 16..={MAX_SIDE} pixels"),
        ))
    }
}

/// Renders `points` (coloured by distance to `primitives`) and the shaded
/// `primitives` (see the module docs). Fails on an empty cloud and on image sides
/// outside 16 ‥ [`MAX_SIDE`].
///
/// ```
/// use primfit_core::na::Point3;
/// use primfit_core::render::{RenderOptions, render};
/// use primfit_core::{Pose, Primitive, Shape};
///
/// let points: Vec<Point3<f64>> = (0..400)
///     .map(|i| Point3::new(f64::from(i % 20) / 20.0 - 0.5, f64::from(i / 20) / 20.0 - 0.5, 0.01))
///     .collect();
/// let square = Primitive::new(Shape::Square { side: 1.0 }, Pose::identity());
/// let options = RenderOptions { width: 64, height: 48, ..Default::default() };
/// let picture = render(&points, &[square], &options)?;
/// assert_eq!(picture.rgb.len(), 3 * 64 * 48);
/// assert!((picture.scale - 0.01).abs() < 1e-9); // every point is 1 cm off the square
/// # Ok::<(), primfit_core::Error>(())
/// ```
pub fn render(
    points: &[Point3<f64>],
    primitives: &[Primitive],
    options: &RenderOptions,
) -> Result<Picture> {
    check_side("image_width", options.width)?;
    check_side("image_height", options.height)?;
    if let Some(scale) = options.scale {
        check::positive("color_scale", scale)?;
    }
    if points.is_empty() {
        return Err(Error::EmptyCloud);
    }
    let (w, h) = (options.width as usize, options.height as usize);
    let max = options.max_points.unwrap_or(w * h / 12).max(1);
    let drawn: Vec<Point3<f64>> = subsample(points.len(), max)
        .into_iter()
        .map(|i| points[i])
        .collect();
    let (distances, scale) = distances_and_scale(&drawn, primitives, options.scale)?;
    let camera = match options.view {
        Some(view) => OrbitFrame::scene(Point3::origin()).camera(view),
        None => OrbitFrame::principal(&drawn).camera(DEFAULT_VIEW),
    };
    let projection = Projection::fit(camera, &drawn, options.width, options.height);
    let mut canvas = Canvas::new(w, h, BACKGROUND);
    draw_primitives(&mut canvas, &projection, primitives);
    let projected: Vec<[f64; 3]> = drawn.iter().map(|p| projection.project(p)).collect();
    let (near, far) = projected
        .iter()
        .fold((f64::NEG_INFINITY, f64::INFINITY), |(n, f), p| {
            (n.max(p[2]), f.min(p[2]))
        });
    // Toward the camera by 1 % of the depth range or 1.5 pixels, whichever is more.
    let bias = (0.01 * (near - far)).max(1.5 / projection.zoom());
    let size = (w.min(h) as f64 / 900.0).round().max(1.0) as usize;
    for (p, d) in projected.iter().zip(&distances) {
        canvas.splat([p[0], p[1], p[2] + bias], size, viridis(d / scale));
    }
    legend::colour_bar(&mut canvas, scale);
    Ok(Picture {
        width: options.width,
        height: options.height,
        rgb: canvas.into_bytes(),
        scale,
        points_drawn: drawn.len(),
    })
}

/// Draws every primitive's triangles, Lambert-shaded in its palette colour.
fn draw_primitives(canvas: &mut Canvas, projection: &Projection, primitives: &[Primitive]) {
    let c = projection.camera;
    let light = (c.back + 0.6 * c.up - 0.4 * c.right).normalize();
    for (k, primitive) in primitives.iter().enumerate() {
        let base = palette_color(k);
        let mesh = primitive.triangulate();
        let screen: Vec<[f64; 3]> = mesh
            .vertices
            .iter()
            .map(|v| projection.project(v))
            .collect();
        for f in &mesh.faces {
            let [a, b, cc] = f.map(|i| mesh.vertices[i as usize]);
            let normal = (b - a).cross(&(cc - a));
            let n = normal.norm();
            if n <= 0.0 || !n.is_finite() {
                continue;
            }
            let shade = 0.3 + 0.7 * (normal / n).dot(&light).abs();
            let color = base.map(|x| (f64::from(x) * shade).round().min(255.0) as u8);
            canvas.triangle(f.map(|i| screen[i as usize]), color);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Pose, Shape};

    fn square_cloud() -> Vec<Point3<f64>> {
        (0..2500)
            .map(|i| {
                Point3::new(
                    f64::from(i % 50) / 50.0 - 0.5,
                    f64::from(i / 50) / 50.0 - 0.5,
                    0.0,
                )
            })
            .collect()
    }

    #[test]
    fn a_picture_has_the_size_asked_and_is_not_blank() {
        let square = Primitive::new(Shape::Square { side: 1.0 }, Pose::identity());
        let options = RenderOptions {
            width: 160,
            height: 90,
            ..Default::default()
        };
        let picture = render(&square_cloud(), &[square], &options).expect("render");
        assert_eq!(picture.rgb.len(), 3 * 160 * 90);
        let painted = picture.rgb.chunks(3).filter(|p| *p != BACKGROUND).count();
        assert!(painted > 160 * 90 / 4, "{painted} pixels painted");
        let png = picture.encode_png().expect("png");
        assert_eq!(&png[1..4], b"PNG");
    }

    #[test]
    fn bad_sizes_and_empty_clouds_are_refused() {
        let mut options = RenderOptions {
            width: 8,
            ..Default::default()
        };
        let e = render(&square_cloud(), &[], &options).expect_err("small");
        assert!(e.to_string().starts_with("image_width must be"), "{e}");
        options.width = 100;
        options.height = 100_000;
        assert!(render(&square_cloud(), &[], &options).is_err());
        options.height = 100;
        assert!(matches!(render(&[], &[], &options), Err(Error::EmptyCloud)));
    }

    #[test]
    fn an_empty_model_paints_every_point_at_the_top_of_the_scale() {
        let options = RenderOptions {
            width: 64,
            height: 64,
            view: Some(View {
                azimuth: 0.0,
                elevation: 90.0,
            }),
            ..Default::default()
        };
        let picture = render(&square_cloud(), &[], &options).expect("render");
        let top = viridis(1.0);
        assert!(picture.rgb.chunks(3).any(|p| p == top));
        assert_eq!(picture.scale, 1.0);
    }
}
