//! Interval parameters of a study (being written).
