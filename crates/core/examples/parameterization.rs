//! Box-constrained vs logit L-BFGS on the synthetic scenes: evaluations, continuous loss,
//! binary loss after thresholding and after polish. Backs the choice documented in
//! `primfit_core::solve`.
//!
//!     cargo run --release --example parameterization
use primfit_core::ShapeKind;
use primfit_core::Silent;
use primfit_core::fit::{FitOptions, fit};
use primfit_core::solve::{Parameterization, SolverOptions};
use primfit_core::synth::{Density, HallwayParams, PipeParams, hallway, pipe};

fn main() {
    println!(
        "| scene | parameterization | iterations | evaluations | continuous loss | thresholded | polished | undecided p |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for seed in 0..3 {
        let scenes = [
            (
                "pipe",
                pipe(&PipeParams {
                    seed,
                    ..Default::default()
                })
                .unwrap(),
                true,
            ),
            (
                "hallway",
                hallway(&HallwayParams {
                    seed,
                    length: 6.0,
                    density: Density::PerArea(400.0),
                    ..Default::default()
                })
                .unwrap(),
                false,
            ),
        ];
        for (name, scene, tubes) in scenes {
            for parameterization in [Parameterization::Box, Parameterization::Logit] {
                let mut o = FitOptions {
                    size: Some(1.0),
                    solver: SolverOptions {
                        parameterization,
                        ..Default::default()
                    },
                    ..FitOptions::lattice()
                };
                if tubes {
                    o.kinds = vec![ShapeKind::Cylinder, ShapeKind::Elbow];
                    (o.radius, o.bend, o.spacing) = (Some(0.1), Some(0.5), Some(0.5));
                }
                let r = fit(&scene.cloud, &o, &Silent).unwrap();
                let s = &r.solution;
                let undecided = s
                    .probability
                    .iter()
                    .filter(|p| **p > 0.01 && **p < 0.99)
                    .count();
                println!(
                    "| {name} {seed} | {} | {} | {} | {:.4} | {:.4} | {:.4} | {undecided} |",
                    parameterization.name(),
                    s.iterations,
                    s.evaluations,
                    s.history.last().copied().unwrap_or(f64::NAN),
                    s.thresholded.total,
                    s.binary.total
                );
            }
        }
    }
}
