//! Small numeric helpers shared by the shape modules: sample counts, low-discrepancy
//! sequences, apportionment, ray/slab and polynomial root finding.

use nalgebra::{Point3, Vector3};

/// The golden angle π(3 − √5) in radians: successive multiples of it give the most even
/// angular spread (Vogel 1979, used by the sunflower disk and the Fibonacci sphere).
pub(super) const GOLDEN_ANGLE: f64 = 2.399_963_229_728_653_3;

/// The plastic number, the real root of x³ = x + 1; its inverse powers drive the R2
/// sequence (Roberts 2018), the 2-D analogue of the golden-ratio sequence.
const PLASTIC: f64 = 1.324_717_957_244_746;

/// The number of samples for a surface of `area` at `spacing`: `round(area / spacing²)`,
/// at least 1.
pub(super) fn sample_count(area: f64, spacing: f64) -> usize {
    debug_assert!(
        spacing.is_finite() && spacing > 0.0,
        "spacing must be positive and finite"
    );
    ((area / (spacing * spacing)).round() as usize).max(1)
}

/// The number of cells of width about `spacing` that cover `length`: `round(length / spacing)`,
/// at least 1.
pub(super) fn cell_count(length: f64, spacing: f64) -> usize {
    debug_assert!(
        spacing.is_finite() && spacing > 0.0,
        "spacing must be positive and finite"
    );
    ((length / spacing).round() as usize).max(1)
}

/// The `i`-th point of the R2 low-discrepancy sequence in the unit square.
pub(super) fn r2(i: usize) -> (f64, f64) {
    let a1 = 1.0 / PLASTIC;
    let a2 = a1 * a1;
    let i = i as f64;
    ((0.5 + a1 * i).fract(), (0.5 + a2 * i).fract())
}

/// Splits `total` into integer parts proportional to `weights` (Hamilton's largest-remainder
/// method): the parts sum to `total` exactly and each is within 1 of its quota. Ties are
/// broken by index, so the result is deterministic. All zeros if the weights sum to ≤ 0.
pub(super) fn apportion(weights: &[f64], total: usize) -> Vec<usize> {
    let sum: f64 = weights.iter().sum();
    if sum.is_nan() || sum <= 0.0 {
        return vec![0; weights.len()];
    }
    let quotas: Vec<f64> = weights
        .iter()
        .map(|w| w.max(0.0) / sum * total as f64)
        .collect();
    let mut parts: Vec<usize> = quotas.iter().map(|q| q.floor() as usize).collect();
    let assigned: usize = parts.iter().sum();
    let mut by_remainder: Vec<usize> = (0..weights.len()).collect();
    by_remainder.sort_by(|&a, &b| {
        let (ra, rb) = (quotas[a] - quotas[a].floor(), quotas[b] - quotas[b].floor());
        rb.total_cmp(&ra).then(a.cmp(&b))
    });
    for &i in by_remainder.iter().take(total.saturating_sub(assigned)) {
        parts[i] += 1;
    }
    parts
}

/// The parameter interval `[t_in, t_out]` over which the ray `o + t·d` lies inside the
/// axis-aligned box `[lo, hi]` (slab method), for all real t (no `t ≥ 0` clamp).
/// `None` when the ray's line misses the box. Axes with `d = 0` are handled exactly.
pub(super) fn slab<const N: usize>(
    o: [f64; N],
    d: [f64; N],
    lo: [f64; N],
    hi: [f64; N],
) -> Option<(f64, f64)> {
    let (mut t_in, mut t_out) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..N {
        if d[k] == 0.0 {
            if o[k] < lo[k] || o[k] > hi[k] {
                return None;
            }
            continue;
        }
        let (a, b) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
        t_in = t_in.max(a.min(b));
        t_out = t_out.min(a.max(b));
    }
    (t_in <= t_out).then_some((t_in, t_out))
}

/// The first `t ≥ 0` of the interval `[t_in, t_out]` (`None` if it lies entirely before 0).
pub(super) fn first_nonnegative(span: Option<(f64, f64)>) -> Option<f64> {
    let (t_in, t_out) = span?;
    (t_out >= 0.0).then_some(t_in.max(0.0))
}

