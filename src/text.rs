//! Small text helpers: "did you mean …?" suggestions for error messages, and the width of the
//! output-name column of the stdout tables.

/// Width of the output-name column of a stdout table, in characters: the longest name, and at
/// least the six of its header `output`.
pub fn name_column_width<'a>(names: impl IntoIterator<Item = &'a str>) -> usize {
    names
        .into_iter()
        .map(|name| name.chars().count())
        .max()
        .unwrap_or(6)
        .max(6)
}

/// Edit distance (insertions, deletions, substitutions) between two strings, by characters.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b_chars: Vec<char> = b.chars().collect();
    let mut previous: Vec<usize> = (0..=b_chars.len()).collect();
    let mut current = vec![0; b_chars.len() + 1];
    for (i, ca) in a.chars().enumerate() {
        current[0] = i + 1;
        for (j, cb) in b_chars.iter().enumerate() {
            let substitution = previous[j] + usize::from(ca != *cb);
            current[j + 1] = substitution.min(previous[j + 1] + 1).min(current[j] + 1);
        }
        std::mem::swap(&mut previous, &mut current);
    }
    previous[b_chars.len()]
}

/// The candidate closest to `wanted`, if it is close enough to be a plausible typo (at most a third
/// of the longer name, or two characters for short names, differ) or an abbreviation (the shortest
/// candidate containing `wanted`, e.g. `elbow` → `elbow_joint`).
pub fn closest<'a>(wanted: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let candidates: Vec<&'a str> = candidates.into_iter().collect();
    let best = candidates
        .iter()
        .map(|c| (edit_distance(wanted, c), *c))
        .min_by_key(|(distance, _)| *distance)?;
    let limit = (wanted.chars().count().max(best.1.chars().count()) / 3).max(2);
    if best.0 <= limit {
        return Some(best.1);
    }
    candidates
        .iter()
        .filter(|c| !wanted.is_empty() && c.contains(wanted))
        .min_by_key(|c| c.len())
        .copied()
}

/// `"; did you mean 'x'?"` for the closest candidate, or an empty string.
pub fn closest_suggestion<'a>(
    wanted: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> String {
    closest(wanted, candidates)
        .map(|c| format!("; did you mean '{c}'?"))
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("same", "same"), 0);
    }

    #[test]
    fn suggestions_only_for_near_misses() {
        let names = ["link.upper_arm_link.mass", "link.forearm_link.mass"];
        assert_eq!(
            closest("link.forarm_link.mass", names),
            Some("link.forearm_link.mass")
        );
        assert_eq!(closest("something.else", names), None);
        assert_eq!(
            closest("elbow", ["shoulder_joint", "elbow_joint"]),
            Some("elbow_joint")
        );
    }
}
