//! Mission validation: everything is checked before anything moves.
//!
//! In: mission JSON (text or value) and a [`ValidationContext`] (registry, limits, frames,
//! home). Out: a [`ValidMission`], or every error found as a JSON pointer into the mission plus
//! a message. Checks: JSON form, target, known behavior and method, argument names and types
//! (located with the behavior's JSON Schema), the behavior's own range checks, speeds against
//! the vehicle's limit, heights against the ceiling, known frames, and the geofence.

use super::methods::{canonicalize, escape_token, Canonical};
use super::model::{MissionItem, PlanItem, ValidMission, CALL};
use crate::behavior::ParsedGoal;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

mod context;
mod limits;
pub mod schema_check;

pub use context::{ContextSnapshot, Limits, ValidationContext, HOME_TOLERANCE_M};
use limits::check_limits;
use schema_check::Problem;

/// One problem: where (RFC 6901 pointer into the mission) and what.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct ValidationError {
    pub pointer: String,
    pub message: String,
}

impl std::fmt::Display for ValidationError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let at = if self.pointer.is_empty() {
            "(mission)"
        } else {
            &self.pointer
        };
        write!(f, "{at}: {}", self.message)
    }
}

const TOP_LEVEL: [&str; 2] = ["target", "plan"];
/// Most warnings a mission keeps; the rest are counted in one more. A warning per unknown field
/// would let a mission hold ten times its JSON in words (issue 29, item 10).
pub const MAX_WARNINGS: usize = 20;

/// The warnings kept and how many more there were.
#[derive(Default)]
struct Warnings {
    kept: Vec<String>,
    more: usize,
}

impl Warnings {
    fn push(&mut self, warning: impl FnOnce() -> String) {
        if self.kept.len() < MAX_WARNINGS {
            self.kept.push(warning());
        } else {
            self.more += 1;
        }
    }

    fn into_list(mut self) -> Vec<String> {
        if self.more > 0 {
            self.kept
                .push(format!("{} more warnings not listed", self.more));
        }
        self.kept
    }
}

const ITEM_KEYS: [&str; 3] = ["behavior", "method", "args"];
fn at(pointer: &str, message: impl Into<String>) -> ValidationError {
    ValidationError {
        pointer: pointer.to_string(),
        message: message.into(),
    }
}

/// Parses and validates mission text.
pub fn validate_text(
    text: &str,
    ctx: &ValidationContext,
) -> Result<ValidMission, Vec<ValidationError>> {
    // serde's message ends with the line and column.
    let value: Value =
        serde_json::from_str(text).map_err(|e| vec![at("", format!("not valid JSON: {e}"))])?;
    validate_value(&value, ctx)
}

/// Validates a mission given as JSON. Nothing partial: any error rejects the whole mission.
pub fn validate_value(
    value: &Value,
    ctx: &ValidationContext,
) -> Result<ValidMission, Vec<ValidationError>> {
    let mut errors = Vec::new();
    let mut warnings = Warnings::default();
    let Some(obj) = value.as_object() else {
        return Err(vec![at(
            "",
            "a mission is a JSON object {\"target\": .., \"plan\": [..]}",
        )]);
    };
    for key in obj.keys().filter(|k| !TOP_LEVEL.contains(&k.as_str())) {
        warnings.push(|| format!("unknown top-level field `{key}` ignored"));
    }
    let target = match obj.get("target") {
        Some(Value::String(t)) if t == ctx.drone_id => t.clone(),
        Some(Value::String(t)) => {
            errors.push(at(
                "/target",
                format!("mission is for `{t}`, but this is `{}`", ctx.drone_id),
            ));
            t.clone()
        }
        Some(other) => {
            errors.push(at(
                "/target",
                format!("target must be a drone id string, got {other}"),
            ));
            String::new()
        }
        None => {
            errors.push(at("/target", "missing target (the drone id, e.g. drone_0)"));
            String::new()
        }
    };
    let plan = match obj.get("plan") {
        Some(Value::Array(p)) if p.is_empty() => {
            errors.push(at("/plan", "plan is empty: give at least one item"));
            &[][..]
        }
        Some(Value::Array(p)) if p.len() > ctx.limits.max_items => {
            errors.push(at(
                "/plan",
                format!(
                    "plan has {} items, more than the limit of {}",
                    p.len(),
                    ctx.limits.max_items
                ),
            ));
            &[][..]
        }
        Some(Value::Array(p)) => p.as_slice(),
        Some(other) => {
            errors.push(at(
                "/plan",
                format!("plan must be an array of items, got {other}"),
            ));
            &[][..]
        }
        None => {
            errors.push(at("/plan", "missing plan (an array of items)"));
            &[][..]
        }
    };
    let mut items = Vec::with_capacity(plan.len());
    for (i, raw) in plan.iter().enumerate() {
        let pointer = format!("/plan/{i}");
        match validate_item(raw, &pointer, ctx, &mut warnings) {
            Ok(item) => items.push(item),
            Err(mut e) => errors.append(&mut e),
        }
    }
    if errors.is_empty() {
        Ok(ValidMission {
            target,
            items,
            warnings: warnings.into_list(),
        })
    } else {
        Err(errors)
    }
}

