//! Survey-sized scenes for tiled fitting ([`crate::tiles`]): a multi-room floor with a
//! pipe run crossing it, and a street block of facades and poles. Surfaces are axis
//! aligned; points are drawn area-uniformly at random with Gaussian jitter; the truth is
//! one bounded plane per floor, wall, ground or facade and one cylinder per pipe or pole.

use nalgebra::{Point2, Point3, UnitQuaternion, Vector3};
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::common::{axis_rotation, check_scene_points, gauss};
use crate::atlas::{PlaneShape, Shape};
use crate::{PointCloud, Pose, Primitive, Result, check};

/// Wall and facade height of the floor scene (metres).
const FLOOR_HEIGHT: f64 = 3.0;
/// Radius of the floor scene's pipe (metres) and its height under the ceiling line.
const PIPE_RADIUS: f64 = 0.08;
/// Height of the pipe's axis above the floor (metres).
const PIPE_HEIGHT: f64 = 2.6;
/// Facade height of the street block (metres).
const FACADE_HEIGHT: f64 = 12.0;
/// Street width between building blocks (metres).
const STREET_WIDTH: f64 = 10.0;
/// Pole radius and height of the street block (metres).
const POLE: (f64, f64) = (0.12, 6.0);
/// Distance between poles along a street (metres).
const POLE_STEP: f64 = 25.0;

/// Which survey [`survey`] draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SurveyKind {
    /// Floor slab, walls on a grid of rooms (`cell` metres square, 3 m high), one pipe
    /// along x through the middle of the first row of rooms, 2.6 m up.
    Floor,
    /// Ground, square building blocks (`cell` metres, streets of 10 m between them) with
    /// 12 m facades, and poles every 25 m along the streets.
    Street,
}

/// Parameters of [`survey`]; lengths in metres.
#[derive(Debug, Clone)]
pub struct SurveyParams {
    /// The kind of scene.
    pub kind: SurveyKind,
    /// Extent along x and y (metres).
    pub extent: [f64; 2],
    /// Room side (floor) or block side (street), metres.
    pub cell: f64,
    /// Points in total.
    pub points: usize,
    /// Gaussian jitter σ of every point (metres).
    pub jitter: f64,
    /// Seed of every random draw.
    pub seed: u64,
}

impl Default for SurveyParams {
    fn default() -> Self {
        SurveyParams {
            kind: SurveyKind::Floor,
            extent: [40.0, 20.0],
            cell: 5.0,
            points: 200_000,
            jitter: 0.003,
            seed: 1,
        }
    }
}

/// A survey scene: its points and its true primitives (scene frame, metres).
#[derive(Debug, Clone)]
pub struct SurveyScene {
    /// The sampled points.
    pub cloud: PointCloud,
    /// The true primitives.
    pub truth: Vec<Primitive>,
}

/// A rectangle `[0, a] × [0, b]` in a plane's local frame, placed with rotation `r` and
/// its local origin at `corner`.
fn rect(corner: Point3<f64>, r: UnitQuaternion<f64>, a: f64, b: f64) -> Result<Primitive> {
    let outline = vec![
        Point2::new(0.0, 0.0),
        Point2::new(a, 0.0),
        Point2::new(a, b),
        Point2::new(0.0, b),
    ];
    let shape = PlaneShape::new(outline, Vec::new())?;
    Ok(Primitive::new(
        Shape::Plane(shape),
        Pose::new(r, corner.coords),
    ))
}

/// A vertical wall from `(x0, y0)` along the unit axis `along` (0 = x, 1 = y) over
/// `length`, from z = 0 to `height`.
fn wall(x0: f64, y0: f64, along: usize, length: f64, height: f64) -> Result<Primitive> {
    // Local x along the wall, local y up, normal horizontal.
    let u = Vector3::ith(along, 1.0);
    let n = u.cross(&Vector3::z());
    let m = nalgebra::Matrix3::from_columns(&[u, Vector3::z(), n]);
    let r = UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(m));
    rect(Point3::new(x0, y0, 0.0), r, length, height)
}

/// A cylinder of `radius` with axis along coordinate `axis` from `start` over `length`.
fn tube(start: Point3<f64>, axis: usize, length: f64, radius: f64) -> Primitive {
    let centre = start + Vector3::ith(axis, 0.5 * length);
    Primitive::new(
        Shape::Cylinder { length, radius },
        Pose::new(axis_rotation(axis), centre.coords),
    )
}

