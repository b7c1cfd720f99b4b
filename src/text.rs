//! Small text helpers: "did you mean …?" suggestions for error messages, the width of the
//! output-name column of the stdout tables, and times as messages print them.

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

/// Significant digits a time keeps in a message: enough for any step size ribbon accepts, few
/// enough to drop the grid's rounding (`0.35000000000000003` for `350 · 1e-3`).
pub const MESSAGE_TIME_DIGITS: usize = 12;

/// `t` (s) rounded to [`MESSAGE_TIME_DIGITS`] significant digits, for messages: `0.35` where the
/// step count times the step gave `0.35000000000000003`. Non-finite values pass unchanged.
pub fn message_time(t: f64) -> f64 {
    if !t.is_finite() {
        return t;
    }
    format!("{:.*e}", MESSAGE_TIME_DIGITS - 1, t)
        .parse()
        .unwrap_or(t)
}

#[cfg(test)]
mod message_time_tests {
    use super::message_time;

    #[test]
    fn message_times_drop_the_grids_rounding_and_keep_real_digits() {
        assert_eq!(format!("{}", message_time(350.0 * 1e-3)), "0.35");
        assert_eq!(350.0 * 1e-3, 0.35000000000000003, "the product this is for");
        assert_eq!(format!("{}", message_time(0.262)), "0.262");
        assert_eq!(
            format!("{}", message_time(0.1234567890123)),
            "0.123456789012"
        );
        assert_eq!(format!("{}", message_time(3.25e-7)), "0.000000325");
        assert!(message_time(f64::NAN).is_nan());
        assert_eq!(message_time(f64::INFINITY), f64::INFINITY);
    }
}
