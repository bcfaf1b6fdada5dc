//! Fits synthetic pipes and nine-cylinder scenes against their truth (developer aid).
use primfit::ShapeKind;
use primfit::fit::{FitOptions, binary_chamfer, fit};
use primfit::metrics::{MetricsOptions, evaluate};
use primfit::progress::Silent;
use primfit::synth::{NineCylinderParams, PipeParams, nine_cylinders, pipe};

fn main() {
    for (seed, beta) in [(3, 16), (3, 64), (3, usize::MAX), (0, 64)] {
        let scene = pipe(&PipeParams {
            seed,
            ..Default::default()
        })
        .unwrap();
        let h = &scene.lattice;
        let (len, radius, bend) = match (&h.shapes[0], &h.shapes[1]) {
            (primfit::Shape::Cylinder { length, radius }, primfit::Shape::Elbow { bend, .. }) => {
                (*length, *radius, *bend)
            }
            _ => panic!("{:?}", h.shapes),
        };
        let o = FitOptions {
            kinds: vec![ShapeKind::Cylinder, ShapeKind::Elbow],
            size: Some(len),
            radius: Some(radius),
            bend: Some(bend),
            spacing: Some(h.spacing),
            beta: Some(beta),
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let r = fit(&scene.cloud, &o, &Silent).unwrap();
        let el = t.elapsed().as_secs_f64();
        let m = evaluate(
            &scene.cloud.points,
            &r.primitives,
            Some(&scene.truth),
            &MetricsOptions::default(),
        )
        .unwrap();
        let bf = binary_chamfer(&scene.cloud, &r.primitives, &r.settings)
            .unwrap()
            .total;
        let bt = binary_chamfer(&scene.cloud, &scene.truth, &r.settings)
            .unwrap()
            .total;
        let tr = m.truth.unwrap();
        println!(
            "hist {:?}",
            &r.solution.history[..r.solution.history.len().min(6)]
        );
        println!(
            "pipe seed {seed} beta {beta}: {} pts, {} cands, fit {} vs truth {}, P {:.2} R {:.2}, chamfer fit {bf:.3} truth {bt:.3}, p2m {:.4} m2p {:.4}, {el:.2}s, iters {}",
            scene.cloud.len(),
            r.stats.candidates,
            r.primitives.len(),
            scene.truth.len(),
            tr.precision,
            tr.recall,
            m.point_to_model_mean,
            m.model_to_point_mean,
            r.solution.iterations
        );
    }
    for seed in 0..3 {
        let p = NineCylinderParams {
            seed,
            mask: 0b101_011_110,
            ..Default::default()
        };
        let scene = nine_cylinders(&p).unwrap();
        let o = FitOptions {
            kinds: vec![ShapeKind::Cylinder],
            size: Some(p.height),
            radius: Some(p.radius),
            spacing: Some(scene.lattice.spacing),
            origin: Some(scene.lattice.origin),
            ..Default::default()
        };
        let r = fit(&scene.cloud, &o, &Silent).unwrap();
        let m = evaluate(
            &scene.cloud.points,
            &r.primitives,
            Some(&scene.truth),
            &MetricsOptions::default(),
        )
        .unwrap();
        let tr = m.truth.unwrap();
        println!(
            "nine seed {seed}: {} cands, fit {} truth {} P {:.2} R {:.2} p2m {:.4} m2p {:.4}",
            r.stats.candidates,
            r.primitives.len(),
            scene.truth.len(),
            tr.precision,
            tr.recall,
            m.point_to_model_mean,
            m.model_to_point_mean
        );
    }
}