fn validate_item(
    raw: &Value,
    pointer: &str,
    ctx: &ValidationContext,
    warnings: &mut Warnings,
) -> Result<PlanItem, Vec<ValidationError>> {
    let Some(obj) = raw.as_object() else {
        return Err(vec![at(
            pointer,
            "an item is an object {\"behavior\", \"method\", \"args\"}",
        )]);
    };
    for key in obj.keys().filter(|k| !ITEM_KEYS.contains(&k.as_str())) {
        warnings.push(|| format!("{pointer}: unknown field `{key}` ignored"));
    }
    let mut errors = Vec::new();
    let behavior = match obj.get("behavior") {
        Some(Value::String(b)) if ctx.registry.get(b).is_some() => Some(b.clone()),
        Some(Value::String(b)) => {
            let known: Vec<&str> = ctx.registry.iter().map(|s| s.name).collect();
            errors.push(at(
                &format!("{pointer}/behavior"),
                format!("unknown behavior `{b}`; known: {}", known.join(", ")),
            ));
            None
        }
        Some(other) => {
            errors.push(at(
                &format!("{pointer}/behavior"),
                format!("behavior must be a string, got {other}"),
            ));
            None
        }
        None => {
            errors.push(at(&format!("{pointer}/behavior"), "missing behavior"));
            None
        }
    };
    let method = match obj.get("method") {
        None | Some(Value::Null) => CALL.to_string(),
        Some(Value::String(m)) => m.clone(),
        Some(other) => {
            errors.push(at(
                &format!("{pointer}/method"),
                format!("method must be a string, got {other}"),
            ));
            CALL.to_string()
        }
    };
    let args = match obj.get("args") {
        None | Some(Value::Null) => Map::new(),
        Some(Value::Object(a)) => a.clone(),
        Some(other) => {
            errors.push(at(
                &format!("{pointer}/args"),
                format!("args must be an object of named arguments, got {other}"),
            ));
            Map::new()
        }
    };
    let Some(behavior) = behavior else {
        return Err(errors);
    };
    if !errors.is_empty() {
        return Err(errors);
    }
    let args_pointer = format!("{pointer}/args");
    let canonical = canonicalize(&behavior, &method, &args).map_err(|errs| {
        errs.into_iter()
            .map(|e| {
                if e.message.starts_with("unknown method") {
                    at(&format!("{pointer}/method"), e.message)
                } else {
                    at(&join(&args_pointer, &escape_token(&e.key)), e.message)
                }
            })
            .collect::<Vec<_>>()
    })?;
    let goal = Value::Object(canonical.goal.clone());
    let parsed = check_goal(&behavior, &goal, &canonical, &args_pointer, ctx)?;
    check_limits(&goal, parsed.summary(), &canonical, &args_pointer, ctx)?;
    let written = MissionItem {
        behavior,
        method,
        args,
    };
    PlanItem::new(&written, canonical.options).map_err(|e| vec![at(&args_pointer, e.to_string())])
}

