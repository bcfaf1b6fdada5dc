//! The colour bar drawn in a picture's bottom-left corner: the distance scale from 0 to
//! its top, labelled with both ends in a tiny built-in digit font.

use super::colormap::viridis;
use super::raster::Canvas;

/// 3 × 5 glyphs of `0`–`9` and `.`, rows top to bottom, bit 2 = left column.
const GLYPHS: [[u8; 5]; 11] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
    [0, 0, 0, 0, 2],
];

/// Ink of the labels and the bar's frame.
const INK: [u8; 3] = [40, 40, 40];

/// `value` with three significant digits and no exponent (`0.0123`, `1.25`, `350`).
pub fn label(value: f64) -> String {
    if !value.is_finite() || value <= 0.0 {
        return "0".into();
    }
    let decimals = (2 - value.log10().floor() as i32).clamp(0, 9) as usize;
    format!("{value:.decimals$}")
}

/// Draws `text` (digits and `.`; other characters are skipped as spaces) with its top
/// left corner at `(x, y)`, each font pixel `s × s` image pixels.
fn text(canvas: &mut Canvas, text: &str, x: usize, y: usize, s: usize) {
    for (n, ch) in text.chars().enumerate() {
        let glyph = match ch {
            '0'..='9' => GLYPHS[ch as usize - '0' as usize],
            '.' => GLYPHS[10],
            _ => continue,
        };
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    fill(canvas, x + n * 4 * s + col * s, y + row * s, s, s, INK);
                }
            }
        }
    }
}

/// Fills a rectangle, clipped to the canvas.
fn fill(canvas: &mut Canvas, x: usize, y: usize, w: usize, h: usize, color: [u8; 3]) {
    for yy in y..(y + h).min(canvas.height) {
        for xx in x..(x + w).min(canvas.width) {
            canvas.rgb[yy * canvas.width + xx] = color;
        }
    }
}

/// Draws the colour bar of the scale `0 … top` (scene units) over everything else.
pub fn colour_bar(canvas: &mut Canvas, top: f64) {
    let s = (canvas.height / 250).max(1);
    let margin = 4 * s;
    let bar_w = (canvas.width / 4).clamp(20, 300);
    let bar_h = 4 * s;
    let needed = margin * 2 + bar_h + 7 * s;
    if canvas.height < needed || canvas.width < bar_w + 2 * margin {
        return; // too small an image for a legend
    }
    let y = canvas.height - needed + margin;
    fill(canvas, margin - 1, y - 1, bar_w + 2, bar_h + 2, INK);
    for i in 0..bar_w {
        let color = viridis(i as f64 / (bar_w - 1) as f64);
        fill(canvas, margin + i, y, 1, bar_h, color);
    }
    let text_y = y + bar_h + 2 * s;
    text(canvas, "0", margin, text_y, s);
    let top_label = label(top);
    let width = (top_label.len() * 4 - 1) * s;
    text(
        canvas,
        &top_label,
        (margin + bar_w).saturating_sub(width),
        text_y,
        s,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_keep_three_significant_digits() {
        assert_eq!(label(0.012345), "0.0123");
        assert_eq!(label(1.25), "1.25");
        assert_eq!(label(350.2), "350");
        assert_eq!(label(0.0), "0");
        assert_eq!(label(f64::INFINITY), "0");
    }

    #[test]
    fn the_bar_is_drawn_when_there_is_room() {
        let mut c = Canvas::new(200, 100, [255; 3]);
        colour_bar(&mut c, 0.5);
        assert!(c.rgb.contains(&viridis(0.0)) && c.rgb.contains(&INK));
        let mut tiny = Canvas::new(10, 10, [255; 3]);
        colour_bar(&mut tiny, 0.5);
        assert!(tiny.rgb.iter().all(|p| *p == [255; 3]));
    }
}
