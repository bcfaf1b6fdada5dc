//! A polygon's edges bucketed into horizontal slabs of its y-range, so that the
//! point-in-polygon test of a [`super::PlaneShape`] looks at the edges near the query's
//! y instead of at all of them. It gives exactly the answer of a scan over every edge:
//! an edge that a horizontal line at `y` crosses spans `y`, so it is listed in the slab
//! of `y`.

use nalgebra::Point2;

/// Most slabs: enough that an outline of thousands of edges has a few per slab, few
/// enough that the lists stay small (4 bytes per listed edge).
const MAX_SLABS: usize = 4096;

/// The edges of a polygon, in slabs of equal height over its y-range.
#[derive(Debug, Clone)]
pub(super) struct EdgeSlabs {
    /// The y of the bottom of slab 0 (local units).
    y0: f64,
    /// Slab height (local units, > 0).
    height: f64,
    /// Number of slabs (≥ 1).
    count: usize,
    /// Slab `s` lists `ids[starts[s]..starts[s + 1]]`, ascending edge indices.
    starts: Vec<u32>,
    ids: Vec<u32>,
}

impl EdgeSlabs {
    /// Buckets `edges`, whose vertices lie in `[lo_y, hi_y]`.
    pub(super) fn new(edges: &[[Point2<f64>; 2]], lo_y: f64, hi_y: f64) -> Self {
        let count = edges.len().clamp(1, MAX_SLABS);
        let height = ((hi_y - lo_y) / count as f64).max(f64::MIN_POSITIVE);
        let mut slabs = EdgeSlabs {
            y0: lo_y,
            height,
            count,
            starts: Vec::new(),
            ids: Vec::new(),
        };
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); count];
        for (e, [a, b]) in edges.iter().enumerate() {
            let (s0, s1) = (slabs.slab_of(a.y.min(b.y)), slabs.slab_of(a.y.max(b.y)));
            for list in &mut lists[s0..=s1] {
                list.push(e as u32);
            }
        }
        slabs.starts.push(0);
        for list in lists {
            slabs.ids.extend(list);
            slabs.starts.push(slabs.ids.len() as u32);
        }
        slabs
    }

    /// The slab holding `y`, clamped to the existing ones.
    fn slab_of(&self, y: f64) -> usize {
        let s = ((y - self.y0) / self.height).floor();
        if s.is_nan() || s < 0.0 {
            0
        } else {
            (s as usize).min(self.count - 1)
        }
    }

    /// The edges (indices, ascending) that may cross the horizontal line at `y`.
    pub(super) fn near(&self, y: f64) -> &[u32] {
        self.slab(self.slab_of(y))
    }

    fn slab(&self, s: usize) -> &[u32] {
        &self.ids[self.starts[s] as usize..self.starts[s + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A zig-zag ring of `n` edges: long and short, steep and flat.
    fn ring(n: usize) -> Vec<[Point2<f64>; 2]> {
        let v: Vec<Point2<f64>> = (0..n)
            .map(|i| {
                let t = i as f64 / n as f64 * std::f64::consts::TAU;
                let r = if i % 3 == 0 {
                    1.0
                } else {
                    0.6 + 0.1 * (i % 5) as f64
                };
                Point2::new(r * t.cos() * 2.0, r * t.sin())
            })
            .collect();
        (0..n).map(|i| [v[i], v[(i + 1) % n]]).collect()
    }

    #[test]
    fn the_slab_of_y_lists_every_edge_the_line_at_y_crosses() {
        for n in [3, 7, 40, 300] {
            let edges = ring(n);
            let (lo, hi) = edges
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), [a, _]| {
                    (lo.min(a.y), hi.max(a.y))
                });
            let slabs = EdgeSlabs::new(&edges, lo, hi);
            for i in 0..400 {
                let y = -2.0 + 4.0 * i as f64 / 400.0;
                let near = slabs.near(y);
                assert!(near.windows(2).all(|w| w[0] < w[1]));
                for (e, [a, b]) in edges.iter().enumerate() {
                    if (a.y > y) != (b.y > y) {
                        assert!(near.contains(&(e as u32)), "n {n}, y {y}, edge {e}");
                    }
                }
            }
            // The slabs are a partition for the query, not a copy of every edge.
            if n >= 40 {
                assert!(slabs.near(0.0).len() < n / 4, "{}", slabs.near(0.0).len());
            }
        }
    }

    #[test]
    fn a_flat_polygon_has_one_slab_and_still_answers() {
        let edges = vec![[Point2::new(0.0, 0.0), Point2::new(1.0, 0.0)]];
        let slabs = EdgeSlabs::new(&edges, 0.0, 0.0);
        assert_eq!(slabs.near(5.0), &[0]);
        assert_eq!(slabs.near(-5.0), &[0]);
    }
}
