//! Fits of scenes that are *not* on the lattice (issue 8): synthetic hallways and pipes
//! rotated by arbitrary angles (any axis, up to 180°) and shifted by up to a whole lattice
//! step, fitted with `frame = auto` and refinement. Requirements, per scene:
//!
//! - point→model mean ≤ 2 × the added noise σ (per-axis jitter);
//! - model→point mean ≤ 2 × σ;
//! - primitive count within 20 % of the truth's.
//!
//! The clouds are dense enough that the truth itself meets the model→point bound (its
//! samples are on average about σ from the nearest input point).

use primfit_core::ShapeKind;
use primfit_core::Silent;
use primfit_core::fit::FrameChoice;
use primfit_core::fit::{FitOptions, FitResult, fit};
use primfit_core::metrics::{Metrics, MetricsOptions, evaluate};
use primfit_core::na::{Matrix3, UnitQuaternion};
use primfit_core::refine::RefineOptions;
use primfit_core::synth::{
    Density, HallwayParams, Misalignment, Noise, PipeParams, Scene, hallway, pipe,
};

/// Any rotation, and a shift of up to one lattice step.
const ANYWHERE: Misalignment = Misalignment {
    offset: 1.0,
    angle: std::f64::consts::PI,
};

fn measures(scene: &Scene, r: &FitResult) -> Metrics {
    evaluate(
        &scene.cloud.points,
        &r.primitives,
        None,
        &MetricsOptions::default(),
    )
    .unwrap()
}

/// The smallest angle (degrees) between `q` and a rotation that maps the coordinate axes
/// onto themselves (the 24 signed permutations): how far from "a multiple of 90°" the
/// scene was turned.
fn degrees_from_axis_aligned(q: &UnitQuaternion<f64>) -> f64 {
    let mut best = f64::INFINITY;
    for perm in [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ] {
        for signs in 0..8u32 {
            let mut m = Matrix3::zeros();
            for (col, &row) in perm.iter().enumerate() {
                m[(row, col)] = if signs >> col & 1 == 1 { -1.0 } else { 1.0 };
            }
            if m.determinant() < 0.0 {
                continue;
            }
            let p = UnitQuaternion::from_matrix(&m);
            best = best.min(q.angle_to(&p).to_degrees());
        }
    }
    best
}

fn check(name: &str, scene: &Scene, r: &FitResult, sigma: f64) {
    // The scene really is off the lattice: turned well away from any axis-aligned
    // orientation (so no lattice orientation fits it) and shifted.
    let turn = degrees_from_axis_aligned(&scene.misalignment.rotation);
    assert!(
        turn >= 10.0,
        "{name}: only {turn:.1}° from axis-aligned; pick another seed"
    );
    assert!(
        scene.misalignment.translation.norm() > 0.0,
        "{name}: not shifted"
    );
    let m = measures(scene, r);
    let truth = scene.truth.len() as f64;
    let count = r.primitives.len() as f64;
    let summary = format!(
        "{name}: turned {turn:.1}° off the axes, {} primitives (truth {truth}), point→model {:.4}, \
         model→point {:.4}, σ {sigma}, frame {:?}",
        r.primitives.len(),
        m.point_to_model_mean,
        m.model_to_point_mean,
        r.settings.frame
    );
    eprintln!("{summary}");
    assert!(m.point_to_model_mean <= 2.0 * sigma, "{summary}");
    assert!(m.model_to_point_mean <= 2.0 * sigma, "{summary}");
    assert!((count - truth).abs() <= 0.2 * truth, "{summary}");
}

fn auto(kinds: Vec<ShapeKind>, size: f64) -> FitOptions {
    FitOptions {
        kinds,
        size: Some(size),
        frame: FrameChoice::Auto,
        refine: Some(RefineOptions::default()),
        ..FitOptions::lattice()
    }
}

#[test]
fn misaligned_hallways_fit_within_twice_the_noise() {
    let sigma = 0.02;
    for seed in [1, 2] {
        let scene = hallway(&HallwayParams {
            length: 5.0,
            width: 2.0,
            height: 2.0,
            density: Density::PerArea(1000.0),
            noise: Noise {
                jitter: sigma,
                drift: 0.0,
            },
            misalignment: ANYWHERE,
            seed,
            ..Default::default()
        })
        .unwrap();
        let r = fit(&scene.cloud, &auto(vec![ShapeKind::Square], 1.0), &Silent).unwrap();
        check(&format!("hallway {seed}"), &scene, &r, sigma);
    }
}

