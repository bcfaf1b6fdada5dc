//! Free space on ray-cast scenes (issue 21): the lattice chamfer fit without and with the
//! free-space term ("hybrid"), the ray likelihood's MCMC, and the default compact fit
//! without and with free space, on the open-top room, the corridor with a doorway and
//! the box in front of a wall (`synth::ray_scene`). Prints one markdown table row per
//! (scene, method): primitives, point→model mean, model→point mean, coverage within
//! 3 cm, wall time; the truth's own row first. Results: `docs/free_space.md`.
//!
//! ```text
//! cargo run --release -p primfit-core --example free_space_scenes [-- COLUMNS ROWS [SEED]]
//! ```
use std::time::Instant;

use primfit_core::fit::FrameChoice;
use primfit_core::fit::{FitOptions, McmcFitOptions, MethodOptions, fit};
use primfit_core::metrics::{MetricsOptions, evaluate, point_to_model_distances};
use primfit_core::na::Point3;
use primfit_core::synth::{RAY_SCENES, ray_scene};
use primfit_core::{Primitive, Silent};

/// A point within this of the model is covered (m).
const COVERED: f64 = 0.03;
/// Spacing of the model samples of model→point (m).
const MODEL_SAMPLES: f64 = 0.05;

fn row(scene: &str, method: &str, points: &[Point3<f64>], model: &[Primitive], seconds: f64) {
    let measures = MetricsOptions {
        sample_spacing: Some(MODEL_SAMPLES),
        coverage_tau: Some(COVERED),
        ..Default::default()
    };
    let m = evaluate(points, model, None, &measures).expect("metrics");
    let d = point_to_model_distances(points, model).expect("distances");
    let covered = d.iter().filter(|x| **x <= COVERED).count() as f64 / d.len() as f64;
    println!(
        "| {scene} | {method} | {} | {:.4} | {:.4} | {:.2} % | {seconds:.2} |",
        model.len(),
        m.point_to_model_mean,
        m.model_to_point_mean,
        100.0 * covered
    );
}

/// The thesis's lattice: 1 m squares, 0.5 m step, scene axes through the origin.
fn lattice(free_space: bool) -> FitOptions {
    FitOptions {
        kinds: vec![primfit_core::ShapeKind::Square],
        size: Some(1.0),
        spacing: Some(0.5),
        origin: Some(Point3::origin()),
        frame: FrameChoice::Axis,
        refine: None,
        free_space: Some(free_space),
        ..Default::default()
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let (columns, rows) = (*args.first().unwrap_or(&64), *args.get(1).unwrap_or(&48));
    let seed = *args.get(2).unwrap_or(&1) as u64;
    println!("| scene | method | primitives | point→model | model→point | coverage@3cm | s |");
    println!("|---|---|---|---|---|---|---|");
    for name in RAY_SCENES {
        let scene = ray_scene(name, columns, rows, seed)?;
        let points = &scene.cloud.points;
        row(name, "truth", points, &scene.truth, 0.0);
        let runs: [(&str, FitOptions); 5] = [
            ("lattice chamfer", lattice(false)),
            ("lattice hybrid (free space)", lattice(true)),
            (
                "lattice mcmc",
                FitOptions {
                    method: MethodOptions::Mcmc(McmcFitOptions {
                        sigma: Some(0.02),
                        ..Default::default()
                    }),
                    seed,
                    ..lattice(false)
                },
            ),
            (
                "compact chamfer",
                FitOptions {
                    free_space: Some(false),
                    ..Default::default()
                },
            ),
            ("compact hybrid (free space)", FitOptions::default()),
        ];
        for (method, options) in runs {
            let t = Instant::now();
            let result = fit(&scene.cloud, &options, &Silent)?;
            row(
                name,
                method,
                points,
                &result.primitives,
                t.elapsed().as_secs_f64(),
            );
        }
    }
    Ok(())
}
