//! Integration tests of the `primfit` binary.

#[test]
fn placeholder() {
    let _ = env!("CARGO_BIN_EXE_primfit");
}
