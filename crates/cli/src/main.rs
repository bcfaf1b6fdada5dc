//! The `primfit` command-line tool.
fn main() {}
