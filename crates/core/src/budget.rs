//! Up-front limits on what one call may ask of the machine: memory, threads and work.
//!
//! Every entry point (the fit, `evaluate`, `register`, the synthetic scenes, the
//! coefficients built directly from Python) estimates what it is about to allocate or
//! run **before** it allocates, and refuses with [`Error::OverLimit`] naming the option
//! to change. The estimates are upper bounds in plain units: bytes, samples, particles.
//! The judgements (how much memory is "too much", how many threads) are the constants
//! here, documented in the README's "Reliability" section.

use crate::error::{Error, Remedy, Result, Unit};

/// The share of the machine's physical memory a call may plan to use by default.
pub const DEFAULT_MEMORY_SHARE: f64 = 0.5;

/// At most this many worker threads per logical core: more only adds switching.
pub const MAX_THREADS_PER_CORE: usize = 4;

/// Physical memory in bytes (Linux `/proc/meminfo`), or 8 GiB when unknown.
pub fn physical_memory() -> u64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("MemTotal:"))?;
            line.split_whitespace()
                .nth(1)?
                .parse::<u64>()
                .ok()
                .map(|kb| kb * 1024)
        })
        .unwrap_or(8 << 30)
}

/// The default memory budget: [`DEFAULT_MEMORY_SHARE`] of the machine's memory (bytes).
pub fn default_memory_budget() -> u64 {
    (physical_memory() as f64 * DEFAULT_MEMORY_SHARE) as u64
}

/// Logical cores this process may run on (1 when unknown).
pub fn available_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The most worker threads a call may start: [`MAX_THREADS_PER_CORE`] per core.
pub fn max_threads() -> usize {
    available_cores() * MAX_THREADS_PER_CORE
}

/// `threads` (named `name`: `threads`, `RAYON_NUM_THREADS`) is at least 1 and at most
/// [`max_threads`].
pub fn check_threads(name: &str, threads: usize) -> Result<usize> {
    let max = max_threads();
    if (1..=max).contains(&threads) {
        Ok(threads)
    } else {
        let expected = format!(
            "between 1 and {max} ({MAX_THREADS_PER_CORE} per core of the {} here)",
            available_cores()
        );
        Err(Error::out_of_range(name, threads, expected))
    }
}

/// Refuses a plan that needs `need` bytes when `budget` bytes are allowed; `what` says
/// what would be built (`the samples of 2e9 candidates`), `remedies` what would shrink
/// it, most useful first.
pub fn check_memory(what: &str, need: u64, budget: u64, remedies: Vec<Remedy>) -> Result<()> {
    check(what, need as f64, budget as f64, Unit::Bytes, remedies)
}

/// Refuses a plan of `need` things of the kind `unit` names when at most `limit` are
/// allowed (samples of a surface, particles, points of a synthetic scene).
pub fn check_count(
    what: &str,
    need: f64,
    limit: f64,
    unit: &'static str,
    remedies: Vec<Remedy>,
) -> Result<()> {
    check(what, need, limit, Unit::Count(unit), remedies)
}

fn check(what: &str, need: f64, limit: f64, unit: Unit, remedies: Vec<Remedy>) -> Result<()> {
    // NaN (an estimate from a degenerate input) is refused too.
    if need <= limit {
        Ok(())
    } else {
        Err(Error::OverLimit {
            what: what.to_string(),
            need,
            limit,
            unit,
            remedies,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn threads_are_bounded_by_the_cores_and_the_error_names_the_option() {
        assert_eq!(check_threads("threads", 1).unwrap(), 1);
        assert_eq!(
            check_threads("threads", max_threads()).unwrap(),
            max_threads()
        );
        for bad in [0, max_threads() + 1, 100_000] {
            let e = check_threads("threads", bad).unwrap_err().to_string();
            assert!(e.starts_with("threads must be between 1 and"), "{e}");
        }
    }

    #[test]
    fn plans_over_the_budget_are_refused_with_the_remedy_and_nan_is_over() {
        assert!(check_memory("x", 10, 10, vec![]).is_ok());
        let e = check_memory("the samples", 11, 10, vec![Remedy::Raise("spacing")]);
        let text = e.unwrap_err().to_string();
        assert!(
            text.contains("the samples") && text.contains("spacing"),
            "{text}"
        );
        assert!(check_count("a scene", f64::NAN, 1e6, "points", vec![]).is_err());
        assert!(check_count("a scene", f64::INFINITY, 1e6, "points", vec![]).is_err());
    }
}
