//! Placeholder: one HHT-I3 step (being written).
fn main() {}
