//! The nine-cylinder scenes of thesis §5.5 (training/testing the existence network).

use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::common::{Density, LatticeHint, Noise, Piece, Scene, axis_rotation, sample_pieces};
use crate::atlas::Shape;
use crate::check::{self, non_negative, positive};
use crate::{Error, PointCloud, Pose, Primitive, Result};

/// Parameters of [`nine_cylinders`]. Lengths in metres (scene units).
///
/// Candidate k (bit k of `mask`, k = 0..9) is the vertical cylinder centred at
/// `((k % 3 − 1)·pitch, (k / 3 − 1)·pitch, 0)`; the lattice spacing is `pitch`, origin 0.
#[derive(Debug, Clone, PartialEq)]
pub struct NineCylinderParams {
    /// Which of the nine cylinders exist (bit k ↔ candidate k); must be < 512.
    pub mask: u16,
    /// Grid pitch (distance between neighbouring axes); must exceed `2 · radius`.
    pub pitch: f64,
    /// Cylinder radius.
    pub radius: f64,
    /// Cylinder height (length along z).
    pub height: f64,
    /// How many points (per-area densities give every cylinder the same expected count).
    pub density: Density,
    /// Per-point jitter and per-cylinder drift.
    pub noise: Noise,
    /// Largest alignment offset in grid pitches: the whole scene is shifted along a
    /// random one of ±x, ±y by `u · offset · pitch`, u uniform in [0, 1]
    /// (0 = aligned, 1 = up to one neighbour away).
    pub offset: f64,
    /// RNG seed.
    pub seed: u64,
}

impl Default for NineCylinderParams {
    fn default() -> Self {
        NineCylinderParams {
            mask: 0b1_1111_1111,
            pitch: 1.0,
            radius: 0.2,
            height: 1.0,
            density: Density::PerArea(200.0),
            noise: Noise {
                jitter: 0.01,
                drift: 0.01,
            },
            offset: 0.0,
            seed: 0,
        }
    }
}

fn validate(p: &NineCylinderParams) -> Result<()> {
    positive("pitch", p.pitch)?;
    positive("radius", p.radius)?;
    positive("height", p.height)?;
    non_negative("offset", p.offset)?;
    check::at_most("mask", usize::from(p.mask), 511)?;
    if p.pitch <= 2.0 * p.radius {
        // Disjoint cylinders.
        let expected = format!(
            "more than the cylinder diameter 2 · radius = {}",
            2.0 * p.radius
        );
        return Err(Error::out_of_range("pitch", p.pitch, expected));
    }
    Ok(())
}

/// The nine candidate cylinders (index k ↔ bit k of the mask), on the aligned lattice.
pub fn nine_cylinders_candidates(params: &NineCylinderParams) -> Result<Vec<Primitive>> {
    validate(params)?;
    let shape = Shape::Cylinder {
        length: params.height,
        radius: params.radius,
    };
    Ok((0..9)
        .map(|k| {
            let t = Vector3::new((k % 3) as f64 - 1.0, (k / 3) as f64 - 1.0, 0.0) * params.pitch;
            Primitive::new(shape.clone(), Pose::new(axis_rotation(2), t))
        })
        .collect())
}

/// A nine-cylinder scene: the candidates selected by `mask`, sampled with jitter and
/// drift, then shifted by the alignment offset (cloud and truth; the candidates stay).
pub fn nine_cylinders(params: &NineCylinderParams) -> Result<Scene> {
    let candidates = nine_cylinders_candidates(params)?;
    let mut truth: Vec<Primitive> = candidates
        .into_iter()
        .enumerate()
        .filter(|(k, _)| params.mask >> k & 1 == 1)
        .map(|(_, p)| p)
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let pieces: Vec<Piece> = truth.iter().cloned().map(Piece::Prim).collect();
    let mut points = sample_pieces(&pieces, params.density, params.noise, &mut rng)?;
    let mut misalignment = Pose::identity();
    if params.offset > 0.0 {
        let dir =
            [Vector3::x(), -Vector3::x(), Vector3::y(), -Vector3::y()][rng.random_range(0..4)];
        misalignment.translation = dir * (rng.random::<f64>() * params.offset * params.pitch);
        for p in &mut points {
            *p += misalignment.translation;
        }
        for t in &mut truth {
            t.pose = misalignment.compose(&t.pose);
        }
    }
    Ok(Scene {
        cloud: PointCloud::from_points(points),
        truth,
        lattice: LatticeHint {
            spacing: params.pitch,
            origin: Point3::origin(),
            shapes: vec![Shape::Cylinder {
                length: params.height,
                radius: params.radius,
            }],
        },
        misalignment,
    })
}
