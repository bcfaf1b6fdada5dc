//! Candidate geometries of the registration filter: the particles (poses of one mesh,
//! with a fast surface-distance grid), the explicit outlier primitive (a uniformly
//! filled box), and a chain of geometries seen as one candidate set.

use std::sync::Arc;

use nalgebra::{Point3, Vector3};
use rand::{Rng, RngExt};
use rayon::prelude::*;

use crate::atlas::MeshShape;
use crate::chamfer::CandidateGeometry;
use crate::lattice::{CandidateSet, Template};
use crate::spatial::PointIndex;

/// Distance to a mesh surface from a regular grid of closest points, in the mesh's local
/// frame.
///
/// Every grid node within the padding of the surface stores its exact closest surface
/// point (a node farther away, a surface point no closer than that); a query trilinearly
/// interpolates those points and measures the distance to the result. Where the
/// closest-point map is affine (near a flat piece of surface) this is exact; near curved
/// surface the error is of order `cell² / curvature radius`, far below the cell size, so
/// no exact query is needed in the filter's inner loop (about 20× cheaper than the
/// mesh's exact closest-point query). Outside the grid, the distance to the grid box is
/// added to the value at the clamped point. Units: the mesh's local units.
#[derive(Debug)]
pub struct DistanceGrid {
    lo: Point3<f64>,
    /// The mesh's bounding box (unpadded).
    mesh_lo: Point3<f64>,
    mesh_hi: Point3<f64>,
    cell: f64,
    /// The padding about the mesh's box within which nodes are exact (local units).
    pad: f64,
    dims: [usize; 3],
    closest: Vec<[f32; 3]>,
}

impl DistanceGrid {
    /// Tabulates `mesh` over its bounding box padded by `pad` (local units), with
    /// `cells` cells along the longest axis (at least 2).
    pub fn new(mesh: &MeshShape, cells: usize, pad: f64) -> Self {
        let (mut lo, mut hi) = (
            Point3::from(Vector3::repeat(f64::INFINITY)),
            Point3::from(Vector3::repeat(f64::NEG_INFINITY)),
        );
        for v in &mesh.mesh.vertices {
            lo = lo.inf(v);
            hi = hi.sup(v);
        }
        let (mesh_lo, mesh_hi) = (lo, hi);
        let (lo, hi) = (lo - Vector3::repeat(pad), hi + Vector3::repeat(pad));
        let cell = (hi - lo).max() / cells.max(2) as f64;
        let dims = [0, 1, 2].map(|a| ((hi[a] - lo[a]) / cell).ceil() as usize + 1);
        // Row by row along x, each query starting from the face of the previous cell's
        // answer (its distance bounds the search), the rows in parallel. Exact within
        // `pad` of the surface, what the largest kernel can see; farther, a surface
        // point no closer than the exact one (a bound, as beyond the grid).
        let closest: Vec<[f32; 3]> = (0..dims[1] * dims[2])
            .into_par_iter()
            .flat_map_iter(|row| {
                let (j, l) = (row % dims[1], row / dims[1]);
                let mut face = None;
                (0..dims[0]).map(move |i| {
                    let p = lo + Vector3::new(i as f64, j as f64, l as f64) * cell;
                    let (c, f) = mesh.closest_point_from_face(&p, face, pad);
                    face = Some(f);
                    [c.x as f32, c.y as f32, c.z as f32]
                })
            })
            .collect();
        DistanceGrid {
            lo,
            mesh_lo,
            mesh_hi,
            cell,
            pad,
            dims,
            closest,
        }
    }

    /// Grid cell size (local units).
    pub fn cell(&self) -> f64 {
        self.cell
    }

    /// A lower bound on [`DistanceGrid::distance`] that costs a few comparisons: the
    /// distance from `p` (local frame) to the mesh's bounding box (local units).
    #[inline]
    pub fn box_distance(&self, p: &Point3<f64>) -> f64 {
        (p.coords - p.coords.sup(&self.mesh_lo.coords).inf(&self.mesh_hi.coords)).norm()
    }

