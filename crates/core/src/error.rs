//! The crate's error type: every fallible public function returns [`Result`].
//!
//! Variants carry the fault as data (which option, its value, what it must be) so that
//! each front end can word it its own way: the CLI names its flags, Python picks the
//! exception. Options are named by their library field (`size`, `beta`,
//! `memory_budget`, …), never by a CLI flag. `Display` gives one line with those names;
//! [`Error::describe_with`] gives the same line with the names mapped. Range checks
//! that build [`Error::OutOfRange`] live in [`crate::check`].

use std::fmt::{self, Write};
use std::path::PathBuf;

/// Errors of primfit-core. Messages are one line, name the offending input, and say
/// what would fix it where that is known.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An option or argument lies outside its documented range (a size ≤ 0, a
    /// probability above 1, a count of 0, …).
    OutOfRange {
        /// The option's library name (`size`, `kernel_shrink`, `owner[3]`, …).
        name: String,
        /// The value given, as text.
        value: String,
        /// What it must be (`positive and finite`, `in (0, 1]`, `at least 1`, …).
        expected: String,
    },
    /// A name that is not one of the choices (a point model, a frame, a primitive type).
    Unknown {
        /// What was being named (`point model`, `primitive type`, …).
        what: &'static str,
        /// The name given.
        value: String,
        /// The accepted names, as a phrase (`existence or independent`).
        expected: &'static str,
    },
    /// A point cloud with no points where points are needed.
    EmptyCloud,
    /// An input item with a NaN or infinite coordinate.
    NonFinite {
        /// What the item is (`point`, `mesh "a.ply" vertex`, …).
        what: String,
        /// Its position in its list.
        index: usize,
    },
    /// Two lists that must have one entry each do not have the same length.
    Mismatch {
        /// The list that has the wrong length (`owners`, `normals`, …).
        what: &'static str,
        /// Its length.
        len: usize,
        /// The list it must match (`samples`, `points`, …).
        per: &'static str,
        /// That list's length.
        expected: usize,
    },
    /// An index into a list that does not have that many entries.
    IndexOutOfRange {
        /// Where the index was found (`owner[3]`, `face 7`, …).
        what: String,
        /// The index given.
        index: usize,
        /// What it indexes (`candidate`, `vertex`, …).
        item: &'static str,
        /// How many there are (valid indices are `0..count`).
        count: usize,
    },
    /// An input that a stage requires is absent.
    Missing {
        /// What is absent (`each point's sensor origin`, …).
        what: String,
        /// Who needs it (`the ray likelihood`, …).
        needed_by: &'static str,
    },
    /// A field of a JSON document is absent or not what it must be.
    Json {
        /// The field's path (`pose.scale`, `size.side`, …).
        field: String,
        /// What it must be (`a positive number`, …).
        expected: String,
    },
    /// The problem is larger than a fixed limit or the memory budget.
    OverLimit {
        /// What would be too large (`a square of area 4.0 sampled every 1e-9`, …).
        what: String,
        /// How much it would need, in `unit`.
        need: f64,
        /// The most allowed, in `unit`.
        limit: f64,
        /// What `need` and `limit` count.
        unit: Unit,
        /// Changes of options that would make it fit, most useful first.
        remedies: Vec<Remedy>,
    },
    /// A fault in one item of a list (a candidate, a primitive entry).
    Item {
        /// What the item is (`candidate`, `primitive`).
        what: &'static str,
        /// Its position in the list.
        index: usize,
        /// The item's fault.
        #[source]
        source: Box<Error>,
    },
    /// A file could not be opened, read or written.
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying OS error.
        #[source]
        source: std::io::Error,
    },
    /// A file was read but its contents are not what they must be.
    Format {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A file whose format is not one that is read, or whose content is not what its
    /// extension says (a `.pcd` name on a LAS file).
    UnknownFormat {
        /// The file concerned.
        path: PathBuf,
        /// What was found (`the extension '.bin'`, `a '.pcd' name on LAS content`).
        found: String,
        /// The formats accepted, as a phrase.
        accepted: &'static str,
    },
    /// Any other invalid input, as a sentence (only where no variant above fits).
    InvalidArgument(String),
    /// The caller stopped the work ([`crate::Progress::cancelled`]).
    Cancelled,
}

