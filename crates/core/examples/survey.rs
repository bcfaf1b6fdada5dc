//! Writes a survey-sized synthetic scene ([`primfit_core::synth::survey`]) for tiled
//! fitting: `cargo run --release -p primfit-core --example survey -- floor|street POINTS
//! OUT.laz|OUT.ply [EXTENT_X EXTENT_Y CELL]`. LAZ/LAS at 1 mm steps.

use std::path::Path;

use primfit_core::io::{self, Encoding, write_las};
use primfit_core::synth::{SurveyKind, SurveyParams, survey};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        return Err(
            "usage: survey floor|street POINTS OUT.laz|OUT.ply [EXTENT_X EXTENT_Y CELL]".into(),
        );
    }
    let kind = match args[1].as_str() {
        "floor" => SurveyKind::Floor,
        "street" => SurveyKind::Street,
        other => return Err(format!("unknown survey kind {other}: floor or street").into()),
    };
    let mut params = SurveyParams {
        kind,
        points: args[2].parse()?,
        ..Default::default()
    };
    if kind == SurveyKind::Street {
        params.extent = [400.0, 400.0];
        params.cell = 60.0;
        params.jitter = 0.01;
    }
    if args.len() >= 7 {
        params.extent = [args[4].parse()?, args[5].parse()?];
        params.cell = args[6].parse()?;
    }
    let scene = survey(&params)?;
    let out = Path::new(&args[3]);
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_lowercase();
    if ext == "las" || ext == "laz" {
        write_las(out, &scene.cloud.points, 0.001)?;
    } else {
        io::write_cloud(out, &scene.cloud, Encoding::BinaryLittleEndian)?;
    }
    println!(
        "{}: {} points, {} true primitives",
        out.display(),
        scene.cloud.len(),
        scene.truth.len()
    );
    Ok(())
}
