//! The synthetic rooms of issue 14 (`synth::room_presets`): for each, its points and true
//! surfaces, the compact model's segments and primitives against them, and optionally
//! the cloud (PLY, `label` = true surface) and the truth (JSON, DESIGN §3 entries)
//! written for the comparison benches.
//!
//! ```text
//! cargo run --release -p primfit-core --example room_scenes -- [NAME ...] [--write DIR]
//! ```

use std::collections::BTreeMap;
use std::path::PathBuf;

use primfit_core::PointIndex;
use primfit_core::Silent;
use primfit_core::compact::{CompactOptions, compact_model};
use primfit_core::io::{Encoding, write_cloud, write_json_atomic};
use primfit_core::na::Vector3;
use primfit_core::synth::{RoomScene, room, room_presets};

/// The three most frequent true surfaces among `ids` (`(surface, points)`).
fn majority(labels: &[i32], ids: &[usize]) -> Vec<(i32, usize)> {
    let mut counts = BTreeMap::new();
    for &i in ids {
        *counts.entry(labels[i]).or_insert(0usize) += 1;
    }
    let mut v: Vec<(i32, usize)> = counts.into_iter().collect();
    v.sort_by_key(|x| std::cmp::Reverse(x.1));
    v.truncate(3);
    v
}

/// Prints the detection and the compact model of `scene`.
fn report(name: &str, scene: &RoomScene) -> Result<(), Box<dyn std::error::Error>> {
    let points = &scene.cloud.points;
    let labels = scene.cloud.labels.as_deref().unwrap_or_default();
    let index = PointIndex::new(points);
    let model = compact_model(points, &index, &CompactOptions::default(), &Silent)?;
    let d = &model.detection;
    println!(
        "{name}: {} points, {} true surfaces (points each {:?}), σ = {:.5}",
        points.len(),
        scene.truth.len(),
        scene.points_per_surface,
        scene.sigma
    );
    println!(
        "  detection σ {:.5} / {:.5}, spacing {:.5}, {} segments, {} unassigned",
        d.noise,
        d.model_noise,
        d.spacing,
        d.segments.len(),
        d.unassigned.len()
    );
    let room_axis = |v: Vector3<f64>| scene.pose.rotation.inverse() * v;
    for (k, s) in d.segments.iter().enumerate() {
        println!(
            "  segment {k}: {} {} points, rms {:.4}, true surfaces {:?}",
            s.model.name(),
            s.points.len(),
            s.rms,
            majority(labels, &s.points)
        );
    }
    println!(
        "  {} of {} proposed primitives:",
        model.primitives.len(),
        model.proposed
    );
    for (k, p) in model.primitives.iter().enumerate() {
        let axis = room_axis(p.pose.rotation * Vector3::z());
        println!(
            "    {k} {} area {:.3}, axis (room frame) ({:.3}, {:.3}, {:.3})",
            p.shape.kind().name(),
            p.area(),
            axis.x,
            axis.y,
            axis.z
        );
    }
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let (mut names, mut out) = (Vec::new(), None);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--write" => out = args.next().map(PathBuf::from),
            _ => names.push(a),
        }
    }
    for (name, params) in room_presets()? {
        if !names.is_empty() && !names.iter().any(|n| n == name) {
            continue;
        }
        let scene = room(&params)?;
        report(name, &scene)?;
        if let Some(dir) = &out {
            std::fs::create_dir_all(dir)?;
            let cloud = dir.join(format!("{name}.ply"));
            write_cloud(&cloud, &scene.cloud, Encoding::BinaryLittleEndian)?;
            let truth: Vec<_> = scene.truth.iter().map(|p| p.to_json()).collect();
            let json = serde_json::json!({
                "sigma": scene.sigma,
                "points_per_surface": scene.points_per_surface,
                "primitives": truth,
            });
            write_json_atomic(&dir.join(format!("{name}.truth.json")), &json)?;
            println!("  written {}", cloud.display());
        }
    }
    Ok(())
}
