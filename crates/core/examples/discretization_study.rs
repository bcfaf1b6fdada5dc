//! The discretisation study of thesis §6.3.1 / figure 6-2: lattice spacing `2^i × base`
//! (`i = −2..2`, base 0.5 = half the segment length, the spacing on which the pipe's truth
//! lives), each level over N trials (default 20) of a pipe at a random alignment (a shift
//! of up to one base step). Prints a markdown table of the DESIGN §4 chamfer error,
//! point→model mean and wall time per level, with and without refinement.
//!
//! `cargo run --release --example discretization_study [TRIALS]`

mod common;

use common::{fit_trials, header, pipe_options, row, trials, truth_outcomes, truth_row};

fn main() {
    let n = trials();
    let base = 0.5;
    println!("{}", header("level i (spacing)"));
    let truth = truth_outcomes(n);
    for i in -2i32..=2 {
        let spacing = base * 2f64.powi(i);
        let options = pipe_options(spacing);
        let (plain, refined) = fit_trials(n, &options);
        println!("{}", row(&format!("{i} ({spacing})"), &plain, &refined));
    }
    println!("{}", truth_row(&truth));
}
