//! Negative log-likelihoods of the six-in-a-row toy (thesis §4.3, fig. 4-4) for every
//! single- and double-candidate scene, planar and cylindrical, written as CSV:
//! `six_squares.csv` and `six_cylinders.csv`, each a 6×6 matrix (row i, column k: the
//! scene {candidate i, candidate k}; the diagonal: {candidate i} alone), candidates at
//! 7..12 m, points sampled on the one at 10 m. Render with `examples/ray_toy_heatmap.py`.
//!
//! ```text
//! cargo run --release --example ray_toy_heatmap -- OUT_DIR
//! python3 examples/ray_toy_heatmap.py OUT_DIR
//! ```
use std::io::Write;
use std::path::PathBuf;

use primfit_core::ray::{RayModel, RayTable, Rays};
use primfit_core::synth::{SixInARowParams, SixVariant, six_in_a_row};

fn matrix(variant: SixVariant) -> primfit_core::Result<(Vec<f64>, [[f64; 6]; 6])> {
    let toy = six_in_a_row(&SixInARowParams {
        variant,
        ..Default::default()
    })?;
    let rays = Rays::from_cloud(&toy.scene.cloud)?;
    let model = RayModel {
        rate: 0.05,
        sigma: 0.01,
        min_cos: 0.2,
    };
    let table = RayTable::build(&rays, &toy.candidates, model)?;
    let mut m = [[0.0; 6]; 6];
    for (i, row) in m.iter_mut().enumerate() {
        for (k, cell) in row.iter_mut().enumerate() {
            let scene: Vec<bool> = (0..6).map(|c| c == i || c == k).collect();
            *cell = -table.log_likelihood(&scene)?;
        }
    }
    let distances = toy.candidates.iter().map(|c| c.center().x).collect();
    Ok((distances, m))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "target/ray_toy".into()),
    );
    std::fs::create_dir_all(&out)?;
    for (name, variant) in [
        ("six_squares", SixVariant::Squares),
        ("six_cylinders", SixVariant::Cylinders),
    ] {
        let (distances, m) = matrix(variant)?;
        let path = out.join(format!("{name}.csv"));
        let mut f = std::fs::File::create(&path)?;
        let head: Vec<String> = distances.iter().map(|d| format!("{d}")).collect();
        writeln!(f, "nll,{}", head.join(","))?;
        for (d, row) in distances.iter().zip(&m) {
            let cells: Vec<String> = row.iter().map(|v| format!("{v:.6}")).collect();
            writeln!(f, "{d},{}", cells.join(","))?;
        }
        println!("wrote {}", path.display());
    }
    Ok(())
}
