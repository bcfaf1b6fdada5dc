//! The core fitter against ground truth on synthetic scenes (issue: core fitter).
//!
//! "As good as the truth" is measured on the fitter's own terms: the exact binary chamfer
//! of the fitted set against the true set's, and the DESIGN §4 measures of both.

use primfit_core::Silent;
use primfit_core::fit::{FitOptions, FitResult, binary_chamfer, fit};
use primfit_core::metrics::{Metrics, MetricsOptions, evaluate};
use primfit_core::synth::{
    HallwayParams, NineCylinderParams, PipeParams, Scene, hallway, nine_cylinders, pipe,
};
use primfit_core::{Shape, ShapeKind};

/// Fit options matching the lattice the scene's truth lives on.
fn options_for(scene: &Scene) -> FitOptions {
    let h = &scene.lattice;
    let mut o = FitOptions {
        kinds: Vec::new(),
        spacing: Some(h.spacing),
        origin: Some(h.origin),
        ..FitOptions::lattice()
    };
    for s in &h.shapes {
        o.kinds.push(s.kind());
        match *s {
            Shape::Square { side } => o.size = Some(side),
            Shape::Cylinder { length, radius } => {
                o.size = Some(length);
                o.radius = Some(radius);
            }
            Shape::Elbow { bend, radius } => {
                o.bend = Some(bend);
                o.radius = Some(radius);
            }
            _ => panic!("unexpected lattice shape {s:?}"),
        }
    }
    o
}

fn measures(scene: &Scene, model: &[primfit_core::Primitive]) -> Metrics {
    evaluate(
        &scene.cloud.points,
        model,
        Some(&scene.truth),
        &MetricsOptions::default(),
    )
    .unwrap()
}

/// Asserts the fit is as good as the truth; returns (fit, its metrics).
fn assert_as_good_as_truth(name: &str, scene: &Scene, jitter: f64) -> (FitResult, Metrics) {
    let r = fit(&scene.cloud, &options_for(scene), &Silent).unwrap();
    let fitted = binary_chamfer(&scene.cloud, &r.primitives, &r.settings)
        .unwrap()
        .total;
    let truth = binary_chamfer(&scene.cloud, &scene.truth, &r.settings)
        .unwrap()
        .total;
    assert!(
        fitted <= 1.01 * truth,
        "{name}: binary chamfer {fitted} vs truth {truth}"
    );
    let m = measures(scene, &r.primitives);
    let t = measures(scene, &scene.truth);
    assert!(
        m.point_to_model_mean <= t.point_to_model_mean + jitter,
        "{name}: point→model {} vs truth {}",
        m.point_to_model_mean,
        t.point_to_model_mean
    );
    assert!(
        m.model_to_point_mean <= t.model_to_point_mean + jitter,
        "{name}: model→point {} vs truth {}",
        m.model_to_point_mean,
        t.model_to_point_mean
    );
    (r, m)
}

#[test]
fn pipes_are_recovered_exactly() {
    for seed in 0..3 {
        let scene = pipe(&PipeParams {
            seed,
            ..Default::default()
        })
        .unwrap();
        let jitter = PipeParams::default().noise.jitter;
        let (r, m) = assert_as_good_as_truth(&format!("pipe {seed}"), &scene, jitter);
        let truth = m.truth.unwrap();
        assert_eq!(
            (truth.precision, truth.recall),
            (1.0, 1.0),
            "pipe {seed}: {} vs {}",
            r.primitives.len(),
            scene.truth.len()
        );
    }
}

#[test]
fn nine_cylinder_subsets_are_recovered_exactly() {
    for (seed, mask) in [(0, 0b111_111_111), (1, 0b101_010_101), (2, 0b000_110_001)] {
        let scene = nine_cylinders(&NineCylinderParams {
            seed,
            mask,
            ..Default::default()
        })
        .unwrap();
        let jitter = NineCylinderParams::default().noise.jitter;
        let (_, m) = assert_as_good_as_truth(&format!("nine {mask:09b}"), &scene, jitter);
        let truth = m.truth.unwrap();
        assert_eq!(
            (truth.precision, truth.recall),
            (1.0, 1.0),
            "mask {mask:09b}"
        );
    }
}

#[test]
fn hallways_are_tiled_as_well_as_the_truth() {
    for (seed, ceiling) in [(0, false), (1, true)] {
        let p = HallwayParams {
            seed,
            ceiling,
            length: 6.0,
            density: primfit_core::synth::Density::PerArea(400.0),
            ..Default::default()
        };
        let scene = hallway(&p).unwrap();
        let (r, _) = assert_as_good_as_truth(&format!("hallway {seed}"), &scene, p.noise.jitter);
        // Many tilings are equally good; none may invent a surface: every square lies on
        // one of the true planes.
        for q in &r.primitives {
            let c = q.center();
            let on_plane = c.z.abs() < 1e-9
                || (c.z - 2.5).abs() < 1e-9
                || c.y.abs() < 1e-9
                || (c.y - 2.0).abs() < 1e-9;
            assert!(
                on_plane,
                "hallway {seed}: square off the true planes at {c:?}"
            );
        }
    }
}

#[test]
fn misaligned_scenes_stay_within_a_quarter_step() {
    // Random offsets up to half a lattice step: a surface is then at most half a step
    // from a lattice position, a quarter on average. Averaged over seeds, both means
    // stay below a quarter step plus the jitter.
    let mut p2m = Vec::new();
    let mut m2p = Vec::new();
    let mut spacing = 0.0;
    let mut jitter = 0.0;
    for seed in 0..6 {
        let p = PipeParams {
            seed,
            misalignment: primfit_core::synth::Misalignment {
                offset: 0.5,
                angle: 0.0,
            },
            ..Default::default()
        };
        jitter = p.noise.jitter;
        let scene = pipe(&p).unwrap();
        spacing = scene.lattice.spacing;
        let r = fit(&scene.cloud, &options_for(&scene), &Silent).unwrap();
        let m = measures(&scene, &r.primitives);
        p2m.push(m.point_to_model_mean);
        m2p.push(m.model_to_point_mean);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let bound = spacing / 4.0 + jitter;
    assert!(mean(&p2m) < bound, "point→model {p2m:?} (bound {bound})");
    assert!(mean(&m2p) < bound, "model→point {m2p:?} (bound {bound})");
}

#[test]
fn same_seed_gives_bit_identical_results_on_one_or_two_threads() {
    let scene = pipe(&PipeParams {
        seed: 4,
        ..Default::default()
    })
    .unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let r = fit(&scene.cloud, &options_for(&scene), &Silent).unwrap();
            (
                serde_json::to_string(&r.to_json(serde_json::json!({}))).unwrap(),
                r.solution.probability,
                r.solution.history,
            )
        })
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.0, b.0);
    assert_eq!(
        a.1.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        b.1.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
    assert_eq!(
        a.2.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        b.2.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
    assert_eq!(a.0, run(2).0, "two runs on two threads differ");
}

#[test]
fn types_are_selectable() {
    // A pipe fitted with cylinders only cannot explain its elbows as well.
    let scene = pipe(&PipeParams {
        seed: 1,
        ..Default::default()
    })
    .unwrap();
    let mut o = options_for(&scene);
    o.kinds = vec![ShapeKind::Cylinder];
    let r = fit(&scene.cloud, &o, &Silent).unwrap();
    assert!(
        r.primitives
            .iter()
            .all(|p| p.shape.kind() == ShapeKind::Cylinder)
    );
}
