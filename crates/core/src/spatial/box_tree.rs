//! [`BoxTree`]: exact nearest-point distances for queries that lie far from the points,
//! such as the surface samples of candidates beside a scan.
//!
//! A kd-tree's cells are the half-spaces of its splits: beside a dense surface they
//! reach out into the empty space around it, so a query at height `h` over the surface
//! must open every leaf within `h` of its foot (on a 1 cm-spaced surface and `h` = 0.3 m,
//! hundreds of leaves). Here every node keeps the tight box of its own points instead:
//! every box of that surface lies at least `h` from the query, and only the few leaves
//! around the foot are opened. The search also starts from a hint (the previous query's
//! nearest point, for a run of nearby queries), whose distance bounds it from the first
//! node.
//!
//! Distances are squared, computed as `dx² + dy² + dz²` like [`super::PointIndex`], so
//! the two return bit-identical distances for the same points.

use nalgebra::Point3;

use super::{as_array, squared_distance};

/// Most points of a leaf.
const LEAF_POINTS: usize = 16;

/// Subtrees of more points than this are built in parallel.
const PARALLEL_BUILD_POINTS: usize = 1 << 15;

/// Nodes a search may hold to open later: at most one per level of the tree, and median
/// splits of at most `u32::MAX` points into leaves of [`LEAF_POINTS`] give fewer than 32
/// levels.
const SEARCH_STACK: usize = 64;

/// A node: the tight box of its points; a leaf holds `points[first..first + count]`, an
/// inner node (`count == 0`) has its left child next in the array and its right child
/// at `right`.
#[derive(Debug, Clone, Copy)]
struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    first: u32,
    count: u32,
    right: u32,
}

/// A bounding-box tree over points for exact nearest-distance queries (module docs).
#[derive(Debug, Clone)]
pub struct BoxTree {
    /// The points, reordered so that each leaf's are consecutive.
    points: Vec<[f64; 3]>,
    /// Depth-first; empty when there are no points.
    nodes: Vec<Node>,
}

/// Where the next search of a run of nearby queries starts (see [`BoxTree::nearest`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Hint(u32);