/// The real roots of `a t² + b t + c` where the linear term has been removed by shifting
/// the parameter to the vertex: returns `t0 ± √(−c/a)` for the quadratic `a (t − t0)² + c`.
/// `None` when there is no real root or `a = 0`.
pub(super) fn symmetric_roots(t0: f64, a: f64, c: f64) -> Option<[f64; 2]> {
    if a.is_nan() || a <= 0.0 {
        return None;
    }
    let h2 = -c / a;
    (h2 >= 0.0).then(|| {
        let h = h2.sqrt();
        [t0 - h, t0 + h]
    })
}

/// Evaluates Σ `c[i]` tⁱ (coefficients in ascending order) by Horner's rule.
fn horner(c: &[f64], t: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &ci| acc * t + ci)
}

/// The real roots of the polynomial Σ `c[i]` tⁱ in `[lo, hi]`, ascending.
///
/// Exact up to rounding for every degree: the roots of the derivative (found recursively)
/// split `[lo, hi]` into intervals where the polynomial is monotonic, and each interval
/// with a sign change holds exactly one root, found by bisection to full precision.
/// A critical point where the value vanishes to rounding (a tangency, i.e. a double root)
/// is reported as a root too.
pub(super) fn poly_roots_in(c: &[f64], lo: f64, hi: f64) -> Vec<f64> {
    let degree = match c.iter().rposition(|&ci| ci != 0.0) {
        Some(d) => d,
        None => return Vec::new(),
    };
    let c = &c[..=degree];
    if degree == 0 || lo.is_nan() || hi.is_nan() || lo > hi {
        return Vec::new();
    }
    if degree == 1 {
        let t = -c[0] / c[1];
        return if (lo..=hi).contains(&t) {
            vec![t]
        } else {
            Vec::new()
        };
    }
    let derivative: Vec<f64> = c
        .iter()
        .enumerate()
        .skip(1)
        .map(|(i, ci)| i as f64 * ci)
        .collect();
    let m = lo.abs().max(hi.abs());
    let scale: f64 = c
        .iter()
        .enumerate()
        .map(|(i, ci)| ci.abs() * m.powi(i as i32))
        .sum();
    let tangency_tol = 64.0 * f64::EPSILON * scale;

    let critical = poly_roots_in(&derivative, lo, hi);
    let mut knots = Vec::with_capacity(critical.len() + 2);
    knots.push(lo);
    knots.extend(critical.iter().copied().filter(|&t| t > lo && t < hi));
    knots.push(hi);

    let mut roots: Vec<f64> = Vec::new();
    let mut push = |t: f64| {
        if roots.last().is_none_or(|&last| t > last) {
            roots.push(t);
        }
    };
    for (k, w) in knots.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
        let (fa, fb) = (horner(c, a), horner(c, b));
        let is_interior_critical = k > 0;
        if fa == 0.0 || (is_interior_critical && fa.abs() <= tangency_tol) {
            push(a);
        } else if fb != 0.0 && (fa < 0.0) != (fb < 0.0) {
            push(bisect(c, a, b, fa));
        }
    }
    if horner(c, hi) == 0.0 {
        push(hi);
    }
    roots
}

/// Bisects the sign change of the polynomial `c` on `[a, b]` (`fa = p(a)`) down to adjacent
/// floating-point numbers.
fn bisect(c: &[f64], mut a: f64, mut b: f64, fa: f64) -> f64 {
    let negative_at_a = fa < 0.0;
    for _ in 0..2100 {
        let mid = 0.5 * (a + b);
        if mid <= a || mid >= b {
            break;
        }
        let fm = horner(c, mid);
        if fm == 0.0 {
            return mid;
        }
        if (fm < 0.0) == negative_at_a {
            a = mid;
        } else {
            b = mid;
        }
    }
    0.5 * (a + b)
}

/// The point of the circle (centre `centre`, unit normal `normal`, radius `radius`) that is
/// closest to `p`. The closest point lies along the projection of `p − centre` onto the
/// circle's plane; when that projection vanishes (`p` on the circle's axis) every circle
/// point is equally close and the one in direction `fallback` (a unit vector in the plane)
/// is returned.
pub(super) fn closest_on_circle(
    p: &Point3<f64>,
    centre: &Point3<f64>,
    normal: &Vector3<f64>,
    radius: f64,
    fallback: &Vector3<f64>,
) -> Point3<f64> {
    let q = p - centre;
    let in_plane = q - normal * q.dot(normal);
    let len = in_plane.norm();
    if len > f64::MIN_POSITIVE && len.is_finite() {
        centre + in_plane * (radius / len)
    } else {
        centre + fallback * radius
    }
}
