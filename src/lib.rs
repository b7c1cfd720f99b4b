//! # ribbon
//!
//! How far can a robot's motion drift when its CAD masses, inertias and link lengths are only known
//! to a few percent? ribbon loads a URDF, lets any inertial or geometric value be declared an
//! interval parameter, and computes bound envelopes of joint motion, frames and efforts over time.
//!
//! Modules, in data-flow order:
//! - [`model`] — URDF → kinematic tree ([`model::Model`]);
//! - [`ros`] — ROS packages on disk (`package://` URIs) and xacro files refused with their command;
//! - [`params`] — the parameter registry (dotted paths such as `link.forearm_link.mass`);
//! - [`sidecar`] — the sidecar file as written, and the expansion of its `[parameters]` patterns;
//! - [`spatial`] — 6D spatial algebra;
//! - [`dynamics`] — CRBA, RNEA, forward dynamics and frame placements on a per-thread
//!   [`dynamics::Data`];
//! - [`linalg`] — the one in-place Cholesky, shared by dynamics, integrator and bound optimisers;
//! - [`isa`] — which SIMD instruction set a vectorised kernel runs with (baseline or AVX2);
//! - [`mcap_io`] — the one MCAP layer: a file written whole, its checksums and records read back;
//! - [`integrate`] — the second-order HHT-I3 integrator for index-3 DAEs;
//! - [`uq`] — quadrature, Legendre/Chebyshev surrogates and their bounds (pure mathematics);
//! - [`setup`] — URDF, sidecar, scene and parameter box loaded and checked in one place;
//! - [`distributed`] — one study across many machines: plan, shards of runs, merge;
//! - [`output`] — CSV, summary JSON, MCAP and SVG writers, and the output-path rules;
//! - [`study_front`] — what the study commands share: options, the driver, progress, warnings,
//!   the stdout table;
//! - [`nominal_run`] — one nominal trajectory as `simulate` runs it (also the Python package's);
//! - [`state_dynamics`] — rigid-body dynamics at one given state, as `dynamics` computes it;
//! - [`interrupt`] — SIGINT/SIGTERM: stop at the next step, or at once on a second signal;
//! - [`cli`] — the `ribbon` command line.
//!
//! ## Limitations
//! - URDF planar and spherical joints are refused with a clear message (not supported yet).
//! - Visual and collision geometry, materials, transmissions and Gazebo tags are ignored.

#![warn(missing_docs)]

pub mod analysis;
pub mod atomic_file;
pub mod cli;
pub mod constraints;
pub mod distributed;
pub mod dynamics;
pub mod effects;
pub mod environment;
mod error;
pub mod geometry;
pub mod integrate;
pub mod interrupt;
pub mod isa;
pub mod linalg;
pub mod mcap_io;
pub mod model;
pub mod nominal_run;
pub mod output;
pub mod params;
pub mod ros;
pub mod scene;
pub mod set_flags;
pub mod setup;
pub mod sidecar;
pub mod simulate;
pub mod spatial;
pub mod starter;
pub mod state_dynamics;
pub mod study_front;
#[cfg(test)]
pub(crate) mod test_support;
pub mod text;
pub mod uncertainty;
pub mod uq;

pub use error::{Error, UNTRUSTED_EXIT_CODE};