impl BoxTree {
    /// Builds the tree (in parallel for large inputs). Points must be finite; at most
    /// `u32::MAX` points.
    pub fn new(points: &[Point3<f64>]) -> Self {
        let mut coords: Vec<[f64; 3]> = points.iter().map(as_array).collect();
        let nodes = if coords.is_empty() {
            Vec::new()
        } else {
            build(&mut coords, 0)
        };
        BoxTree {
            points: coords,
            nodes,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// The squared distance from `q` to the nearest point (infinite when there are no
    /// points). `hint` is read as a first guess and set to the nearest point, so that a
    /// run of nearby queries each starts from the last one's answer; the distance does
    /// not depend on it.
    pub fn nearest(&self, q: &Point3<f64>, hint: &mut Hint) -> f64 {
        self.search(q, hint).map_or(f64::INFINITY, |(_, d)| d)
    }

    /// The nearest point to `q` and its squared distance (`None` when there are no
    /// points), with `hint` as in [`BoxTree::nearest`]. Among points at exactly the same
    /// distance the one returned depends on the hint.
    pub fn nearest_point(&self, q: &Point3<f64>, hint: &mut Hint) -> Option<(Point3<f64>, f64)> {
        self.search(q, hint)
            .map(|(at, d)| (Point3::from(self.points[at as usize]), d))
    }

    /// The position (in the reordered points) of the nearest point to `q` and its
    /// squared distance; `None` when there are no points.
    fn search(&self, q: &Point3<f64>, hint: &mut Hint) -> Option<(u32, f64)> {
        if self.points.is_empty() {
            return None;
        }
        let mut best_at = if (hint.0 as usize) < self.points.len() {
            hint.0
        } else {
            0
        };
        let q = as_array(q);
        let mut best = squared_distance(&q, &self.points[best_at as usize]);
        // Nodes still to open, with their boxes' squared distances.
        let mut stack = [(0u32, 0.0f64); SEARCH_STACK];
        let mut depth = 0;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if n.count > 0 {
                let start = n.first as usize;
                for (k, p) in self.points[start..start + n.count as usize]
                    .iter()
                    .enumerate()
                {
                    let d = squared_distance(&q, p);
                    if d < best {
                        best = d;
                        best_at = (start + k) as u32;
                    }
                }
            } else {
                let (left, right) = (node + 1, n.right as usize);
                let dl = box_distance(&q, &self.nodes[left]);
                let dr = box_distance(&q, &self.nodes[right]);
                let ((near, dn), (far, df)) = if dl <= dr {
                    ((left, dl), (right, dr))
                } else {
                    ((right, dr), (left, dl))
                };
                if df < best {
                    stack[depth] = (far as u32, df);
                    depth += 1;
                }
                if dn < best {
                    node = near;
                    continue;
                }
            }
            // The next node on the stack that can still hold a nearer point.
            loop {
                if depth == 0 {
                    *hint = Hint(best_at);
                    return Some((best_at, best));
                }
                depth -= 1;
                let (next, d) = stack[depth];
                if d < best {
                    node = next as usize;
                    break;
                }
            }
        }
    }
}

/// The squared distance from `q` to the node's box (0 inside): no larger than the
/// squared distance to any point in it, in floating point too (rounding is monotone).
#[inline]
fn box_distance(q: &[f64; 3], n: &Node) -> f64 {
    let gap = |a: usize| (n.lo[a] - q[a]).max(q[a] - n.hi[a]).max(0.0);
    let (gx, gy, gz) = (gap(0), gap(1), gap(2));
    gx * gx + gy * gy + gz * gz
}

/// The nodes over `points` (reordered in place), depth-first; `offset` is the position of
/// `points[0]` in the whole array.
fn build(points: &mut [[f64; 3]], offset: usize) -> Vec<Node> {
    let (lo, hi) = bounds(points);
    if points.len() <= LEAF_POINTS {
        return vec![Node {
            lo,
            hi,
            first: offset as u32,
            count: points.len() as u32,
            right: 0,
        }];
    }
    // Split at the median of the box's longest axis.
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let mid = points.len() / 2;
    points.select_nth_unstable_by(mid, |p, q| p[axis].total_cmp(&q[axis]));
    let (left_points, right_points) = points.split_at_mut(mid);
    let (left, right) = if left_points.len() + right_points.len() > PARALLEL_BUILD_POINTS {
        rayon::join(
            || build(left_points, offset),
            || build(right_points, offset + mid),
        )
    } else {
        (
            build(left_points, offset),
            build(right_points, offset + mid),
        )
    };
    let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
    let right_at = (1 + left.len()) as u32;
    nodes.push(Node {
        lo,
        hi,
        first: 0,
        count: 0,
        right: right_at,
    });
    // Each subtree numbered its nodes from 0; they now start at 1 and at `right_at`.
    nodes.extend(shifted(left, 1));
    nodes.extend(shifted(right, right_at));
    nodes
}

/// `nodes` with their right-child links moved by `by` places.
fn shifted(nodes: Vec<Node>, by: u32) -> impl Iterator<Item = Node> {
    nodes.into_iter().map(move |mut n| {
        if n.count == 0 {
            n.right += by;
        }
        n
    })
}

/// The tight box of `points` (not empty).
fn bounds(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = points[0];
    let mut hi = points[0];
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::PointIndex;
    use rand::{Rng, RngExt, SeedableRng};

    /// A noisy patch of a plane and a short tube: dense surfaces with empty space around.
    fn surfaces(rng: &mut impl Rng) -> Vec<Point3<f64>> {
        let mut pts = Vec::new();
        for _ in 0..3000 {
            let (x, y) = (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            pts.push(Point3::new(x, y, 0.001 * rng.random_range(-1.0..1.0)));
        }
        for _ in 0..2000 {
            let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let z = rng.random_range(0.0..0.8);
            pts.push(Point3::new(0.3 + 0.1 * a.cos(), -0.2 + 0.1 * a.sin(), z));
        }
        // Exact duplicates and a grid of equal coordinates (ties).
        pts.extend_from_within(0..50);
        pts.extend(
            (0..100)
                .map(|i| Point3::new(0.5 + 0.01 * (i % 10) as f64, 0.5, 0.01 * (i / 10) as f64)),
        );
        pts
    }

    #[test]
    fn matches_brute_force_and_the_kd_tree_bit_for_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let pts = surfaces(&mut rng);
        let tree = BoxTree::new(&pts);
        let kd = PointIndex::new(&pts);
        let mut hint = Hint::default();
        for k in 0..5000 {
            // Near, far and outside the points' box; some exactly on points.
            let spread = [0.01, 0.3, 3.0][k % 3];
            let q = if k % 7 == 0 {
                pts[k % pts.len()]
            } else {
                let c = pts[(k * 31) % pts.len()];
                c + nalgebra::Vector3::new(
                    rng.random_range(-spread..spread),
                    rng.random_range(-spread..spread),
                    rng.random_range(-spread..spread),
                )
            };
            let brute = pts
                .iter()
                .map(|p| squared_distance(&as_array(&q), &as_array(p)))
                .fold(f64::INFINITY, f64::min);
            let got = tree.nearest(&q, &mut hint);
            assert_eq!(got.to_bits(), brute.to_bits(), "query {k}");
            // The point it names is one of the cloud's, at that distance.
            let (p, d) = tree.nearest_point(&q, &mut hint).unwrap();
            assert_eq!(d.to_bits(), brute.to_bits(), "query {k}");
            assert!(pts.contains(&p), "query {k}");
            assert_eq!(
                squared_distance(&as_array(&q), &as_array(&p)).to_bits(),
                d.to_bits()
            );
            assert_eq!(
                got.to_bits(),
                kd.nearest(&q).unwrap().1.to_bits(),
                "query {k}"
            );
        }
    }

    #[test]
    fn the_hint_changes_nothing_but_where_the_search_starts() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(8);
        let pts = surfaces(&mut rng);
        let tree = BoxTree::new(&pts);
        let q = Point3::new(0.2, 0.1, 0.4);
        let fresh = tree.nearest(&q, &mut Hint::default());
        for start in [0, 17, pts.len() as u32 - 1, u32::MAX] {
            let mut hint = Hint(start);
            assert_eq!(tree.nearest(&q, &mut hint).to_bits(), fresh.to_bits());
            // The hint now names a nearest point: searching again from it gives the same.
            assert!((hint.0 as usize) < pts.len());
            assert_eq!(tree.nearest(&q, &mut hint).to_bits(), fresh.to_bits());
        }
    }

