//! scratch diagnostics (not committed)
mod common;
use common::{measure, pipe_options, pipe_scene};
use primfit::fit::fit;
use primfit::progress::Progress;
use primfit::refine::RefineOptions;
struct P;
impl Progress for P {
    fn message(&self, t: &str) {
        if !t.starts_with("settings") {
            eprintln!("  {t}");
        } else {
            let v: Vec<&str> = t
                .split(",")
                .filter(|x| {
                    x.contains("noise")
                        || x.contains("point_spacing")
                        || x.contains("sample_spacing")
                })
                .collect();
            eprintln!("  {v:?}");
        }
    }
}
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let spacing: f64 = a[1].parse().unwrap();
    let seeds: Vec<u64> = a[2].split(',').map(|s| s.parse().unwrap()).collect();
    for seed in seeds {
        let scene = pipe_scene(1000 + seed);
        let mut o = pipe_options(spacing);
        o.refine = Some(RefineOptions::default());
        let r = fit(&scene.cloud, &o, &P).unwrap();
        let m = measure(&scene, &r.primitives, 0.0);
        let t = measure(&scene, &scene.truth, 0.0);
        println!(
            "seed {seed}: {} prims (truth {}), chamfer {:.2} (truth {:.2}), p2m {:.4} (truth {:.4})",
            r.primitives.len(),
            scene.truth.len(),
            m.chamfer,
            t.chamfer,
            m.point_to_model,
            t.point_to_model
        );
        if a.len() > 3 {
            for p in &r.primitives {
                println!("   {:?} at {:.3?}", p.shape, p.pose.translation.as_slice());
            }
            for p in &scene.truth {
                println!(" T {:?} at {:.3?}", p.shape, p.pose.translation.as_slice());
            }
        }
    }
}
