//! The pipe scene (thesis §6.3.1): a random chain of straight runs and right-angle elbows.

use std::f64::consts::FRAC_PI_2;

use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::common::{
    Density, LatticeHint, Misalignment, Noise, Piece, Scene, axis_rotation, elbow_rotation,
    misalign, sample_pieces,
};
use crate::atlas::Shape;
use crate::check::{self, positive};
use crate::cloud::bounds_of;
use crate::{Error, PointCloud, Pose, Primitive, Result};

/// The most straight runs a pipe may have.
const MAX_PIPE_SEGMENTS: usize = 1000;

/// Parameters of [`pipe`]. Lengths in metres (scene units).
///
/// The lattice spacing is `s = segment_length / 2`, origin 0. The chain starts at the
/// origin; straight runs are `k · segment_length` long (k uniform in `1..=max_run`) and
/// tiled by cylinders of length `segment_length`; consecutive runs are joined by an
/// elbow of bend radius `bend` that turns by 90° to a random perpendicular axis.
#[derive(Debug, Clone, PartialEq)]
pub struct PipeParams {
    /// Number of straight runs (≥ 1); there are `segments − 1` elbows.
    pub segments: usize,
    /// Most cylinders in one run (≥ 1).
    pub max_run: usize,
    /// Cylinder length L.
    pub segment_length: f64,
    /// Elbow bend radius B (centre line); a positive multiple of `L/2`. `None` = `L/2`.
    pub bend: Option<f64>,
    /// Tube radius r < B. `None` = `0.1 · L`.
    pub radius: Option<f64>,
    /// How many points.
    pub density: Density,
    /// Per-point jitter and per-primitive drift.
    pub noise: Noise,
    /// Optional rigid misalignment.
    pub misalignment: Misalignment,
    /// RNG seed.
    pub seed: u64,
}

impl Default for PipeParams {
    fn default() -> Self {
        PipeParams {
            segments: 4,
            max_run: 3,
            segment_length: 1.0,
            bend: None,
            radius: None,
            density: Density::PerArea(1000.0),
            noise: Noise {
                jitter: 0.005,
                drift: 0.0,
            },
            misalignment: Misalignment::default(),
            seed: 0,
        }
    }
}

/// A piece of the chain's centre line: a straight run or a quarter arc.
#[derive(Debug, Clone, Copy)]
enum Part {
    /// From `start` along `dir` for `len`.
    Run {
        start: Point3<f64>,
        dir: Vector3<f64>,
        len: f64,
    },
    /// Quarter arc about `centre` from radial `a` to radial `b` (unit vectors), radius `bend`.
    Arc {
        centre: Point3<f64>,
        a: Vector3<f64>,
        b: Vector3<f64>,
        bend: f64,
    },
}

impl Part {
    /// Points along the centre line, at most `h` apart (ends included).
    fn centre_line(&self, h: f64) -> Vec<Point3<f64>> {
        match *self {
            Part::Run { start, dir, len } => {
                let n = ((len / h).ceil() as usize).max(1);
                (0..=n)
                    .map(|i| start + dir * (len * i as f64 / n as f64))
                    .collect()
            }
            Part::Arc { centre, a, b, bend } => {
                let n = ((FRAC_PI_2 * bend / h).ceil() as usize).max(1);
                (0..=n)
                    .map(|i| {
                        let t = FRAC_PI_2 * i as f64 / n as f64;
                        centre + (a * t.cos() + b * t.sin()) * bend
                    })
                    .collect()
            }
        }
    }
}

/// The six signed coordinate axes.
fn axes() -> [Vector3<f64>; 6] {
    [
        Vector3::x(),
        -Vector3::x(),
        Vector3::y(),
        -Vector3::y(),
        Vector3::z(),
        -Vector3::z(),
    ]
}

/// True when some point of `a` is within `limit` of some point of `b`; skips the pair
/// loop when the sets' bounding boxes are already farther apart than `limit`.
fn too_close(a: &[Point3<f64>], b: &[Point3<f64>], limit: f64) -> bool {
    match (bounds_of(a), bounds_of(b)) {
        (Some((alo, ahi)), Some((blo, bhi))) => {
            let gap = (blo - ahi).sup(&(alo - bhi)).sup(&Vector3::zeros());
            gap.norm() <= limit && a.iter().any(|p| b.iter().any(|q| (p - q).norm() <= limit))
        }
        _ => false,
    }
}

/// True when adding `new` (centre-line samples) to the chain keeps it clear of every
/// part at chain distance ≥ 3: centre lines more than `2r + h` apart (`h` = sample step,
/// so the true distance exceeds `2r`). Parts at chain distance 2 (run–elbow–run,
/// elbow–run–elbow) need no test: each elbow lies beyond the end planes of its runs
/// whenever r < B, so their tubes are in disjoint half-spaces.
fn fits(chain: &[Vec<Point3<f64>>], new: &[Point3<f64>], r: f64, h: f64) -> bool {
    let n = chain.len();
    chain[..n.saturating_sub(2)]
        .iter()
        .all(|line| !too_close(line, new, 2.0 * r + h))
}

