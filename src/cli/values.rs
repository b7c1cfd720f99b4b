//! Parsing command-line values: comma-separated vectors and `PATH=VALUE` overrides.

use crate::Error;

/// Parses `"1,-0.5,2"` into numbers; `expected` is the length the robot needs and `what` names the
/// entries for the message (e.g. the coordinate names).
pub fn parse_vector(
    flag: &str,
    text: &str,
    expected: usize,
    what: &str,
) -> Result<Vec<f64>, Error> {
    let bad = |message: String| Error::BadArgument {
        flag: flag.to_string(),
        message,
    };
    let trimmed = text.trim();
    let values: Vec<f64> = if trimmed.is_empty() {
        Vec::new()
    } else {
        trimmed
            .split(',')
            .enumerate()
            .map(|(i, item)| {
                let value: f64 = item.trim().parse().map_err(|_| {
                    bad(format!(
                        "element {} ('{}') is not a number",
                        i + 1,
                        item.trim()
                    ))
                })?;
                if value.is_finite() {
                    Ok(value)
                } else {
                    Err(bad(format!(
                        "element {} is {value}; give finite numbers",
                        i + 1
                    )))
                }
            })
            .collect::<Result<_, _>>()?
    };
    if values.len() != expected {
        return Err(bad(format!(
            "expected {expected} comma-separated numbers ({what}), got {}",
            values.len()
        )));
    }
    Ok(values)
}

/// Splits `PATH=VALUE` (the value may be negative; the path may not contain `=`).
pub fn parse_set(text: &str) -> Result<(String, f64), Error> {
    let bad = |message: String| Error::BadArgument {
        flag: "--set".to_string(),
        message,
    };
    let (path, value) = text
        .split_once('=')
        .ok_or_else(|| bad(format!("'{text}' is not of the form PATH=VALUE")))?;
    let value: f64 = value
        .trim()
        .parse()
        .map_err(|_| bad(format!("in '{text}', '{}' is not a number", value.trim())))?;
    Ok((path.trim().to_string(), value))
}

/// Applies `--set PATH=VALUE` flags to a model (validated, then one refresh).
pub fn apply_set_flags(model: &mut crate::model::Model, flags: &[String]) -> Result<(), Error> {
    for flag in flags {
        let (path, value) = parse_set(flag)?;
        let target = crate::params::resolve(model, &path)?;
        crate::params::validate_value(model, target, value)?;
        crate::params::set(model, target, value);
    }
    if let Some(joint) = model
        .description
        .joints
        .iter()
        .find(|j| j.joint_type.has_axis() && j.axis.iter().all(|a| *a == 0.0))
    {
        return Err(Error::BadArgument {
            flag: "--set".to_string(),
            message: format!("the axis of joint '{}' would be zero", joint.name),
        });
    }
    model.refresh();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors() {
        assert_eq!(
            parse_vector("--q", "-0.5, 1", 2, "q").unwrap(),
            vec![-0.5, 1.0]
        );
        let msg = parse_vector("--q", "1,2", 3, "3 joints")
            .unwrap_err()
            .to_string();
        assert_eq!(
            msg,
            "--q: expected 3 comma-separated numbers (3 joints), got 2"
        );
        let msg = parse_vector("--v", "1,x", 2, "v").unwrap_err().to_string();
        assert!(msg.contains("element 2 ('x') is not a number"), "{msg}");
        assert!(parse_vector("--v", "1,inf", 2, "v").is_err());
    }

    #[test]
    fn set_values() {
        assert_eq!(
            parse_set("joint.a.b.origin.x=-0.1").unwrap(),
            ("joint.a.b.origin.x".to_string(), -0.1)
        );
        assert!(parse_set("link.a.mass").is_err());
        assert!(parse_set("link.a.mass=abc").is_err());
    }
}
