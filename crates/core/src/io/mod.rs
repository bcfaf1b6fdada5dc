//! File input/output.
