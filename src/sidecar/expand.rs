//! Expansion of `[parameters]`: which keys become which dimensions.
//!
//! (`[parameters]`, `[bind]` keys, model) ⇒ (entries in dimension order, notes)
//!
//! Rules (README "The sidecar"):
//! - an ordinary path or a free symbol is one dimension, at its place in the file;
//! - a pattern (`"link.*.mass"`) expands in place into one dimension per match, in registry order
//!   ([`crate::params::list`]), each named by its full path; with `shared = true` it is one
//!   dimension named by the pattern key that moves every match together;
//! - who owns a path matched by several keys: an explicit `[parameters]` key or a `[bind]` key
//!   always wins over a pattern (wherever it appears in the file); of two patterns, the **later
//!   one in the file** wins (as later rules refine earlier ones: `"joint.*.origin.*"` then
//!   `"joint.*.origin.roll"`). Each such decision is a note naming both keys;
//! - matches a pattern cannot use are not matches: with `rel`, paths whose URDF value is 0 (a
//!   relative interval of 0 is empty); with `*` in the NAME of a `link` pattern, links that carry
//!   no dynamics — without mass (no `<inertial>`, or mass 0) or part of the fixed world (the root
//!   link of a fixed base and links fixed to it). Each pattern says how many it skipped in a note;
//! - errors: a misplaced `*`, a pattern that matches no path of the robot (with the closest
//!   shapes), a pattern left with no dimension, `[lower, upper]` on a pattern (its matches have
//!   different URDF values, which one interval cannot contain), `rel`/`abs` on a symbol, `shared`
//!   on anything but a pattern (a single value has nothing to share; refused so that a dimension
//!   never silently changes from a value to a factor), `shared` + `abs` over matches of different
//!   units.
//!
//! Numbers (bounds from `rel`/`abs`, URDF value inside, possible values) are checked by
//! [`crate::uncertainty::ParameterSpace`], which builds the dimensions from these entries.

use super::error::SidecarError;
use super::file::{located, BindDeclaration, ParameterDeclaration};
use super::interval::{IntervalForm, IntervalSpec};
use super::pattern::{PathPattern, PATTERN_KINDS};
use crate::environment::Environment;
use crate::model::Model;
use crate::params::{self, ParamInfo, ParamTarget};
use crate::text::closest_suggestion;
use std::collections::HashMap;

/// How many paths a note lists before "and N more".
const NOTE_LIST_LENGTH: usize = 6;

/// How many pattern shapes a "matches nothing" message lists.
const SHAPE_LIST_LENGTH: usize = 12;

/// `[table] "key"`, the way messages name a sidecar key.
pub fn key_label(table: &str, key: &str) -> String {
    format!("[{table}] \"{key}\"")
}

/// Whether `key` can be a free symbol: `[A-Za-z_][A-Za-z0-9_]*`.
pub fn is_symbol_name(key: &str) -> bool {
    let mut chars = key.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The name of the square-root function of `[bind]` expressions, which no symbol may take.
const RESERVED_SYMBOL: &str = "sqrt";

/// One dimension-to-be of `[parameters]`.
#[derive(Clone, Debug, PartialEq)]
pub struct ParameterEntry {
    /// The key it comes from, as written: the path or symbol itself, or the pattern key.
    pub source: String,
    /// The line of that key in the sidecar, when read from a file.
    pub line: Option<usize>,
    /// The key's value as written (TOML), for messages.
    pub value: String,
    /// The interval as written.
    pub interval: IntervalSpec,
    /// What the dimension moves.
    pub kind: EntryKind,
}

/// What one entry moves.
#[derive(Clone, Debug, PartialEq)]
pub enum EntryKind {
    /// One model value: an explicit key (`from_pattern` false) or one match of a pattern.
    Path {
        /// Its full path (the dimension's name).
        path: String,
        /// The value it writes.
        target: ParamTarget,
        /// Whether it is a pattern's match (then `source` is the pattern key).
        from_pattern: bool,
    },
    /// A free symbol (the dimension's name is `source`).
    Symbol,
    /// A shared pattern: every match moves with one dimension named by the pattern key.
    Group {
        /// The matches in registry order: full path and target.
        members: Vec<(String, ParamTarget)>,
        /// `""` for `rel` (a factor), the matches' common unit for `abs` (an offset).
        unit: &'static str,
    },
}

impl ParameterEntry {
    /// The dimension's name: the full path, the symbol, or the pattern key of a group.
    pub fn name(&self) -> &str {
        match &self.kind {
            EntryKind::Path { path, .. } => path,
            EntryKind::Symbol | EntryKind::Group { .. } => &self.source,
        }
    }
}

/// `[parameters]` expanded: entries in dimension order, and what the expansion decided.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExpandedParameters {
    /// One entry per dimension of ξ, in order.
    pub entries: Vec<ParameterEntry>,
    /// Decisions worth knowing (overrides, skipped zero values, links not matched), one line
    /// each, starting with the file name.
    pub notes: Vec<String>,
}

