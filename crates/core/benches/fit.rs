//! Criterion bench of a whole fit (lattice, coefficients, L-BFGS, threshold, polish) for
//! both point models at 20k (pipe), 100k and 1M (hallway) points.
//!
//! `cargo bench -p primfit-core --bench fit`. The 1M independent fit is left out unless
//! `PRIMFIT_BENCH_LARGE=1` (it builds 320 M entries per iteration).

mod common;

use std::time::Duration;

use common::{BenchScene, Kind};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use primfit_core::Silent;
use primfit_core::chamfer::PointModel;
use primfit_core::fit::fit;

fn whole_fit(c: &mut Criterion) {
    for model in [PointModel::Existence, PointModel::Independent] {
        let mut group = c.benchmark_group(format!("fit/{}", model.name()));
        group.sample_size(10);
        group.warm_up_time(Duration::from_millis(100));
        for (kind, points) in [
            (Kind::Pipe, 20_000),
            (Kind::Hallway, 100_000),
            (Kind::Hallway, 1_000_000),
        ] {
            let scene = BenchScene::new(kind, points, model);
            if model == PointModel::Independent
                && points >= 1_000_000
                && std::env::var_os("PRIMFIT_BENCH_LARGE").is_none()
            {
                continue;
            }
            // A 1M fit takes seconds: 10 samples is already most of a minute.
            group.measurement_time(Duration::from_secs(if points >= 1_000_000 {
                20
            } else {
                5
            }));
            let cloud = scene.cloud();
            let options = scene.options();
            group.bench_with_input(
                BenchmarkId::from_parameter(scene.name()),
                &cloud,
                |b, cloud| b.iter(|| fit(cloud, &options, &Silent).expect("fit").primitives.len()),
            );
        }
        group.finish();
    }
}

criterion_group!(benches, whole_fit);
criterion_main!(benches);
