//! One module per subcommand.

pub mod eval;
pub mod fit;
pub mod register;
pub mod synth;

/// How much to print.
#[derive(Debug, Clone, Copy)]
pub struct Output {
    /// Print nothing but errors.
    pub quiet: bool,
    /// Print details.
    pub verbose: bool,
}

/// Parses a comma-separated list of three numbers (`x,y,z`).
pub fn parse_point(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| e.to_string())?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => Err(format!("expected three finite numbers x,y,z, got {s:?}")),
    }
}

/// Parses a count or `inf` (unlimited, as `usize::MAX`).
pub fn parse_limit(s: &str) -> Result<usize, String> {
    match s {
        "inf" | "all" | "none" => Ok(usize::MAX),
        _ => match s.parse::<usize>() {
            Ok(0) => Err("must be at least 1 (or inf)".into()),
            Ok(n) => Ok(n),
            Err(e) => Err(format!("{e} (expected a count or inf)")),
        },
    }
}
