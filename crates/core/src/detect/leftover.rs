//! Curved surfaces too thin for region growing, found among the points no segment took
//! (unassigned, or in clutter).
//!
//! Region growing joins neighbours whose normals agree within the growing angle. On a
//! tube whose radius `r` is not much larger than the normal neighbourhood's radius `R`,
//! neighbouring normals differ by about `s / r` (`s` the spacing: 22° for a 5 cm pipe at
//! 1.9 cm spacing, where `R` ≈ 7 cm), so the tube breaks into fragments smaller than a
//! segment and its points end unassigned. Those neighbourhoods still see the tube's
//! cross-section, so their normals lie roughly across its axis, which is all the
//! cylinder fit's initial axis needs ([`super::cylinder`]).
//!
//! 0. A plane segment that is a strip narrower than a neighbourhood and that its plane
//!    does not explain at full resolution is classified again from its own points: on a
//!    subsampled cloud, a tube only a couple of samples wide looks like a noisy strip to
//!    neighbourhoods wider than itself, and its samples pass as a plane through its axis.
//! 1. The unassigned and clutter points are cut into connected pieces: points closer
//!    than [`LINK_SPACINGS`] spacings are linked.
//! 2. Each piece of at least the smallest segment is classified as a whole
//!    ([`super::classify`], normals from the piece's own neighbourhoods, the curved
//!    models always tried), at the detection's model σ or the piece's median
//!    neighbourhood residual where that is larger.
//! 3. A piece a cylinder or a sphere explains becomes a segment. A piece only a plane
//!    explains does not: a planar leftover is a crease band or a fragment beside a
//!    plane that already explains it. A piece no one model explains (a thin pipe with
//!    its bend or a tee) is split as a grown region is ([`super::split`]) on its own
//!    points, and the cylinders and spheres among its parts become segments.
//! 4. The curved segments, old and new, are merged by the rule of [`super::merge`]:
//!    a tube cut into pieces (where a few of its points joined no piece) is one.
//!
//! Pieces are found in ascending point order and classified independently, so the
//! result does not depend on the thread count.

use nalgebra::Point3;
use rayon::prelude::*;

use super::classify::{Oriented, classify, spreads};
use super::merge::{Part, merge_parts};
use super::noise::quadric_residuals;
use super::normals::{FlatnessOrder, Neighbourhoods, median};
use super::plane::Moments;
use super::split::Splitter;
use super::{Detection, Segment, SurfaceModel};
use crate::schedule::map_largest_first;
use crate::spatial::PointIndex;

/// Unassigned points closer than this many point spacings belong to one piece: about
/// the distance to the farthest of the nearest few neighbours of a random sampling.
pub const LINK_SPACINGS: f64 = 2.5;

/// Points whose links are searched at once: the links of a chunk are held together
/// (about 10 per point on a surface), not those of every leftover point of a large scan.
const LINK_CHUNK: usize = 1 << 16;

/// Disjoint sets over `0..n` whose root is their lowest member (path halving).
struct Forest {
    parent: Vec<usize>,
}

impl Forest {
    fn new(n: usize) -> Self {
        Forest {
            parent: (0..n).collect(),
        }
    }

    /// The lowest member of the set of `i`.
    fn root(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    /// Joins the sets of `a` and `b`.
    fn join(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.root(a), self.root(b));
        self.parent[ra.max(rb)] = ra.min(rb);
    }
}

/// What a leftover piece is judged by.
#[derive(Debug, Clone, Copy)]
pub(super) struct Leftovers {
    /// The median point spacing (scene units).
    pub spacing: f64,
    /// Neighbours per normal.
    pub k: usize,
    /// The detection's model σ (scene units).
    pub sigma: f64,
    /// Model tolerance `t`, in σ.
    pub tolerance: f64,
    /// Whether spheres are tried.
    pub spheres: bool,
    /// Smallest piece, in points.
    pub min_points: usize,
    /// Cosine of the largest angle between the axes of merged cylinders; also the
    /// growing angle a split piece's parts are judged by.
    pub cos_angle: f64,
    /// The detection's median neighbourhood radius (scene units): a segment narrower
    /// than this was classified from neighbourhoods wider than itself.
    pub reach: f64,
    /// Neighbours that connect points when a piece is split (the growing neighbourhood).
    pub neighbours: usize,
}

