//! `[parameters]` keys with `*` segments: `"link.*.mass"`, `"link.*.com.*"`, `"joint.*.origin.*"`.
//!
//! key ⇒ [`PathPattern`] ⇒ which registry paths ([`crate::params::PathParts`]) it matches
//!
//! A path is `kind.NAME.field` (`link`/`joint`) or `kind.field` (`scene`), where NAME may contain
//! dots and slashes and the field has one or two dotted parts (`mass`, `com.x`). A `*` stands for
//! one whole segment: the whole NAME (`joint_0.0` and `iris__/imu_link` are one NAME) or one field
//! part. The kind is always written out. Matching is done per registry entry: the pattern's last
//! segments are aligned with the entry's field parts, and what is left between the kind and them
//! is the NAME (`*` or the literal name).

use crate::params::PathParts;

/// The path kinds a pattern can start with.
pub const PATTERN_KINDS: [&str; 3] = ["link", "joint", "scene"];

/// A parsed `[parameters]` key with at least one `*` segment.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PathPattern<'k> {
    /// The key as written.
    pub key: &'k str,
    /// `link`, `joint` or `scene`.
    pub kind: &'k str,
    /// The dotted segments after the kind (`["*", "com", "*"]`).
    rest: Vec<&'k str>,
}

/// Where a pattern's segments fall on one registry entry.
struct Alignment<'p, 'k> {
    /// The segments standing for the NAME (empty for `scene` paths).
    name: &'p [&'k str],
    /// The segments standing for the field parts, one each.
    fields: &'p [&'k str],
}

impl<'k> PathPattern<'k> {
    /// Parses `key` as a pattern: `Ok(None)` when it has no `*` (an ordinary path or symbol), an
    /// error (the reason, for a message naming the key) when a `*` is misplaced.
    pub fn parse(key: &'k str) -> Result<Option<PathPattern<'k>>, String> {
        if !key.contains('*') {
            return Ok(None);
        }
        let mut segments = key.split('.');
        let kind = segments.next().unwrap_or_default();
        let rest: Vec<&str> = segments.collect();
        if let Some(partial) = rest
            .iter()
            .chain(std::iter::once(&kind))
            .find(|s| s.contains('*') && **s != "*")
        {
            return Err(format!(
                "'*' stands for one whole dotted segment (a whole NAME or one field part), not for part of one ('{partial}'); write e.g. \"link.*.mass\" or \"link.*.com.*\""
            ));
        }
        if !PATTERN_KINDS.contains(&kind) {
            return Err(format!(
                "a pattern starts with the kind of path it matches, written out: {}; e.g. \"link.*.mass\"",
                PATTERN_KINDS.join(", ")
            ));
        }
        if rest.len() < 2 {
            return Err(format!(
                "'{key}' names no value: a path is {kind}.{}; e.g. \"{}\"",
                if kind == "scene" {
                    "FIELD.PART"
                } else {
                    "NAME.FIELD"
                },
                match kind {
                    "joint" => "joint.*.origin.z",
                    "scene" => "scene.gravity.*",
                    _ => "link.*.mass",
                }
            ));
        }
        Ok(Some(PathPattern { key, kind, rest }))
    }

    /// How the segments fall on an entry with these parts, when the counts allow it.
    fn align<'p>(&'p self, parts: &PathParts<'_>) -> Option<Alignment<'p, 'k>> {
        if parts.kind != self.kind {
            return None;
        }
        let field_count = parts.field.split('.').count();
        let name_count = usize::from(parts.name.is_some());
        if self.rest.len() < field_count + name_count
            || (parts.name.is_none() && self.rest.len() != field_count)
        {
            return None;
        }
        let (name, fields) = self.rest.split_at(self.rest.len() - field_count);
        Some(Alignment { name, fields })
    }

    /// Whether the pattern matches the path with these parts.
    pub fn matches(&self, parts: &PathParts<'_>) -> bool {
        let Some(aligned) = self.align(parts) else {
            return false;
        };
        let name_matches = match parts.name {
            None => true,
            Some(_) if aligned.name == ["*"] => true,
            Some(name) => {
                // The NAME may contain dots: compare the joined segments without allocating.
                let mut rest = name;
                aligned.name.iter().enumerate().all(|(i, segment)| {
                    if i > 0 {
                        match rest.strip_prefix('.') {
                            Some(r) => rest = r,
                            None => return false,
                        }
                    }
                    match rest.strip_prefix(segment) {
                        Some(r) => {
                            rest = r;
                            true
                        }
                        None => false,
                    }
                }) && rest.is_empty()
            }
        };
        name_matches
            && aligned
                .fields
                .iter()
                .zip(parts.field.split('.'))
                .all(|(pattern, field)| *pattern == "*" || *pattern == field)
    }

