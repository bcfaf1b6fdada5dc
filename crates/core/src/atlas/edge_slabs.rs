//! A polygon's edges bucketed into horizontal slabs of its y-range, so that the
//! point-in-polygon test and the closest edge of a [`super::PlaneShape`] look at the
//! edges near the query's y instead of at all of them.
//!
//! Both queries give exactly the answers of a scan over every edge: an edge that a
//! horizontal line at `y` crosses spans `y`, so it is listed in the slab of `y`; and
//! slabs are visited outward from the query's until the vertical gap to the next one
//! exceeds the best distance found, ties going to the lower edge index as in a scan.

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
    /// Number of edges.
    edges: usize,
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
            edges: edges.len(),
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

    /// The vertical distance from `y` to slab `s` (0 inside it).
    fn gap(&self, s: usize, y: f64) -> f64 {
        let bottom = self.y0 + s as f64 * self.height;
        (bottom - y).max(y - (bottom + self.height)).max(0.0)
    }

    /// The edge index minimising `distance2(edge)` (ties: the lower index), given that
    /// an edge in slab `s` is at least `gap(s, q_y)` from the query; `None` without
    /// edges. `distance2` is the squared distance from the query to an edge.
    pub(super) fn closest(&self, q_y: f64, distance2: impl Fn(usize) -> f64) -> Option<usize> {
        let start = self.slab_of(q_y);
        let mut best: Option<(f64, usize)> = None;
        let visit = |s: usize, best: &mut Option<(f64, usize)>| {
            for &e in self.slab(s) {
                let d2 = distance2(e as usize);
                let better = best.is_none_or(|(b, i)| d2 < b || (d2 == b && (e as usize) < i));
                if better {
                    *best = Some((d2, e as usize));
                }
            }
        };
        visit(start, &mut best);
        // A query far from the polygon reaches most slabs, whose lists repeat long
        // edges: one pass over every edge is then cheaper, and gives the same answer.
        let reach = best.map_or(f64::INFINITY, |(d2, _)| d2).sqrt();
        if reach / self.height >= (self.count / 4) as f64 {
            let mut scan: Option<(f64, usize)> = None;
            for e in 0..self.edges {
                let d2 = distance2(e);
                if scan.is_none_or(|(b, _)| d2 < b) {
                    scan = Some((d2, e));
                }
            }
            return scan.map(|(_, e)| e);
        }
        for step in 1..self.count {
            let (below, above) = (start.checked_sub(step), start + step);
            let candidates = [below, (above < self.count).then_some(above)];
            if candidates.iter().all(Option::is_none) {
                break;
            }
            let reach = best.map_or(f64::INFINITY, |(d2, _)| d2);
            let mut any = false;
            for s in candidates.into_iter().flatten() {
                let g = self.gap(s, q_y);
                if g * g <= reach {
                    visit(s, &mut best);
                    any = true;
                }
            }
            if !any {
                break;
            }
        }
        best.map(|(_, e)| e)
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

    fn segment_distance2(q: &Point2<f64>, [a, b]: &[Point2<f64>; 2]) -> f64 {
        let ab = b - a;
        let t = ((q - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
        (q - (a + ab * t)).norm_squared()
    }

    #[test]
    fn slab_queries_agree_with_a_scan_of_every_edge() {
        for n in [3, 7, 40, 300] {
            let edges = ring(n);
            let (lo, hi) = edges
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), [a, _]| {
                    (lo.min(a.y), hi.max(a.y))
                });
            let slabs = EdgeSlabs::new(&edges, lo, hi);
            for i in 0..400 {
                let q = Point2::new(
                    -3.0 + 6.0 * ((i * 37) % 400) as f64 / 400.0,
                    -2.0 + 4.0 * i as f64 / 400.0,
                );
                // Crossing edges of the line y = q.y are all in the slab of q.y.
                let crossing: Vec<u32> = (0..edges.len() as u32)
                    .filter(|&e| {
                        let [a, b] = edges[e as usize];
                        (a.y > q.y) != (b.y > q.y)
                    })
                    .collect();
                let near = slabs.near(q.y);
                assert!(crossing.iter().all(|e| near.contains(e)), "n {n}, q {q:?}");
                // The closest edge is the scan's (lowest index among the minima).
                let d2 = |e: usize| segment_distance2(&q, &edges[e]);
                let scan = (0..edges.len())
                    .min_by(|&a, &b| d2(a).total_cmp(&d2(b)))
                    .unwrap();
                assert_eq!(slabs.closest(q.y, d2), Some(scan), "n {n}, q {q:?}");
            }
        }
    }

    #[test]
    fn a_flat_polygon_has_one_slab_and_still_answers() {
        let edges = vec![[Point2::new(0.0, 0.0), Point2::new(1.0, 0.0)]];
        let slabs = EdgeSlabs::new(&edges, 0.0, 0.0);
        assert_eq!(slabs.near(5.0), &[0]);
        assert_eq!(slabs.closest(-3.0, |_| 1.0), Some(0));
        let none = EdgeSlabs::new(&[], 0.0, 1.0);
        assert_eq!(none.closest(0.5, |_| 1.0), None);
    }
}
