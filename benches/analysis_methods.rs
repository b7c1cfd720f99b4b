//! Placeholder: the method comparison (being written).
fn main() {}