impl Leftovers {
    /// Moves the pieces of `detection`'s unassigned and clutter points that a cylinder or
    /// sphere explains into new segments (module docs), keeping the segments and the
    /// clutter lists largest first.
    pub fn absorb(&self, points: &[Point3<f64>], detection: &mut Detection) {
        let reclassified = self.reclassify_strips(points, &mut detection.segments);
        let mut left: Vec<usize> = detection
            .unassigned
            .iter()
            .chain(detection.clutter.iter().flatten())
            .copied()
            .collect();
        left.sort_unstable();
        let mut pieces = self.pieces(points, &left);
        pieces.retain(|ids| ids.len() >= self.min_points);
        let found: Vec<Segment> =
            map_largest_first(pieces, Vec::len, |ids| self.curved(points, ids, true))
                .into_iter()
                .flatten()
                .collect();
        if found.is_empty() && reclassified == 0 {
            return;
        }
        let mut taken = vec![false; points.len()];
        for s in &found {
            for &i in &s.points {
                taken[i] = true;
            }
        }
        detection.unassigned.retain(|&i| !taken[i]);
        for c in &mut detection.clutter {
            c.retain(|&i| !taken[i]);
        }
        detection.clutter.retain(|c| !c.is_empty());
        detection
            .clutter
            .sort_by(|a, b| b.len().cmp(&a.len()).then(a.first().cmp(&b.first())));
        // Pieces of one tube (cut where a few of its points joined no piece) and the
        // curved segments growing found become one by the merge rule.
        let (curved, planes): (Vec<Segment>, Vec<Segment>) =
            std::mem::take(&mut detection.segments)
                .into_iter()
                .chain(found)
                .partition(|s| !matches!(s.model, SurfaceModel::Plane { .. }));
        let parts: Vec<Part> = curved
            .into_iter()
            .map(|s| Part {
                moments: Moments::of(points, &s.points),
                sigma: self.sigma.max(s.rms),
                model: Some(s.model),
                rms: s.rms,
                ids: s.points,
            })
            .collect();
        let merged = merge_parts(parts, points, self.cos_angle, self.tolerance);
        detection.segments = planes;
        detection
            .segments
            .extend(merged.into_iter().filter_map(|p| {
                Some(Segment {
                    model: p.model?,
                    rms: p.rms,
                    points: p.ids,
                })
            }));
        detection.segments.sort_by(|a, b| {
            b.points
                .len()
                .cmp(&a.points.len())
                .then(a.points.first().cmp(&b.points.first()))
        });
    }

    /// Re-classifies, from their own points, the plane segments that are strips
    /// narrower than a neighbourhood ([`Self::reach`]) and that their plane does not
    /// explain at full resolution (RMS above `t σ`): a tube thinner than the
    /// subsampled neighbourhoods is seen by them as a noisy strip, and its sample
    /// segment passes as a plane through its axis. Its own points, at the input's
    /// spacing, show the tube. Returns how many became curved.
    fn reclassify_strips(&self, points: &[Point3<f64>], segments: &mut [Segment]) -> usize {
        let limit = self.tolerance * self.sigma;
        let strips: Vec<usize> = (0..segments.len())
            .into_par_iter()
            .filter(|&k| {
                let s = &segments[k];
                matches!(s.model, SurfaceModel::Plane { .. })
                    && s.rms > limit
                    && s.points.len() >= self.min_points
                    && spreads(&s.points.iter().map(|&i| points[i]).collect::<Vec<_>>())[1]
                        < self.reach
            })
            .collect();
        let curved: Vec<(usize, Segment)> = strips
            .into_par_iter()
            .filter_map(|k| {
                // A strip is one tube or nothing: it replaces its plane segment whole.
                let found = self.curved(points, segments[k].points.clone(), false);
                Some((k, found.into_iter().next()?))
            })
            .collect();
        let n = curved.len();
        for (k, segment) in curved {
            segments[k] = segment;
        }
        n
    }

