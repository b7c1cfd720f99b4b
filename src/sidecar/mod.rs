//! The sidecar file `ROBOT.uncertainty.toml` (design contract): its format as written, and the
//! expansion of its `[parameters]` keys — paths, free symbols and patterns with `*` segments —
//! into the dimensions of a study. [`crate::scene`] reads the scene and outputs from it,
//! [`crate::uncertainty`] builds the parameter box from the expansion.
//!
//! file ⇒ [`SidecarFile`] ([`read_sidecar`], read and parsed once: [`parse_sidecar`]) ⇒ with a
//! model: [`ExpandedParameters`] ([`expand_parameters`])
//!
//! ```toml
//! [parameters]
//! "link.*.mass"        = { rel = 0.03 }                 # one dimension per link with mass
//! "link.*.scale"       = { rel = 0.05 }                 # mass and inertia together, per link
//! "joint.*.origin.z"   = { abs = 0.0005, shared = true } # one dimension moving every match
//! "link.tool0.mass"    = [0.0, 1.2]                     # an explicit key wins over a pattern
//! ```
//!
//! What it does not do: compute bounds from `rel`/`abs`, check values against the URDF or the box
//! for physical consistency (that is [`crate::uncertainty::ParameterSpace`]), or resolve `[scene]`
//! (that is [`crate::scene::Scene::resolve`]).

mod error;
mod expand;
mod file;
mod interval;
mod pattern;

pub use error::SidecarError;
pub use expand::{
    expand_parameters, is_symbol_name, key_label, EntryKind, ExpandedParameters, ParameterEntry,
};
pub use file::{
    located, parse_sidecar, read_sidecar, AnalysisSection, BaseSection, BindDeclaration,
    ContactSection, DriveSection, GeometrySection, InitialSection, JointSelection, LoopSection,
    OutputsSection, ParameterDeclaration, ParameterDeclarations, SceneSection, SidecarFile,
    SpringSection,
};
pub use interval::{read_interval, IntervalForm, IntervalSpec, FORMS};
pub use pattern::{PathPattern, PATTERN_KINDS};

#[cfg(test)]
mod tests;
