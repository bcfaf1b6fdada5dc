//! [`Limit`]: a count that may be unlimited (α and β of the chamfer, the solver's search
//! points). Written `inf` on the command line, in Python and in `result.json`.

use std::fmt;

use crate::{Error, Result};

/// A count that may be unlimited: every item, or at most `n` (`n ≥ 1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Limit {
    /// No limit (`inf`).
    All,
    /// At most this many.
    At(usize),
}

impl Limit {
    /// The bound, `None` for [`Limit::All`].
    pub const fn get(self) -> Option<usize> {
        match self {
            Limit::All => None,
            Limit::At(n) => Some(n),
        }
    }

    /// `None` → [`Limit::All`], `Some(n)` → [`Limit::At`]`(n)`.
    pub const fn from_bound(bound: Option<usize>) -> Limit {
        match bound {
            None => Limit::All,
            Some(n) => Limit::At(n),
        }
    }

    /// Whether `count` items exceed the limit.
    pub fn exceeded_by(self, count: usize) -> bool {
        self.get().is_some_and(|n| count > n)
    }

    /// Parses `inf` (also `all`, `none`) or a count of at least 1; an error names the
    /// option `name`.
    pub fn parse(name: &str, text: &str) -> Result<Limit> {
        match text.trim() {
            "inf" | "all" | "none" => Ok(Limit::All),
            t => match t.parse::<usize>() {
                Ok(0) => Err(Error::out_of_range(name, 0, "at least 1 (or inf)")),
                Ok(n) => Ok(Limit::At(n)),
                Err(_) => Err(Error::out_of_range(name, t, "a count or inf")),
            },
        }
    }
}

impl fmt::Display for Limit {
    /// `inf` or the count.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Limit::All => f.write_str("inf"),
            Limit::At(n) => write!(f, "{n}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_counts_and_inf_and_names_the_option_otherwise() {
        assert_eq!(Limit::parse("beta", "32").unwrap(), Limit::At(32));
        for all in ["inf", "all", "none", " inf "] {
            assert_eq!(Limit::parse("beta", all).unwrap(), Limit::All);
        }
        assert_eq!(
            Limit::parse("beta", "0").unwrap_err().to_string(),
            "beta must be at least 1 (or inf), got 0"
        );
        assert!(Limit::parse("alpha", "-3").is_err());
        assert_eq!(Limit::All.to_string(), "inf");
        assert_eq!(Limit::At(7).to_string(), "7");
        assert_eq!(Limit::from_bound(Limit::At(4).get()), Limit::At(4));
        assert!(Limit::At(4).exceeded_by(5) && !Limit::At(4).exceeded_by(4));
        assert!(!Limit::All.exceeded_by(usize::MAX));
    }
}
