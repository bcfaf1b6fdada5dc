//! A fixed colour palette for colouring exported primitives.

/// Twelve well-separated colours (Tableau 10 plus two), as `[r, g, b]`.
pub const PALETTE: [[u8; 3]; 12] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
    [255, 187, 120],
    [152, 223, 138],
];

/// The palette colour for primitive number `index`, cycling through [`PALETTE`].
/// Useful for the `vertex_colors` argument of [`super::write_mesh`].
pub fn palette_color(index: usize) -> [u8; 3] {
    PALETTE[index % PALETTE.len()]
}
