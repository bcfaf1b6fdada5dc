//! The toys of thesis §4.3 under the ray likelihood and under the hybrid loss (chamfer +
//! free space): the six-in-a-row (fig. 4-4; squares and cylinders at 7..12 m, points
//! from the one at 10 m) and the misaligned plane (fig. 4-6, table 4.1: points on a plane
//! at 10 m, candidates 10 cm in front of it and 10 cm behind it). Prints markdown
//! tables; results in `docs/free_space.md`.
//!
//! ```text
//! cargo run --release -p primfit-core --example thesis_toys
//! ```
use primfit_core::chamfer::{ChamferOptions, Coefficients, Evaluator};
use primfit_core::lattice::CandidateSet;
use primfit_core::ray::{FreeSpace, RayModel, RayTable, Rays};
use primfit_core::synth::{SixInARowParams, SixVariant, six_in_a_row};
use primfit_core::{PointCloud, Primitive, Result, Silent};

/// The ray model of both toys (the one of `ray_toy_heatmap`).
const MODEL: RayModel = RayModel {
    rate: 0.05,
    sigma: 0.01,
    min_cos: 0.2,
};
/// The chamfer's cap distance of the hybrid loss (m): `d_cap = CAP²`.
const CAP: f64 = 0.5;
/// Candidate sample spacing of the hybrid loss (m).
const SAMPLES: f64 = 0.05;

/// The ray log-likelihood and the hybrid loss (chamfer + free space) of every scene.
struct Scores {
    log_likelihood: Vec<f64>,
    hybrid: Vec<f64>,
    free: Vec<f64>,
}

fn score(cloud: &PointCloud, candidates: &[Primitive], scenes: &[Vec<bool>]) -> Result<Scores> {
    let rays = Rays::from_cloud(cloud)?;
    let table = RayTable::build(&rays, candidates, MODEL)?;
    let set = CandidateSet::from_primitives(candidates, SAMPLES)?;
    let loss = ChamferOptions {
        cap: CAP * CAP,
        surface_distance: true,
        ..Default::default()
    };
    let coeffs = Coefficients::build(&cloud.points, &set, &loss, &Silent)?;
    let mut chamfer = Evaluator::new(&coeffs);
    let free = FreeSpace::build(&rays, candidates, CAP * CAP)?;
    let mut out = Scores {
        log_likelihood: Vec::new(),
        hybrid: Vec::new(),
        free: Vec::new(),
    };
    for s in scenes {
        out.log_likelihood.push(table.log_likelihood(s)?);
        let f = free.binary_value(s)?;
        out.hybrid.push(chamfer.binary_value(s).total + f);
        out.free.push(f);
    }
    Ok(out)
}

/// `ln` of each scene's share of `Σ exp(ll)` (the thesis's table 4.1 normalisation).
fn normalised(ll: &[f64]) -> Vec<f64> {
    let top = ll.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let z = top + ll.iter().map(|l| (l - top).exp()).sum::<f64>().ln();
    ll.iter().map(|l| l - z).collect()
}

fn six(variant: SixVariant) -> Result<()> {
    let toy = six_in_a_row(&SixInARowParams {
        variant,
        ..Default::default()
    })?;
    let scenes: Vec<Vec<bool>> = (0..6).map(|i| (0..6).map(|k| k == i).collect()).collect();
    let s = score(&toy.scene.cloud, &toy.candidates, &scenes)?;
    println!("\n{variant:?}: one candidate at a time (points from the one at 10 m)\n");
    println!(
        "| candidate at | −log-likelihood (nats) | chamfer only (m²) | hybrid: + free space (m²) |"
    );
    println!("|---|---|---|---|");
    for (i, c) in toy.candidates.iter().enumerate() {
        println!(
            "| {:.0} m | {:.1} | {:.2} | {:.2} |",
            c.center().x,
            -s.log_likelihood[i],
            s.hybrid[i] - s.free[i],
            s.hybrid[i]
        );
    }
    Ok(())
}

fn misaligned() -> Result<()> {
    // Candidates 9.9, 10.0, 10.1 m …; points from the one at 10.0 m, which is left out.
    let toy = six_in_a_row(&SixInARowParams {
        first: 9.9,
        step: 0.1,
        true_index: 1,
        ..Default::default()
    })?;
    let candidates = vec![toy.candidates[0].clone(), toy.candidates[2].clone()];
    let names = ["empty", "front only", "back only", "both"];
    let scenes = vec![
        vec![false, false],
        vec![true, false],
        vec![false, true],
        vec![true, true],
    ];
    let s = score(&toy.scene.cloud, &candidates, &scenes)?;
    let share = normalised(&s.log_likelihood);
    let thesis = [
        "−0.69 (50 %)",
        "−358.2 (0 %)",
        "−0.69 (50 %)",
        "−358.2 (0 %)",
    ];
    println!("\nmisaligned plane: candidates 10 cm in front of and behind the points\n");
    println!(
        "| scene | thesis table 4.1 | ours: normalised log-likelihood | ours: chamfer only (m²) | ours: hybrid (m²) |"
    );
    println!("|---|---|---|---|---|");
    for k in 0..4 {
        println!(
            "| {} | {} | {:.2} ({:.0} %) | {:.2} | {:.2} |",
            names[k],
            thesis[k],
            share[k],
            100.0 * share[k].exp(),
            s.hybrid[k] - s.free[k],
            s.hybrid[k]
        );
    }
    Ok(())
}

fn main() -> Result<()> {
    six(SixVariant::Squares)?;
    six(SixVariant::Cylinders)?;
    misaligned()
}
