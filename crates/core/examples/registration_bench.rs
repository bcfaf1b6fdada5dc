//! Registration benchmark, our side: synthetic scenes (thesis §6.3.3) at several outlier
//! levels and seeds, registered with the particle filter; prints one JSON line per run
//! and can write every scene (PLY) and its truth for other tools
//! (`benches/registration_compare.py` drives this and Open3D in one run).
//!
//! ```text
//! cargo run --release --example registration_bench -- [--levels 0.5,0.8,0.9,0.95]
//!     [--seeds 20] [--inliers 100] [--translation T] [--model mesh.ply] [--scenes DIR]
//!     [--rotation-only] [--scale LO,HI] [--partial] [--clutter] [--absent]
//!     [--pair-hypotheses N] [--accept P] [--first-seed S] [--no-sensors] [tuning flags]
//! ```
//!
//! `--partial`: the object is seen by a depth sensor from one random viewpoint
//! (`synth::partial_view`: self-occluded, range noise 0.3 % of the size) and `--inliers`
//! of its pixels are kept; `--clutter` adds a plane under it and two other objects
//! (their scan is a quarter of the outliers, the rest uniform); `--absent`: the same
//! scenes without the object (every point an outlier; errors are then meaningless).
//!
//! `--translation T`: the true translation is uniform in `[-T·size, T·size]³` (size =
//! diagonal of the model's bounding box); default 0.25. `--scale LO,HI`: the object is
//! scaled by a factor uniform in `[LO, HI]` and the scale is searched in (0.5, 2).
//! Errors: rotation angle (degrees) and translation distance relative to the model size
//! (scaled by the true scale); with `--scale` also the relative scale error.

use std::path::PathBuf;
use std::str::FromStr;
use std::time::Instant;

use primfit_core::atlas::MeshShape;
use primfit_core::io;
use primfit_core::register::{RegisterOptions, register};
use primfit_core::synth::{
    PartialViewParams, RegistrationParams, Scene, asymmetric_object, partial_view, registration,
};
use primfit_core::{Pose, Silent};
use serde_json::json;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let levels: Vec<f64> = get("--levels")
        .unwrap_or_else(|| "0.5,0.8,0.9,0.95".into())
        .split(',')
        .map(|s| s.parse().expect("outlier level"))
        .collect();
    let seeds: u64 = parsed_or(get("--seeds"), 20, "seed count");
    let first: u64 = parsed_or(get("--first-seed"), 0, "seed");
    let inliers: usize = parsed_or(get("--inliers"), 100, "inliers");
    let rotation_only = args.iter().any(|a| a == "--rotation-only");
    let rel_t: f64 = parsed_or(get("--translation"), 0.25, "translation");
    let scenes = get("--scenes").map(PathBuf::from);
    let scale: Option<(f64, f64)> = get("--scale").map(|s| {
        let v: Vec<f64> = s.split(',').map(|x| x.parse().expect("scale")).collect();
        (v[0], v[1])
    });
    let mesh = match get("--model") {
        Some(p) => {
            MeshShape::new(p.clone(), io::read_mesh(p.as_ref()).expect("model")).expect("mesh")
        }
        None => asymmetric_object(),
    };
    let (lo, hi) = primfit_core::bounds_of(&mesh.mesh.vertices).expect("vertices");
    let size = (hi - lo).norm();
    if let Some(dir) = &scenes {
        std::fs::create_dir_all(dir).expect("scene folder");
        io::write_mesh(
            &dir.join("model.ply"),
            &mesh.mesh,
            None,
            io::Encoding::BinaryLittleEndian,
        )
        .expect("model");
    }
    for &level in &levels {
        let outliers = (inliers as f64 * level / (1.0 - level)).round() as usize;
        for seed in first..first + seeds {
            let kind = SceneKind {
                partial: args.iter().any(|a| a == "--partial"),
                clutter: args.iter().any(|a| a == "--clutter"),
                absent: args.iter().any(|a| a == "--absent"),
            };
            let translation = if rotation_only { 0.0 } else { rel_t * size };
            let mut scene = make_scene(&mesh, kind, inliers, outliers, translation, scale, seed);
            if args.iter().any(|a| a == "--no-sensors") {
                // As most real scans arrive: no per-point sensor origins.
                scene.cloud.sensors = None;
            }
            let truth = scene.truth.first().map_or(Pose::identity(), |t| t.pose);
            if let Some(dir) = &scenes {
                write_scene(dir, &format!("scene_{level}_{seed}"), &scene, &truth, size);
            }
            let options = options(&get, rotation_only, scale, seed);
            let (t0, c0) = (Instant::now(), cpu_seconds());
            let result = register(&scene.cloud, &mesh, &options, &Silent).expect("register");
            let seconds = t0.elapsed().as_secs_f64();
            let cpu = cpu_seconds().zip(c0).map(|(b, a)| b - a);
            let Some(o) = result.objects.first() else {
                println!(
                    "{}",
                    json!({"method": "primfit", "level": level, "seed": seed, "found": false,
                        "rotation_deg": 180.0, "translation_rel": 1.0, "seconds": seconds,
                        "cpu_seconds": cpu, "existence": 0.0})
                );
                continue;
            };
            let pose = o.primitive.pose;
            let rot = pose.rotation.angle_to(&truth.rotation).to_degrees();
            let trans = (pose.translation - truth.translation).norm() / (size * truth.scale);
            let scale_rel = (pose.scale - truth.scale).abs() / truth.scale;
            let frot = o
                .filter_pose
                .rotation
                .angle_to(&truth.rotation)
                .to_degrees();
            let ftrans =
                (o.filter_pose.translation - truth.translation).norm() / (size * truth.scale);
            println!(
                "{}",
                json!({"method": "primfit", "level": level, "seed": seed, "found": true,
                    "present": !kind.absent, "rotation_deg": rot,
                    "translation_rel": trans, "seconds": seconds, "existence": o.existence,
                    "inlier_share": o.inlier_share, "margin": o.margin, "runner_up": o.runner_up_margin, "filter_rotation_deg": frot,
                    "filter_translation_rel": ftrans, "rounds": o.rounds.len(), "cpu_seconds": cpu,
                    "scale_rel": scale_rel})
            );
        }
    }
}

