//! One `[parameters]` value as written: `[lower, upper]`, `{ rel = … }` or `{ abs = … }`, each
//! optionally with `shared = true` (patterns only).
//!
//! TOML value ⇒ [`IntervalSpec`] (checked for form and for numbers that need no robot: finite,
//! positive amounts, ordered bounds of non-zero width)

/// How an interval is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IntervalForm {
    /// `[lower, upper]`: absolute bounds in the parameter's unit.
    Bounds(f64, f64),
    /// `{ rel = fraction }`: ±`fraction` · |URDF value| (0.01 is ±1 %).
    Relative(f64),
    /// `{ abs = amount }`: ±`amount` around the URDF value, in the parameter's unit.
    Absolute(f64),
}

/// A `[parameters]` value: the interval and whether a pattern's matches share one dimension.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntervalSpec {
    /// The interval.
    pub form: IntervalForm,
    /// `shared = true`: one dimension moves every match of a pattern together.
    pub shared: bool,
}

/// What to write, for messages.
pub const FORMS: &str =
    "write [lower, upper], { rel = fraction } (±fraction of the URDF value) or { abs = amount }";

fn number(value: &toml::Value) -> Option<f64> {
    match value {
        toml::Value::Float(x) => Some(*x),
        // Whole numbers in TOML (`[2, 3]`) are bounds too; i64 → f64 is exact up to 2^53.
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// Reads one `[parameters]` value. The error is the reason, for a message that names the key.
pub fn read_interval(value: &toml::Value) -> Result<IntervalSpec, String> {
    let form = match value {
        toml::Value::Array(items) => match items.as_slice() {
            [lower, upper] => match (number(lower), number(upper)) {
                (Some(lower), Some(upper)) => IntervalForm::Bounds(lower, upper),
                _ => return Err(format!("bounds must be numbers; {FORMS}")),
            },
            _ => {
                return Err(format!(
                    "an interval has two bounds, not {}; {FORMS}",
                    items.len()
                ))
            }
        },
        toml::Value::Table(table) => return read_table(table),
        _ => return Err(FORMS.to_string()),
    };
    check_form(form)?;
    Ok(IntervalSpec {
        form,
        shared: false,
    })
}

fn read_table(table: &toml::Table) -> Result<IntervalSpec, String> {
    let mut form = None;
    let mut shared = false;
    for (name, value) in table {
        match name.as_str() {
            "rel" | "abs" => {
                if form.is_some() {
                    return Err(format!(
                        "an inline table holds exactly one key, rel or abs (not both), and optionally shared = true; {FORMS}"
                    ));
                }
                let Some(amount) = number(value) else {
                    return Err(format!("'{name}' must be a number; {FORMS}"));
                };
                form = Some(if name == "rel" {
                    IntervalForm::Relative(amount)
                } else {
                    IntervalForm::Absolute(amount)
                });
            }
            "shared" => {
                shared = value.as_bool().ok_or_else(|| {
                    "'shared' must be true or false (true: one dimension moves every match of the pattern together)".to_string()
                })?;
            }
            other => {
                return Err(format!(
                    "unknown key '{other}' in an inline table; it holds exactly one key, rel or abs, and optionally shared = true; {FORMS}"
                ))
            }
        }
    }
    let Some(form) = form else {
        return Err(format!(
            "an inline table holds exactly one key, rel or abs (and optionally shared = true); {FORMS}"
        ));
    };
    check_form(form)?;
    Ok(IntervalSpec { form, shared })
}

/// The checks that need no robot.
fn check_form(form: IntervalForm) -> Result<(), String> {
    match form {
        IntervalForm::Relative(rel) if !(rel.is_finite() && rel > 0.0) => {
            Err("rel must be a finite fraction > 0 (0.01 is ±1 %)".to_string())
        }
        IntervalForm::Absolute(amount) if !(amount.is_finite() && amount > 0.0) => Err(
            "abs must be a finite amount > 0 (abs = 0 is no uncertainty: remove the entry, or use --set to change a value)".to_string(),
        ),
        IntervalForm::Bounds(lower, upper) if !(lower.is_finite() && upper.is_finite()) => {
            Err("the bounds must be finite numbers".to_string())
        }
        IntervalForm::Bounds(lower, upper) if lower > upper => Err(format!(
            "the lower bound is above the upper bound; write [{upper}, {lower}]"
        )),
        IntervalForm::Bounds(lower, upper) if lower == upper => Err(
            "the interval has zero width, which is no uncertainty: widen it or remove the entry (use --set to change a value)".to_string(),
        ),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<IntervalSpec, String> {
        let table: toml::Table = toml::from_str(&format!("x = {text}")).unwrap();
        read_interval(&table["x"])
    }

    #[test]
    fn forms() {
        assert_eq!(
            read("[1, 2.5]").unwrap().form,
            IntervalForm::Bounds(1.0, 2.5)
        );
        assert_eq!(
            read("{ rel = 0.05, shared = true }").unwrap(),
            IntervalSpec {
                form: IntervalForm::Relative(0.05),
                shared: true
            }
        );
        assert_eq!(
            read("{ shared = false, abs = 0.002 }").unwrap(),
            IntervalSpec {
                form: IntervalForm::Absolute(0.002),
                shared: false
            }
        );
    }

    #[test]
    fn bad_forms_say_what_to_write() {
        for (text, expected) in [
            ("{ rel = 0.1, abs = 0.1 }", "not both"),
            ("{ shared = true }", "exactly one key, rel or abs"),
            (
                "{ rel = 0.1, shared = 1 }",
                "'shared' must be true or false",
            ),
            ("{ rel = 0.1, share = true }", "unknown key 'share'"),
            ("{ abs = 0 }", "abs must be a finite amount > 0"),
            ("[2, 1]", "write [1, 2]"),
            ("[1, 1]", "zero width"),
            ("\"1\"", "write [lower, upper]"),
        ] {
            let message = read(text).unwrap_err();
            assert!(message.contains(expected), "{text}: {message}");
        }
    }
}
