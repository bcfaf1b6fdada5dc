//! scratch
#[path = "../benches/common/mod.rs"]
mod common;
fn main() {
    for name in std::env::args().skip(1) {
        let scene = common::BenchScene::parse(&name).unwrap();
        let cloud = scene.cloud();
        let (settings, cands, co) = scene.coefficients(&cloud);
        let mut last: Vec<f64> = (0..co.points()).map(|j| { let r = co.row(j); co.dist[r.end-1].sqrt() }).collect();
        last.sort_by(|a,b| a.total_cmp(b));
        let q = |f: f64| last[((last.len()-1) as f64 * f) as usize];
        println!("{name}: cap {} n {} maxr {:?} beta-th dist quantiles 0 {:.3} 10% {:.3} 50% {:.3} 90% {:.3} 99% {:.3} max {:.3}", settings.chamfer.cap.sqrt(), cands.templates.len(), cands.templates.iter().map(|t| t.radius).collect::<Vec<_>>(), q(0.0), q(0.1), q(0.5), q(0.9), q(0.99), q(1.0));
    }
}