    /// The connected pieces of `ids` (ascending), each ascending, in order of their
    /// lowest point. Each point's links are searched in parallel, a chunk of
    /// [`LINK_CHUNK`] points at a time, and joined in order.
    fn pieces(&self, points: &[Point3<f64>], ids: &[usize]) -> Vec<Vec<usize>> {
        let pts: Vec<Point3<f64>> = ids.iter().map(|&i| points[i]).collect();
        let index = PointIndex::new(&pts);
        let link = LINK_SPACINGS * self.spacing;
        let mut forest = Forest::new(pts.len());
        for start in (0..pts.len()).step_by(LINK_CHUNK) {
            let end = (start + LINK_CHUNK).min(pts.len());
            let links: Vec<Vec<u32>> = (start..end)
                .into_par_iter()
                .map(|k| {
                    let later = |&(j, _): &(u32, f64)| j as usize > k;
                    let within = index.within(&pts[k], link * link);
                    within.into_iter().filter(later).map(|(j, _)| j).collect()
                })
                .collect();
            for (k, js) in (start..end).zip(links) {
                for j in js {
                    forest.join(k, j as usize);
                }
            }
        }
        let mut piece_of = vec![usize::MAX; pts.len()];
        let mut pieces: Vec<Vec<usize>> = Vec::new();
        for (k, &id) in ids.iter().enumerate() {
            let root = forest.root(k);
            if piece_of[root] == usize::MAX {
                piece_of[root] = pieces.len();
                pieces.push(Vec::new());
            }
            pieces[piece_of[root]].push(id);
        }
        pieces
    }

    /// The curved segments of the piece `ids`: the whole piece if a cylinder or sphere
    /// explains it; none if a plane does; else, with `split`, the cylinders and spheres
    /// of its split ([`Self::split_curved`]).
    fn curved(&self, points: &[Point3<f64>], ids: Vec<usize>, split: bool) -> Vec<Segment> {
        let pts: Vec<Point3<f64>> = ids.iter().map(|&i| points[i]).collect();
        let index = PointIndex::new(&pts);
        let nb = Neighbourhoods::new(&pts, &index, self.k);
        let own: Vec<usize> = (0..pts.len()).collect();
        let residual = median(&mut nb.residual.clone()).unwrap_or(0.0);
        let sigma = self.sigma.max(residual);
        // A fine σ of 0: the curved models are always tried.
        let cos_angle = vec![self.cos_angle; pts.len()];
        let surface = Oriented {
            points: &pts,
            normals: &nb.normals,
            cos_angle: &cos_angle,
        };
        let c = classify(surface, &own, (sigma, 0.0), self.tolerance, self.spheres);
        match c.model {
            Some(SurfaceModel::Plane { .. }) => Vec::new(),
            Some(model) => vec![Segment {
                points: ids,
                model,
                rms: c.rms,
            }],
            None if split => self.split_curved(surface, &nb, sigma, own, &ids),
            None => Vec::new(),
        }
    }

