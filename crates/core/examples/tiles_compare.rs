//! Tiled fit vs one fit of the same synthetic floor (issue 18's acceptance comparison).
//!
//! `cargo run --release -p primfit-core --example tiles_compare -- POINTS TILE_SIZE [HALO]`
//! prints, for the single fit and the tiled fit: primitives, point→model and model→point
//! means, the share of model area covered twice, and wall seconds.

use std::time::Instant;

use primfit_core::metrics::{MetricsOptions, double_cover_share, evaluate};
use primfit_core::synth::{SurveyParams, survey};
use primfit_core::tiles::fit_tiled;
use primfit_core::{FitOptions, Primitive, Silent, fit};

fn report(
    name: &str,
    points: &[primfit_core::na::Point3<f64>],
    model: &[Primitive],
    secs: f64,
    h: f64,
) {
    let m = evaluate(points, model, None, &MetricsOptions::default()).expect("metrics");
    let twice = double_cover_share(model, h, h).expect("overlap");
    println!(
        "{name}: {} primitives, point→model mean {:.5}, model→point mean {:.5}, covered twice {:.3} %, {secs:.1} s",
        model.len(),
        m.point_to_model_mean,
        m.model_to_point_mean,
        100.0 * twice
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let points: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(200_000);
    let tile: f64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(15.0);
    let halo: Option<f64> = args.get(3).and_then(|a| a.parse().ok());
    let scene = survey(&SurveyParams {
        points,
        ..Default::default()
    })
    .expect("scene");
    let cloud = scene.cloud;
    println!(
        "floor: {} points, {} true primitives",
        cloud.len(),
        scene.truth.len()
    );
    let options = FitOptions::default();
    let t = Instant::now();
    let tiled = fit_tiled(&cloud, &options, Some(tile), halo, &Silent).expect("tiled fit");
    let tiled_s = t.elapsed().as_secs_f64();
    let h = 3.0 * tiled.settings.point_spacing.max(1e-3);
    report("tiled", &cloud.points, &tiled.primitives, tiled_s, h);
    if std::env::var("SKIP_SINGLE").is_err() {
        let t = Instant::now();
        let single = fit(&cloud, &options, &Silent).expect("single fit");
        let single_s = t.elapsed().as_secs_f64();
        report("single", &cloud.points, &single.primitives, single_s, h);
    }
}
