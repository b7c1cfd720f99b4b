//! Parsing command-line values: comma-separated vectors and `PATH=VALUE` overrides (`--set`).
//! Below `cli/` because a nominal run (`nominal_run.rs`) and the Python package apply the same
//! overrides; `cli` re-exports it.

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

/// Applies `--set PATH=VALUE` flags to a model and its environment (validated, then one refresh).
pub fn apply_set_flags(
    model: &mut crate::model::Model,
    environment: &mut crate::environment::Environment,
    flags: &[String],
) -> Result<(), Error> {
    apply_set_flags_with_symbols(model, environment, flags, None)
}

/// [`apply_set_flags`] where a flag may also name a free symbol of `sidecar` (the file and its name
/// in messages), `--set r_wheel=0.3`: the `[bind]` expressions that use the symbols given are
/// evaluated again (the other symbols at their midpoints) and written, and checked as a study
/// checks them ([`crate::uncertainty::ParameterSpace::apply_symbol_values`]); path flags are
/// written after them, so an explicit path wins. The box is expanded only when a flag names a symbol. An unknown name gets
/// the closest path or symbol as a suggestion.
pub fn apply_set_flags_with_symbols(
    model: &mut crate::model::Model,
    environment: &mut crate::environment::Environment,
    flags: &[String],
    sidecar: Option<(&crate::sidecar::SidecarFile, &str)>,
) -> Result<(), Error> {
    let symbol_keys: Vec<&str> = sidecar
        .map(|(file, _)| {
            file.parameters
                .iter()
                .map(|declaration| declaration.key.as_str())
                .filter(|k| crate::uncertainty::is_symbol_name(k))
                .collect()
        })
        .unwrap_or_default();
    let mut paths = Vec::new();
    let mut symbols: Vec<(String, f64)> = Vec::new();
    for flag in flags {
        let (name, value) = parse_set(flag)?;
        match crate::params::resolve_without_suggestion(model, environment, &name) {
            Ok(target) => {
                crate::params::validate_value(model, target, value)?;
                paths.push((target, value));
            }
            Err(crate::params::ParamError::Unknown { .. })
                if symbol_keys.contains(&name.as_str()) =>
            {
                symbols.push((name, value));
            }
            Err(crate::params::ParamError::Unknown { path, .. }) => {
                let listed = crate::params::list(model, environment);
                let names = listed
                    .iter()
                    .map(|p| p.path.as_str())
                    .chain(symbol_keys.iter().copied());
                return Err(crate::params::ParamError::Unknown {
                    suggestion: crate::text::closest_suggestion(&path, names.collect::<Vec<_>>()),
                    path,
                }
                .into());
            }
            Err(other) => return Err(other.into()),
        }
    }
    if let (Some((file, name)), false) = (sidecar, symbols.is_empty()) {
        let space =
            crate::uncertainty::ParameterSpace::from_sidecar(file, model, environment, name)?;
        let values: Vec<(usize, f64)> = symbols
            .iter()
            .filter_map(|(symbol, value)| space.symbol_index(symbol).map(|k| (k, *value)))
            .collect();
        space.apply_symbol_values(model, environment, &values)?;
    }
    for (target, value) in paths {
        crate::params::set(model, environment, target, value);
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