    /// Whether the `*` stands for the NAME (`link.*.mass`, not `link.tool0.com.*`): such patterns
    /// skip links that carry no dynamics.
    pub fn name_is_wildcard(&self) -> bool {
        self.rest.len() >= 2 && self.rest[0] == "*" && self.kind != "scene"
    }

    /// The path of an entry with the pattern's `*` positions starred (`link.*.com.x` for pattern
    /// `link.*.com.w` and entry `link.base.com.x`), when the segment counts fit: candidates for a
    /// "did you mean" when the pattern matches nothing.
    pub fn generalise(&self, parts: &PathParts<'_>) -> Option<String> {
        let aligned = self.align(parts)?;
        let mut text = self.kind.to_string();
        if let Some(name) = parts.name {
            text.push('.');
            text.push_str(if aligned.name == ["*"] { "*" } else { name });
        }
        for (pattern, field) in aligned.fields.iter().zip(parts.field.split('.')) {
            text.push('.');
            text.push_str(if *pattern == "*" { "*" } else { field });
        }
        Some(text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parts<'a>(kind: &'static str, name: Option<&'a str>, field: &'static str) -> PathParts<'a> {
        PathParts { kind, name, field }
    }

    fn pattern(key: &str) -> PathPattern<'_> {
        PathPattern::parse(key).unwrap().unwrap()
    }

    #[test]
    fn plain_keys_are_not_patterns() {
        assert_eq!(PathPattern::parse("link.a.mass"), Ok(None));
        assert_eq!(PathPattern::parse("l1"), Ok(None));
    }

    #[test]
    fn star_matches_a_whole_name_even_with_dots_and_slashes() {
        let p = pattern("link.*.mass");
        assert!(p.matches(&parts("link", Some("iris__/imu_link"), "mass")));
        assert!(p.matches(&parts("link", Some("joint_0.0"), "mass")));
        assert!(!p.matches(&parts("link", Some("a"), "scale")));
        assert!(!p.matches(&parts("joint", Some("a"), "mass")));
        assert!(p.name_is_wildcard());
        let p = pattern("joint.*.origin.*");
        assert!(p.matches(&parts("joint", Some("joint_0.0"), "origin.roll")));
        assert!(!p.matches(&parts("joint", Some("j"), "axis.x")));
        assert!(!p.matches(&parts("joint", Some("j"), "damping")));
    }

    #[test]
    fn literal_names_with_dots_match_exactly() {
        let p = pattern("joint.joint_0.0.origin.*");
        assert!(p.matches(&parts("joint", Some("joint_0.0"), "origin.x")));
        assert!(!p.matches(&parts("joint", Some("joint_0"), "origin.x")));
        assert!(!p.matches(&parts("joint", Some("joint_0.0.1"), "origin.x")));
        assert!(!p.name_is_wildcard());
        assert!(pattern("scene.gravity.*").matches(&parts("scene", None, "gravity.z")));
        assert!(pattern("scene.*.z").matches(&parts("scene", None, "gravity.z")));
        // `link.*.*` has one field part: mass and scale, not com.x.
        let p = pattern("link.*.*");
        assert!(p.matches(&parts("link", Some("a"), "scale")));
        assert!(!p.matches(&parts("link", Some("a"), "com.x")));
    }

    #[test]
    fn misplaced_stars_are_refused() {
        for (key, expected) in [
            ("link.wrist_*.mass", "not for part of one ('wrist_*')"),
            ("*.a.mass", "written out: link, joint, scene"),
            ("lnk.*.mass", "written out"),
            ("link.*", "names no value"),
            ("scene.*", "names no value"),
        ] {
            let message = PathPattern::parse(key).unwrap_err();
            assert!(message.contains(expected), "{key}: {message}");
        }
    }

    #[test]
    fn generalised_entries_suggest_the_intended_pattern() {
        let p = pattern("link.*.com.w");
        assert_eq!(
            p.generalise(&parts("link", Some("base"), "com.x"))
                .as_deref(),
            Some("link.*.com.x")
        );
        let p = pattern("joint.elbw.origin.*");
        assert_eq!(
            p.generalise(&parts("joint", Some("elbow"), "origin.z"))
                .as_deref(),
            Some("joint.elbow.origin.*")
        );
        assert_eq!(p.generalise(&parts("scene", None, "gravity.x")), None);
    }
}
