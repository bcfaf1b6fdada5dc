//! A small z-buffered rasteriser: filled triangles and square point splats into an
//! RGB image, nearest surface wins.

/// An RGB image with a depth per pixel (larger = nearer).
#[derive(Debug, Clone)]
pub(crate) struct Canvas {
    pub width: usize,
    pub height: usize,
    /// Row-major, top row first.
    pub rgb: Vec<[u8; 3]>,
    depth: Vec<f64>,
}

impl Canvas {
    /// A `width × height` canvas filled with `background`, infinitely far.
    pub fn new(width: usize, height: usize, background: [u8; 3]) -> Canvas {
        Canvas {
            width,
            height,
            rgb: vec![background; width * height],
            depth: vec![f64::NEG_INFINITY; width * height],
        }
    }

    /// Writes `color` at pixel `(x, y)` if `z` is nearer than what is there.
    fn plot(&mut self, x: usize, y: usize, z: f64, color: [u8; 3]) {
        let i = y * self.width + x;
        if z > self.depth[i] {
            self.depth[i] = z;
            self.rgb[i] = color;
        }
    }

    /// Fills the triangle of pixel-space corners `[x, y, depth]` (any winding) in
    /// `color`, depth interpolated linearly; pixel centres are at `+0.5`.
    pub fn triangle(&mut self, corners: [[f64; 3]; 3], color: [u8; 3]) {
        let [a, b, c] = corners;
        let area = edge(a, b, c);
        if area.abs() < 1e-12 || !area.is_finite() {
            return;
        }
        let range = |k: usize, limit: usize| {
            let lo = a[k].min(b[k]).min(c[k]).floor().max(0.0);
            let hi = a[k].max(b[k]).max(c[k]).ceil().min(limit as f64);
            (lo as usize, hi.max(0.0) as usize)
        };
        let (x0, x1) = range(0, self.width);
        let (y0, y1) = range(1, self.height);
        for y in y0..y1 {
            for x in x0..x1 {
                let p = [x as f64 + 0.5, y as f64 + 0.5, 0.0];
                let (wa, wb, wc) = (
                    edge(b, c, p) / area,
                    edge(c, a, p) / area,
                    edge(a, b, p) / area,
                );
                if wa >= 0.0 && wb >= 0.0 && wc >= 0.0 {
                    self.plot(x, y, wa * a[2] + wb * b[2] + wc * c[2], color);
                }
            }
        }
    }

    /// A square of `size` pixels centred on `[x, y, depth]`.
    pub fn splat(&mut self, p: [f64; 3], size: usize, color: [u8; 3]) {
        let half = size as f64 / 2.0;
        let x0 = (p[0] - half).round();
        let y0 = (p[1] - half).round();
        for dy in 0..size {
            for dx in 0..size {
                let (x, y) = (x0 + dx as f64, y0 + dy as f64);
                if x >= 0.0 && y >= 0.0 && (x as usize) < self.width && (y as usize) < self.height {
                    self.plot(x as usize, y as usize, p[2], color);
                }
            }
        }
    }

    /// Pixels into a flat RGB buffer.
    pub fn into_bytes(self) -> Vec<u8> {
        self.rgb.into_iter().flatten().collect()
    }
}

/// Twice the signed area of the triangle `(a, b, p)` in the image plane.
fn edge(a: [f64; 3], b: [f64; 3], p: [f64; 3]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearer_triangles_hide_farther_ones_whatever_the_order() {
        let red = [255, 0, 0];
        let blue = [0, 0, 255];
        for order in [[0, 1], [1, 0]] {
            let mut c = Canvas::new(10, 10, [0; 3]);
            let tris = [
                ([[0.0, 0.0, 1.0], [10.0, 0.0, 1.0], [0.0, 10.0, 1.0]], red),
                ([[0.0, 0.0, 2.0], [0.0, 10.0, 2.0], [10.0, 0.0, 2.0]], blue),
            ];
            for k in order {
                c.triangle(tris[k].0, tris[k].1);
            }
            assert_eq!(c.rgb[0], blue);
            assert_eq!(c.rgb[99], [0; 3]);
        }
    }

    #[test]
    fn splats_are_clipped_to_the_image() {
        let mut c = Canvas::new(4, 4, [0; 3]);
        c.splat([1.0, 1.0, 0.0], 3, [9; 3]);
        c.splat([100.0, -5.0, 0.0], 3, [9; 3]);
        assert_eq!(c.rgb.iter().filter(|p| **p == [9; 3]).count(), 4);
    }
}
