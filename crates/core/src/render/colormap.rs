//! The colour scale of point-to-model distances, and the scale's range.

use nalgebra::Point3;

use crate::metrics::{percentile, point_to_model_distances};
use crate::{Primitive, Result};

/// Viridis (matplotlib's perceptually uniform scale) at 0, 0.1, …, 1.
const VIRIDIS: [[u8; 3]; 11] = [
    [68, 1, 84],
    [72, 36, 117],
    [65, 68, 135],
    [53, 95, 141],
    [42, 120, 142],
    [33, 145, 140],
    [34, 168, 132],
    [68, 191, 112],
    [122, 209, 81],
    [189, 223, 38],
    [253, 231, 37],
];

/// The colour of `t ∈ [0, 1]` (clamped; NaN as 1) on the viridis scale: dark violet
/// at 0 (on the model), yellow at 1 (the top of the scale or beyond).
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 1.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    std::array::from_fn(|k| (f64::from(a[k]) * (1.0 - f) + f64::from(b[k]) * f).round() as u8)
}

/// Distances of `points` to the model, and the top of their colour scale (scene
/// units): `scale` when given, else the 95th percentile of the finite distances (1
/// when there are none or it is 0), so that the worst 5 % of points show in yellow.
pub fn distances_and_scale(
    points: &[Point3<f64>],
    primitives: &[Primitive],
    scale: Option<f64>,
) -> Result<(Vec<f64>, f64)> {
    let distances = point_to_model_distances(points, primitives)?;
    let scale = scale.unwrap_or_else(|| {
        let finite: Vec<f64> = distances
            .iter()
            .copied()
            .filter(|d| d.is_finite())
            .collect();
        let p95 = percentile(&finite, 0.95);
        if p95.is_finite() && p95 > 0.0 {
            p95
        } else {
            1.0
        }
    });
    Ok((distances, scale))
}

/// Indices of at most `max` of `count` items, evenly strided (all when `count ≤ max`).
pub fn subsample(count: usize, max: usize) -> Vec<usize> {
    if count <= max {
        return (0..count).collect();
    }
    (0..max).map(|k| k * count / max).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_runs_from_violet_to_yellow() {
        assert_eq!(viridis(0.0), VIRIDIS[0]);
        assert_eq!(viridis(1.0), VIRIDIS[10]);
        assert_eq!(viridis(7.0), VIRIDIS[10]);
        assert_eq!(viridis(f64::NAN), VIRIDIS[10]);
        assert_eq!(viridis(0.05), [70, 19, 101]);
    }

    #[test]
    fn subsamples_are_even_and_bounded() {
        assert_eq!(subsample(3, 10), [0, 1, 2]);
        assert_eq!(subsample(10, 4), [0, 2, 5, 7]);
    }
}
