//! The reproducible benchmark table (DESIGN §5, issue 4): generates the benchmark scenes,
//! fits them with 1 thread and with every core, optionally runs the NumPy/SciPy reference
//! (`benches/numpy_reference.py`) on the same scenes, and prints one markdown table.
//!
//! ```text
//! cargo run --release --example bench_table                     # Rust only
//! cargo run --release --example bench_table -- --numpy PYTHON   # + NumPy reference
//! scripts/bench.sh                                              # both, venv handled
//! ```
//!
//! Every measurement runs in a **child process** (this binary again), so each peak RSS
//! (`VmHWM` of `/proc/self/status`) belongs to one fit only. Runs under 30 s are
//! repeated (fits 7 times, the reference 3 times) and the table shows the run of median
//! time. Child modes:
//!
//! * `--run SCENE --threads N`: one fit in a rayon pool of N threads; prints one JSON line;
//! * `--export SCENE DIR`: writes the cloud, the candidate templates and poses (`.npy`) and
//!   the resolved settings (`meta.json`) for the NumPy reference;
//! * `--score SCENE DIR`: point→model mean of the NumPy result (`DIR/numpy_result.json`).
//!
//! Options of the parent: `--scenes a,b,…` (default: [`DEFAULT_SCENES`]), `--threads N`
//! (default: all cores; 1 thread is always measured too), `--numpy PYTHON`,
//! `--numpy-timeout SECONDS` (default 900), `--numpy-scenes a,b,…`, `--work DIR`,
//! `--json FILE` (raw measurements). `PRIMFIT_BENCH_MEMORY_BUDGET=BYTES` overrides the
//! fitter's memory budget (default: half the machine's memory) in every child.

#[path = "../benches/common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::time::Instant;

use common::BenchScene;
use primfit_core::Error;
use primfit_core::Progress;
use primfit_core::fit::{FitResult, fit};
use primfit_core::metrics::{MetricsOptions, evaluate};
use serde_json::{Value, json};

/// Scenes of the default table: the 20k pipe, the 100k and 1M hallways (both point
/// models at 20k and 100k) and the 10M memory check. The 10M fit skips the polish sweeps
/// (their cost grows faster than the point count at present); the polish state is still
/// built, so its memory peak is a whole fit's.
const DEFAULT_SCENES: &str =
    "pipe-20k,pipe-20k-indep,hallway-100k,hallway-100k-indep,hallway-1m,hallway-10m-nosweeps";

/// Scenes the NumPy reference runs on by default (its 1M run takes minutes; 10M would
/// not fit in memory as it stores dense rows).
const DEFAULT_NUMPY_SCENES: &str =
    "pipe-20k,pipe-20k-indep,hallway-100k,hallway-100k-indep,hallway-1m";

/// Peak resident set size of this process, bytes (`VmHWM`).
fn peak_rss() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
            line.split_whitespace().nth(1)?.parse::<u64>().ok()
        })
        .map_or(0, |kb| kb * 1024)
}