    /// Whether the exact surface distance of `p` (local frame) is surely above `r` (local
    /// units), from [`DistanceGrid::distance`] at a few operations' cost; `false` means
    /// "maybe not". Where the exact distance `d` is at most `r`, the 8 nodes about `p`
    /// lie within `r + √3 c` of the surface (`c` the cell), inside the padding where
    /// nodes are exact when `r < pad − √3 c`, and each node's closest point is within
    /// `d + 2√3 c` of `p`, so the interpolated distance is at most `d + 2√3 c`: above
    /// `r + 2√3 c` it proves `d > r`. For a larger `r` it claims nothing.
    pub fn surely_beyond(&self, p: &Point3<f64>, r: f64) -> bool {
        let corner = 3f64.sqrt() * self.cell;
        if r >= self.pad - corner {
            return false;
        }
        self.box_distance(p) > r || self.distance(p) > r + 2.0 * corner
    }

    /// The tabulated closest surface point of the grid node nearest `p` (local frame,
    /// clamped to the grid): a point within about a cell of `p`'s own closest point, to
    /// start an exact query from ([`MeshShape::closest_point_near`]).
    pub fn hint(&self, p: &Point3<f64>) -> Point3<f64> {
        let node = |a: usize| {
            // Rounded half away from zero (for x ≥ 0; a negative x saturates to node 0),
            // without a call to `round`, which baseline x86-64 does not inline.
            let x = (p[a] - self.lo[a]) / self.cell + 0.5;
            (x as usize).min(self.dims[a] - 1)
        };
        let (nx, nxy) = (self.dims[0], self.dims[0] * self.dims[1]);
        let v = self.closest[node(0) + node(1) * nx + node(2) * nxy];
        Point3::new(v[0] as f64, v[1] as f64, v[2] as f64)
    }

    /// Distance from `p` (local frame) to the mesh surface (local units).
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        let mut f = [0.0; 3];
        let mut base = [0usize; 3];
        let mut q = *p;
        for a in 0..3 {
            let max = (self.dims[a] - 1) as f64;
            let x = ((p[a] - self.lo[a]) / self.cell).clamp(0.0, max);
            q[a] = self.lo[a] + x * self.cell;
            let b = (x as usize).min(self.dims[a] - 2); // x ≥ 0: truncation is floor
            base[a] = b;
            f[a] = x - b as f64;
        }
        let (nx, nxy) = (self.dims[0], self.dims[0] * self.dims[1]);
        let mut c = Vector3::zeros();
        for l in 0..2 {
            let wl = if l == 0 { 1.0 - f[2] } else { f[2] };
            for j in 0..2 {
                let wj = wl * if j == 0 { 1.0 - f[1] } else { f[1] };
                for i in 0..2 {
                    let w = wj * if i == 0 { 1.0 - f[0] } else { f[0] };
                    let v = self.closest[(base[0] + i) + (base[1] + j) * nx + (base[2] + l) * nxy];
                    c += Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64) * w;
                }
            }
        }
        (q.coords - c).norm() + (p - q).norm()
    }
}

/// The particles: poses of one mesh template, as a [`CandidateGeometry`]. Sample
/// queries use the shared local-frame template; surface distances use the
/// [`DistanceGrid`] (exact near the surface).
#[derive(Debug)]
pub struct Particles {
    /// The template and the particle poses (`template_of` all 0).
    pub set: CandidateSet,
    /// Surface distances of the template's mesh.
    pub grid: Arc<DistanceGrid>,
}

impl Particles {
    /// Particles at `poses` of `template`.
    pub fn new(template: Template, grid: Arc<DistanceGrid>, poses: Vec<crate::Pose>) -> Self {
        let n = poses.len();
        let set = CandidateSet::from_parts(vec![template], vec![0; n], poses)
            .expect("one template, every id 0");
        Particles { set, grid }
    }
}

impl CandidateGeometry for Particles {
    fn len(&self) -> usize {
        self.set.len()
    }
    fn sample_count(&self, i: usize) -> usize {
        self.set.sample_count(i)
    }
    fn scene_samples(&self, i: usize, out: &mut Vec<Point3<f64>>) {
        self.set.scene_samples(i, out)
    }
    fn bounding_ball(&self, i: usize) -> (Point3<f64>, f64) {
        self.set.bounding_ball(i)
    }
    fn nearest_sample(&self, i: usize, y: &Point3<f64>) -> (u32, f64) {
        self.set.nearest_sample(i, y)
    }
    #[inline]
    fn surface_distance(&self, i: usize, y: &Point3<f64>) -> f64 {
        let pose = &self.set.poses[i];
        let d = self.grid.distance(&pose.to_local(y)) * pose.scale;
        d * d
    }
    fn nearest_samples(
        &self,
        i: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    ) {
        self.set.nearest_samples(i, y, k, out)
    }
}