/// The true primitives of the scene of `p`.
fn truth(p: &SurveyParams) -> Result<Vec<Primitive>> {
    let [x, y] = p.extent;
    let ground = rect(Point3::origin(), UnitQuaternion::identity(), x, y)?;
    let mut out = vec![ground];
    match p.kind {
        SurveyKind::Floor => {
            let lines =
                |span: f64| (0..=(span / p.cell).round() as usize).map(|k| k as f64 * p.cell);
            for wx in lines(x).filter(|v| *v <= x) {
                out.push(wall(wx, 0.0, 1, y, FLOOR_HEIGHT)?);
            }
            for wy in lines(y).filter(|v| *v <= y) {
                out.push(wall(0.0, wy, 0, x, FLOOR_HEIGHT)?);
            }
            let pipe_y = (0.5 * p.cell).min(0.5 * y);
            out.push(tube(
                Point3::new(0.0, pipe_y, PIPE_HEIGHT),
                0,
                x,
                PIPE_RADIUS,
            ));
        }
        SurveyKind::Street => {
            let pitch = p.cell + STREET_WIDTH;
            let (nx, ny) = ((x / pitch).floor() as usize, (y / pitch).floor() as usize);
            for i in 0..nx {
                for j in 0..ny {
                    let (x0, y0) = (
                        i as f64 * pitch + 0.5 * STREET_WIDTH,
                        j as f64 * pitch + 0.5 * STREET_WIDTH,
                    );
                    let c = p.cell;
                    out.push(wall(x0, y0, 0, c, FACADE_HEIGHT)?);
                    out.push(wall(x0, y0 + c, 0, c, FACADE_HEIGHT)?);
                    out.push(wall(x0, y0, 1, c, FACADE_HEIGHT)?);
                    out.push(wall(x0 + c, y0, 1, c, FACADE_HEIGHT)?);
                }
            }
            let (r, h) = POLE;
            for j in 0..=ny {
                let py = j as f64 * pitch + 1.5;
                for k in 0..(x / POLE_STEP).floor() as usize {
                    let px = 5.0 + k as f64 * POLE_STEP;
                    if py < y {
                        out.push(tube(Point3::new(px, py, 0.0), 2, h, r));
                    }
                }
            }
        }
    }
    Ok(out)
}

/// A survey scene of `params`: the truth's surfaces sampled with `params.points` points
/// in total, each primitive's share proportional to its area.
pub fn survey(params: &SurveyParams) -> Result<SurveyScene> {
    check::positive("cell", params.cell)?;
    check::positive("extent x", params.extent[0])?;
    check::positive("extent y", params.extent[1])?;
    check::non_negative("jitter", params.jitter)?;
    check_scene_points("survey", params.points as f64, "fewer points")?;
    let truth = truth(params)?;
    let total: f64 = truth.iter().map(Primitive::area).sum();
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut points = Vec::with_capacity(params.points);
    for prim in &truth {
        let n = (params.points as f64 * prim.area() / total).round() as usize;
        for _ in 0..n {
            let local = sample_local(&prim.shape, &mut rng);
            let jitter = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng));
            points.push(prim.pose.to_scene(&local) + jitter * params.jitter);
        }
    }
    Ok(SurveyScene {
        cloud: PointCloud::from_points(points),
        truth,
    })
}

/// An area-uniform local point of a rectangle plane `[0, a] × [0, b]` or a cylinder.
fn sample_local<R: Rng>(shape: &Shape, rng: &mut R) -> Point3<f64> {
    match shape {
        Shape::Cylinder { length, radius } => {
            let t = rng.random::<f64>() * std::f64::consts::TAU;
            let z = (rng.random::<f64>() - 0.5) * length;
            Point3::new(radius * t.cos(), radius * t.sin(), z)
        }
        Shape::Plane(p) => {
            let o = p.outline();
            let (a, b) = (o[2].x, o[2].y);
            Point3::new(rng.random::<f64>() * a, rng.random::<f64>() * b, 0.0)
        }
        _ => Point3::origin(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_has_walls_a_pipe_and_the_requested_points() {
        let s = survey(&SurveyParams {
            points: 10_000,
            ..Default::default()
        })
        .unwrap();
        // Floor + 9 walls across x + 5 along x + one pipe.
        assert_eq!(s.truth.len(), 1 + 9 + 5 + 1);
        assert!((s.cloud.len() as i64 - 10_000).abs() < 20);
        let (lo, hi) = s.cloud.bounds().unwrap();
        assert!(lo.x > -0.1 && hi.x < 40.1 && hi.z < 3.1);
    }

    #[test]
    fn street_has_facades_and_poles() {
        let s = survey(&SurveyParams {
            kind: SurveyKind::Street,
            extent: [100.0, 100.0],
            cell: 40.0,
            points: 5_000,
            ..Default::default()
        })
        .unwrap();
        let poles = s
            .truth
            .iter()
            .filter(|p| matches!(p.shape, Shape::Cylinder { .. }))
            .count();
        assert_eq!(s.truth.len() - poles, 1 + 4 * 4);
        assert!(poles >= 8);
    }
}
