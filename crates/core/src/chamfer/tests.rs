//! Chamfer tests: brute-force expectations, explicit formulas, finite differences.

use nalgebra::Point3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;
use crate::progress::Silent;

/// A random small problem: J points, N candidates with 1..=4 samples each.
struct Problem {
    cloud: Vec<Point3<f64>>,
    samples: Vec<Point3<f64>>,
    owner: Vec<usize>,
    n: usize,
    p: Vec<f64>,
}

fn random_problem(seed: u64, n: usize, j: usize) -> Problem {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let pt = |rng: &mut ChaCha8Rng| {
        Point3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
    };
    let cloud = (0..j).map(|_| pt(&mut rng)).collect();
    let mut samples = Vec::new();
    let mut owner = Vec::new();
    for i in 0..n {
        for _ in 0..rng.random_range(1..=4) {
            samples.push(pt(&mut rng));
            owner.push(i);
        }
    }
    // Interleave owners so grouping is exercised.
    let p = (0..n).map(|_| rng.random_range(0.02..0.98)).collect();
    Problem {
        cloud,
        samples,
        owner,
        n,
        p,
    }
}

fn coefficients(pr: &Problem, opts: &ChamferOptions) -> Coefficients {
    let sets = SampleSets::new(&pr.samples, &pr.owner, pr.n).unwrap();
    Coefficients::build(&pr.cloud, &sets, opts, &Silent).unwrap()
}

fn loss(pr: &Problem, opts: &ChamferOptions, p: &[f64]) -> (LossValue, Vec<f64>) {
    let c = coefficients(pr, opts);
    let mut ev = Evaluator::new(&c);
    let mut g = vec![0.0; pr.n];
    let v = ev.evaluate(p, &mut g);
    (v, g)
}

fn sq(a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    (a - b).norm_squared()
}

/// Expected binary chamfer by enumerating all 2^N scenes (existence semantics).
fn brute_force_existence(pr: &Problem, cap: f64) -> (f64, f64) {
    let (mut prim, mut point) = (0.0, 0.0);
    let g: Vec<f64> = (0..pr.n)
        .map(|i| {
            pr.samples
                .iter()
                .zip(&pr.owner)
                .filter(|(_, o)| **o == i)
                .map(|(x, _)| {
                    pr.cloud
                        .iter()
                        .map(|y| sq(x, y))
                        .fold(f64::INFINITY, f64::min)
                })
                .sum()
        })
        .collect();
    for mask in 0u32..(1 << pr.n) {
        let exists = |i: usize| mask & (1 << i) != 0;
        let prob: f64 = (0..pr.n)
            .map(|i| if exists(i) { pr.p[i] } else { 1.0 - pr.p[i] })
            .product();
        prim += prob * (0..pr.n).filter(|&i| exists(i)).map(|i| g[i]).sum::<f64>();
        let pt: f64 = pr
            .cloud
            .iter()
            .map(|y| {
                pr.samples
                    .iter()
                    .zip(&pr.owner)
                    .filter(|(_, o)| exists(**o))
                    .map(|(x, _)| sq(x, y))
                    .fold(f64::INFINITY, f64::min)
            })
            .map(|d| if d.is_finite() { d } else { cap })
            .sum();
        point += prob * pt;
    }
    (prim, point)
}

/// DESIGN §2 `independent` formula, written out with explicit products.
fn explicit_independent(pr: &Problem, cap: f64) -> f64 {
    pr.cloud
        .iter()
        .map(|y| {
            let mut e: Vec<(f64, usize)> = pr
                .samples
                .iter()
                .zip(&pr.owner)
                .map(|(x, &o)| (sq(x, y), o))
                .collect();
            e.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut total = 0.0;
            for k in 0..e.len() {
                let before: f64 = e[..k].iter().map(|(_, o)| 1.0 - pr.p[*o]).product();
                total += e[k].0 * pr.p[e[k].1] * before;
            }
            total + e.iter().map(|(_, o)| 1.0 - pr.p[*o]).product::<f64>() * cap
        })
        .sum()
}

fn rel_close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs()).max(1e-300)
}

#[test]
fn existence_model_equals_brute_force_enumeration() {
    for seed in 0..12 {
        let n = 1 + (seed as usize % 10);
        let pr = random_problem(seed, n, 7);
        let cap = 0.3 + seed as f64 * 0.1;
        let opts = ChamferOptions {
            cap,
            ..Default::default()
        };
        let (v, _) = loss(&pr, &opts, &pr.p);
        let (prim, point) = brute_force_existence(&pr, cap);
        assert!(
            rel_close(v.primitive, prim, 1e-9),
            "seed {seed}: primitive {} vs {prim}",
            v.primitive
        );
        assert!(
            rel_close(v.point, point, 1e-9),
            "seed {seed}: point {} vs {point}",
            v.point
        );
        assert!(rel_close(v.total, prim + point, 1e-9));
    }
}

