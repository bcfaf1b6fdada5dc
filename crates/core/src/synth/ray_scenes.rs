//! Ray-cast test scenes for free space (rays through empty space): an open-top room, a
//! corridor with a doorway into a second room, and a box in front of a wall. Each is a
//! set of axis-aligned rectangles whose edges lie on the 0.5 m lattice through the origin
//! (the thesis's 1 m squares on a 0.5 m lattice fit them exactly), scanned by
//! [`depth_sensor`] from a few poses with 1 cm range noise. Lengths in metres.

use nalgebra::{Point3, Vector3};

use super::depth::{SensorParams, depth_sensor, look_at};
use super::room::face;
use crate::{Error, PointCloud, Primitive, Result};

/// σ of the range noise of every scene (m).
pub const RAY_SCENE_RANGE_NOISE: f64 = 0.01;

/// A ray-cast scene: the cloud (with sensor origins and normals) and its true surfaces.
#[derive(Debug, Clone)]
pub struct RayScene {
    /// The scene's name (`room`, `corridor`, `object`).
    pub name: &'static str,
    /// The scan.
    pub cloud: PointCloud,
    /// The true surfaces (bounded planes).
    pub truth: Vec<Primitive>,
}

/// The names [`ray_scene`] knows.
pub const RAY_SCENES: [&str; 3] = ["room", "corridor", "object"];

/// The scene `name` ([`RAY_SCENES`]) scanned at `columns × rows` pixels per frame, noise
/// drawn from `seed`.
pub fn ray_scene(name: &str, columns: usize, rows: usize, seed: u64) -> Result<RayScene> {
    let (name, truth, eyes) = match name {
        "room" => ("room", open_room()?, room_eyes()),
        "corridor" => ("corridor", corridor()?, corridor_eyes()),
        "object" => ("object", object_before_wall()?, object_eyes()),
        other => {
            return Err(Error::Unknown {
                what: "ray-cast scene",
                value: other.into(),
                expected: "room, corridor or object",
            });
        }
    };
    let poses = eyes
        .iter()
        .map(|(eye, target)| look_at(Point3::from(*eye), Point3::from(*target)))
        .collect::<Result<Vec<_>>>()?;
    let cloud = depth_sensor(
        &truth,
        &SensorParams {
            poses,
            h_fov: 80f64.to_radians(),
            v_fov: 60f64.to_radians(),
            columns,
            rows,
            max_range: 20.0,
            range_noise: RAY_SCENE_RANGE_NOISE,
            seed,
            ..Default::default()
        },
    )?;
    Ok(RayScene { name, cloud, truth })
}

/// The rectangle `lo..hi` (one coordinate equal: the plane `axis = lo[axis]`), facing +axis.
fn rect(axis: usize, lo: [f64; 3], hi: [f64; 3]) -> Result<Primitive> {
    face(
        axis,
        1.0,
        lo[axis],
        &Vector3::from(lo),
        &Vector3::from(hi),
        &[],
    )
}

/// A 4 × 3 m room, walls 2 m high, no ceiling.
fn open_room() -> Result<Vec<Primitive>> {
    Ok(vec![
        rect(2, [0.0, 0.0, 0.0], [4.0, 3.0, 0.0])?,
        rect(0, [0.0, 0.0, 0.0], [0.0, 3.0, 2.0])?,
        rect(0, [4.0, 0.0, 0.0], [4.0, 3.0, 2.0])?,
        rect(1, [0.0, 0.0, 0.0], [4.0, 0.0, 2.0])?,
        rect(1, [0.0, 3.0, 0.0], [4.0, 3.0, 2.0])?,
    ])
}

/// Six poses in the middle of the room, 1.5 m up, looking at the walls and corners.
fn room_eyes() -> Vec<([f64; 3], [f64; 3])> {
    vec![
        ([2.0, 1.5, 1.5], [4.0, 1.5, 0.6]),
        ([2.0, 1.5, 1.5], [0.0, 1.5, 0.6]),
        ([2.0, 1.2, 1.5], [2.0, 3.0, 0.6]),
        ([2.0, 1.8, 1.5], [2.0, 0.0, 0.6]),
        ([1.5, 1.0, 1.5], [4.0, 3.0, 0.6]),
        ([2.5, 2.0, 1.5], [0.0, 0.0, 0.6]),
    ]
}

/// A corridor 6 m long (x), 2 m wide (y ∈ [0, 2]), walls 2 m high, no ceiling; a doorway
/// 1 × 1.5 m in the wall y = 2 at x ∈ [2.5, 3.5] opens into a room reaching y = 4.
fn corridor() -> Result<Vec<Primitive>> {
    Ok(vec![
        rect(2, [0.0, 0.0, 0.0], [6.0, 2.0, 0.0])?,
        rect(1, [0.0, 0.0, 0.0], [6.0, 0.0, 2.0])?,
        rect(1, [0.0, 2.0, 0.0], [2.5, 2.0, 2.0])?,
        rect(1, [3.5, 2.0, 0.0], [6.0, 2.0, 2.0])?,
        rect(1, [2.5, 2.0, 1.5], [3.5, 2.0, 2.0])?,
        // The room behind the doorway: floor and back wall.
        rect(2, [1.5, 2.0, 0.0], [4.5, 4.0, 0.0])?,
        rect(1, [1.5, 4.0, 0.0], [4.5, 4.0, 2.0])?,
    ])
}

/// Four poses in the corridor looking at the doorway and along the corridor.
fn corridor_eyes() -> Vec<([f64; 3], [f64; 3])> {
    vec![
        ([3.0, 0.3, 1.4], [3.0, 4.0, 0.6]),
        ([1.5, 0.5, 1.4], [3.5, 2.0, 0.7]),
        ([4.5, 0.5, 1.4], [2.5, 2.0, 0.7]),
        ([0.5, 1.0, 1.4], [6.0, 1.0, 0.5]),
    ]
}

/// A wall (x = 4, y ∈ [−2, 2], 2.5 m high) and its floor, with a 1 × 1 × 1 m box at
/// x ∈ [2, 3], y ∈ [−0.5, 0.5] in front of it (its front, top and two sides).
fn object_before_wall() -> Result<Vec<Primitive>> {
    Ok(vec![
        rect(2, [0.0, -2.0, 0.0], [4.0, 2.0, 0.0])?,
        rect(0, [4.0, -2.0, 0.0], [4.0, 2.0, 2.5])?,
        rect(0, [2.0, -0.5, 0.0], [2.0, 0.5, 1.0])?,
        rect(2, [2.0, -0.5, 1.0], [3.0, 0.5, 1.0])?,
        rect(1, [2.0, -0.5, 0.0], [3.0, -0.5, 1.0])?,
        rect(1, [2.0, 0.5, 0.0], [3.0, 0.5, 1.0])?,
    ])
}

/// Four poses in front of the box, 1.4 m up, looking at it and past it.
fn object_eyes() -> Vec<([f64; 3], [f64; 3])> {
    vec![
        ([0.0, 0.0, 1.4], [4.0, 0.0, 0.5]),
        ([0.0, -1.5, 1.4], [3.0, 0.5, 0.5]),
        ([0.0, 1.5, 1.4], [3.0, -0.5, 0.5]),
        ([0.5, 0.0, 2.0], [3.0, 0.0, 0.0]),
    ]
}