/// `base` + `/` + `suffix`, where `suffix` is already a JSON pointer below `base`.
fn join(base: &str, suffix: &str) -> String {
    if suffix.is_empty() {
        base.to_string()
    } else {
        format!("{base}/{suffix}")
    }
}

/// Runs the behavior's own parsing and checks, once: the parsed goal is what the behavior
/// gets when the item starts. On failure, locates each problem.
fn check_goal(
    behavior: &str,
    goal: &Value,
    canonical: &Canonical,
    args_pointer: &str,
    ctx: &ValidationContext,
) -> Result<ParsedGoal, Vec<ValidationError>> {
    let Some(spec) = ctx.registry.get(behavior) else {
        return Err(vec![at(args_pointer, "unknown behavior")]);
    };
    let message = match (spec.parse)(goal) {
        Ok(parsed) => return Ok(parsed),
        Err(f) => f.message,
    };
    let located = schema_errors(&spec.args_schema, goal, canonical, args_pointer);
    if !located.is_empty() {
        return Err(located);
    }
    let pointer = match leading_key(&message, goal) {
        Some((name, Some(i))) => join(args_pointer, &format!("{}/{i}", canonical.origin_of(&name))),
        Some((name, None)) => join(args_pointer, &canonical.origin_of(&name)),
        None => args_pointer.to_string(),
    };
    Err(vec![at(&pointer, message)])
}

/// Problems the JSON Schema of the arguments finds, each at its own pointer.
fn schema_errors(
    schema: &Value,
    goal: &Value,
    canonical: &Canonical,
    args_pointer: &str,
) -> Vec<ValidationError> {
    let located = |path: &[String]| {
        let Some((first, rest)) = path.split_first() else {
            return args_pointer.to_string();
        };
        let mut origin = canonical.origin_of(first);
        for token in rest {
            origin.push('/');
            origin.push_str(&escape_token(token));
        }
        join(args_pointer, &origin)
    };
    schema_check::check(schema, goal)
        .into_iter()
        .map(|found| {
            let message = match found.problem {
                Problem::Missing(name) => format!("missing argument `{name}`"),
                Problem::Unknown(name) => format!("unknown argument `{name}`"),
                Problem::Invalid(message) => message,
            };
            at(&located(&found.path), message)
        })
        .collect()
}

/// The argument a behavior's message starts with (`speed must be ..`, `path[2] must ..`),
/// with its index when it has one.
fn leading_key(message: &str, goal: &Value) -> Option<(String, Option<usize>)> {
    let word: String = message
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '[' || *c == ']')
        .collect();
    let (name, index) = match word.split_once('[') {
        Some((n, rest)) => (
            n.to_string(),
            rest.trim_end_matches(']').parse::<usize>().ok(),
        ),
        None => (word, None),
    };
    goal.get(&name)?;
    Some((name, index))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warnings_beyond_the_most_kept_are_counted_in_one() {
        let mut warnings = Warnings::default();
        for k in 0..MAX_WARNINGS + 5 {
            warnings.push(|| format!("w{k}"));
        }
        let list = warnings.into_list();
        assert_eq!(list.len(), MAX_WARNINGS + 1);
        assert_eq!(list[0], "w0");
        assert_eq!(list[MAX_WARNINGS], "5 more warnings not listed");
    }

    #[test]
    fn pointer_tokens_are_escaped() {
        assert_eq!(escape_token("a/b~c"), "a~1b~0c");
        assert_eq!(join("/plan/0/args", ""), "/plan/0/args");
    }

    #[test]
    fn leading_key_finds_indexed_arguments() {
        let goal = serde_json::json!({"path": [[0, 0, 0]], "speed": 1});
        assert_eq!(
            leading_key("path[0] must be finite", &goal),
            Some(("path".into(), Some(0)))
        );
        assert_eq!(
            leading_key("speed must be positive", &goal),
            Some(("speed".into(), None))
        );
        assert_eq!(leading_key("give yaw_angle", &goal), None);
    }
}