    #[test]
    fn a_tree_built_in_parallel_answers_the_same() {
        // Above PARALLEL_BUILD_POINTS the halves are built by separate tasks and their
        // nodes renumbered when joined.
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let mut pts = surfaces(&mut rng);
        while pts.len() <= 2 * PARALLEL_BUILD_POINTS {
            pts.extend_from_within(..5000);
            let k = pts.len() - 5000;
            for p in &mut pts[k..] {
                p.x += 2.5 * (k / 5000) as f64;
            }
        }
        let tree = BoxTree::new(&pts);
        let kd = PointIndex::new(&pts);
        let mut hint = Hint::default();
        for k in 0..2000 {
            let c = pts[(k * 7919) % pts.len()];
            let q = c + nalgebra::Vector3::new(0.0, 0.0, [0.0, 0.05, 0.4, 2.0][k % 4]);
            let got = tree.nearest(&q, &mut hint);
            assert_eq!(
                got.to_bits(),
                kd.nearest(&q).unwrap().1.to_bits(),
                "query {k}"
            );
        }
    }

    #[test]
    fn small_and_empty_inputs() {
        assert_eq!(
            BoxTree::new(&[]).nearest(&Point3::origin(), &mut Hint::default()),
            f64::INFINITY
        );
        assert_eq!(
            BoxTree::new(&[]).nearest_point(&Point3::origin(), &mut Hint::default()),
            None
        );
        let one = BoxTree::new(&[Point3::new(1.0, 2.0, 2.0)]);
        assert_eq!(one.nearest(&Point3::origin(), &mut Hint(5)), 9.0);
        assert_eq!(
            one.nearest_point(&Point3::origin(), &mut Hint(5)),
            Some((Point3::new(1.0, 2.0, 2.0), 9.0))
        );
    }
}
