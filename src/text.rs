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

/// Longest message printed as one line, characters: a longer one is laid out by [`laid_out`].
/// Two lines of a 100-column terminal; the long ones are a failure with its cause, the values it
/// failed at and what to do (issue 42: some ran past 1 000 characters on one line).
pub const LONG_MESSAGE_CHARS: usize = 200;

/// Indentation of a laid-out message's detail lines.
const DETAIL_INDENT: &str = "\n  ";

/// Words ending in a full stop that do not end a sentence.
const ABBREVIATIONS: [&str; 4] = ["e.g", "i.e", "cf", "vs"];

/// A message of one line longer than [`LONG_MESSAGE_CHARS`] as a one-line headline (its first
/// clause) and indented detail lines, one per further clause: the message is cut after each
/// sentence (`. ` before a capital letter) and at each `; `, never inside brackets, parentheses
/// or double quotes. Shorter messages, and messages that already have lines, are returned as
/// they are. Only line breaks and indentation are added: the words are the message's own.
pub fn laid_out(message: &str) -> String {
    if message.contains('\n') || message.chars().count() <= LONG_MESSAGE_CHARS {
        return message.to_string();
    }
    let bytes = message.as_bytes();
    let mut parts: Vec<&str> = Vec::new();
    let (mut start, mut depth, mut quoted) = (0, 0usize, false);
    for (i, &b) in bytes.iter().enumerate() {
        match b {
            b'"' => quoted = !quoted,
            b'(' | b'[' if !quoted => depth += 1,
            b')' | b']' if !quoted => depth = depth.saturating_sub(1),
            b';' | b'.' if !quoted && depth == 0 && bytes.get(i + 1) == Some(&b' ') => {
                let clause = &message[start..i];
                let ends = if b == b';' {
                    true
                } else {
                    bytes.get(i + 2).is_some_and(u8::is_ascii_uppercase)
                        && !ABBREVIATIONS.iter().any(|a| clause.ends_with(a))
                };
                if ends {
                    parts.push(if b == b'.' {
                        &message[start..=i]
                    } else {
                        clause
                    });
                    start = i + 2;
                }
            }
            _ => {}
        }
    }
    parts.push(&message[start..]);
    let mut parts = parts.into_iter().filter(|p| !p.trim().is_empty());
    let mut text = parts.next().unwrap_or_default().to_string();
    for part in parts {
        text.push_str(DETAIL_INDENT);
        text.push_str(part);
    }
    text
}

#[cfg(test)]
mod laid_out_tests {
    use super::*;

    #[test]
    fn a_long_message_gets_a_headline_and_a_line_per_clause() {
        let message = format!(
            "simulation failed: Newton did not converge at t = 0.2 s (step 200; {}); worst: \
             joint 'a' (effective inertia 1e-3, e.g. a light link). Likely cause: the step. Use \
             --keep-going to exclude \"x; y. Z\" samples",
            "x".repeat(150)
        );
        assert_eq!(
            laid_out(&message),
            format!(
                "simulation failed: Newton did not converge at t = 0.2 s (step 200; {})\n  \
                 worst: joint 'a' (effective inertia 1e-3, e.g. a light link).\n  Likely cause: \
                 the step.\n  Use --keep-going to exclude \"x; y. Z\" samples",
                "x".repeat(150)
            )
        );
        // Short, or already laid out: unchanged.
        assert_eq!(laid_out("a; b. C"), "a; b. C");
        let lines = format!("{message}\n  more");
        assert_eq!(laid_out(&lines), lines);
        // Words are kept: only line breaks and indentation are added.
        let words = |s: &str| s.split_whitespace().collect::<Vec<_>>().join(" ");
        assert_eq!(
            words(&laid_out(&message))
                .replace("; ", " ")
                .replace(";", ""),
            words(&message).replace("; ", " ").replace(";", "")
        );
    }
}
