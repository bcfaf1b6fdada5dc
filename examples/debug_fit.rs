//! Fits a synthetic hallway and reports the worst-explained points (developer aid).
use primfit::fit::{FitOptions, fit};
use primfit::metrics::point_to_model_distances;
use primfit::progress::Silent;
use primfit::synth::{HallwayParams, hallway};

fn main() {
    let scene = hallway(&HallwayParams::default()).unwrap();
    let r = fit(&scene.cloud, &FitOptions::default(), &Silent).unwrap();
    let d = point_to_model_distances(&scene.cloud.points, &r.primitives).unwrap();
    let mut worst: Vec<(f64, usize)> = d.iter().copied().zip(0..).collect();
    worst.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (dist, j) in worst.iter().take(8) {
        println!("{dist:.3} at {:?}", scene.cloud.points[*j]);
    }
    let h = &r.solution.history;
    println!(
        "iterations {} stop {:?} flips {}",
        r.solution.iterations, r.solution.stop, r.solution.flips
    );
    for k in [0, 1, 2, 5, 10, 20, 50, 100, 150, h.len() - 1] {
        if k < h.len() {
            println!("  f[{k}] = {:.6}", h[k]);
        }
    }
    let p = &r.solution.probability;
    let mid = p.iter().filter(|x| **x > 0.05 && **x < 0.95).count();
    println!("undecided (0.05..0.95): {mid} of {}", p.len());
    let truth = primfit::fit::binary_chamfer(&scene.cloud, &scene.truth, &r.settings).unwrap();
    let fitted = primfit::fit::binary_chamfer(&scene.cloud, &r.primitives, &r.settings).unwrap();
    println!("exact binary chamfer: fit {fitted:?}\n                      truth {truth:?}");
    println!(
        "thresholded {:?}\nfinal {:?}",
        r.solution.thresholded, r.solution.binary
    );
}
