//! A bounding-volume hierarchy over a mesh's triangles: exact closest point and first
//! ray hit in O(log n) typical time.
//!
//! Built top-down by median split of the triangle centroids along the longest axis of
//! their bounding box, so the tree is balanced (depth ≈ log₂(n/[`LEAF_SIZE`])) whatever the
//! triangle sizes. Queries walk it depth-first, nearer child first, and prune boxes that
//! cannot beat the best answer so far; pruning only skips boxes that provably hold
//! nothing better, so the answers equal those of a brute-force scan.

use nalgebra::{Point3, Vector3};

use super::TriMesh;
use super::numeric::slab;

/// Relative slack on a hint's distance in [`TriangleBvh::closest_point_near`]: a hint
/// on the surface rounded in its last bits still bounds the search.
const HINT_SLACK: f64 = 1e-6;

/// At most this many triangles in a leaf.
const LEAF_SIZE: usize = 4;

/// An axis-aligned box.
#[derive(Debug, Clone, Copy)]
struct Aabb {
    lo: Point3<f64>,
    hi: Point3<f64>,
}

impl Aabb {
    fn empty() -> Self {
        Aabb {
            lo: Point3::from([f64::INFINITY; 3]),
            hi: Point3::from([f64::NEG_INFINITY; 3]),
        }
    }

    fn grow(&mut self, p: &Point3<f64>) {
        self.lo = self.lo.inf(p);
        self.hi = self.hi.sup(p);
    }

    /// Squared distance from `p` to the box (0 inside).
    fn distance2(&self, p: &Point3<f64>) -> f64 {
        (0..3)
            .map(|k| (self.lo[k] - p[k]).max(p[k] - self.hi[k]).max(0.0).powi(2))
            .sum()
    }

    /// The ray parameters where `o + t d` is inside the box.
    fn ray_span(&self, o: &Point3<f64>, d: &Vector3<f64>) -> Option<(f64, f64)> {
        slab(
            o.coords.into(),
            (*d).into(),
            self.lo.coords.into(),
            self.hi.coords.into(),
        )
    }
}

/// A node: a leaf holds `count > 0` triangles from `first`; an inner node (`count == 0`)
/// has its two children at `first` and `first + 1`.
#[derive(Debug, Clone, Copy)]
struct Node {
    bounds: Aabb,
    first: u32,
    count: u32,
}

/// The hierarchy and the triangles' corners, stored in leaf order.
#[derive(Debug, Clone)]
pub(super) struct TriangleBvh {
    nodes: Vec<Node>,
    triangles: Vec<[Point3<f64>; 3]>,
}

impl TriangleBvh {
    /// Builds the hierarchy over all faces of `mesh` (face indices must be in range).
    pub(super) fn new(mesh: &TriMesh) -> Self {
        let triangles: Vec<[Point3<f64>; 3]> = mesh
            .faces
            .iter()
            .map(|f| f.map(|i| mesh.vertices[i as usize]))
            .collect();
        let centroids: Vec<Point3<f64>> = triangles
            .iter()
            .map(|[a, b, c]| Point3::from((a.coords + b.coords + c.coords) / 3.0))
            .collect();
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let mut nodes = vec![Node {
            bounds: Aabb::empty(),
            first: 0,
            count: 0,
        }];
        build(&mut nodes, 0, &mut order, 0, &triangles, &centroids);
        let triangles = order.iter().map(|&i| triangles[i as usize]).collect();
        TriangleBvh { nodes, triangles }
    }

    /// The closest point of any triangle to `p` (`None` only for an empty mesh).
    pub(super) fn closest_point(&self, p: &Point3<f64>) -> Option<Point3<f64>> {
        self.closest_point_near(p, None)
    }

    /// [`TriangleBvh::closest_point`], given `hint`, a point at or near the surface (e.g.
    /// a nearby query's answer): nodes farther than the hint (plus a relative
    /// [`HINT_SLACK`]) are skipped from the start, which makes a sweep of nearby queries
    /// several times cheaper. The answer is always a face's point; a hint closer than
    /// the surface (off it) falls back to the plain query.
    pub(super) fn closest_point_near(
        &self,
        p: &Point3<f64>,
        hint: Option<&Point3<f64>>,
    ) -> Option<Point3<f64>> {
        let start = hint.map_or(f64::INFINITY, |h| (h - p).norm_squared());
        self.closest_bounded(p, start).map(|(q, _)| q)
    }