/// A `[parameters]` key after classification.
enum KeyClass<'k> {
    Path(ParamTarget),
    Symbol,
    Pattern(PathPattern<'k>),
}

/// Who owns a path.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Owner {
    /// `[parameters]` key number `usize` (explicit path).
    Explicit(usize),
    /// A `[bind]` key (its index in `[bind]`).
    Bound(usize),
    /// `[parameters]` key number `usize` (a pattern).
    Pattern(usize),
}

/// A pattern's matches after the skips.
struct PatternMatches {
    /// Registry paths the pattern fits, before skipping.
    matched: usize,
    /// Usable matches (registry indices).
    usable: Vec<usize>,
    /// Links not matched because they carry no dynamics: name and why.
    no_dynamics: Vec<String>,
    /// Paths skipped because `rel` of 0 is empty.
    zero: Vec<String>,
}

/// Expands `[parameters]` (patterns, ownership, skips) against `model` and `environment`; `bind` is read only for
/// its keys (bound paths are taken out of patterns' matches). `file` names the sidecar in messages.
pub fn expand_parameters(
    parameters: &[ParameterDeclaration],
    bind: &[BindDeclaration],
    model: &Model,
    environment: &Environment,
    file: &str,
) -> Result<ExpandedParameters, SidecarError> {
    let registry = params::list(model, environment);
    let mut classes: Vec<(KeyClass<'_>, IntervalSpec)> = Vec::with_capacity(parameters.len());
    for declaration in parameters {
        classes.push(classify(declaration, model, environment, file)?);
    }

    // Ownership: explicit and bound paths first, then patterns in file order (later wins).
    let mut owner: HashMap<ParamTarget, Owner> = HashMap::new();
    for (k, (class, _)) in classes.iter().enumerate() {
        if let KeyClass::Path(target) = class {
            owner.insert(*target, Owner::Explicit(k));
        }
    }
    for (b, key) in bind.iter().map(|b| &b.key).enumerate() {
        // A key that is no path is reported when [bind] is resolved.
        if let Ok(target) = params::resolve_without_suggestion(model, environment, key) {
            owner.entry(target).or_insert(Owner::Bound(b));
        }
    }
    let keys: Vec<&String> = parameters.iter().map(|p| &p.key).collect();
    let bind_keys: Vec<&String> = bind.iter().map(|b| &b.key).collect();
    let mut matches: Vec<Option<PatternMatches>> = Vec::with_capacity(classes.len());
    // (winner, loser) → paths the later pattern took from the earlier one.
    let mut taken: Vec<((usize, usize), Vec<String>)> = Vec::new();
    let mut notes = Vec::new();
    for (k, (class, interval)) in classes.iter().enumerate() {
        let KeyClass::Pattern(pattern) = class else {
            matches.push(None);
            continue;
        };
        let at = located(file, parameters[k].line);
        let file = at.as_str();
        let found = pattern_matches(pattern, interval, &registry, model, environment);
        if found.matched == 0 {
            return Err(SidecarError::PatternMatchesNothing {
                file: file.to_string(),
                key: key_label("parameters", keys[k]),
                robot: model.name().to_string(),
                hint: shapes_hint(pattern, &registry, model),
            });
        }
        for &r in &found.usable {
            let entry = &registry[r];
            match owner.get(&entry.target).copied() {
                None => {
                    owner.insert(entry.target, Owner::Pattern(k));
                }
                Some(Owner::Pattern(earlier)) => {
                    owner.insert(entry.target, Owner::Pattern(k));
                    match taken.iter_mut().find(|(pair, _)| *pair == (k, earlier)) {
                        Some((_, paths)) => paths.push(entry.path.clone()),
                        None => taken.push(((k, earlier), vec![entry.path.clone()])),
                    }
                }
                Some(Owner::Explicit(_) | Owner::Bound(_)) => {}
            }
        }
        matches.push(Some(found));
    }

    let mut entries = Vec::new();
    for (k, (class, interval)) in classes.iter().enumerate() {
        let key = keys[k];
        let value = parameters[k].value.clone();
        let line = parameters[k].line;
        // Errors about the key point at its line (notes keep the file's name alone).
        let at = located(file, line);
        let entry = |kind| ParameterEntry {
            source: key.clone(),
            line,
            value: value.clone(),
            interval: *interval,
            kind,
        };
        let found = match class {
            KeyClass::Path(target) => {
                entries.push(entry(EntryKind::Path {
                    path: key.clone(),
                    target: *target,
                    from_pattern: false,
                }));
                continue;
            }
            KeyClass::Symbol => {
                entries.push(entry(EntryKind::Symbol));
                continue;
            }
            KeyClass::Pattern(_) => matches[k]
                .as_ref()
                .ok_or_else(|| unreachable_pattern(&at, key))?,
        };
        let label = key_label("parameters", key);
        let mut own = Vec::new();
        let (mut overridden, mut later) = (0, 0);
        for &r in &found.usable {
            let info = &registry[r];
            match owner.get(&info.target).copied() {
                Some(Owner::Pattern(p)) if p == k => own.push(r),
                Some(Owner::Explicit(e)) => {
                    overridden += 1;
                    notes.push(format!(
                        "{file}: {} overrides the match of {label} (an explicit key wins over a pattern)",
                        key_label("parameters", keys[e])
                    ));
                }
                Some(Owner::Bound(b)) => {
                    overridden += 1;
                    notes.push(format!(
                        "{file}: {} is taken out of the matches of {label} (a bound value follows its expression)",
                        key_label("bind", bind_keys[b])
                    ));
                }
                _ => later += 1,
            }
        }
        if !found.no_dynamics.is_empty() {
            notes.push(format!(
                "{file}: {label}: {} not matched because {} no dynamics: {}",
                count(found.no_dynamics.len(), "link is", "links are"),
                if found.no_dynamics.len() == 1 {
                    "it carries"
                } else {
                    "they carry"
                },
                list(&found.no_dynamics)
            ));
        }
        if !found.zero.is_empty() {
            notes.push(format!(
                "{file}: {label} = {value}: {} 0 in the URDF and skipped (a relative interval of 0 is empty; give such values {{ abs = … }}): {}",
                count(found.zero.len(), "match is", "matches are"),
                list(&found.zero)
            ));
        }
        if own.is_empty() {
            let mut reasons = Vec::new();
            if !found.zero.is_empty() {
                reasons.push(format!(
                    "{} 0 with rel",
                    count(found.zero.len(), "is", "are")
                ));
            }
            if !found.no_dynamics.is_empty() {
                reasons.push(format!(
                    "{} on links without dynamics",
                    count(found.no_dynamics.len(), "is", "are")
                ));
                if kinematic_only(model) {
                    reasons.push(
                        "no moving link of this robot has an <inertial> (a kinematic-only \
                         description, as ROS-Industrial's support packages are): its motion needs \
                         each moving link's mass and inertia, so add <inertial> elements (from CAD \
                         or the manufacturer's data) before declaring them uncertain"
                            .to_string(),
                    );
                }
            }
            if overridden > 0 {
                reasons.push(format!("{overridden} taken by explicit or [bind] keys"));
            }
            if later > 0 {
                reasons.push(format!("{later} taken by later patterns"));
            }
            return Err(SidecarError::PatternGivesNothing {
                file: at.clone(),
                key: label,
                matched: found.matched,
                reason: reasons.join(", "),
            });
        }
        if interval.shared {
            let members: Vec<(String, ParamTarget)> = own
                .iter()
                .map(|&r| (registry[r].path.clone(), registry[r].target))
                .collect();
            let unit = match interval.form {
                IntervalForm::Absolute(_) => common_unit(&own, &registry).map_err(|units| {
                    SidecarError::SharedMixedUnits {
                        file: at.clone(),
                        key: label.clone(),
                        value: value.clone(),
                        units,
                    }
                })?,
                _ => "",
            };
            entries.push(entry(EntryKind::Group { members, unit }));
        } else {
            for &r in &own {
                entries.push(entry(EntryKind::Path {
                    path: registry[r].path.clone(),
                    target: registry[r].target,
                    from_pattern: true,
                }));
            }
        }
    }
    for ((winner, loser), paths) in &taken {
        notes.push(format!(
            "{file}: {} takes {} from the earlier {} (of two patterns, the later one in the file wins): {}",
            key_label("parameters", keys[*winner]),
            count(paths.len(), "match", "matches"),
            key_label("parameters", keys[*loser]),
            list(paths)
        ));
    }
    Ok(ExpandedParameters { entries, notes })
}

/// A pattern entry without its matches is a bug of this module, reported as an error rather than a
/// panic.
fn unreachable_pattern(file: &str, key: &str) -> SidecarError {
    SidecarError::BadPattern {
        file: file.to_string(),
        key: key_label("parameters", key),
        reason: "internal error: the pattern's matches were lost; please report this".to_string(),
    }
}

/// Classifies one key and takes its interval, refusing forms that do not fit the key.
fn classify<'k>(
    declaration: &'k ParameterDeclaration,
    model: &Model,
    environment: &Environment,
    file: &str,
) -> Result<(KeyClass<'k>, IntervalSpec), SidecarError> {
    let at = located(file, declaration.line);
    let file = at.as_str();
    let key = declaration.key.as_str();
    let label = key_label("parameters", key);
    let class = match params::resolve_without_suggestion(model, environment, key) {
        Ok(target) => KeyClass::Path(target),
        Err(error) => match PathPattern::parse(key) {
            Err(reason) => {
                return Err(SidecarError::BadPattern {
                    file: file.to_string(),
                    key: label,
                    reason,
                })
            }
            Ok(Some(pattern)) => KeyClass::Pattern(pattern),
            Ok(None) if is_symbol_name(key) => {
                if key == RESERVED_SYMBOL {
                    return Err(SidecarError::ReservedSymbol {
                        file: file.to_string(),
                        key: label,
                    });
                }
                KeyClass::Symbol
            }
            Ok(None) => {
                // The message with its suggestion, searched only now that it is needed.
                let reason = params::resolve(model, environment, key)
                    .err()
                    .unwrap_or(error);
                return Err(SidecarError::UnknownKey {
                    file: file.to_string(),
                    key: label,
                    reason: reason.to_string(),
                });
            }
        },
    };
    let bad = |reason: String| SidecarError::BadInterval {
        file: file.to_string(),
        key: label.clone(),
        value: declaration.value.clone(),
        reason,
    };
    let interval = declaration.interval.clone().map_err(bad)?;
    match (&class, interval.form, interval.shared) {
        (KeyClass::Symbol, IntervalForm::Relative(_) | IntervalForm::Absolute(_), _) => {
            return Err(bad(format!(
                "a free symbol has no URDF value, so it takes explicit bounds only: {key} = [lower, upper]"
            )))
        }
        (KeyClass::Pattern(_), IntervalForm::Bounds(..), _) => {
            return Err(bad(
                "a pattern's matches have different URDF values, and one [lower, upper] would have to contain each of them; give the pattern { rel = fraction } or { abs = amount } (per match), or write an explicit key for a path that needs its own bounds".to_string(),
            ))
        }
        (KeyClass::Path(_) | KeyClass::Symbol, _, true) => {
            return Err(bad(
                "shared = true makes one dimension move every match of a pattern together; a single path or symbol has nothing to share: remove shared (or write a pattern such as \"link.*.mass\")".to_string(),
            ))
        }
        _ => {}
    }
    Ok((class, interval))
}

