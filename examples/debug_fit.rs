//! Hallway fit vs truth, plane by plane (developer aid).
use primfit::fit::{FitOptions, binary_chamfer, fit};
use primfit::metrics::point_to_model_distances;
use primfit::progress::Silent;
use primfit::synth::{Density, HallwayParams, hallway};

fn plane(c: &primfit::na::Point3<f64>) -> &'static str {
    if c.z.abs() < 1e-9 {
        "floor"
    } else if c.y.abs() < 1e-9 {
        "wall y=0"
    } else if (c.y - 2.0).abs() < 1e-9 {
        "wall y=2"
    } else {
        "other"
    }
}

fn main() {
    let p = HallwayParams {
        seed: 0,
        length: 6.0,
        density: Density::PerArea(400.0),
        ..Default::default()
    };
    let scene = hallway(&p).unwrap();
    let r = fit(
        &scene.cloud,
        &FitOptions {
            size: Some(1.0),
            ..Default::default()
        },
        &Silent,
    )
    .unwrap();
    for (name, set) in [("truth", &scene.truth), ("fit", &r.primitives)] {
        let mut v: Vec<String> = set
            .iter()
            .map(|q| {
                let c = q.center();
                format!("{} ({:.1},{:.1},{:.1})", plane(&c), c.x, c.y, c.z)
            })
            .collect();
        v.sort();
        let loss = binary_chamfer(&scene.cloud, set, &r.settings).unwrap();
        println!("{name}: {} primitives, {:?}", set.len(), loss);
        for s in v {
            if !s.starts_with("floor") {
                continue;
            }
            print!("{s}; ");
        }
        println!();
    }
    let d = point_to_model_distances(&scene.cloud.points, &r.primitives).unwrap();
    let far: Vec<_> = scene
        .cloud
        .points
        .iter()
        .zip(&d)
        .filter(|(_, d)| **d > 0.05)
        .map(|(p, d)| format!("({:.2},{:.2},{:.2}):{d:.2}", p.x, p.y, p.z))
        .take(10)
        .collect();
    println!("far points: {far:?}");
}