    /// [`TriangleBvh::closest_point`] and the face it lies on (an index in leaf order),
    /// given the face of a nearby query's answer (an out-of-range face is no hint),
    /// exact where a face is within `reach` of `p`: the distance to the hint face bounds
    /// the search from the start. Where that distance exceeds `reach`, only the faces
    /// within `reach` are searched (few boxes come that close to a point far from the
    /// surface), and if there are none the hint face's closest point is the answer.
    pub(super) fn closest_face_near(
        &self,
        p: &Point3<f64>,
        face: Option<u32>,
        reach: f64,
    ) -> Option<(Point3<f64>, u32)> {
        let hinted = face.and_then(|f| {
            let tri = self.triangles.get(f as usize)?;
            Some((closest_on_triangle(p, tri), f))
        });
        let Some((q, f)) = hinted else {
            return self.closest_bounded(p, f64::INFINITY);
        };
        let d2 = (q - p).norm_squared();
        if d2 <= reach * reach {
            return self.closest_bounded(p, d2);
        }
        self.closest_within(p, reach * reach).or(Some((q, f)))
    }

    /// The closest face point to `p` and its face, searched among the faces nearer than
    /// a squared distance `start2` (plus the relative [`HINT_SLACK`]: a hint rounded in
    /// its last bits still bounds the search), else among all.
    fn closest_bounded(&self, p: &Point3<f64>, start2: f64) -> Option<(Point3<f64>, u32)> {
        if self.triangles.is_empty() {
            return None;
        }
        let start = start2 * (1.0 + HINT_SLACK).powi(2);
        match self.closest_within(p, start) {
            Some(c) => Some(c),
            None if start.is_finite() => self.closest_within(p, f64::INFINITY),
            None => None,
        }
    }

    /// The closest face point to `p` among those nearer than `√bound2`, and its face
    /// (`None` if none).
    fn closest_within(&self, p: &Point3<f64>, bound2: f64) -> Option<(Point3<f64>, u32)> {
        let mut best: Option<(f64, Point3<f64>, u32)> = None;
        let bound = |best: &Option<(f64, Point3<f64>, u32)>| best.map_or(bound2, |b| b.0);
        let mut stack = vec![(0u32, self.nodes[0].bounds.distance2(p))];
        while let Some((index, box_d2)) = stack.pop() {
            if box_d2 >= bound(&best) {
                continue;
            }
            let node = &self.nodes[index as usize];
            if node.count > 0 {
                for (k, tri) in self.leaf(node).iter().enumerate() {
                    if triangle_box_distance2(p, tri) >= bound(&best) {
                        continue;
                    }
                    let q = closest_on_triangle(p, tri);
                    let d2 = (q - p).norm_squared();
                    if d2 < bound(&best) {
                        best = Some((d2, q, node.first + k as u32));
                    }
                }
                continue;
            }
            let children = [node.first, node.first + 1]
                .map(|c| (c, self.nodes[c as usize].bounds.distance2(p)));
            let [near, far] = if children[0].1 <= children[1].1 {
                children
            } else {
                [children[1], children[0]]
            };
            stack.push(far);
            stack.push(near);
        }
        best.map(|(_, q, f)| (q, f))
    }

    /// The smallest `t ≥ 0` at which `o + t d` hits a triangle (Möller–Trumbore).
    pub(super) fn ray_intersect(&self, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
        if self.triangles.is_empty() {
            return None;
        }
        let mut best = f64::INFINITY;
        let mut stack = vec![0u32];
        while let Some(index) = stack.pop() {
            let node = &self.nodes[index as usize];
            match node.bounds.ray_span(o, d) {
                Some((t_in, t_out)) if t_out >= 0.0 && t_in <= best => {}
                _ => continue,
            }
            if node.count > 0 {
                for tri in self.leaf(node) {
                    if let Some(t) = ray_triangle(o, d, tri) {
                        best = best.min(t);
                    }
                }
            } else {
                stack.extend([node.first, node.first + 1]);
            }
        }
        best.is_finite().then_some(best)
    }

