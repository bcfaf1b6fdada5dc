//! Criterion benches of the loss (issue 4): coefficient building and one loss + gradient
//! evaluation, for both point models, at 20k (pipe), 100k and 1M (hallway) points.
//!
//! `cargo bench -p primfit-core --bench chamfer` (a few minutes; 1M groups take 10 short
//! samples). Filter with criterion's usual
//! `cargo bench -p primfit-core --bench chamfer -- evaluate/existence`.

mod common;

use std::time::Duration;

use common::{BenchScene, Kind};
use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, BenchmarkId, Criterion, criterion_group, criterion_main};
use primfit_core::Silent;
use primfit_core::chamfer::{Coefficients, Evaluator, PointModel};

/// The benchmark scenes at each size: a pipe at 20k, the hallway at 100k and 1M.
pub fn scenes(model: PointModel) -> Vec<BenchScene> {
    vec![
        BenchScene::new(Kind::Pipe, 20_000, model),
        BenchScene::new(Kind::Hallway, 100_000, model),
        BenchScene::new(Kind::Hallway, 1_000_000, model),
    ]
}

/// Small sample counts so the whole run takes minutes; 1M inputs get 10 short samples.
pub fn configure(group: &mut BenchmarkGroup<'_, WallTime>, points: usize) {
    if points >= 1_000_000 {
        group.sample_size(10);
        group.warm_up_time(Duration::from_millis(500));
        group.measurement_time(Duration::from_secs(5));
    } else {
        group.sample_size(10);
        group.warm_up_time(Duration::from_millis(500));
        group.measurement_time(Duration::from_secs(3));
    }
}

fn models() -> [PointModel; 2] {
    [PointModel::Existence, PointModel::Independent]
}

/// The independent model at 1M hallway points holds 320 M entries (3.6 GiB): its build
/// alone is tens of seconds, too slow for a few-minute run. `PRIMFIT_BENCH_LARGE=1`
/// includes it.
fn included(scene: &BenchScene) -> bool {
    scene.model == PointModel::Existence
        || scene.points < 1_000_000
        || std::env::var_os("PRIMFIT_BENCH_LARGE").is_some()
}

fn coefficients(c: &mut Criterion) {
    for model in models() {
        let mut group = c.benchmark_group(format!("coefficients/{}", model.name()));
        for scene in scenes(model).iter().filter(|s| included(s)) {
            configure(&mut group, scene.points);
            let cloud = scene.cloud();
            let (settings, candidates) = scene.prepare(&cloud);
            group.bench_with_input(
                BenchmarkId::from_parameter(scene.name()),
                &cloud,
                |b, cloud| {
                    b.iter(|| {
                        Coefficients::build(&cloud.points, &candidates, &settings.chamfer, &Silent)
                            .expect("coefficients")
                    })
                },
            );
        }
        group.finish();
    }
}

fn evaluate(c: &mut Criterion) {
    for model in models() {
        let mut group = c.benchmark_group(format!("evaluate/{}", model.name()));
        for scene in scenes(model).iter().filter(|s| included(s)) {
            configure(&mut group, scene.points);
            let cloud = scene.cloud();
            let (_, _, coeffs) = scene.coefficients(&cloud);
            let n = coeffs.candidates();
            let mut evaluator = Evaluator::new(&coeffs);
            let p = vec![0.5; n];
            let mut grad = vec![0.0; n];
            group.throughput(criterion::Throughput::Elements(coeffs.entries() as u64));
            group.bench_function(BenchmarkId::from_parameter(scene.name()), |b| {
                b.iter(|| evaluator.evaluate(&p, &mut grad).total)
            });
        }
        group.finish();
    }
}

criterion_group!(benches, coefficients, evaluate);
criterion_main!(benches);