/// CPU seconds (user + system, all threads) this process has used so far, from
/// `/proc/self/stat` (clock ticks of 1/100 s). Less sensitive to other load than wall time.
fn cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            // Fields after the parenthesised command name; utime and stime are 14 and 15.
            let rest = s.rsplit_once(')')?.1;
            let f: Vec<&str> = rest.split_whitespace().collect();
            Some((f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

/// A [`Progress`] that records when each stage starts and finishes and when each message
/// arrives (seconds since creation).
struct StageTimer {
    t0: Instant,
    log: Mutex<Vec<(String, f64)>>,
}

impl StageTimer {
    fn new() -> Self {
        StageTimer {
            t0: Instant::now(),
            log: Mutex::new(Vec::new()),
        }
    }
    fn push(&self, what: String) {
        let t = self.t0.elapsed().as_secs_f64();
        self.log.lock().expect("timer lock").push((what, t));
    }
    /// Seconds between the first event starting with `a` and the next one starting with `b`.
    fn between(&self, a: &str, b: &str) -> f64 {
        let log = self.log.lock().expect("timer lock");
        let Some(i) = log.iter().position(|e| e.0.starts_with(a)) else {
            return f64::NAN;
        };
        log[i + 1..]
            .iter()
            .find(|e| e.0.starts_with(b))
            .map_or(f64::NAN, |e| e.1 - log[i].1)
    }
    /// Seconds from creation to the first event starting with `a`.
    fn at(&self, a: &str) -> f64 {
        let log = self.log.lock().expect("timer lock");
        log.iter()
            .find(|e| e.0.starts_with(a))
            .map_or(f64::NAN, |e| e.1)
    }
}

impl Progress for StageTimer {
    fn start(&self, stage: &str, _total: u64) {
        self.push(format!("start {stage}"));
    }
    fn finish(&self) {
        self.push("finish".into());
    }
    fn message(&self, text: &str) {
        self.push(format!("message {text}"));
    }
}

fn scene_arg(name: &str) -> BenchScene {
    BenchScene::parse(name).unwrap_or_else(|| {
        eprintln!("unknown scene {name:?} (pipe-20k, hallway-1m, hallway-100k-indep, …)");
        std::process::exit(2)
    })
}

/// Child: one fit in a pool of `threads` threads; one JSON line on stdout.
fn run_child(scene: BenchScene, threads: usize) -> Value {
    let t = Instant::now();
    let cloud = scene.cloud();
    let generate = t.elapsed().as_secs_f64();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    pool.install(|| {
        let timer = StageTimer::new();
        let (t, cpu) = (Instant::now(), cpu_seconds());
        let mut options = scene.options();
        if let Some(b) = std::env::var("PRIMFIT_BENCH_MEMORY_BUDGET")
            .ok()
            .and_then(|b| b.parse().ok())
        {
            options.memory_budget = Some(b);
        }
        let result = fit(&cloud, &options, &timer);
        let total = t.elapsed().as_secs_f64();
        let cpu = cpu_seconds() - cpu;
        let mut v = json!({
            "scene": scene.name(),
            "model": scene.model.name(),
            "threads": threads,
            "points": cloud.len(),
            "generate_seconds": generate,
            "fit_cpu_seconds": cpu,
        });
        match result {
            Ok(r) => {
                let t = Instant::now();
                let m = evaluate(
                    &cloud.points,
                    &r.primitives,
                    None,
                    &MetricsOptions::default(),
                )
                .expect("metrics");
                let metrics = t.elapsed().as_secs_f64();
                fill(&mut v, &r, &timer, total, metrics, m.point_to_model_mean);
            }
            Err(e @ Error::OverLimit { .. }) => v["refused"] = json!(e.to_string()),
            Err(e) => v["error"] = json!(e.to_string()),
        }
        v["peak_rss"] = json!(peak_rss());
        v
    })
}

fn fill(v: &mut Value, r: &FitResult, timer: &StageTimer, total: f64, metrics: f64, mean: f64) {
    let s = &r.stats;
    let lbfgs = timer.between("start solve", "finish");
    v["candidates"] = json!(s.lattice_candidates);
    v["kept"] = json!(s.candidates);
    v["entries"] = json!(s.entries);
    v["bytes_per_entry"] = json!(s.bytes_per_entry);
    v["coefficient_bytes"] = json!(s.coefficient_bytes);
    v["estimated_bytes"] = json!(s.estimated_bytes);
    v["iterations"] = json!(r.solution.iterations);
    v["evaluations"] = json!(r.solution.evaluations);
    v["flips"] = json!(r.solution.flips);
    v["stop"] = json!(format!("{:?}", r.solution.stop));
    v["loss"] = json!(r.solution.history.last());
    v["binary_loss"] = json!(r.solution.binary.total);
    v["primitives"] = json!(r.primitives.len());
    v["point_to_model_mean"] = json!(mean);
    v["seconds"] = json!({
        "resolve": timer.at("message settings"),
        "lattice": s.lattice_seconds,
        "primitive_term": timer.between("start primitive term", "finish"),
        "point_term": timer.between("start point term", "finish"),
        "coefficients": s.coefficient_seconds,
        "lbfgs": lbfgs,
        "threshold_polish": s.solve_seconds - lbfgs,
        "solve": s.solve_seconds,
        "fit": total,
        "metrics": metrics,
    });
}

/// Writes a C-order little-endian `.npy` file (format 1.0).
fn write_npy(path: &Path, descr: &str, shape: &[usize], data: &[u8]) -> std::io::Result<()> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + header length (2) + header + '\n', padded to 64 bytes.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(data);
    std::fs::write(path, out)
}

fn f64_bytes(values: impl IntoIterator<Item = f64>) -> Vec<u8> {
    values.into_iter().flat_map(f64::to_le_bytes).collect()
}

/// Child: writes what the NumPy reference needs into `dir`.
fn export(scene: BenchScene, dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let cloud = scene.cloud();
    let (settings, candidates) = scene.prepare(&cloud);
    let p = |name: &str| dir.join(name);
    let coords =
        |pts: &[primfit_core::na::Point3<f64>]| f64_bytes(pts.iter().flat_map(|q| [q.x, q.y, q.z]));
    write_npy(
        &p("cloud.npy"),
        "<f8",
        &[cloud.len(), 3],
        &coords(&cloud.points),
    )?;
    for (t, template) in candidates.templates.iter().enumerate() {
        let name = format!("template_{t}.npy");
        write_npy(
            &p(&name),
            "<f8",
            &[template.samples.len(), 3],
            &coords(&template.samples),
        )?;
    }
    let n = candidates.len();
    let template_of: Vec<u8> = candidates
        .template_of
        .iter()
        .flat_map(|t| (*t as i32).to_le_bytes())
        .collect();
    write_npy(&p("template_of.npy"), "<i4", &[n], &template_of)?;
    let rotations = f64_bytes(candidates.poses.iter().flat_map(|pose| {
        let m = *pose.rotation.to_rotation_matrix().matrix();
        // Row-major 3 × 3: scene = R · local + t.
        (0..3).flat_map(move |r| (0..3).map(move |c| m[(r, c)]))
    }));
    write_npy(&p("rotation.npy"), "<f8", &[n, 3, 3], &rotations)?;
    let translations = f64_bytes(candidates.poses.iter().flat_map(|pose| {
        assert!(
            (pose.scale - 1.0).abs() < 1e-12,
            "lattice poses have scale 1"
        );
        [pose.translation.x, pose.translation.y, pose.translation.z]
    }));
    write_npy(&p("translation.npy"), "<f8", &[n, 3], &translations)?;
    let radii = f64_bytes(candidates.templates.iter().map(|t| t.radius));
    write_npy(
        &p("template_radius.npy"),
        "<f8",
        &[candidates.templates.len()],
        &radii,
    )?;
    let c = &settings.chamfer;
    let o = &settings.solver;
    let meta = json!({
        "scene": scene.name(),
        "model": c.model.name(),
        "alpha": c.alpha,
        "beta": c.beta,
        "cap2": c.cap,
        "primitive_weight": c.primitive_weight,
        "point_weight": c.point_weight,
        "initial": o.initial,
        "threshold": o.threshold,
        "max_iterations": o.max_iterations,
        "memory": o.memory,
        "ftol": o.ftol,
        "pgtol": o.pgtol,
        "templates": candidates.templates.len(),
        "candidates": n,
        "points": cloud.len(),
    });
    std::fs::write(p("meta.json"), serde_json::to_vec_pretty(&meta)?)
}

/// Child: point→model mean of the candidates the NumPy reference kept.
fn score(scene: BenchScene, dir: &Path) -> Value {
    let cloud = scene.cloud();
    let (_, candidates) = scene.prepare(&cloud);
    let text = std::fs::read_to_string(dir.join("numpy_result.json")).expect("numpy_result.json");
    let result: Value = serde_json::from_str(&text).expect("numpy_result.json is JSON");
    let chosen: Vec<usize> = result["chosen"]
        .as_array()
        .expect("chosen")
        .iter()
        .map(|v| v.as_u64().expect("index") as usize)
        .collect();
    let model: Vec<_> = chosen.iter().map(|&i| candidates.primitive(i)).collect();
    match evaluate(&cloud.points, &model, None, &MetricsOptions::default()) {
        Ok(m) => json!({"point_to_model_mean": m.point_to_model_mean, "primitives": model.len()}),
        Err(e) => json!({"error": e.to_string(), "primitives": model.len()}),
    }
}

/// Runs this binary with `args`; parses the last stdout line as JSON.
fn child(args: &[String]) -> Value {
    let exe = std::env::current_exe().expect("current exe");
    let out = Command::new(exe).args(args).output().expect("spawn child");
    let stdout = String::from_utf8_lossy(&out.stdout);
    match stdout
        .lines()
        .last()
        .and_then(|l| serde_json::from_str(l).ok())
    {
        Some(v) if out.status.success() => v,
        _ => json!({
            "error": format!(
                "child {args:?} failed ({}): {}",
                out.status,
                String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")
            )
        }),
    }
}

/// Runs of each fit (all cores, and one thread) when one takes under
/// [`REPEAT_UNDER_SECONDS`]: the table shows the run of median time, so that one slow
/// or fast run of a 0.1 s fit does not set its ratios.
const FIT_REPEATS: usize = 7;

/// Runs of the NumPy reference on a scene when one takes under [`REPEAT_UNDER_SECONDS`]
/// (its time varies by a fifth from run to run: 4.2 and 5.4 s on the 20k pipe).
const REFERENCE_REPEATS: usize = 3;

/// Runs longer than this (seconds) are not repeated.
const REPEAT_UNDER_SECONDS: f64 = 30.0;

/// Up to `repeats` results of `run` (stopping after one without a time, or longer than
/// [`REPEAT_UNDER_SECONDS`]), each logged; the one of median `time`.
fn median_run(
    repeats: usize,
    time: impl Fn(&Value) -> Option<f64>,
    mut run: impl FnMut() -> Value,
) -> Value {
    let mut runs = Vec::new();
    while runs.len() < repeats {
        let v = run();
        eprintln!("   {v}");
        let t = time(&v);
        runs.push((t.unwrap_or(f64::INFINITY), v));
        if !t.is_some_and(|t| t < REPEAT_UNDER_SECONDS) {
            break;
        }
    }
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let middle = (runs.len() - 1) / 2;
    runs.swap_remove(middle).1
}

/// The time a fit child reports, `None` when it did not fit.
fn fit_seconds(v: &Value) -> Option<f64> {
    v["seconds"]["fit"].as_f64()
}

/// Parent: the NumPy reference on one scene, scored by a child. `None` when skipped.
fn numpy(scene: BenchScene, python: &str, timeout: u64, work: &Path) -> Value {
    let dir = work.join(scene.name());
    let _ = std::fs::remove_dir_all(&dir);
    let e = child(&["--export".into(), scene.name(), dir.display().to_string()]);
    if e.get("error").is_some() {
        return e;
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../benches/numpy_reference.py");
    let out = Command::new("timeout")
        .arg(timeout.to_string())
        .arg(python)
        .arg(&script)
        .arg(&dir)
        .output();
    let out = match out {
        Ok(o) => o,
        Err(err) => return json!({"error": format!("cannot run {python}: {err}")}),
    };
    if out.status.code() == Some(124) {
        return json!({"timeout": timeout});
    }
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().last().unwrap_or("").to_string();
        return json!({"error": format!("numpy_reference.py failed ({}): {last}", out.status)});
    }
    let text = std::fs::read_to_string(dir.join("numpy_result.json")).unwrap_or_default();
    let mut v: Value = serde_json::from_str(&text).unwrap_or(json!({"error": "no result"}));
    let s = child(&["--score".into(), scene.name(), dir.display().to_string()]);
    v["point_to_model_mean"] = s["point_to_model_mean"].clone();
    if let Some(obj) = v.as_object_mut() {
        obj.remove("chosen");
    }
    let _ = std::fs::remove_dir_all(&dir);
    v
}

fn secs(v: &Value) -> String {
    match v.as_f64() {
        Some(s) if s >= 100.0 => format!("{s:.0} s"),
        Some(s) if s >= 10.0 => format!("{s:.1} s"),
        Some(s) if s >= 0.1 => format!("{s:.2} s"),
        Some(s) if s.is_finite() => format!("{:.1} ms", s * 1e3),
        _ => "—".into(),
    }
}

fn bytes(v: &Value) -> String {
    match v.as_f64() {
        Some(b) if b >= (1u64 << 30) as f64 => format!("{:.2} GiB", b / (1u64 << 30) as f64),
        Some(b) => format!("{:.0} MiB", b / (1u64 << 20) as f64),
        None => "—".into(),
    }
}

fn count(v: &Value) -> String {
    let Some(n) = v.as_u64() else {
        return "—".into();
    };
    let s = n.to_string();
    let mut out = String::new();
    for (k, c) in s.chars().enumerate() {
        if k > 0 && (s.len() - k) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

fn ratio(a: Option<f64>, b: Option<f64>) -> String {
    match (a, b) {
        (Some(a), Some(b)) if b > 0.0 && a.is_finite() => format!("{:.1}×", a / b),
        _ => "—".into(),
    }
}

/// Markdown table of the measurements (`rows`: (all-core run, 1-thread run, numpy)).
fn table(rows: &[(Value, Value, Value)], threads: usize) -> String {
    let mut t = String::new();
    t.push_str(&format!(
        "| scene | model | points | candidates (not dominated) | entries | B/entry | coefficients | per iteration | iterations (evals) | total ({threads} thr) | CPU time | total (1 thr) | speed-up {threads}/1 | peak RSS (estimate) | point→model mean | NumPy total | NumPy CPU | NumPy RSS | NumPy point→model | vs NumPy (wall) | vs NumPy (CPU) |\n"
    ));
    t.push_str("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (r, one, np) in rows {
        let s = &r["seconds"];
        if r.get("refused").is_some() || r.get("error").is_some() {
            let why = if r.get("refused").is_some() {
                "refused"
            } else {
                "error"
            };
            t.push_str(&format!(
                "| {} | {} | {} | {why} (see below) | | | | | | | | | | {} | | | | | | | |\n",
                r["scene"].as_str().unwrap_or("?"),
                r["model"].as_str().unwrap_or("?"),
                count(&r["points"]),
                bytes(&r["peak_rss"]),
            ));
            continue;
        }
        let per_iter = match (s["lbfgs"].as_f64(), r["iterations"].as_f64()) {
            (Some(a), Some(n)) if n > 0.0 => json!(a / n),
            _ => Value::Null,
        };
        let total = s["fit"].as_f64();
        let total1 = one["seconds"]["fit"].as_f64();
        let np_total = np["total_seconds"].as_f64();
        let np_cell = if np.get("timeout").is_some() {
            format!("> {} s", np["timeout"])
        } else if np.get("error").is_some() {
            "error".into()
        } else {
            secs(&np["total_seconds"])
        };
        let peak = format!(
            "{} ({})",
            bytes(&r["peak_rss"]),
            bytes(&r["estimated_bytes"])
        );
        let np_mean = np["point_to_model_mean"]
            .as_f64()
            .map_or("—".into(), |m| format!("{m:.4} m"));
        t.push_str(&format!(
            "| {} | {} | {} | {} ({}) | {} | {} | {} | {} | {} ({}) | {} | {} | {} | {} | {} | {:.4} m | {} | {} | {} | {} | {} | {} |\n",
            r["scene"].as_str().unwrap_or("?"),
            r["model"].as_str().unwrap_or("?"),
            count(&r["points"]),
            count(&r["candidates"]),
            count(&r["kept"]),
            count(&r["entries"]),
            r["bytes_per_entry"],
            secs(&s["coefficients"]),
            secs(&per_iter),
            r["iterations"],
            r["evaluations"],
            secs(&s["fit"]),
            secs(&r["fit_cpu_seconds"]),
            secs(&one["seconds"]["fit"]),
            ratio(total1, total),
            peak,
            r["point_to_model_mean"].as_f64().unwrap_or(f64::NAN),
            np_cell,
            secs(&np["cpu_seconds"]),
            bytes(&np["peak_rss"]),
            np_mean,
            ratio(np_total, total),
            ratio(np["cpu_seconds"].as_f64(), r["fit_cpu_seconds"].as_f64()),
        ));
    }
    t
}

/// Per-stage seconds of every all-core run (the profile by timers).
fn stages(rows: &[(Value, Value, Value)]) -> String {
    let keys = [
        "resolve",
        "lattice",
        "primitive_term",
        "point_term",
        "coefficients",
        "lbfgs",
        "threshold_polish",
        "fit",
        "metrics",
    ];
    let mut t = String::from(
        "| scene | resolve (index, spacing) | lattice | primitive term | point term | coefficients (all) | L-BFGS | threshold + polish | fit | metrics |\n|---|",
    );
    t.push_str(&"---:|".repeat(keys.len()));
    t.push('\n');
    for (r, _, _) in rows {
        if r.get("seconds").is_none() {
            continue;
        }
        t.push_str(&format!("| {} |", r["scene"].as_str().unwrap_or("?")));
        for k in keys {
            t.push_str(&format!(" {} |", secs(&r["seconds"][k])));
        }
        t.push('\n');
    }
    t
}

fn numpy_stages(rows: &[(Value, Value, Value)]) -> String {
    let mut t = String::from(
        "| scene | NumPy: trees | primitive term | point term | L-BFGS-B | iterations (evals) | per evaluation | total |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for (r, _, np) in rows {
        if np.get("total_seconds").is_none() {
            continue;
        }
        let s = &np["seconds"];
        let per_eval = match (s["solve"].as_f64(), np["evaluations"].as_f64()) {
            (Some(a), Some(n)) if n > 0.0 => json!(a / n),
            _ => Value::Null,
        };
        t.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} ({}) | {} | {} |\n",
            r["scene"].as_str().unwrap_or("?"),
            secs(&s["trees"]),
            secs(&s["primitive_term"]),
            secs(&s["point_term"]),
            secs(&s["solve"]),
            np["iterations"],
            np["evaluations"],
            secs(&per_eval),
            secs(&np["total_seconds"]),
        ));
    }
    t
}

fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mem = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("MemTotal:"))?
                .split_whitespace()
                .nth(1)?
                .parse::<f64>()
                .ok()
        })
        .map_or("?".into(), |kb| {
            format!("{:.1} GiB", kb / (1u64 << 20) as f64)
        });
    let load = std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default();
    format!("{cpu}, {cores} cores, {mem} RAM; load average at start {load}")
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    if let Some(name) = get("--run") {
        let threads = get("--threads").and_then(|t| t.parse().ok()).unwrap_or(1);
        println!("{}", run_child(scene_arg(&name), threads));
        return;
    }
    if let Some(name) = get("--export") {
        let dir = PathBuf::from(args.last().expect("DIR"));
        export(scene_arg(&name), &dir).expect("export");
        println!("{}", json!({"exported": dir.display().to_string()}));
        return;
    }
    if let Some(name) = get("--score") {
        let dir = PathBuf::from(args.last().expect("DIR"));
        println!("{}", score(scene_arg(&name), &dir));
        return;
    }

    let scenes: Vec<BenchScene> = get("--scenes")
        .unwrap_or_else(|| DEFAULT_SCENES.into())
        .split(',')
        .map(scene_arg)
        .collect();
    let numpy_scenes: Vec<BenchScene> = get("--numpy-scenes")
        .unwrap_or_else(|| DEFAULT_NUMPY_SCENES.into())
        .split(',')
        .map(scene_arg)
        .collect();
    let threads = get("--threads")
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let python = get("--numpy");
    let timeout: u64 = get("--numpy-timeout")
        .and_then(|t| t.parse().ok())
        .unwrap_or(900);
    let work = PathBuf::from(get("--work").unwrap_or_else(|| {
        std::env::temp_dir()
            .join(format!("primfit-bench-{}", std::process::id()))
            .display()
            .to_string()
    }));
    let conditions = machine();

    let mut rows = Vec::new();
    for scene in &scenes {
        let name = scene.name();
        let run = |threads: usize| {
            eprintln!("== {name}: {threads} thread(s)");
            let args = [
                "--run".into(),
                name.clone(),
                "--threads".into(),
                threads.to_string(),
            ];
            median_run(FIT_REPEATS, fit_seconds, || child(&args))
        };
        let all = run(threads);
        let fitted = all.get("seconds").is_some();
        let one = if fitted && threads > 1 {
            run(1)
        } else {
            Value::Null
        };
        let np = match &python {
            Some(py) if fitted && numpy_scenes.contains(scene) => {
                eprintln!("== {name}: NumPy reference");
                let total = |v: &Value| v["total_seconds"].as_f64();
                median_run(REFERENCE_REPEATS, total, || {
                    numpy(*scene, py, timeout, &work)
                })
            }
            _ => Value::Null,
        };
        rows.push((all, one, np));
    }
    let _ = std::fs::remove_dir_all(&work);

    println!("Machine: {conditions}.\n");
    println!("{}", table(&rows, threads));
    println!("Stages (seconds, {threads} threads):\n");
    println!("{}", stages(&rows));
    if python.is_some() {
        println!("NumPy reference stages:\n");
        println!("{}", numpy_stages(&rows));
    }
    for (r, _, np) in &rows {
        for key in ["refused", "error"] {
            if let Some(msg) = r.get(key).and_then(Value::as_str) {
                println!(
                    "- {} {key} (peak RSS {}): {msg}",
                    r["scene"].as_str().unwrap_or("?"),
                    bytes(&r["peak_rss"])
                );
            }
            if let Some(msg) = np.get(key).and_then(Value::as_str) {
                println!(
                    "- NumPy {} {key}: {msg}",
                    r["scene"].as_str().unwrap_or("?")
                );
            }
        }
    }
    if let Some(path) = get("--json") {
        let raw: Vec<Value> = rows
            .iter()
            .map(|(a, b, c)| json!({"all": a, "one": b, "numpy": c}))
            .collect();
        std::fs::write(&path, serde_json::to_vec_pretty(&raw).expect("json"))
            .expect("write --json");
    }
}
