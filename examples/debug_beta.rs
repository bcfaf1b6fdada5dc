//! How large must β be? Fit/truth binary chamfer ratio per scene and β (developer aid).
use primfit::ShapeKind;
use primfit::fit::{FitOptions, binary_chamfer, fit};
use primfit::progress::Silent;
use primfit::synth::{Density, HallwayParams, PipeParams, hallway, pipe};

fn main() {
    for (beta, init) in [(32, 0.5)] {
        let mut line = format!("init {init}:");
        for seed in 0..4 {
            let scene = pipe(&PipeParams {
                seed,
                ..Default::default()
            })
            .unwrap();
            let o = FitOptions {
                kinds: vec![ShapeKind::Cylinder, ShapeKind::Elbow],
                size: Some(1.0),
                radius: Some(0.1),
                bend: Some(0.5),
                spacing: Some(0.5),
                beta: Some(beta),
                solver: primfit::solve::SolverOptions {
                    initial: init,
                    ..Default::default()
                },
                ..Default::default()
            };
            let t = std::time::Instant::now();
            let r = fit(&scene.cloud, &o, &Silent).unwrap();
            let f = binary_chamfer(&scene.cloud, &r.primitives, &r.settings)
                .unwrap()
                .total;
            let tr = binary_chamfer(&scene.cloud, &scene.truth, &r.settings)
                .unwrap()
                .total;
            line += &format!(
                " pipe{seed} {:.3} ({:.2}s)",
                f / tr,
                t.elapsed().as_secs_f64()
            );
        }
        for seed in 0..2 {
            let p = HallwayParams {
                seed,
                ceiling: seed == 1,
                length: 6.0,
                density: Density::PerArea(400.0),
                ..Default::default()
            };
            let scene = hallway(&p).unwrap();
            let o = FitOptions {
                size: Some(1.0),
                beta: Some(beta),
                solver: primfit::solve::SolverOptions {
                    initial: init,
                    ..Default::default()
                },
                ..Default::default()
            };
            let r = fit(&scene.cloud, &o, &Silent).unwrap();
            let f = binary_chamfer(&scene.cloud, &r.primitives, &r.settings)
                .unwrap()
                .total;
            let tr = binary_chamfer(&scene.cloud, &scene.truth, &r.settings)
                .unwrap()
                .total;
            line += &format!(" hall{seed} {:.3}", f / tr);
        }
        println!("{line}");
    }
}
