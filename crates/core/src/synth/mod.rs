//! Synthetic scenes with ground truth (DESIGN §1 `synth`).
//!
//! Every generator takes a params struct (with [`Default`] and a `seed`), draws from a
//! seeded [`rand_chacha::ChaCha8Rng`] (same seed ⇒ bit-identical scene), and returns a [`Scene`]:
//! the point cloud, the true primitives, and the [`LatticeHint`] on which the truth
//! lives, so a test can build the matching candidate set.
//!
//! [`depth_sensor`] instead ray-casts a truth from sensor poses (multi-frame scans with
//! sensor origins, for the ray likelihood); [`partial_view`] uses it for registration
//! scenes seen from one viewpoint (a mesh's near side among clutter). [`room`] is a furnished room whose truth is
//! its visible faces as bounded planes and its tubes as cylinders, seen area-uniformly
//! or by a depth camera with quantised depth ([`RoomScene`]; not a lattice scene).
//!
//! Noise model, applied in this order (all lengths in scene units, metres by default):
//!
//! 1. points are drawn **area-uniformly at random** on the true surfaces
//!    ([`Density`]: points per unit area or a total count);
//! 2. **drift**: every surface piece gets one random offset `~ N(0, drift² I)` added to
//!    all of its points (the truth does not move);
//! 3. **jitter**: every point gets an independent offset `~ N(0, jitter² I)`;
//! 4. **misalignment** ([`Misalignment`]): one rigid motion applied to the cloud *and*
//!    the truth, recorded in [`Scene::misalignment`]; the lattice hint stays where it
//!    was, so a misaligned truth is (deliberately) off the lattice.
//!
//! Lattice convention (the fitter's candidate lattice): translations are
//! `origin + spacing · (i, j, k)` with integers `i, j, k`; flat patches have their normal
//! and cylinders their axis along ±x/y/z (local z mapped onto an axis); an elbow's
//! rotation maps its local axes onto signed coordinate axes (12 orientations: plane
//! normal ∈ {x, y, z} × 4 quadrants) with its torus centre on the lattice.

mod common;
mod depth;
mod hallway;
mod nine;
mod partial_view;
mod pipe;
mod ray_scenes;
mod registration;
mod room;
mod room_presets;
mod room_view;
mod six;
mod survey;

#[cfg(test)]
pub(crate) use common::jittered_samples;
pub use common::{
    Density, LatticeHint, Misalignment, Noise, Scene, axis_rotation, elbow_rotation,
    sample_shape_local,
};
pub use depth::{SensorParams, depth_sensor, look_at, orbit_poses, walk_poses};
pub use hallway::{HallwayParams, hallway};
pub use nine::{NineCylinderParams, nine_cylinders, nine_cylinders_candidates};
pub use partial_view::{PartialViewParams, partial_view};
pub use pipe::{PipeParams, pipe};
pub use ray_scenes::{RAY_SCENE_RANGE_NOISE, RAY_SCENES, RayScene, ray_scene};
pub use registration::{RegistrationParams, asymmetric_object, registration};
pub use room::{Furniture, RoomGeometry, Tube};
pub use room_presets::{
    LOW_NOISE_SIGMA, PRESET_DENSITY, PRESET_RANGE_SIGMA, PRESET_SIGMA, room_preset, room_presets,
};
pub use room_view::{
    KINECT_DISPARITY_STEP, MIN_SENSOR_DEPTH, RoomParams, RoomScene, RoomView, room,
};
pub use six::{SixInARow, SixInARowParams, SixVariant, six_in_a_row};
pub use survey::{SurveyKind, SurveyParams, SurveyScene, survey};
