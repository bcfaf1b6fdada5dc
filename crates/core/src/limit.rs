//! [`Limit`]: a count that may be unlimited (α and β of the chamfer, the solver's search
//! points). Written `inf` on the command line, in Python and in `result.json`.

use std::fmt;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

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

impl Serialize for Limit {
    /// `"inf"` or the count.
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            Limit::All => s.serialize_str("inf"),
            Limit::At(n) => s.serialize_u64(*n as u64),
        }
    }
}

/// A limit as JSON writes it: a count or a word.
#[derive(Deserialize)]
#[serde(untagged)]
enum LimitText {
    Count(u64),
    Word(String),
}

impl<'de> Deserialize<'de> for Limit {
    /// `"inf"` (`"all"`, `"none"`) or a count of at least 1.
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let text = match LimitText::deserialize(d)? {
            LimitText::Count(n) => n.to_string(),
            LimitText::Word(w) => w,
        };
        Limit::parse("limit", &text).map_err(serde::de::Error::custom)
    }
}

/// Serde of a [`Limit`] as `result.json` writes `search_points`: the count, and
/// [`Limit::All`] as the largest count (`18446744073709551615`) as it always has been;
/// `"inf"` is read too.
pub mod as_count {
    use serde::{Deserialize, Deserializer, Serializer};

    use super::{Limit, LimitText};

    /// Writes the count, `u64::MAX` for [`Limit::All`].
    pub fn serialize<S: Serializer>(l: &Limit, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(l.get().map_or(u64::MAX, |n| n as u64))
    }

    /// Reads a count (`u64::MAX` or more: [`Limit::All`]) or `"inf"`.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Limit, D::Error> {
        match LimitText::deserialize(d)? {
            LimitText::Count(n) if n == u64::MAX || usize::try_from(n).is_err() => Ok(Limit::All),
            LimitText::Count(n) => Limit::parse("limit", &n.to_string()),
            LimitText::Word(w) => Limit::parse("limit", &w),
        }
        .map_err(serde::de::Error::custom)
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

    #[test]
    fn json_spells_all_as_inf_and_reads_it_back() {
        let text = serde_json::to_string(&[Limit::All, Limit::At(32)]).unwrap();
        assert_eq!(text, r#"["inf",32]"#);
        let back: Vec<Limit> = serde_json::from_str(r#"["inf", 32, "all"]"#).unwrap();
        assert_eq!(back, [Limit::All, Limit::At(32), Limit::All]);
        assert!(serde_json::from_str::<Limit>("0").is_err());
        assert!(serde_json::from_str::<Limit>(r#""many""#).is_err());
        #[derive(serde::Serialize, serde::Deserialize, PartialEq, Debug)]
        struct Solver {
            #[serde(with = "as_count")]
            points: Limit,
        }
        let all = serde_json::to_string(&Solver { points: Limit::All }).unwrap();
        assert_eq!(all, r#"{"points":18446744073709551615}"#);
        for text in [all.as_str(), r#"{"points":"inf"}"#] {
            let back: Solver = serde_json::from_str(text).unwrap();
            assert_eq!(back.points, Limit::All);
        }
    }
}