#[test]
fn misaligned_pipes_fit_within_twice_the_noise() {
    let sigma = 0.01;
    for seed in [1, 2] {
        let scene = pipe(&PipeParams {
            segments: 3,
            max_run: 2,
            density: Density::PerArea(4000.0),
            noise: Noise {
                jitter: sigma,
                drift: 0.0,
            },
            misalignment: ANYWHERE,
            seed,
            ..Default::default()
        })
        .unwrap();
        let mut o = auto(vec![ShapeKind::Cylinder, ShapeKind::Elbow], 1.0);
        o.radius = Some(0.1);
        o.bend = Some(0.5);
        let r = fit(&scene.cloud, &o, &Silent).unwrap();
        check(&format!("pipe {seed}"), &scene, &r, sigma);
    }
}

#[test]
fn the_estimated_frame_matches_the_misalignment() {
    let scene = hallway(&HallwayParams {
        length: 4.0,
        misalignment: ANYWHERE,
        seed: 7,
        ..Default::default()
    })
    .unwrap();
    let r = fit(&scene.cloud, &auto(vec![ShapeKind::Square], 1.0), &Silent).unwrap();
    // Every lattice axis is (up to sign) a rotated scene axis.
    let truth = scene.misalignment.rotation.to_rotation_matrix();
    let est = r.settings.frame.to_rotation_matrix();
    for i in 0..3 {
        let best = (0..3)
            .map(|j| est.matrix().column(i).dot(&truth.matrix().column(j)).abs())
            .fold(0.0, f64::max);
        assert!(best > (1.0f64).to_radians().cos(), "axis {i}: {best}");
    }
}

/// The bundled real scan, PCL's SAC plane test cloud (`examples/plane_scan.ply`, the same
/// bytes as `../shared/data/sac_plane_test.ply`: 3 283 stereo points of a floor and a
/// strip of a tilted second plane, 1.3 cm apart), fitted as `primfit fit` does by default
/// (frame `auto`, refinement). Requirements, relative to the scan's own scales (its noise
/// σ and median point spacing h, as the fit estimates them):
///
/// - coverage: every point within 2h of the model (99 %), and 88 % within h/2 (squares
///   that shrink away from each other leave gaps that fail this: the refinement before
///   issue 8's fix had 85 % and a point→model mean of 2.05σ);
/// - point→model mean ≤ 2σ;
/// - model→point mean ≤ h (no patch hangs off the data).
#[test]
fn the_real_plane_scan_is_covered_tightly() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/plane_scan.ply");
    let cloud = primfit_core::io::read_cloud(&path).unwrap();
    assert_eq!(cloud.len(), 3283);
    let defaults = FitOptions {
        frame: FrameChoice::Auto,
        refine: Some(RefineOptions::default()),
        ..FitOptions::lattice()
    };
    let r = fit(&cloud, &defaults, &Silent).unwrap();
    let h = r.settings.point_spacing;
    let sigma = r.settings.noise;
    let m = evaluate(
        &cloud.points,
        &r.primitives,
        None,
        &MetricsOptions::default(),
    )
    .unwrap();
    let tight = evaluate(
        &cloud.points,
        &r.primitives,
        None,
        &MetricsOptions {
            coverage_tau: Some(h / 2.0),
            ..Default::default()
        },
    )
    .unwrap();
    let summary = format!(
        "plane scan: {} squares, point→model mean {:.4} (σ {sigma:.4}), model→point mean {:.4} \
         (h {h:.4}), coverage@2h {:.3}, coverage@h/2 {:.3}",
        r.primitives.len(),
        m.point_to_model_mean,
        m.model_to_point_mean,
        m.coverage,
        tight.coverage
    );
    eprintln!("{summary}");
    assert!(!r.primitives.is_empty(), "{summary}");
    assert!(m.coverage >= 0.99, "{summary}");
    assert!(tight.coverage >= 0.88, "{summary}");
    assert!(m.point_to_model_mean <= 2.0 * sigma, "{summary}");
    assert!(m.model_to_point_mean <= h, "{summary}");
}
