//! `primfit view`: one self-contained HTML page to orbit a scan and its fit.
//!
//! The page is `assets/viewer.html` with the viewer script `assets/viewer.js` (plain
//! WebGL 2, written for primfit: no library, no network access at view time) and the
//! data inlined as JSON in `<script id="primfit-data">`:
//!
//! ```text
//! { "title", "origin": [x, y, z], "extent", "scale", "scale_label",
//!   "frame": { "up", "front", "target", "azimuth", "elevation" },
//!   "points": { "count", "total", "xyz", "error", "rgb" },
//!   "primitives": [ { "name", "type", "existence", "color", "xyz", "faces" } ] }
//! ```
//!
//! Binary arrays are base64 little-endian: `xyz` `f32` × 3 relative to `origin` (the
//! points' bounding-box centre, so that georeferenced coordinates keep their
//! precision), `faces` `u32` × 3, `error` one byte per point (distance ÷ `scale` ×
//! 255, clamped), `rgb` the scan's colours (or `null`). At most
//! [`HtmlOptions::max_points`] points are embedded, an even subsample of the cloud
//! (300 000 by default: about 5 MB of page); every primitive is embedded whole.

use std::path::Path;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use nalgebra::{Point3, Vector3};
use serde_json::{Value, json};

use super::camera::{DEFAULT_VIEW, OrbitFrame};
use super::colormap::{distances_and_scale, subsample};
use super::legend::label;
use crate::io::{palette_color, write_atomic};
use crate::{Error, PointCloud, Primitive, Result, check};

/// The page template.
const TEMPLATE: &str = include_str!("../../assets/viewer.html");
/// The viewer script.
const VIEWER_JS: &str = include_str!("../../assets/viewer.js");

/// Points embedded by default.
pub const DEFAULT_HTML_POINTS: usize = 300_000;

/// Options of [`write_html`].
#[derive(Debug, Clone, PartialEq)]
pub struct HtmlOptions {
    /// The page title (e.g. the scan's file name).
    pub title: String,
    /// The most points embedded (an even subsample beyond), at least 1.
    pub max_points: usize,
    /// The distance at the top of the colour scale (scene units, positive; named
    /// `color_scale` in errors); `None`: the 95th percentile of the embedded points'
    /// distances.
    pub scale: Option<f64>,
}

impl Default for HtmlOptions {
    fn default() -> Self {
        HtmlOptions {
            title: "primfit".into(),
            max_points: DEFAULT_HTML_POINTS,
            scale: None,
        }
    }
}

/// What [`write_html`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct HtmlSummary {
    /// Points in the cloud.
    pub points_total: usize,
    /// Points embedded in the page.
    pub points_embedded: usize,
    /// The top of the colour scale, scene units.
    pub scale: f64,
    /// Size of the page, bytes.
    pub bytes: usize,
}

/// Little-endian bytes of `f32` coordinates relative to `origin`, as base64.
fn positions(points: impl Iterator<Item = Point3<f64>>, origin: &Point3<f64>) -> String {
    let bytes: Vec<u8> = points
        .flat_map(|p| {
            let d = p - origin;
            [d.x as f32, d.y as f32, d.z as f32]
        })
        .flat_map(f32::to_le_bytes)
        .collect();
    STANDARD.encode(bytes)
}