/// Whether no moving link of `model` has an `<inertial>` (a kinematic-only description).
fn kinematic_only(model: &Model) -> bool {
    model
        .links
        .iter()
        .zip(&model.description.links)
        .all(|(link, spec)| link.body.is_none() || !spec.has_inertial)
}

/// Why a link cannot be a match of a `link.*` pattern, if it cannot.
fn no_dynamics(model: &Model, link: usize) -> Option<&'static str> {
    let spec = &model.description.links[link];
    if model.links[link].body.is_none() {
        Some("fixed to the world")
    } else if !spec.has_inertial {
        Some("no <inertial>")
    } else if spec.inertial.mass == 0.0 {
        Some("mass 0")
    } else {
        None
    }
}

/// The link a target belongs to.
fn link_of(target: ParamTarget) -> Option<usize> {
    match target {
        ParamTarget::LinkMass(l)
        | ParamTarget::LinkScale(l)
        | ParamTarget::LinkCom(l, _)
        | ParamTarget::LinkInertia(l, _) => Some(l),
        _ => None,
    }
}

fn pattern_matches(
    pattern: &PathPattern<'_>,
    interval: &IntervalSpec,
    registry: &[ParamInfo],
    model: &Model,
    environment: &Environment,
) -> PatternMatches {
    let mut found = PatternMatches {
        matched: 0,
        usable: Vec::new(),
        no_dynamics: Vec::new(),
        zero: Vec::new(),
    };
    for (r, info) in registry.iter().enumerate() {
        if !pattern.matches(&params::parts_of(model, info.target)) {
            continue;
        }
        found.matched += 1;
        if let Some(link) = link_of(info.target).filter(|_| pattern.name_is_wildcard()) {
            if let Some(why) = no_dynamics(model, link) {
                let name = &model.description.links[link].name;
                let described = format!("{name} ({why})");
                if !found.no_dynamics.contains(&described) {
                    found.no_dynamics.push(described);
                }
                continue;
            }
        }
        if matches!(interval.form, IntervalForm::Relative(_))
            && params::get(model, environment, info.target) == 0.0
        {
            found.zero.push(info.path.clone());
            continue;
        }
        found.usable.push(r);
    }
    found
}