/// The outlier level of thesis §6.3.3 without its samples: the expected squared
/// distance from a point of an axis-aligned box (the scene's bounding box) to the
/// nearest of `count` uniform samples of it, `E[r²] = Γ(5/3) · (4πρ/3)^(−2/3)` for the
/// density ρ = count / volume (Poisson approximation). It is the scale against which a
/// particle must explain a point: a particle gains on `y` only where it is closer than
/// that. The filter's rounds need only this; [`OutlierBox`] adds the samples for the
/// chamfer solve.
#[derive(Debug, Clone, Copy)]
pub struct OutlierLevel {
    lo: Point3<f64>,
    hi: Point3<f64>,
    /// Uniform samples of the box for the density.
    count: usize,
    expected: f64,
}

/// Γ(5/3).
const GAMMA_5_3: f64 = 0.902_745_292_950_934;

impl OutlierLevel {
    /// The box `[lo, hi]` (scene units) at the density whose expected squared
    /// nearest-sample distance is `kernel²` (`kernel` in scene units); the sample count
    /// is clamped to `1..=max_samples`, and the expectation follows the clamped count.
    pub fn new(lo: Point3<f64>, hi: Point3<f64>, kernel: f64, max_samples: usize) -> Self {
        let volume = (hi - lo).iter().map(|e| e.max(1e-12)).product::<f64>();
        // E[r²] = Γ(5/3)(4πρ/3)^(−2/3)  ⇔  ρ = (3 / 4π) (Γ(5/3) / E[r²])^(3/2).
        let rho = 3.0 / (4.0 * std::f64::consts::PI) * (GAMMA_5_3 / (kernel * kernel)).powf(1.5);
        let count = ((rho * volume).round() as usize).clamp(1, max_samples.max(1));
        let rho = count as f64 / volume;
        let expected = GAMMA_5_3 * (4.0 * std::f64::consts::PI * rho / 3.0).powf(-2.0 / 3.0);
        OutlierLevel {
            lo,
            hi,
            count,
            expected,
        }
    }

    /// Expected squared nearest-sample distance inside the box (scene units²).
    pub fn expected_distance(&self) -> f64 {
        self.expected
    }

    /// The outlier primitive's "surface distance" to `y` (scene units²): the expected
    /// squared nearest-sample distance plus the squared distance to the box for points
    /// outside it.
    #[inline]
    pub fn cost(&self, y: &Point3<f64>) -> f64 {
        let out = (y.coords - y.coords.sup(&self.lo.coords).inf(&self.hi.coords)).norm_squared();
        self.expected + out
    }
}

/// The explicit outlier primitive of thesis §6.3.3 as a candidate of the chamfer: as
/// many uniform random points of the box as its [`OutlierLevel`]'s density asks for. Its continuous "surface
/// distance" is [`OutlierLevel::cost`].
#[derive(Debug)]
pub struct OutlierBox {
    level: OutlierLevel,
    samples: Vec<Point3<f64>>,
    index: PointIndex,
}

impl OutlierBox {
    /// The samples of `level`, drawn from `rng`.
    pub fn new(level: OutlierLevel, rng: &mut impl Rng) -> Self {
        let (lo, hi) = (level.lo, level.hi);
        let samples: Vec<Point3<f64>> = (0..level.count)
            .map(|_| lo + (hi - lo).map(|e| e * rng.random::<f64>()))
            .collect();
        OutlierBox {
            level,
            index: PointIndex::new(&samples),
            samples,
        }
    }
}

