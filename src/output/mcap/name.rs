//! Output names and their topics (design contract): the parts of a name are joined with dots in
//! the name (`frame.tool0.z`) and with slashes in the topic (`/ribbon/envelope/frame/tool0/z`).

/// An output's name as its parts: the kind (`q`, `frame`, …), the joint, link, drive or loop, and
/// any component (`x`, `rz`, `0`).
///
/// A `&str` converts by splitting at every dot, which is right unless a joint or link name itself
/// contains a dot: build those with [`OutputName::from_parts`], so that only the separating dots
/// become slashes (`from_parts(&["q", "joint_0.0"])` → topic `…/q/joint_0.0`, which Foxglove then
/// needs quoted in a message path).
///
/// ```
/// # use ribbon::output::mcap::OutputName;
/// let name = OutputName::from("frame.tool0.z");
/// assert_eq!(name.name(), "frame.tool0.z");
/// assert_eq!(name.topic_suffix(), "frame/tool0/z");
/// let dotted = OutputName::from_parts(&["q", "joint_0.0"]);
/// assert_eq!(dotted.name(), "q.joint_0.0");
/// assert_eq!(dotted.topic_suffix(), "q/joint_0.0");
/// ```
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct OutputName {
    parts: Vec<String>,
}

impl OutputName {
    /// A name from its parts, kept as they are.
    pub fn from_parts<S: AsRef<str>>(parts: &[S]) -> Self {
        Self {
            parts: parts.iter().map(|p| p.as_ref().to_string()).collect(),
        }
    }

    /// The parts.
    pub fn parts(&self) -> &[String] {
        &self.parts
    }

    /// The output name: the parts joined with dots.
    pub fn name(&self) -> String {
        self.parts.join(".")
    }

    /// The topic below `/ribbon/envelope/` or `/ribbon/error/`: the parts joined with slashes.
    pub fn topic_suffix(&self) -> String {
        self.parts.join("/")
    }

    /// True if there is no part or a part is empty (no topic can be made of it).
    pub fn has_empty_part(&self) -> bool {
        self.parts.is_empty() || self.parts.iter().any(String::is_empty)
    }
}

impl From<&str> for OutputName {
    /// Splits at every dot.
    fn from(name: &str) -> Self {
        Self {
            parts: name.split('.').map(str::to_string).collect(),
        }
    }
}

impl From<&String> for OutputName {
    /// Splits at every dot.
    fn from(name: &String) -> Self {
        Self::from(name.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contract_examples() {
        assert_eq!(
            OutputName::from("q.elbow_joint").topic_suffix(),
            "q/elbow_joint"
        );
        assert_eq!(
            OutputName::from("frame.tool0.z").topic_suffix(),
            "frame/tool0/z"
        );
    }

    #[test]
    fn empty_parts_are_flagged() {
        for bad in ["", "q.", ".q", "q..x"] {
            assert!(OutputName::from(bad).has_empty_part(), "{bad:?}");
        }
        assert!(OutputName::from_parts::<&str>(&[]).has_empty_part());
        assert!(!OutputName::from("q.j1").has_empty_part());
    }
}