/// The registration options of one run: the defaults with `count = 1`, every answer
/// reported (`min_confidence = 0`), and the tuning flags given.
fn options(
    get: &dyn Fn(&str) -> Option<String>,
    rotation_only: bool,
    scale: Option<(f64, f64)>,
    seed: u64,
) -> RegisterOptions {
    let d = RegisterOptions::default();
    RegisterOptions {
        translation: !rotation_only,
        scale: scale.map(|_| (0.5, 2.0)),
        count: Some(1),
        min_confidence: 0.0, // every answer is logged, right or wrong
        seed,
        initial_particles: parsed_or(get("--initial"), d.initial_particles, "count"),
        particles: parsed_or(get("--particles"), d.particles, "count"),
        kernel_start: parsed_or(get("--kernel-start"), d.kernel_start, "fraction"),
        kernel_shrink: parsed_or(get("--kernel-shrink"), d.kernel_shrink, "factor"),
        kernel_end: parsed_or(get("--kernel-end"), d.kernel_end, "fraction"),
        ess: parsed_or(get("--ess"), d.ess, "share"),
        local_moves: parsed_or(get("--local-moves"), d.local_moves, "count"),
        translation_spread: parsed_or(get("--tspread"), d.translation_spread, "factor"),
        screen: get("--screen").map(|s| s.parse().expect("count")),
        vote_peaks: parsed_or(get("--vote-peaks"), d.vote_peaks, "count"),
        basin_share: parsed_or(get("--basin-share"), d.basin_share, "share"),
        flip_moves: parsed_or(get("--flip-moves"), d.flip_moves, "count"),
        vote_keep: parsed_or(get("--vote-keep"), d.vote_keep, "count"),
        vote_bin: parsed_or(get("--vote-bin"), d.vote_bin, "fraction"),
        vote_spacing: parsed_or(get("--vote-spacing"), d.vote_spacing, "fraction"),
        max_rounds: parsed_or(get("--max-rounds"), d.max_rounds, "count"),
        primitive_weight: get("--primitive-weight").map(|s| s.parse().expect("weight")),
        search_support: parsed_or(get("--search-support"), d.search_support, "points"),
        pair_hypotheses: parsed_or(get("--pair-hypotheses"), d.pair_hypotheses, "count"),
        accept_without_search: parsed_or(get("--accept"), d.accept_without_search, "share"),
        ..d
    }
}

/// Writes `scene`'s cloud (`name.ply`) and its truth `truth` (`name.json`: the pose
/// and the model size `size`) to `dir`.
fn write_scene(dir: &std::path::Path, name: &str, scene: &Scene, truth: &Pose, size: f64) {
    io::write_cloud(
        &dir.join(format!("{name}.ply")),
        &scene.cloud,
        io::Encoding::BinaryLittleEndian,
    )
    .expect("scene");
    let t = truth.translation;
    let r = truth.rotation.to_rotation_matrix();
    let rows: Vec<Vec<f64>> = r
        .matrix()
        .row_iter()
        .map(|row| row.iter().copied().collect())
        .collect();
    let doc = json!({"size": size, "translation": [t.x, t.y, t.z], "rotation_matrix": rows});
    io::write_json_atomic(&dir.join(format!("{name}.json")), &doc).expect("truth");
}

/// Which scenes the bench builds.
#[derive(Clone, Copy)]
struct SceneKind {
    partial: bool,
    clutter: bool,
    absent: bool,
}

/// One bench scene: whole-surface samples (`synth::registration`) or a partial view.
fn make_scene(
    mesh: &MeshShape,
    kind: SceneKind,
    inliers: usize,
    outliers: usize,
    translation: f64,
    scale: Option<(f64, f64)>,
    seed: u64,
) -> Scene {
    if !kind.partial {
        let params = RegistrationParams {
            inliers: if kind.absent { 0 } else { inliers },
            outliers,
            translation,
            scale,
            seed,
            ..Default::default()
        };
        let mut scene = registration(mesh, &params).expect("scene");
        if kind.absent {
            scene.truth.clear();
        }
        return scene;
    }
    let (lo, hi) = primfit_core::bounds_of(&mesh.mesh.vertices).expect("vertices");
    let structured = if kind.clutter { outliers / 4 } else { 0 };
    let params = PartialViewParams {
        inliers,
        outliers: outliers - structured,
        clutter_points: structured,
        plane: kind.clutter,
        distractors: if kind.clutter { 2 } else { 0 },
        object: !kind.absent,
        translation,
        range_noise: 0.003 * (hi - lo).norm(),
        seed,
        ..Default::default()
    };
    partial_view(mesh, &params).expect("scene")
}

/// User + system CPU time of this process so far (Linux `/proc/self/stat`; `None`
/// elsewhere): with the machine shared, CPU time is steadier than wall time.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which is in parentheses and may hold spaces).
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    // USER_HZ is 100 on every Linux platform Rust supports.
    Some(ticks / 100.0)
}

/// `value` parsed, or `default` when the flag was not given; panics naming `what` when the
/// value does not parse.
fn parsed_or<T: FromStr>(value: Option<String>, default: T, what: &str) -> T
where
    T::Err: std::fmt::Debug,
{
    value.map_or(default, |s| s.parse().expect(what))
}
