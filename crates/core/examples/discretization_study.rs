//! The discretisation study of thesis §6.3.1 / figure 6-2: lattice spacing `2^i × base`
//! (`i = −2..2`, base 0.5 = half the segment length, the spacing on which the pipe's truth
//! lives), each level over N trials (default 20) of a pipe at a random alignment (a shift
//! of up to one base step). Prints a markdown table of the DESIGN §4 chamfer error,
//! point→model mean and wall time per level, with and without refinement.
//!
//! `cargo run --release --example discretization_study [TRIALS]`

mod common;

use common::{fit_both, header, measure, pipe_options, pipe_scene, row, trials, truth_row};

fn main() {
    let n = trials();
    let base = 0.5;
    println!("{}", header("level i (spacing)"));
    let truth: Vec<_> = (0..n)
        .map(|seed| {
            let scene = pipe_scene(1000 + seed);
            measure(&scene, &scene.truth, 0.0)
        })
        .collect();
    for i in -2i32..=2 {
        let spacing = base * 2f64.powi(i);
        let options = pipe_options(spacing);
        let (mut plain, mut refined) = (Vec::new(), Vec::new());
        for seed in 0..n {
            let scene = pipe_scene(1000 + seed);
            let (p, r) = fit_both(&scene, &options);
            plain.push(p);
            refined.push(r);
        }
        println!("{}", row(&format!("{i} ({spacing})"), &plain, &refined));
    }
    println!("{}", truth_row(&truth));
}