#[test]
fn independent_model_equals_explicit_formula() {
    for seed in 0..10 {
        let pr = random_problem(100 + seed, 1 + seed as usize % 8, 6);
        let cap = 0.5;
        let opts = ChamferOptions {
            model: PointModel::Independent,
            cap,
            ..Default::default()
        };
        let (v, _) = loss(&pr, &opts, &pr.p);
        assert!(
            rel_close(v.point, explicit_independent(&pr, cap), 1e-9),
            "seed {seed}"
        );
    }
}

fn check_gradient(pr: &Problem, opts: &ChamferOptions) {
    let (_, g) = loss(pr, opts, &pr.p);
    let c = coefficients(pr, opts);
    let mut ev = Evaluator::new(&c);
    let mut scratch = vec![0.0; pr.n];
    let h = 1e-6;
    for i in 0..pr.n {
        let mut plus = pr.p.clone();
        plus[i] += h;
        let mut minus = pr.p.clone();
        minus[i] -= h;
        let fd = (ev.evaluate(&plus, &mut scratch).total - ev.evaluate(&minus, &mut scratch).total)
            / (2.0 * h);
        assert!(
            (fd - g[i]).abs() <= 1e-6 * (1.0 + fd.abs()),
            "∂/∂p_{i}: analytic {} vs fd {fd} ({opts:?})",
            g[i]
        );
    }
}

#[test]
fn gradients_match_central_differences() {
    for seed in 0..6 {
        let pr = random_problem(200 + seed, 6, 9);
        for model in [PointModel::Existence, PointModel::Independent] {
            for (alpha, beta) in [(None, None), (Some(2), Some(3)), (Some(1), Some(1))] {
                let opts = ChamferOptions {
                    model,
                    alpha,
                    beta,
                    cap: 0.7,
                    surface_distance: false,
                    primitive_weight: 0.5,
                    point_weight: 2.0,
                };
                check_gradient(&pr, &opts);
            }
        }
    }
}

#[test]
fn unlimited_alpha_beta_equal_exact_mode() {
    let pr = random_problem(7, 8, 10);
    for model in [PointModel::Existence, PointModel::Independent] {
        let exact = ChamferOptions {
            model,
            cap: 0.4,
            ..Default::default()
        };
        let large = ChamferOptions {
            alpha: Some(1000),
            beta: Some(1000),
            ..exact.clone()
        };
        let (a, ga) = loss(&pr, &exact, &pr.p);
        let (b, gb) = loss(&pr, &large, &pr.p);
        assert_eq!(a, b);
        assert_eq!(ga, gb);
    }
}

#[test]
fn truncation_degrades_gracefully() {
    // With d_cap above every distance, dropping entries can only raise E_y, and the
    // error shrinks to zero as α and β grow.
    let pr = random_problem(11, 10, 40);
    for model in [PointModel::Existence, PointModel::Independent] {
        let exact = ChamferOptions {
            model,
            cap: 20.0,
            ..Default::default()
        };
        let reference = loss(&pr, &exact, &pr.p).0.point;
        let mut previous = f64::INFINITY;
        for beta in [1, 2, 3, 5, 8, 10] {
            let v = loss(
                &pr,
                &ChamferOptions {
                    beta: Some(beta),
                    ..exact.clone()
                },
                &pr.p,
            )
            .0
            .point;
            assert!(
                v >= reference - 1e-12 && v <= previous + 1e-12,
                "{model:?} β={beta}: {v}"
            );
            previous = v;
        }
        assert!(rel_close(previous, reference, 1e-12));
    }
    let exact = ChamferOptions {
        model: PointModel::Independent,
        cap: 20.0,
        ..Default::default()
    };
    let reference = loss(&pr, &exact, &pr.p).0.point;
    let mut previous = f64::INFINITY;
    for alpha in [1, 2, 3, 4] {
        let v = loss(
            &pr,
            &ChamferOptions {
                alpha: Some(alpha),
                ..exact.clone()
            },
            &pr.p,
        )
        .0
        .point;
        assert!(
            v >= reference - 1e-12 && v <= previous + 1e-12,
            "α={alpha}: {v}"
        );
        previous = v;
    }
    assert!(rel_close(previous, reference, 1e-12));
}

#[test]
fn beta_search_matches_brute_force_selection() {
    // The expanding search must find exactly the β nearest candidates.
    let pr = random_problem(5, 30, 50);
    let opts = ChamferOptions {
        beta: Some(4),
        cap: 0.01,
        ..Default::default()
    };
    let c = coefficients(&pr, &opts);
    let sets = SampleSets::new(&pr.samples, &pr.owner, pr.n).unwrap();
    for (j, y) in pr.cloud.iter().enumerate() {
        let mut all: Vec<(f64, u32)> = (0..pr.n)
            .map(|i| (sets.nearest_sample(i, y).1, i as u32))
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let expect: Vec<u32> = all[..4].iter().map(|e| e.1).collect();
        assert_eq!(&c.cand[c.row(j)], &expect[..]);
    }
}