    fn leaf(&self, node: &Node) -> &[[Point3<f64>; 3]] {
        &self.triangles[node.first as usize..(node.first + node.count) as usize]
    }
}

/// Fills node `index` with the triangles `order` (which start at `offset` in leaf order),
/// splitting at the median centroid along the widest axis until leaves are small.
fn build(
    nodes: &mut Vec<Node>,
    index: usize,
    order: &mut [u32],
    offset: u32,
    triangles: &[[Point3<f64>; 3]],
    centroids: &[Point3<f64>],
) {
    let mut bounds = Aabb::empty();
    let mut spread = Aabb::empty();
    for &i in order.iter() {
        triangles[i as usize].iter().for_each(|v| bounds.grow(v));
        spread.grow(&centroids[i as usize]);
    }
    if order.len() <= LEAF_SIZE {
        nodes[index] = Node {
            bounds,
            first: offset,
            count: order.len() as u32,
        };
        return;
    }
    let extent = spread.hi - spread.lo;
    let axis = extent.iamax();
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    let first_child = nodes.len();
    nodes[index] = Node {
        bounds,
        first: first_child as u32,
        count: 0,
    };
    let placeholder = Node {
        bounds: Aabb::empty(),
        first: 0,
        count: 0,
    };
    nodes.extend([placeholder, placeholder]);
    let (left, right) = order.split_at_mut(mid);
    build(nodes, first_child, left, offset, triangles, centroids);
    build(
        nodes,
        first_child + 1,
        right,
        offset + mid as u32,
        triangles,
        centroids,
    );
}

/// The closest point of triangle `abc` to `p` (Ericson, *Real-Time Collision Detection*,
/// §5.1.5: find the Voronoi region of `p` among vertices, edges and face). Degenerate
/// (zero-area) triangles fall back to their three edges.
pub(super) fn closest_on_triangle(p: &Point3<f64>, [a, b, c]: &[Point3<f64>; 3]) -> Point3<f64> {
    let (ab, ac) = (b - a, c - a);
    if ab.cross(&ac).norm_squared() <= f64::MIN_POSITIVE {
        return [(a, b), (b, c), (c, a)]
            .map(|(s, e)| closest_on_segment(p, s, e))
            .into_iter()
            .min_by(|x, y| (x - p).norm_squared().total_cmp(&(y - p).norm_squared()))
            .unwrap_or(*a);
    }
    let ap = p - a;
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3)); // edge ab; d1 − d3 = |ab|²
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6)); // edge ac; d2 − d6 = |ac|²
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))); // edge bc; sum = |bc|²
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Squared distance from `p` to the bounding box of triangle `abc`: a lower bound on the
/// squared distance to the triangle that costs a few comparisons.
#[inline]
fn triangle_box_distance2(p: &Point3<f64>, [a, b, c]: &[Point3<f64>; 3]) -> f64 {
    let (lo, hi) = (a.inf(b).inf(c), a.sup(b).sup(c));
    (p.coords - p.coords.sup(&lo.coords).inf(&hi.coords)).norm_squared()
}

/// The closest point of segment `se` to `p` (a point if `s = e`).
fn closest_on_segment(p: &Point3<f64>, s: &Point3<f64>, e: &Point3<f64>) -> Point3<f64> {
    let se = e - s;
    let len2 = se.norm_squared();
    if len2 <= 0.0 {
        return *s;
    }
    s + se * ((p - s).dot(&se) / len2).clamp(0.0, 1.0)
}

/// Möller–Trumbore ray/triangle intersection: `t ≥ 0` with `o + t d` in triangle `abc`
/// (edges included). A ray parallel to the triangle's plane is reported as a miss.
fn ray_triangle(o: &Point3<f64>, d: &Vector3<f64>, [a, b, c]: &[Point3<f64>; 3]) -> Option<f64> {
    let (e1, e2) = (b - a, c - a);
    let pv = d.cross(&e2);
    let det = e1.dot(&pv);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(&pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(&e1);
    let v = d.dot(&q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(&q) * inv;
    (t >= 0.0).then_some(t)
}