/// The one unit of these registry entries, or a description of the different ones.
fn common_unit(entries: &[usize], registry: &[ParamInfo]) -> Result<&'static str, String> {
    let mut units: Vec<(&'static str, &str)> = Vec::new();
    for &r in entries {
        if !units.iter().any(|(unit, _)| *unit == registry[r].unit) {
            units.push((registry[r].unit, &registry[r].path));
        }
    }
    match units.as_slice() {
        [(unit, _)] => Ok(unit),
        _ => Err(units
            .iter()
            .map(|(unit, path)| {
                let unit = if unit.is_empty() { "unitless" } else { unit };
                format!("{unit}: {path}")
            })
            .collect::<Vec<_>>()
            .join("; ")),
    }
}

/// "; did you mean …?" plus the pattern shapes of the robot with the same `*` positions.
fn shapes_hint(pattern: &PathPattern<'_>, registry: &[ParamInfo], model: &Model) -> String {
    let mut shapes: Vec<String> = Vec::new();
    for info in registry {
        if let Some(shape) = pattern.generalise(&params::parts_of(model, info.target)) {
            if !shapes.contains(&shape) {
                shapes.push(shape);
            }
        }
    }
    if shapes.is_empty() {
        // No path of this kind has as many segments: show the kind's shapes with `*` for NAME.
        for info in registry {
            let parts = params::parts_of(model, info.target);
            if parts.kind == pattern.kind {
                let shape = match parts.name {
                    Some(_) => format!("{}.*.{}", parts.kind, parts.field),
                    None => format!("{}.{}", parts.kind, parts.field),
                };
                if !shapes.contains(&shape) {
                    shapes.push(shape);
                }
            }
        }
    }
    let suggestion = closest_suggestion(pattern.key, shapes.iter().map(String::as_str));
    if shapes.is_empty() {
        return format!(
            "{suggestion}; the kinds of path are {}",
            PATTERN_KINDS.join(", ")
        );
    }
    let more = shapes.len().saturating_sub(SHAPE_LIST_LENGTH);
    shapes.truncate(SHAPE_LIST_LENGTH);
    format!(
        "{suggestion}; paths of this shape on the robot: {}{}",
        shapes.join(", "),
        if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        }
    )
}

fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

fn list(items: &[String]) -> String {
    let mut text = items
        .iter()
        .take(NOTE_LIST_LENGTH)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    if items.len() > NOTE_LIST_LENGTH {
        text.push_str(&format!(" and {} more", items.len() - NOTE_LIST_LENGTH));
    }
    text
}
