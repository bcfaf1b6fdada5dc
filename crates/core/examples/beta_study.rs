//! How large must β (candidates kept per point) be? For synthetic pipes and hallways,
//! the ratio of the fit's exact binary chamfer to the truth's, per β. Backs the default
//! β = 32 documented in `primfit_core::fit`.
//!
//!     cargo run --release --example beta_study
use primfit_core::Limit;
use primfit_core::ShapeKind;
use primfit_core::Silent;
use primfit_core::fit::{FitOptions, binary_chamfer, fit};
use primfit_core::synth::{Density, HallwayParams, PipeParams, Scene, hallway, pipe};

/// Fit chamfer ÷ truth chamfer (≤ 1 means as good as the truth or better).
fn ratio(scene: &Scene, options: &FitOptions) -> f64 {
    let r = fit(&scene.cloud, options, &Silent).expect("fit");
    let fitted = binary_chamfer(&scene.cloud, &r.primitives, &r.settings)
        .expect("chamfer")
        .total;
    let truth = binary_chamfer(&scene.cloud, &scene.truth, &r.settings)
        .expect("chamfer")
        .total;
    fitted / truth
}

fn main() {
    let pipes: Vec<Scene> = (0..4)
        .map(|seed| {
            pipe(&PipeParams {
                seed,
                ..Default::default()
            })
            .expect("pipe")
        })
        .collect();
    let halls: Vec<Scene> = (0..2)
        .map(|seed| {
            let p = HallwayParams {
                seed,
                ceiling: seed == 1,
                length: 6.0,
                density: Density::PerArea(400.0),
                ..Default::default()
            };
            hallway(&p).expect("hallway")
        })
        .collect();
    println!("| β | pipe 0 | pipe 1 | pipe 2 | pipe 3 | hallway 0 | hallway 1 (ceiling) |");
    println!("|---|---|---|---|---|---|---|");
    for beta in [8, 16, 24, 32, 48] {
        let pipe_options = FitOptions {
            kinds: vec![ShapeKind::Cylinder, ShapeKind::Elbow],
            size: Some(1.0),
            radius: Some(0.1),
            bend: Some(0.5),
            spacing: Some(0.5),
            beta: Limit::At(beta),
            ..FitOptions::lattice()
        };
        let hall_options = FitOptions {
            size: Some(1.0),
            beta: Limit::At(beta),
            ..FitOptions::lattice()
        };
        let mut row = format!("| {beta} |");
        for s in &pipes {
            row += &format!(" {:.3} |", ratio(s, &pipe_options));
        }
        for s in &halls {
            row += &format!(" {:.3} |", ratio(s, &hall_options));
        }
        println!("{row}");
    }
}