/// What the amounts of [`Error::OverLimit`] count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    /// Things of the named kind (`samples`, `candidates`, …).
    Count(&'static str),
    /// Bytes of memory.
    Bytes,
}

/// A change of one option that makes a problem smaller ([`Error::OverLimit`]). The
/// option is named by its library field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Remedy {
    /// A larger value of the option (a coarser spacing, a larger budget).
    Raise(&'static str),
    /// A smaller value of the option.
    Lower(&'static str),
    /// The option (a point) nearer the cloud.
    Nearer(&'static str),
    /// Fewer input points.
    Subsample,
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// [`Error::OutOfRange`] from a name, the value (shown with `Display`) and what it
    /// must be.
    pub fn out_of_range(
        name: impl Into<String>,
        value: impl fmt::Display,
        expected: impl Into<String>,
    ) -> Self {
        Error::OutOfRange {
            name: name.into(),
            value: value.to_string(),
            expected: expected.into(),
        }
    }
    /// [`Error::InvalidArgument`], the catch-all: prefer a structured variant.
    pub fn invalid(msg: impl Into<String>) -> Self {
        Error::InvalidArgument(msg.into())
    }
    /// Shorthand for [`Error::Format`].
    pub fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            message: msg.into(),
        }
    }
    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
    /// Shorthand for [`Error::Json`].
    pub fn json(field: impl Into<String>, expected: impl Into<String>) -> Self {
        Error::Json {
            field: field.into(),
            expected: expected.into(),
        }
    }
    /// This error as the fault of item `index` of a list of `what`s.
    pub fn in_item(self, what: &'static str, index: usize) -> Self {
        Error::Item {
            what,
            index,
            source: Box::new(self),
        }
    }
    /// The innermost error: the fault itself under any [`Error::Item`] wrappers.
    pub fn root(&self) -> &Error {
        match self {
            Error::Item { source, .. } => source.root(),
            e => e,
        }
    }
    /// The one-line message with every option name passed through `name_of` (the CLI
    /// maps `size` to `--size`). `to_string()` is this with names unchanged.
    pub fn describe_with(&self, name_of: &dyn Fn(&str) -> String) -> String {
        let mut line = String::new();
        // Writing into a String cannot fail.
        let _ = self.write_line(&mut line, name_of);
        line
    }

    /// Writes the message, naming options through `name_of`.
    fn write_line(&self, f: &mut dyn Write, name_of: &dyn Fn(&str) -> String) -> fmt::Result {
        match self {
            Error::OutOfRange {
                name,
                value,
                expected,
            } => write!(f, "{} must be {expected}, got {value}", name_of(name)),
            Error::Unknown {
                what,
                value,
                expected,
            } => write!(f, "unknown {what} {value:?} (expected {expected})"),
            Error::EmptyCloud => f.write_str("the point cloud is empty: it has no points"),
            Error::NonFinite { what, index } => {
                write!(f, "{what} {index} is not finite (NaN or infinite)")
            }
            Error::Mismatch {
                what,
                len,
                per,
                expected,
            } => write!(
                f,
                "length mismatch: {len} {what} for {expected} {per} (one each expected)"
            ),
            Error::IndexOutOfRange {
                what,
                index,
                item,
                count,
            } => write!(
                f,
                "{what} = {index} is not a {item} index (valid: 0..{count})"
            ),
            Error::Missing { what, needed_by } => write!(f, "{needed_by} needs {what}"),
            Error::Json { field, expected } => write!(f, "{field} must be {expected}"),
            Error::OverLimit {
                what,
                need,
                limit,
                unit,
                remedies,
            } => {
                write!(
                    f,
                    "too large: {what} would need {}, over the limit of {}",
                    unit.amount(*need),
                    unit.limit(*limit)
                )?;
                write_remedies(f, remedies, name_of)
            }
            Error::Item {
                what,
                index,
                source,
            } => {
                write!(f, "{what} {index}: ")?;
                source.write_line(f, name_of)
            }
            Error::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Error::Format { path, message } => write!(f, "{}: {message}", path.display()),
            Error::UnknownFormat {
                path,
                found,
                accepted,
            } => write!(
                f,
                "{}: not a point cloud format that is read: {found} (accepted: {accepted})",
                path.display()
            ),
            Error::InvalidArgument(msg) => write!(f, "invalid argument: {msg}"),
            Error::Cancelled => f.write_str("cancelled"),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write_line(f, &str::to_owned)
    }
}

impl Unit {
    /// `amount` in this unit, for a message: `1.5e9 samples`, `2.0 GiB`.
    fn amount(self, amount: f64) -> String {
        match self {
            Unit::Count(things) => format!("{} {things}", count(amount)),
            Unit::Bytes => bytes(amount),
        }
    }
    /// A limit in this unit: a count without its (already named) things.
    fn limit(self, limit: f64) -> String {
        match self {
            Unit::Count(_) => count(limit),
            Unit::Bytes => bytes(limit),
        }
    }
}

/// `950`, `1.5e9`.
fn count(n: f64) -> String {
    if n < 1e6 {
        format!("{n:.0}")
    } else {
        format!("{n:.1e}")
    }
}

/// `512.0 MiB`, `2.0 GiB`.
fn bytes(n: f64) -> String {
    const GIB: f64 = (1u64 << 30) as f64;
    const MIB: f64 = (1u64 << 20) as f64;
    if n >= GIB {
        format!("{:.1} GiB", n / GIB)
    } else {
        format!("{:.1} MiB", n / MIB)
    }
}

/// `; raise spacing or move origin nearer the cloud` (nothing when there is no remedy).
fn write_remedies(
    f: &mut dyn Write,
    remedies: &[Remedy],
    name_of: &dyn Fn(&str) -> String,
) -> fmt::Result {
    for (k, remedy) in remedies.iter().enumerate() {
        f.write_str(match k {
            0 => "; ",
            _ if k + 1 == remedies.len() => " or ",
            _ => ", ",
        })?;
        match remedy {
            Remedy::Raise(option) => write!(f, "raise {}", name_of(option))?,
            Remedy::Lower(option) => write!(f, "lower {}", name_of(option))?,
            Remedy::Nearer(option) => write!(f, "move {} nearer the cloud", name_of(option))?,
            Remedy::Subsample => f.write_str("subsample the cloud")?,
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_are_one_line_and_name_the_option() {
        let e = Error::out_of_range("size", -1.0, "positive and finite");
        assert_eq!(e.to_string(), "size must be positive and finite, got -1");
        let flag = |n: &str| format!("--{}", n.replace('_', "-"));
        assert_eq!(
            e.describe_with(&flag),
            "--size must be positive and finite, got -1"
        );
        let nested = e.in_item("candidate", 3);
        assert_eq!(
            nested.describe_with(&flag),
            "candidate 3: --size must be positive and finite, got -1"
        );
        assert!(matches!(nested.root(), Error::OutOfRange { .. }));
    }

    #[test]
    fn over_limit_lists_the_remedies_by_option_name() {
        let e = Error::OverLimit {
            what: "a lattice spacing of 1e-9".into(),
            need: 3e12,
            limit: 1e9,
            unit: Unit::Count("cells"),
            remedies: vec![Remedy::Raise("spacing"), Remedy::Nearer("origin")],
        };
        assert_eq!(
            e.to_string(),
            "too large: a lattice spacing of 1e-9 would need 3.0e12 cells, over the limit \
             of 1.0e9; raise spacing or move origin nearer the cloud"
        );
        let flag = |n: &str| format!("--{n}");
        assert!(
            e.describe_with(&flag)
                .ends_with("raise --spacing or move --origin nearer the cloud")
        );
        let three = Error::OverLimit {
            what: "x".into(),
            need: 5.0 * (1u64 << 30) as f64,
            limit: (1u64 << 29) as f64,
            unit: Unit::Bytes,
            remedies: vec![
                Remedy::Lower("beta"),
                Remedy::Subsample,
                Remedy::Raise("memory_budget"),
            ],
        };
        assert_eq!(
            three.to_string(),
            "too large: x would need 5.0 GiB, over the limit of 512.0 MiB; lower beta, \
             subsample the cloud or raise memory_budget"
        );
    }
}
