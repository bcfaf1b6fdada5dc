//! The `primfit` command-line tool: parses arguments, calls `primfit-core`, prints.
//!
//! Exit codes: 0 success; 1 the command failed (bad input file, bad value, I/O);
//! 2 the command line itself is malformed (clap).

mod commands;
mod errors;
mod progress;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Represent a point cloud with geometric primitives only.
#[derive(Debug, Parser)]
#[command(name = "primfit", version, about, long_about = None)]
struct Cli {
    /// Worker threads (default: all cores).
    #[arg(short = 'j', long, global = true)]
    threads: Option<usize>,
    /// No progress bars and no summary.
    #[arg(short, long, global = true)]
    quiet: bool,
    /// More detail (settings, sizes, timings).
    #[arg(short, long, global = true)]
    verbose: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Fit primitives to a scan (PLY) and write result JSON and/or a mesh.
    #[command(allow_negative_numbers = true)]
    Fit(Box<commands::fit::FitArgs>),
    /// Generate a synthetic scene with ground truth.
    #[command(allow_negative_numbers = true)]
    Synth(commands::synth::SynthArgs),
    /// Measure how well a result explains a scan (DESIGN §4 measures, as JSON).
    #[command(allow_negative_numbers = true)]
    Eval(commands::eval::EvalArgs),
    /// Find the pose(s) of a mesh in a scan (particle filter + ICP) and write result JSON.
    Register(commands::register::RegisterArgs),
    /// Draw a scan and a result as a PNG: points coloured by distance to the model,
    /// primitives shaded.
    #[command(allow_negative_numbers = true)]
    Render(commands::render::RenderArgs),
    /// Write one self-contained HTML page to orbit a scan and a result in a browser.
    #[command(allow_negative_numbers = true)]
    View(commands::view::ViewArgs),
}

/// On SIGINT or SIGTERM: remove the temporary files of any write in progress (the
/// outputs stay as they were) and end with the shell's status for that signal,
/// 128 + its number.
fn remove_temporary_files_on_signals() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        return; // Without the handler the default action still ends the process.
    };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            primfit_core::io::remove_temporary_files();
            std::process::exit(128 + signal);
        }
    });
}

/// Starts the global rayon pool with `threads` workers (default: rayon's, all cores or
/// `RAYON_NUM_THREADS`), the main thread being one of them: parallel work it starts is
/// pushed on its own queue rather than injected from outside, and `-j N` runs N
/// threads, not N workers beside an idle main thread (measured in docs/performance.md).
fn start_thread_pool(threads: Option<usize>) -> Result<(), String> {
    let n = match threads {
        Some(n) => primfit_core::budget::check_threads("threads", n)
            .map_err(|e| errors::one_line(&e.into()))?,
        None => 0, // rayon's default
    };
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .use_current_thread()
        .build_global()
        .map_err(|e| match threads {
            Some(n) => format!("cannot start {n} threads: {e}"),
            None => format!("cannot start the worker threads: {e}"),
        })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    remove_temporary_files_on_signals();
    if let Err(e) = start_thread_pool(cli.threads) {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    let out = commands::Output {
        quiet: cli.quiet,
        verbose: cli.verbose,
    };
    let result = match cli.command {
        Command::Fit(a) => commands::fit::run(*a, &out),
        Command::Synth(a) => commands::synth::run(a, &out),
        Command::Eval(a) => commands::eval::run(a, &out),
        Command::Register(a) => commands::register::run(a, &out),
        Command::Render(a) => commands::render::run(a, &out),
        Command::View(a) => commands::view::run(a, &out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", errors::one_line(&e));
            ExitCode::FAILURE
        }
    }
}