/// `[x, y, z]` of a vector, for JSON.
fn triple(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// Writes the viewer page of `cloud` and `primitives` (with their `existence`, one
/// each, optional) to `path`, atomically. Fails on an empty cloud, `max_points` 0 and
/// an `existence` list of another length.
pub fn write_html(
    path: &Path,
    cloud: &PointCloud,
    primitives: &[Primitive],
    existence: Option<&[f64]>,
    options: &HtmlOptions,
) -> Result<HtmlSummary> {
    if cloud.is_empty() {
        return Err(Error::EmptyCloud);
    }
    if options.max_points == 0 {
        return Err(Error::out_of_range("max_points", 0, "at least 1"));
    }
    if let Some(scale) = options.scale {
        check::positive("color_scale", scale)?;
    }
    if let Some(e) = existence {
        check::same_len("existence values", e.len(), "primitives", primitives.len())?;
    }
    let page = page(cloud, primitives, existence, options)?;
    let summary = HtmlSummary {
        points_total: cloud.len(),
        points_embedded: cloud.len().min(options.max_points),
        scale: page.1,
        bytes: page.0.len(),
    };
    write_atomic(path, |w| {
        w.write_all(page.0.as_bytes())
            .map_err(|e| Error::io(path, e))
    })?;
    Ok(summary)
}

/// The page and the top of its colour scale.
fn page(
    cloud: &PointCloud,
    primitives: &[Primitive],
    existence: Option<&[f64]>,
    options: &HtmlOptions,
) -> Result<(String, f64)> {
    let keep = subsample(cloud.len(), options.max_points);
    let points: Vec<Point3<f64>> = keep.iter().map(|&i| cloud.points[i]).collect();
    let (distances, scale) = distances_and_scale(&points, primitives, options.scale)?;
    let (lo, hi) = crate::cloud::bounds_of(&points).unwrap_or_default();
    let origin = nalgebra::center(&lo, &hi);
    let extent = (hi - lo).norm().max(1e-9);
    let frame = OrbitFrame::principal(&points);
    let error: Vec<u8> = distances
        .iter()
        .map(|d| {
            let t = d / scale;
            if t.is_nan() {
                255
            } else {
                (t.clamp(0.0, 1.0) * 255.0).round() as u8
            }
        })
        .collect();
    let rgb = cloud.colors.as_ref().map(|c| {
        let bytes: Vec<u8> = keep.iter().flat_map(|&i| c[i]).collect();
        STANDARD.encode(bytes)
    });
    let prims: Vec<Value> = primitives
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let mesh = p.triangulate();
            let faces: Vec<u8> = mesh
                .faces
                .iter()
                .flatten()
                .flat_map(|i| i.to_le_bytes())
                .collect();
            json!({
                "name": format!("primitive_{k}_{}", p.shape.kind().name()),
                "type": p.shape.kind().name(),
                "existence": existence.map(|e| e[k]),
                "color": palette_color(k),
                "xyz": positions(mesh.vertices.iter().copied(), &origin),
                "faces": STANDARD.encode(faces),
            })
        })
        .collect();
    let data = json!({
        "title": options.title,
        "origin": [origin.x, origin.y, origin.z],
        "extent": extent,
        "scale": scale,
        "scale_label": label(scale),
        "frame": {
            "up": triple(&frame.up),
            "front": triple(&frame.front),
            "target": triple(&(frame.target - origin)),
            "azimuth": DEFAULT_VIEW.azimuth,
            "elevation": DEFAULT_VIEW.elevation,
        },
        "points": {
            "count": points.len(),
            "total": cloud.len(),
            "xyz": positions(points.iter().copied(), &origin),
            "error": STANDARD.encode(&error),
            "rgb": rgb,
        },
        "primitives": prims,
    });
    // `<` only occurs inside JSON strings, where `\u003c` means the same: no `</script>`.
    let data = data.to_string().replace('<', "\\u003c");
    let html = TEMPLATE.replacen("__PRIMFIT_DATA__", &data, 1).replacen(
        "__PRIMFIT_VIEWER_JS__",
        VIEWER_JS,
        1,
    );
    Ok((html, scale))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Pose, Shape};

    #[test]
    fn the_page_embeds_a_bounded_subsample_and_no_closing_tags_in_data() {
        let points: Vec<Point3<f64>> = (0..1000)
            .map(|i| Point3::new(f64::from(i % 40) / 40.0, f64::from(i / 40) / 40.0, 5e5))
            .collect();
        let cloud = PointCloud::from_points(points);
        let square = Primitive::new(Shape::Square { side: 1.0 }, Pose::identity());
        let options = HtmlOptions {
            title: "</script><b>x".into(),
            max_points: 100,
            scale: None,
        };
        let (html, _) = page(&cloud, &[square], Some(&[0.5]), &options).expect("page");
        assert_eq!(
            html.matches("</script>").count(),
            2,
            "the data and the viewer"
        );
        let start = html.find("application/json\">").expect("data") + 18;
        let end = start + html[start..].find("</script>").expect("end");
        let data: Value = serde_json::from_str(&html[start..end]).expect("json");
        assert_eq!(data["points"]["count"], 100);
        assert_eq!(data["points"]["total"], 1000);
        assert_eq!(data["title"], "</script><b>x");
        assert_eq!(data["primitives"][0]["existence"], 0.5);
        let xyz = STANDARD
            .decode(data["points"]["xyz"].as_str().expect("b64"))
            .expect("b64");
        assert_eq!(xyz.len(), 100 * 12);
        assert!(!html.contains("__PRIMFIT"));
    }
}
