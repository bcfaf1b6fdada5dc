//! The synthetic rooms issue 14's targets are shown on (`tests/compact_synthetic.rs`,
//! the `room_scenes` example that writes them as PLY files for the comparison benches):
//! each at most about 100 k points.

use nalgebra::{Point3, Vector3};

use super::depth::look_at;
use super::room::{Furniture, RoomGeometry, Tube};
use super::room_view::{KINECT_DISPARITY_STEP, RoomParams, RoomView};
use crate::Result;

/// Points per m² of the area-uniform rooms: about 100 k points on the default room's
/// 71 m² of floor, walls and furniture (median spacing about 1.4 cm).
pub const PRESET_DENSITY: f64 = 1400.0;

/// Noise σ of the area-uniform rooms (metres), along the surface normal: about 0.7
/// of their point spacing, the regime of a depth camera at 2–3 m.
pub const PRESET_SIGMA: f64 = 0.01;

/// Noise σ of the `rotated-low-noise` room (metres): a fifth of its spacing, where the
/// sampling's own gaps (not the noise) set the distance from a surface to its nearest
/// point.
pub const LOW_NOISE_SIGMA: f64 = 0.003;

/// Range noise σ of the depth-camera rooms (metres), before quantisation.
pub const PRESET_RANGE_SIGMA: f64 = 0.002;

/// The Kinect-type camera of the quantised rooms (room frame): in a corner at 1.6 m,
/// looking across the room and down at 20°.
fn corner_camera() -> Result<crate::Pose> {
    look_at(Point3::new(0.4, 0.4, 1.6), Point3::new(4.0, 3.0, 0.5))
}

/// The room of the depth-camera preset: the cabinet, the table moved back, a pole
/// (r = 10 cm) 1.3 m in front of the camera and a pipe run (r = 5 cm, 10 cm off the
/// floor) across its view 2–2.5 m away (horizontally; nearer floor is below the field of
/// view), where the depth step (about 1.7 cm at 2.5 m) still resolves it, barely.
fn camera_room() -> RoomGeometry {
    let mut g = RoomGeometry::default();
    g.furniture[0] = Furniture::new(Point3::new(2.8, 1.0, 0.0), Vector3::new(1.2, 0.8, 0.75));
    g.tubes.push(Tube {
        from: Point3::new(1.6, 0.8, 0.0),
        to: Point3::new(1.6, 0.8, g.size.z),
        radius: 0.1,
    });
    g.tubes.push(Tube {
        from: Point3::new(1.2, 2.4, 0.15),
        to: Point3::new(2.4, 1.2, 0.15),
        radius: 0.05,
    });
    g
}

/// The named presets, in order:
///
/// | name | room | seen |
/// |---|---|---|
/// | `rotated` | 5 × 4 × 2.5 m, box table and cabinet (15 faces) | area-uniform, yaw 27°, tilt 2° |
/// | `pipe-and-pole` | the same with a ceiling, a pipe run (r = 5 cm) and a pole (r = 10 cm) | area-uniform, yaw 61°, tilt −3° |
/// | `kinect` | the furniture, a pole and a pipe run in front of the camera (`camera_room`) | a 320 × 240 Kinect-type depth camera in a corner (occlusion, quantised depth) |
/// | `kinect-no-occlusion` | the default room | area-uniform, depth quantised as the corner camera would |
/// | `millimetre` | `rotated` a thousand times smaller (unit 10⁻³) | area-uniform |
/// | `table-on-legs` | `rotated` with a table top on four 12 cm legs (30 faces) | area-uniform |
/// | `rotated-low-noise` | `rotated` with σ = [`LOW_NOISE_SIGMA`], a fifth of the spacing | area-uniform |
pub fn room_presets() -> Result<Vec<(&'static str, RoomParams)>> {
    let uniform = RoomParams {
        view: RoomView::Uniform {
            density: PRESET_DENSITY,
        },
        sigma: PRESET_SIGMA,
        ..Default::default()
    };
    let camera = corner_camera()?;
    let legs = RoomGeometry {
        furniture: [
            Furniture::table((1.4, 1.2), (1.2, 0.8, 0.75), 0.08, 0.12, 0.05),
            vec![Furniture::new(
                Point3::new(3.6, 2.6, 0.0),
                Vector3::new(0.6, 0.5, 1.2),
            )],
        ]
        .concat(),
        ..Default::default()
    };
    Ok(vec![
        (
            "rotated",
            RoomParams {
                seed: 1,
                ..uniform.clone()
            },
        ),
        (
            "pipe-and-pole",
            RoomParams {
                geometry: RoomGeometry {
                    ceiling: true,
                    ..Default::default()
                }
                .with_pipe_and_pole(),
                view: RoomView::Uniform { density: 1000.0 },
                yaw: 61f64.to_radians(),
                tilt: -3f64.to_radians(),
                seed: 2,
                ..uniform.clone()
            },
        ),
        (
            "kinect",
            RoomParams {
                geometry: camera_room(),
                view: RoomView::DepthCamera {
                    sensor: camera,
                    pixels: (320, 240),
                    fov: (58f64.to_radians(), 45f64.to_radians()),
                    disparity_step: KINECT_DISPARITY_STEP,
                },
                sigma: PRESET_RANGE_SIGMA,
                yaw: 0.3,
                seed: 3,
                ..uniform.clone()
            },
        ),
        (
            "kinect-no-occlusion",
            RoomParams {
                view: RoomView::QuantisedUniform {
                    density: PRESET_DENSITY,
                    sensor: camera,
                    disparity_step: KINECT_DISPARITY_STEP,
                },
                sigma: PRESET_RANGE_SIGMA,
                seed: 4,
                ..uniform.clone()
            },
        ),
        (
            "millimetre",
            RoomParams {
                unit: 1e-3,
                seed: 5,
                ..uniform.clone()
            },
        ),
        (
            "table-on-legs",
            RoomParams {
                geometry: legs,
                seed: 6,
                ..uniform.clone()
            },
        ),
        (
            "rotated-low-noise",
            RoomParams {
                sigma: LOW_NOISE_SIGMA,
                seed: 7,
                ..uniform
            },
        ),
    ])
}

/// The preset called `name` ([`room_presets`]), or `None`.
pub fn room_preset(name: &str) -> Result<Option<RoomParams>> {
    Ok(room_presets()?
        .into_iter()
        .find(|(n, _)| *n == name)
        .map(|(_, p)| p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::room;

    #[test]
    fn every_preset_builds_within_the_point_budget() {
        for (name, params) in room_presets().unwrap() {
            let scene = room(&params).unwrap();
            let n = scene.cloud.len();
            assert!((30_000..=110_000).contains(&n), "{name}: {n} points");
        }
        assert!(room_preset("rotated").unwrap().is_some());
        assert!(room_preset("nothing").unwrap().is_none());
    }
}
