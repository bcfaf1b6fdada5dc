//! The α study of thesis §6.3.1 / figure 6-3: the `independent` point model with
//! α ∈ {1, 2, 5, 10, 20} sample points per (point, candidate), on the base lattice
//! (spacing 0.5), each over N trials (default 20) of a pipe at a random alignment.
//! Prints a markdown table of the DESIGN §4 chamfer error, point→model mean and wall
//! time per α, with and without refinement.
//!
//! `cargo run --release --example alpha_study [TRIALS]`

mod common;

use common::{fit_trials, header, pipe_options, row, trials, truth_outcomes, truth_row};
use primfit_core::Limit;
use primfit_core::chamfer::PointModel;

fn main() {
    let n = trials();
    println!("{}", header("α"));
    let truth = truth_outcomes(n);
    for alpha in [1usize, 2, 5, 10, 20] {
        let mut options = pipe_options(0.5);
        options.model = PointModel::Independent;
        options.alpha = Limit::At(alpha);
        let (plain, refined) = fit_trials(n, &options);
        println!("{}", row(&alpha.to_string(), &plain, &refined));
    }
    println!("{}", truth_row(&truth));
}
