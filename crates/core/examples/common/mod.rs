//! Shared by the study examples (`discretization_study`, `alpha_study`): the pipe scene of
//! thesis §6.3.1 at a random alignment, one timed fit with and without refinement, and
//! mean ± standard deviation.

use std::time::Instant;

use primfit_core::ShapeKind;
use primfit_core::Silent;
use primfit_core::fit::{FitOptions, fit};
use primfit_core::metrics::{MetricsOptions, evaluate};
use primfit_core::refine::RefineOptions;
use primfit_core::synth::{Density, Misalignment, Noise, PipeParams, Scene, pipe};

/// The seed of trial 0; trial `k` is the pipe of seed `FIRST_SEED + k`.
pub const FIRST_SEED: u64 = 1000;

/// Error and time of one fit.
#[derive(Debug, Clone, Copy)]
pub struct Outcome {
    /// DESIGN §4 chamfer: squared distances summed both ways (scene units²).
    pub chamfer: f64,
    /// Mean point→model distance (scene units).
    pub point_to_model: f64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// A pipe of 3 runs (segment length 1, bend 0.5, radius 0.1, jitter 5 mm) shifted by a
/// random vector of up to one base lattice step (0.5) against the lattice: trial `seed`.
pub fn pipe_scene(seed: u64) -> Scene {
    pipe(&PipeParams {
        segments: 3,
        max_run: 2,
        density: Density::PerArea(500.0),
        noise: Noise {
            jitter: 0.005,
            drift: 0.0,
        },
        misalignment: Misalignment {
            offset: 1.0,
            angle: 0.0,
        },
        seed,
        ..Default::default()
    })
    .expect("pipe parameters are valid")
}

/// Fit options for the pipe's true types and sizes at lattice `spacing`.
pub fn pipe_options(spacing: f64) -> FitOptions {
    FitOptions {
        kinds: vec![ShapeKind::Cylinder, ShapeKind::Elbow],
        size: Some(1.0),
        radius: Some(0.1),
        bend: Some(0.5),
        spacing: Some(spacing),
        // The thesis's cap is tied to the base lattice, not to the level under study.
        cap: Some(0.5),
        ..FitOptions::lattice()
    }
}

/// The DESIGN §4 measures of `prims` against `scene`'s cloud, with `seconds`.
pub fn measure(scene: &Scene, prims: &[primfit_core::Primitive], seconds: f64) -> Outcome {
    let m =
        evaluate(&scene.cloud.points, prims, None, &MetricsOptions::default()).expect("metrics");
    Outcome {
        chamfer: m.chamfer,
        point_to_model: m.point_to_model_mean,
        seconds,
    }
}

/// Fits `scene` with `options` as given (no refinement) and again with refinement
/// ([`RefineOptions::default`]: refinement, merging, coarse-to-fine gap filling):
/// returns both outcomes.
pub fn fit_both(scene: &Scene, options: &FitOptions) -> (Outcome, Outcome) {
    let run = |o: &FitOptions| {
        let t0 = Instant::now();
        let r = fit(&scene.cloud, o, &Silent).expect("fit");
        measure(scene, &r.primitives, t0.elapsed().as_secs_f64())
    };
    let refined = FitOptions {
        refine: Some(RefineOptions::default()),
        ..options.clone()
    };
    (run(options), run(&refined))
}

/// The measures of the true primitives of trials `0..n` (no time).
pub fn truth_outcomes(n: u64) -> Vec<Outcome> {
    (0..n)
        .map(|k| {
            let scene = pipe_scene(FIRST_SEED + k);
            measure(&scene, &scene.truth, 0.0)
        })
        .collect()
}

/// [`fit_both`] on trials `0..n`: the plain outcomes and the refined ones, in trial order.
pub fn fit_trials(n: u64, options: &FitOptions) -> (Vec<Outcome>, Vec<Outcome>) {
    (0..n)
        .map(|k| fit_both(&pipe_scene(FIRST_SEED + k), options))
        .unzip()
}

/// `mean ± std` of `values` (population standard deviation), `precision` decimals.
pub fn mean_std(values: &[f64], precision: usize) -> String {
    let n = values.len().max(1) as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    format!("{mean:.precision$} ± {:.precision$}", var.sqrt())
}

/// The number of trials: the first command-line argument, default 20.
pub fn trials() -> u64 {
    std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20)
}

/// One markdown row: label, then chamfer, point→model and time, plain and refined.
pub fn row(label: &str, plain: &[Outcome], refined: &[Outcome]) -> String {
    let pick = |o: &[Outcome], f: fn(&Outcome) -> f64| o.iter().map(f).collect::<Vec<f64>>();
    format!(
        "| {label} | {} | {} | {} | {} | {} | {} |",
        mean_std(&pick(plain, |o| o.chamfer), 2),
        mean_std(&pick(refined, |o| o.chamfer), 2),
        mean_std(&pick(plain, |o| o.point_to_model), 4),
        mean_std(&pick(refined, |o| o.point_to_model), 4),
        mean_std(&pick(plain, |o| o.seconds), 2),
        mean_std(&pick(refined, |o| o.seconds), 2),
    )
}

/// A last row with the measures of the true primitives (no time).
pub fn truth_row(truth: &[Outcome]) -> String {
    let pick = |f: fn(&Outcome) -> f64| truth.iter().map(f).collect::<Vec<f64>>();
    let c = mean_std(&pick(|o| o.chamfer), 2);
    let p = mean_std(&pick(|o| o.point_to_model), 4);
    format!("| truth | {c} | {c} | {p} | {p} | – | – |")
}

/// The table header matching [`row`].
pub fn header(label: &str) -> String {
    format!(
        "| {label} | chamfer (lattice) | chamfer (refined) | point→model mean (lattice) | point→model mean (refined) | time s (lattice) | time s (refined) |\n|---|---|---|---|---|---|---|"
    )
}
