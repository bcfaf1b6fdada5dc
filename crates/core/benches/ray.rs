//! Ray likelihood benchmarks (thesis §4.3, fig. 4-7): a scene of ~20 000 points from a
//! simulated depth sensor and 500 candidate squares.
//!
//! - `ray/table_build`: the RayTrees and the ray ↔ candidate table for all candidates
//!   (the geometry that the thesis's "from scratch" evaluation redoes every time);
//! - `ray/full_evaluation`: Algorithm 2 on the table, for a scene with ~20 % of the
//!   candidates existing;
//! - `ray/mh_step`: one incremental Metropolis–Hastings step (Algorithm 3): a one-candidate
//!   flip proposal, its likelihood change, accept or reject;
//! - `ray/sampler_1000_steps`: `ray::sample` for 1000 proposals (including its start-up
//!   full evaluation), without the final polish.
//!
//! Thesis (Intel Core i7): 50 ms from scratch, 2 ms incremental, per step.
//!
//! Measured (`cargo bench -p primfit-core --bench ray`, 2 shared cores of an Intel Xeon,
//! 20 266 rays, 4 frames, 500 candidates, 137 712 crossings = 6.8 per ray, 24 B each):
//!
//! | bench | time |
//! |---|---|
//! | `table_build` | 157 ms (once per fit) |
//! | `full_evaluation` | 0.73 ms |
//! | `mh_step` | 16 µs |
//! | `sampler_1000_steps` | 29 ms (29 µs per proposal of ~1.6 flips on average) |
use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use primfit_core::Silent;
use primfit_core::lattice::{CandidateSet, LatticeSpec};
use primfit_core::na::{Point3, UnitQuaternion};
use primfit_core::ray::{
    McmcOptions, PriorOptions, RayModel, RayTable, Rays, SceneState, existence_prior, flip_rates,
    sample,
};
use primfit_core::synth::{HallwayParams, SensorParams, depth_sensor, hallway, walk_poses};
use primfit_core::{Primitive, Shape};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// ~20 000 rays from four frames down a hallway, and 500 supported candidates spread
/// evenly over the lattice.
fn problem() -> (Rays, Vec<Primitive>) {
    let scene = hallway(&HallwayParams::default()).unwrap();
    let poses = walk_poses(
        Point3::new(0.3, 1.0, 1.2),
        Point3::new(6.0, 1.0, 1.2),
        4,
        3.0,
        0.6,
    )
    .unwrap();
    let params = SensorParams {
        poses,
        columns: 80,
        rows: 70,
        ..Default::default()
    };
    let cloud = depth_sensor(&scene.truth, &params).unwrap();
    let spec = LatticeSpec {
        shapes: vec![Shape::Square { side: 1.0 }],
        spacing: 0.5,
        origin: Point3::origin(),
        frame: UnitQuaternion::identity(),
        sample_spacing: 0.1,
    };
    let set = CandidateSet::build(&spec, &cloud).unwrap();
    let all: Vec<Primitive> = (0..set.len()).map(|i| set.primitive(i)).collect();
    let prior = existence_prior(&cloud, &all, &PriorOptions::new(0.5)).unwrap();
    let supported: Vec<Primitive> = all
        .into_iter()
        .zip(prior)
        .filter(|(_, p)| *p > 0.0)
        .map(|(c, _)| c)
        .collect();
    let stride = supported.len() as f64 / 500.0;
    let candidates = (0..500)
        .map(|k| supported[(k as f64 * stride) as usize].clone())
        .collect();
    (Rays::from_cloud(&cloud).unwrap(), candidates)
}

fn model() -> RayModel {
    RayModel {
        rate: 0.1,
        sigma: 0.05,
        min_cos: 0.2,
    }
}

fn bench(c: &mut Criterion) {
    let (rays, candidates) = problem();
    let table = RayTable::build(&rays, &candidates, model()).unwrap();
    eprintln!(
        "ray bench: {} rays, {} frames, {} candidates, {} crossings ({:.1} per ray)",
        table.rays(),
        table.frames(),
        table.candidates(),
        table.entries(),
        table.entries() as f64 / table.rays() as f64
    );
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let exists: Vec<bool> = (0..500).map(|_| rng.random::<f64>() < 0.2).collect();
    let mut group = c.benchmark_group("ray");
    group.sample_size(10);
    group.bench_function("table_build", |b| {
        b.iter(|| RayTable::build(black_box(&rays), &candidates, model()).unwrap())
    });
    group.sample_size(50);
    group.bench_function("full_evaluation", |b| {
        b.iter(|| table.log_likelihood(black_box(&exists)).unwrap())
    });
    let mut state = SceneState::new(&table, exists.clone()).unwrap();
    group.bench_function("mh_step", |b| {
        b.iter(|| {
            let i = rng.random_range(0..500u32);
            let d = state.propose(&[i]).unwrap();
            if d >= 0.0 || rng.random::<f64>().ln() < d {
                state.accept();
            } else {
                state.reject();
            }
        })
    });
    let prior = vec![0.1; 500];
    let options = McmcOptions {
        steps: 1000,
        burn_in: 0,
        polish: false,
        ..Default::default()
    };
    let rates = flip_rates(&table, &prior, &options).unwrap();
    group.sample_size(10);
    group.bench_function("sampler_1000_steps", |b| {
        b.iter(|| sample(&table, &prior, &rates, &options, &Silent).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