#[test]
fn binary_value_is_the_binary_chamfer() {
    let pr = random_problem(3, 5, 12);
    let opts = ChamferOptions {
        cap: 0.9,
        ..Default::default()
    };
    let c = coefficients(&pr, &opts);
    let mut ev = Evaluator::new(&c);
    let exists = [true, false, true, false, false];
    let v = ev.binary_value(&exists);
    let point: f64 = pr
        .cloud
        .iter()
        .map(|y| {
            let d = pr
                .samples
                .iter()
                .zip(&pr.owner)
                .filter(|(_, o)| exists[**o])
                .map(|(x, _)| sq(x, y))
                .fold(f64::INFINITY, f64::min);
            d.min(f64::MAX)
        })
        .sum();
    assert!(rel_close(v.point, point, 1e-12));
}

#[test]
fn all_existing_options_give_the_same_binary_chamfer_bit_for_bit() {
    // Every candidate exists: under the existence model each point costs its nearest
    // candidate whatever β, so β = 1 must give the same bits as β = 8 and β = ∞ (small
    // cap: far points are capped, near ones not).
    let pr = random_problem(21, 30, 400);
    for cap in [0.01, 10.0] {
        let full = ChamferOptions {
            cap,
            primitive_weight: 0.7,
            ..Default::default()
        };
        let all = vec![true; pr.n];
        let value = |o: &ChamferOptions| Evaluator::new(&coefficients(&pr, o)).binary_value(&all);
        let reduced = full.for_all_existing();
        assert_eq!(reduced.beta, Some(1));
        let expect = value(&full);
        assert_eq!(value(&reduced), expect, "cap {cap}");
        let beta8 = ChamferOptions {
            beta: Some(8),
            ..full.clone()
        };
        assert_eq!(value(&beta8.for_all_existing()), value(&beta8), "cap {cap}");
    }
    // The independent model sums over its entries: its options are kept.
    let independent = ChamferOptions {
        model: PointModel::Independent,
        alpha: Some(3),
        beta: Some(5),
        cap: 1.0,
        ..Default::default()
    };
    assert_eq!(independent.for_all_existing(), independent);
}

#[test]
fn evaluation_is_bit_identical_across_thread_counts() {
    let pr = random_problem(9, 40, 3000);
    let opts = ChamferOptions {
        beta: Some(6),
        cap: 0.2,
        ..Default::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let c = coefficients(&pr, &opts);
            let mut ev = Evaluator::new(&c);
            let mut g = vec![0.0; pr.n];
            let v = ev.evaluate(&pr.p, &mut g);
            (c.cand.clone(), c.dist.clone(), v, g)
        })
    };
    let a = run(1);
    let b = run(2);
    assert_eq!(a.0, b.0);
    assert_eq!(a.1, b.1);
    assert_eq!(a.2, b.2);
    assert_eq!(a.3, b.3);
}

#[test]
fn bad_sample_sets_are_errors() {
    let s = [Point3::origin(), Point3::new(1.0, 0.0, 0.0)];
    assert!(SampleSets::new(&s, &[0], 1).is_err());
    assert!(SampleSets::new(&s, &[0, 2], 2).is_err());
    assert!(SampleSets::new(&s, &[0, 0], 2).is_err());
    assert!(
        ChamferOptions {
            beta: Some(0),
            ..Default::default()
        }
        .validate()
        .is_err()
    );
    assert!(
        ChamferOptions {
            cap: f64::NAN,
            ..Default::default()
        }
        .validate()
        .is_err()
    );
}

/// Row sampling keeps whole rows and rescales the point weight by J / rows kept.
#[test]
fn row_sample_keeps_whole_rows_and_reweights() {
    let (cloud, sets) = crate::chamfer::test_problems::segments(1);
    let o = ChamferOptions {
        cap: 0.05,
        beta: Some(4),
        ..Default::default()
    };
    let c = Coefficients::build(&cloud, &sets, &o, &Silent).unwrap();
    let sub = c.row_sample(c.points() / 4);
    let kept = sub.points();
    assert!(kept > 0 && kept < c.points(), "{kept} of {}", c.points());
    let scale = sub.options.point_weight / c.options.point_weight;
    assert!((scale - c.points() as f64 / kept as f64).abs() < 1e-12);
    // Each kept row is a row of the full coefficients.
    let full: Vec<(Vec<u32>, Vec<u64>)> = (0..c.points())
        .map(|j| {
            let r = c.row(j);
            (
                c.cand[r.clone()].to_vec(),
                c.dist[r].iter().map(|d| d.to_bits()).collect(),
            )
        })
        .collect();
    for j in 0..kept {
        let r = sub.row(j);
        let row = (
            sub.cand[r.clone()].to_vec(),
            sub.dist[r].iter().map(|d| d.to_bits()).collect(),
        );
        assert!(full.contains(&row));
    }
    assert_eq!(c.row_sample(usize::MAX).entries(), c.entries());
}
