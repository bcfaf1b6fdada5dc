//! The free-space term inside the fit: its gradient against finite differences, the
//! default (on exactly with sensor origins), and fits of ray-cast scenes with and without
//! it, and by the ray likelihood, against the truth.

use nalgebra::Point3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::pass::charge_free_space;
use super::*;
use crate::chamfer::{ChamferOptions, Coefficients, Evaluator};
use crate::lattice::CandidateSet;
use crate::metrics::{MetricsOptions, evaluate, point_to_model_distances};
use crate::progress::Silent;
use crate::ray::{FreeSpace, Rays};
use crate::synth::ray_scene;
use crate::{Primitive, ShapeKind};

/// The thesis's lattice on the scene axes: 1 m squares, 0.5 m step.
fn lattice(free_space: Option<bool>) -> FitOptions {
    FitOptions {
        kinds: vec![ShapeKind::Square],
        size: Some(1.0),
        spacing: Some(0.5),
        origin: Some(Point3::origin()),
        free_space,
        ..FitOptions::lattice()
    }
}

/// `(model→point mean, share of points within 3 cm)` of `model`.
fn measures(points: &[Point3<f64>], model: &[Primitive]) -> (f64, f64) {
    let options = MetricsOptions {
        sample_spacing: Some(0.05),
        coverage_tau: Some(0.03),
        ..Default::default()
    };
    let m = evaluate(points, model, None, &options).unwrap();
    let d = point_to_model_distances(points, model).unwrap();
    let covered = d.iter().filter(|x| **x <= 0.03).count() as f64 / d.len() as f64;
    (m.model_to_point_mean, covered)
}

#[test]
fn loss_with_free_space_has_the_exact_gradient_and_adds_the_closed_form() {
    let scene = ray_scene("corridor", 16, 12, 3).unwrap();
    let set = CandidateSet::unit_squares(&scene.cloud);
    let chamfer = ChamferOptions {
        cap: 0.25,
        beta: Some(8),
        surface_distance: true,
        primitive_weight: 0.7,
        point_weight: 1.3,
        ..Default::default()
    };
    let plain = Coefficients::build(&scene.cloud.points, &set, &chamfer, &Silent).unwrap();
    let mut charged = plain.clone();
    let prims: Vec<Primitive> = (0..set.len()).map(|i| set.primitive(i)).collect();
    let free = charge_free_space(&scene.cloud, &prims, &chamfer, &mut charged.g).unwrap();
    assert!(free.cost.iter().any(|f| *f > 0.0));
    let n = set.len();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let p: Vec<f64> = (0..n).map(|_| rng.random_range(0.05..0.95)).collect();
    let (mut g_plain, mut grad) = (vec![0.0; n], vec![0.0; n]);
    let base = Evaluator::new(&plain).evaluate(&p, &mut g_plain).total;
    let mut ev = Evaluator::new(&charged);
    let total = ev.evaluate(&p, &mut grad).total;
    // The loss gains exactly w_point · F(p).
    let added = chamfer.point_weight * free.value(&p).unwrap();
    assert!((total - base - added).abs() <= 1e-9 * total.abs());
    // Central differences on a few coordinates (the loss is multilinear in p).
    let h = 1e-5;
    let mut scratch = vec![0.0; n];
    for i in (0..n).step_by(n / 12 + 1) {
        let mut q = p.clone();
        q[i] = p[i] + h;
        let up = ev.evaluate(&q, &mut scratch).total;
        q[i] = p[i] - h;
        let down = ev.evaluate(&q, &mut scratch).total;
        let fd = (up - down) / (2.0 * h);
        assert!(
            (fd - grad[i]).abs() <= 1e-5 * grad[i].abs().max(1.0),
            "candidate {i}: {fd} vs {}",
            grad[i]
        );
        // Its free-space part is w_point · f_i.
        let f_part = grad[i] - g_plain[i];
        assert!(
            (f_part - chamfer.point_weight * free.cost[i]).abs() <= 1e-9 * f_part.abs().max(1.0)
        );
    }
}