/// Validated sizes `(L, s, B, r)`.
fn sizes(p: &PipeParams) -> Result<(f64, f64, f64, f64)> {
    let l = p.segment_length;
    positive("segment_length", l)?;
    let s = l / 2.0;
    let b = p.bend.unwrap_or(s);
    let r = p.radius.unwrap_or(0.1 * l);
    positive("bend", b)?;
    positive("radius", r)?;
    check::multiple_of("bend", b, s, "segment_length / 2")?;
    let fits = b.min(s);
    if r >= fits {
        // The tube must fit inside the bend and inside half a segment.
        let expected = format!("smaller than bend and segment_length / 2 (here {fits})");
        return Err(Error::out_of_range("radius", r, expected));
    }
    check::at_least("segments", p.segments, 1)?;
    check::at_most("segments", p.segments, MAX_PIPE_SEGMENTS)?;
    check::at_least("max_run", p.max_run, 1)?;
    Ok((l, s, b, r))
}

/// Tries to grow a whole chain; `None` when it got stuck (the caller retries).
fn try_chain(
    p: &PipeParams,
    rng: &mut ChaCha8Rng,
    l: f64,
    b: f64,
    r: f64,
) -> Option<Vec<Primitive>> {
    let h = r.min(l / 2.0) / 4.0;
    let cyl = Shape::Cylinder {
        length: l,
        radius: r,
    };
    let elbow = Shape::Elbow { bend: b, radius: r };
    let mut parts: Vec<Primitive> = Vec::new();
    let mut lines: Vec<Vec<Point3<f64>>> = Vec::new();
    let mut pos = Point3::origin();
    let mut dir = axes()[rng.random_range(0..6)];
    for seg in 0..p.segments {
        let k = rng.random_range(1..=p.max_run);
        let run = Part::Run {
            start: pos,
            dir,
            len: k as f64 * l,
        };
        let line = run.centre_line(h);
        if !fits(&lines, &line, r, h) {
            return None;
        }
        let axis = dir.iamax();
        for j in 0..k {
            let c = pos + dir * ((j as f64 + 0.5) * l);
            parts.push(Primitive::new(
                cyl.clone(),
                Pose::new(axis_rotation(axis), c.coords),
            ));
        }
        lines.push(line);
        pos += dir * (k as f64 * l);
        if seg + 1 == p.segments {
            break;
        }
        let mut turns: Vec<Vector3<f64>> = axes()
            .into_iter()
            .filter(|a| a.dot(&dir).abs() < 0.5)
            .collect();
        // Random order, first that fits wins.
        for i in (1..turns.len()).rev() {
            turns.swap(i, rng.random_range(0..=i));
        }
        let mut placed = false;
        for out in turns {
            let centre = pos + out * b;
            let arc = Part::Arc {
                centre,
                a: -out,
                b: dir,
                bend: b,
            };
            let line = arc.centre_line(h);
            if fits(&lines, &line, r, h) {
                let rot = elbow_rotation(&dir, &out).ok()?;
                parts.push(Primitive::new(elbow.clone(), Pose::new(rot, centre.coords)));
                lines.push(line);
                pos = centre + dir * b;
                dir = out;
                placed = true;
                break;
            }
        }
        if !placed {
            return None;
        }
    }
    Some(parts)
}

/// A random pipe on the lattice of spacing `L/2`: its truth is the cylinders (length L,
/// centres on the lattice) and elbows (torus centres on the lattice) that tile it.
/// Never self-intersecting: parts that are not neighbours in the chain keep their centre
/// lines more than `2r` apart.
pub fn pipe(params: &PipeParams) -> Result<Scene> {
    let (l, s, b, r) = sizes(params)?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut chain = None;
    for _ in 0..1000 {
        chain = try_chain(params, &mut rng, l, b, r);
        if chain.is_some() {
            break;
        }
    }
    let chain = chain.ok_or_else(|| {
        Error::invalid(format!(
            "could not grow a non-intersecting pipe of {} segments in 1000 tries",
            params.segments
        ))
    })?;
    let mut truth = chain;
    let pieces: Vec<Piece> = truth.iter().cloned().map(Piece::Prim).collect();
    let mut points = sample_pieces(&pieces, params.density, params.noise, &mut rng)?;
    let misalignment = misalign(&params.misalignment, &mut rng, s, &mut points, &mut truth)?;
    let mut shapes = vec![Shape::Cylinder {
        length: l,
        radius: r,
    }];
    if params.segments > 1 {
        shapes.push(Shape::Elbow { bend: b, radius: r });
    }
    Ok(Scene {
        cloud: PointCloud::from_points(points),
        truth,
        lattice: LatticeHint {
            spacing: s,
            origin: Point3::origin(),
            shapes,
        },
        misalignment,
    })
}