    /// The cylinders and spheres among the parts of a piece no one model explains (a
    /// thin pipe with its bends or a tee, fragmented by growing): the piece's own points
    /// `pts` (`ids` in the cloud) split as grown regions are ([`Splitter`]), at `sigma`.
    fn split_curved(
        &self,
        surface: Oriented,
        nb: &Neighbourhoods,
        sigma: f64,
        own: Vec<usize>,
        ids: &[usize],
    ) -> Vec<Segment> {
        let (pts, n) = (surface.points, surface.points.len());
        let splitter = Splitter {
            samples: pts,
            nb,
            flatness: &FlatnessOrder::new(nb),
            model_sigma: &vec![sigma; n],
            tolerance: self.tolerance,
            spheres: self.spheres,
            min_points: self.min_points,
            neighbours: self.neighbours,
            quadric: &quadric_residuals(pts, nb),
            cos_angle: surface.cos_angle,
        };
        (splitter.parts(own).into_iter())
            .filter_map(|part| match part.model? {
                SurfaceModel::Plane { .. } => None,
                model => Some(Segment {
                    points: part.ids.iter().map(|&k| ids[k]).collect(),
                    model,
                    rms: part.rms,
                }),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::TAU;

    use nalgebra::Vector3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    use super::super::{DetectOptions, detect};
    use super::*;

    #[test]
    fn pieces_are_the_connected_components_of_the_link_graph() {
        // 400 points in a 1 m cube at link distance 2.5 × 0.05 m: many pieces of all
        // sizes, against components found by brute force over all pairs.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let points: Vec<Point3<f64>> = (0..400)
            .map(|_| Point3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let ids: Vec<usize> = (0..400).filter(|i| i % 7 != 3).collect();
        let judge = Leftovers {
            spacing: 0.05,
            k: 8,
            sigma: 0.01,
            tolerance: 2.5,
            spheres: false,
            min_points: 3,
            cos_angle: 0.9,
            reach: 0.1,
            neighbours: 6,
        };
        let link2 = (LINK_SPACINGS * judge.spacing).powi(2);
        let mut brute: Vec<Vec<usize>> = Vec::new();
        let mut seen = vec![false; points.len()];
        for &start in &ids {
            if seen[start] {
                continue;
            }
            seen[start] = true;
            let (mut piece, mut stack) = (Vec::new(), vec![start]);
            while let Some(i) = stack.pop() {
                piece.push(i);
                for &j in &ids {
                    if !seen[j] && (points[i] - points[j]).norm_squared() <= link2 {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
            piece.sort_unstable();
            brute.push(piece);
        }
        assert!(brute.len() > 10 && brute.iter().any(|p| p.len() > 10));
        assert_eq!(judge.pieces(&points, &ids), brute);
    }

    #[test]
    fn a_pipe_thinner_than_a_neighbourhood_is_found_beside_its_floor() {
        // A floor of 1000 points/m² (spacing ≈ 1.6 cm) and a pipe of radius 5 cm lying
        // 10 cm above it along x at the same density, σ = 5 mm: 16-point neighbourhoods
        // (R ≈ 7 cm) wrap most of the pipe's half-circumference.
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let gauss = |rng: &mut ChaCha8Rng| 0.005 * rng.sample::<f64, _>(StandardNormal);
        let mut points = Vec::new();
        for _ in 0..8000 {
            let (x, y) = (rng.random::<f64>() * 4.0, rng.random::<f64>() * 2.0);
            points.push(Point3::new(x, y, gauss(&mut rng)));
        }
        let (r, centre) = (0.05, Vector3::new(0.0, 1.0, 0.15));
        let on_pipe = (TAU * r * 3.0 * 1000.0) as usize;
        for _ in 0..on_pipe {
            let (t, x) = (rng.random::<f64>() * TAU, 0.5 + rng.random::<f64>() * 3.0);
            let radial = Vector3::new(0.0, t.cos(), t.sin());
            points.push(Point3::from(
                centre + Vector3::x() * x + radial * (r + gauss(&mut rng)),
            ));
        }
        let index = PointIndex::new(&points);
        let d = detect(&points, &index, &DetectOptions::default()).unwrap();
        let pipes: Vec<&Segment> = d
            .segments
            .iter()
            .filter(|s| s.model.name() == "cylinder")
            .collect();
        assert_eq!(
            pipes.len(),
            1,
            "{:?}",
            d.segments
                .iter()
                .map(|s| (s.points.len(), s.model))
                .collect::<Vec<_>>()
        );
        let SurfaceModel::Cylinder { axis, radius, .. } = pipes[0].model else {
            unreachable!()
        };
        assert!((radius - r).abs() < 0.05 * r, "r = {radius}");
        assert!(axis.x.abs() > 3f64.to_radians().cos(), "{axis}");
        let on = pipes[0].points.iter().filter(|&&i| i >= 8000).count();
        assert!(on as f64 > 0.8 * on_pipe as f64, "{on} of {on_pipe}");
        assert!(on as f64 > 0.98 * pipes[0].points.len() as f64);
    }

    #[test]
    fn a_piece_no_one_cylinder_explains_is_split_into_its_runs() {
        // What growing leaves of a thin pipe with a bend (seen on a subsampled room):
        // one connected piece of unassigned points, 2 m along x, a quarter torus of
        // bend radius 20 cm, 1.2 m along y; tube radius 5 cm, 4000 points/m², σ = 5 mm.
        // No one cylinder explains the piece; its split finds both runs.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (r, bend, per_m2) = (0.05, 0.2, 4000.0);
        let per_metre = TAU * r * per_m2;
        let mut points = Vec::new();
        let mut tube = |rng: &mut ChaCha8Rng, centre: Vector3<f64>, radial: Vector3<f64>| {
            let t = rng.random::<f64>() * TAU;
            let noise = 0.005 * rng.sample::<f64, _>(StandardNormal);
            let dir = radial * t.cos() + Vector3::z() * t.sin();
            points.push(Point3::from(centre + dir * (r + noise)));
        };
        for _ in 0..(2.0 * per_metre) as usize {
            let x = rng.random::<f64>() * 2.0;
            tube(&mut rng, Vector3::new(x, 0.0, 0.0), Vector3::y());
        }
        for _ in 0..(bend * TAU / 4.0 * per_metre) as usize {
            let a = rng.random::<f64>() * TAU / 4.0;
            let out = Vector3::new(a.sin(), -a.cos(), 0.0);
            tube(&mut rng, Vector3::new(2.0, bend, 0.0) + out * bend, out);
        }
        for _ in 0..(1.2 * per_metre) as usize {
            let y = bend + rng.random::<f64>() * 1.2;
            tube(&mut rng, Vector3::new(2.0 + bend, y, 0.0), Vector3::x());
        }
        let index = PointIndex::new(&points);
        // The room's spacing, set by its sparser walls: the piece is linked whole.
        let spacing = 2.0 * index.median_spacing(&points, points.len()).unwrap();
        // The detection's defaults, at the smallest growing angle (the room's).
        let k = super::super::DEFAULT_NEIGHBOURS;
        let judge = Leftovers {
            spacing,
            k,
            sigma: 0.005,
            tolerance: super::super::DEFAULT_TOLERANCE,
            spheres: false,
            min_points: super::super::MIN_SEGMENT_NEIGHBOURHOODS * k,
            cos_angle: super::super::MIN_ANGLE_DEG.to_radians().cos(),
            reach: 0.05,
            neighbours: super::super::DEFAULT_GROW_NEIGHBOURS,
        };
        assert_eq!(
            judge
                .pieces(&points, &(0..points.len()).collect::<Vec<_>>())
                .len(),
            1
        );
        let mut d = Detection::nothing(points.len(), 0.005);
        judge.absorb(&points, &mut d);
        let runs: Vec<(Vector3<f64>, f64, usize)> = (d.segments.iter())
            .filter_map(|s| match s.model {
                SurfaceModel::Cylinder { axis, radius, .. } => Some((axis, radius, s.points.len())),
                _ => None,
            })
            .collect();
        let along = |v: Vector3<f64>, length: f64| {
            (runs.iter()).any(|&(axis, radius, n)| {
                axis.dot(&v).abs() > 2f64.to_radians().cos()
                    && (radius - r).abs() < 0.05 * r
                    && n as f64 > 0.8 * length * per_metre
            })
        };
        assert!(
            along(Vector3::x(), 2.0) && along(Vector3::y(), 1.2),
            "{runs:?}"
        );
    }
}