#[test]
fn free_space_is_on_exactly_when_the_cloud_has_sensor_origins() {
    let scene = ray_scene("object", 16, 12, 2).unwrap();
    let with = fit(&scene.cloud, &lattice(None), &Silent).unwrap();
    assert!(with.settings.free_space);
    let json = with.settings.to_json();
    assert_eq!(json["free_space"], true);
    let bare = crate::PointCloud::from_points(scene.cloud.points.clone());
    let without = fit(&bare, &lattice(None), &Silent).unwrap();
    assert!(!without.settings.free_space);
    let err = fit(&bare, &lattice(Some(true)), &Silent)
        .unwrap_err()
        .to_string();
    assert!(err.contains("sensor") && err.contains("free"), "{err}");
    let off = fit(&scene.cloud, &lattice(Some(false)), &Silent).unwrap();
    assert!(!off.settings.free_space);
    // The compact model (the default types) takes it too.
    let compact = fit(&scene.cloud, &FitOptions::default(), &Silent).unwrap();
    assert!(compact.settings.free_space);
}

#[test]
fn ray_cast_scenes_fit_without_invented_surface_with_and_without_free_space() {
    for name in crate::synth::RAY_SCENES {
        let scene = ray_scene(name, 48, 36, 1).unwrap();
        let points = &scene.cloud.points;
        let (truth_mp, _) = measures(points, &scene.truth);
        let mut coverage = Vec::new();
        for free_space in [false, true] {
            let result = fit(&scene.cloud, &lattice(Some(free_space)), &Silent).unwrap();
            let (mp, covered) = measures(points, &result.primitives);
            assert!(
                mp <= 1.5 * truth_mp,
                "{name}, free space {free_space}: model→point {mp} vs the truth's {truth_mp}"
            );
            assert!(
                covered > 0.9,
                "{name}, free space {free_space}: coverage {covered}"
            );
            coverage.push(covered);
        }
        assert!(coverage[1] >= coverage[0] - 0.01, "{name}: {coverage:?}");
    }
}

#[test]
fn mcmc_on_ray_cast_scenes_invents_no_surface_and_keeps_coverage() {
    // The corridor's second room is seen only through the doorway, with points several
    // times sparser than the corridor's: counted at the cloud's median density, its
    // unobserved surface dropped it with its points (coverage 88 %).
    for name in ["room", "corridor", "object"] {
        let scene = ray_scene(name, 48, 36, 1).unwrap();
        let points = &scene.cloud.points;
        let options = FitOptions {
            method: MethodOptions::Mcmc(McmcFitOptions {
                sigma: Some(0.02),
                ..Default::default()
            }),
            seed: 1,
            ..lattice(None)
        };
        let result = fit(&scene.cloud, &options, &Silent).unwrap();
        let (truth_mp, _) = measures(points, &scene.truth);
        let (mp, covered) = measures(points, &result.primitives);
        assert!(
            mp <= 1.5 * truth_mp,
            "{name}: model→point {mp} vs the truth's {truth_mp}"
        );
        assert!(covered > 0.99, "{name}: coverage {covered}");
    }
}

#[test]
fn with_free_space_no_chosen_square_blocks_rays() {
    // The box in front of a wall: lattice squares on the box's faces that reach past
    // them into the space rays cross to the wall are candidates; with free space the
    // solver picks none that rays pass through far in front of their points.
    let scene = ray_scene("object", 32, 24, 4).unwrap();
    let result = fit(&scene.cloud, &lattice(Some(true)), &Silent).unwrap();
    let rays = Rays::from_cloud(&scene.cloud).unwrap();
    let free = FreeSpace::build(&rays, &result.primitives, result.settings.chamfer.cap).unwrap();
    let worst = free
        .cost
        .iter()
        .zip(&free.crossings)
        .map(|(f, k)| f / (*k).max(1) as f64)
        .fold(0.0, f64::max);
    assert!(
        worst < 0.1 * result.settings.chamfer.cap,
        "a chosen square blocks rays: {worst}"
    );
}