impl CandidateGeometry for OutlierBox {
    fn len(&self) -> usize {
        1
    }
    fn sample_count(&self, _: usize) -> usize {
        self.samples.len()
    }
    fn scene_samples(&self, _: usize, out: &mut Vec<Point3<f64>>) {
        out.clear();
        out.extend_from_slice(&self.samples);
    }
    fn bounding_ball(&self, _: usize) -> (Point3<f64>, f64) {
        let (lo, hi) = (self.level.lo, self.level.hi);
        (nalgebra::center(&lo, &hi), (hi - lo).norm() / 2.0)
    }
    fn nearest_sample(&self, _: usize, y: &Point3<f64>) -> (u32, f64) {
        self.index.nearest(y).unwrap_or((0, f64::INFINITY))
    }
    fn surface_distance(&self, _: usize, y: &Point3<f64>) -> f64 {
        self.level.cost(y)
    }
    fn nearest_samples(
        &self,
        _: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    ) {
        out.clear();
        out.extend(self.index.nearest_n(y, k.unwrap_or(self.samples.len())));
    }
}

/// Two geometries seen as one candidate set: `a`'s candidates first, then `b`'s.
#[derive(Debug)]
pub struct Chain<'a, A, B> {
    /// First part (indices `0..a.len()`).
    pub a: &'a A,
    /// Second part (indices `a.len()..`).
    pub b: &'a B,
}

impl<A: CandidateGeometry, B: CandidateGeometry> Chain<'_, A, B> {
    #[inline]
    fn split(&self, i: usize) -> Result<usize, usize> {
        let n = self.a.len();
        if i < n { Ok(i) } else { Err(i - n) }
    }
}

macro_rules! chained {
    ($self:ident, $i:ident, $f:ident($($arg:expr),*)) => {
        match $self.split($i) {
            Ok(k) => $self.a.$f(k $(, $arg)*),
            Err(k) => $self.b.$f(k $(, $arg)*),
        }
    };
}

impl<A: CandidateGeometry, B: CandidateGeometry> CandidateGeometry for Chain<'_, A, B> {
    fn len(&self) -> usize {
        self.a.len() + self.b.len()
    }
    fn sample_count(&self, i: usize) -> usize {
        chained!(self, i, sample_count())
    }
    fn scene_samples(&self, i: usize, out: &mut Vec<Point3<f64>>) {
        chained!(self, i, scene_samples(out))
    }
    fn bounding_ball(&self, i: usize) -> (Point3<f64>, f64) {
        chained!(self, i, bounding_ball())
    }
    fn nearest_sample(&self, i: usize, y: &Point3<f64>) -> (u32, f64) {
        chained!(self, i, nearest_sample(y))
    }
    fn surface_distance(&self, i: usize, y: &Point3<f64>) -> f64 {
        chained!(self, i, surface_distance(y))
    }
    fn nearest_samples(
        &self,
        i: usize,
        y: &Point3<f64>,
        k: Option<usize>,
        out: &mut Vec<(u32, f64)>,
    ) {
        chained!(self, i, nearest_samples(y, k, out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::asymmetric_object;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// `surely_beyond` never claims a point within `r` of the surface (checked against
    /// the exact distance), and does claim most points well beyond it.
    #[test]
    fn the_grid_proves_only_true_distance_bounds() {
        let mesh = asymmetric_object();
        let (lo, hi) = crate::cloud::bounds_of(&mesh.mesh.vertices).expect("vertices");
        let size = (hi - lo).norm();
        let pad = 0.25 * size;
        let grid = DistanceGrid::new(&mesh, 24, pad);
        let corner = 3f64.sqrt() * grid.cell();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (mut far, mut claimed) = (0, 0);
        for _ in 0..4000 {
            // Points over the grid and a little beyond it.
            let p = lo + (hi - lo + Vector3::repeat(3.0 * pad)).map(|e| e * rng.random::<f64>())
                - Vector3::repeat(1.5 * pad);
            let exact = (mesh.closest_point(&p) - p).norm();
            for r in [0.01 * size, 0.04 * size, 0.1 * size] {
                let beyond = grid.surely_beyond(&p, r);
                assert!(!beyond || exact > r, "{p}: exact {exact}, r {r}");
                if exact > r + 4.0 * corner {
                    far += 1;
                    claimed += beyond as usize;
                }
            }
        }
        assert!(claimed as f64 > 0.9 * far as f64, "{claimed} of {far}");
        // No claim for a radius the exact padding cannot back.
        assert!(!grid.surely_beyond(&(hi + Vector3::repeat(10.0 * size)), pad));
    }
}
