//! Locates the problems in a goal with the behavior's JSON Schema (draft 2020-12, as schemars
//! writes it): only the keywords those schemas use, listed in [`KEYWORDS`].
//!
//! In: a schema and a value. Out: every problem found, each with the path of the value it is
//! about. The behavior's typed parse decides whether a goal is valid; this only says where it
//! is not (a general JSON Schema validator with its regex engines cost about 1 MB of the
//! binary: BENCHMARKS.md, "Release binary size").

use serde_json::{Map, Value};

/// The keywords checked. A schema with any other keyword, apart from [`ANNOTATIONS`], is not
/// understood: a test walks every registered behavior's schema for that.
pub const KEYWORDS: [&str; 20] = [
    "$ref",
    "type",
    "enum",
    "const",
    "minimum",
    "maximum",
    "exclusiveMinimum",
    "exclusiveMaximum",
    "minLength",
    "maxLength",
    "items",
    "prefixItems",
    "minItems",
    "maxItems",
    "properties",
    "required",
    "additionalProperties",
    "anyOf",
    "oneOf",
    "allOf",
];

/// Keywords that say nothing about validity (`format` is an annotation in draft 2020-12).
pub const ANNOTATIONS: [&str; 9] = [
    "$schema",
    "$defs",
    "title",
    "description",
    "default",
    "examples",
    "format",
    "readOnly",
    "writeOnly",
];

/// Deeper `$ref` chains than this are not followed (a schema referring to itself).
const MAX_DEPTH: usize = 32;

/// What is wrong at a place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Problem {
    /// A required property is absent (the path ends with its name).
    Missing(String),
    /// A property the schema does not allow (the path ends with its name).
    Unknown(String),
    /// Any other rule, in words.
    Invalid(String),
}

/// One problem and the path of the value it is about (object keys and array indices, not
/// escaped).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Found {
    pub path: Vec<String>,
    pub problem: Problem,
}

/// Every problem of `value` under `schema`.
pub fn check(schema: &Value, value: &Value) -> Vec<Found> {
    let mut out = Vec::new();
    let mut path = Vec::new();
    walk(schema, schema, value, &mut path, &mut out, 0);
    out
}

fn walk(
    root: &Value,
    schema: &Value,
    value: &Value,
    path: &mut Vec<String>,
    out: &mut Vec<Found>,
    depth: usize,
) {
    let Some(s) = schema.as_object() else {
        if schema == &Value::Bool(false) {
            invalid(out, path, format!("False schema does not allow {value}"));
        }
        return;
    };
    if depth > MAX_DEPTH {
        return;
    }
    if let Some(target) = s.get("$ref").and_then(Value::as_str) {
        if let Some(sub) = target.strip_prefix('#').and_then(|p| root.pointer(p)) {
            walk(root, sub, value, path, out, depth + 1);
        }
    }
    check_type(s, value, path, out);
    check_values(s, value, path, out);
    match value {
        Value::Array(items) => check_array(root, s, items, path, out, depth),
        Value::Object(fields) => check_object(root, s, fields, path, out, depth),
        _ => {}
    }
    for sub in s
        .get("allOf")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
    {
        walk(root, sub, value, path, out, depth + 1);
    }
    for keyword in ["anyOf", "oneOf"] {
        let Some(subs) = s.get(keyword).and_then(Value::as_array) else {
            continue;
        };
        let valid = subs
            .iter()
            .filter(|sub| {
                let mut found = Vec::new();
                walk(root, sub, value, &mut Vec::new(), &mut found, depth + 1);
                found.is_empty()
            })
            .count();
        if keyword == "anyOf" && valid == 0 {
            let m = format!(
                "{value} is not valid under any of the schemas listed in the 'anyOf' keyword"
            );
            invalid(out, path, m);
        } else if keyword == "oneOf" && valid != 1 {
            let m = format!("{value} is not valid under exactly one of the schemas listed in the 'oneOf' keyword");
            invalid(out, path, m);
        }
    }
}

fn invalid(out: &mut Vec<Found>, path: &[String], message: String) {
    out.push(Found {
        path: path.to_vec(),
        problem: Problem::Invalid(message),
    });
}

fn is_type(value: &Value, name: &str) -> bool {
    match name {
        "null" => value.is_null(),
        "boolean" => value.is_boolean(),
        "string" => value.is_string(),
        "array" => value.is_array(),
        "object" => value.is_object(),
        "number" => value.is_number(),
        "integer" => {
            value.is_i64() || value.is_u64() || value.as_f64().is_some_and(|f| f.fract() == 0.0)
        }
        _ => true,
    }
}

fn check_type(s: &Map<String, Value>, value: &Value, path: &[String], out: &mut Vec<Found>) {
    match s.get("type") {
        Some(Value::String(t)) if !is_type(value, t) => {
            invalid(out, path, format!("{value} is not of type \"{t}\""));
        }
        Some(Value::Array(ts)) => {
            let names: Vec<&str> = ts.iter().filter_map(Value::as_str).collect();
            if !names.iter().any(|t| is_type(value, t)) {
                let listed: Vec<String> = names.iter().map(|t| format!("\"{t}\"")).collect();
                let m = format!("{value} is not of types {}", listed.join(", "));
                invalid(out, path, m);
            }
        }
        _ => {}
    }
}

/// A numeric bound: its keyword, whether a value keeps it, the words when it does not.
type Bound = (&'static str, fn(f64, f64) -> bool, &'static str);

/// JSON equality with numbers compared by value (`1` equals `1.0`).
fn same(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => x.as_f64() == y.as_f64(),
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(a, b)| same(a, b))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| same(v, w)))
        }
        _ => a == b,
    }
}

/// `enum`, `const`, the numeric bounds and the string lengths.
fn check_values(s: &Map<String, Value>, value: &Value, path: &[String], out: &mut Vec<Found>) {
    if let Some(options) = s.get("enum").and_then(Value::as_array) {
        if !options.iter().any(|o| same(o, value)) {
            invalid(
                out,
                path,
                format!("{value} is not one of {}", Value::Array(options.clone())),
            );
        }
    }
    if let Some(c) = s.get("const") {
        if !same(c, value) {
            invalid(out, path, format!("{c} was expected"));
        }
    }
    if let Some(v) = value.as_f64() {
        let bounds: [Bound; 4] = [
            ("minimum", |v, b| v >= b, "is less than the minimum of"),
            ("maximum", |v, b| v <= b, "is greater than the maximum of"),
            (
                "exclusiveMinimum",
                |v, b| v > b,
                "is less than or equal to the minimum of",
            ),
            (
                "exclusiveMaximum",
                |v, b| v < b,
                "is greater than or equal to the maximum of",
            ),
        ];
        for (keyword, holds, words) in bounds {
            if let Some(bound) = s
                .get(keyword)
                .filter(|b| b.as_f64().is_some_and(|b| !holds(v, b)))
            {
                invalid(out, path, format!("{value} {words} {bound}"));
            }
        }
    }
    if let Some(text) = value.as_str() {
        let chars = text.chars().count() as u64;
        if let Some(n) = s
            .get("minLength")
            .and_then(Value::as_u64)
            .filter(|n| chars < *n)
        {
            invalid(out, path, format!("{value} is shorter than {n} characters"));
        }
        if let Some(n) = s
            .get("maxLength")
            .and_then(Value::as_u64)
            .filter(|n| chars > *n)
        {
            invalid(out, path, format!("{value} is longer than {n} characters"));
        }
    }
}

fn check_array(
    root: &Value,
    s: &Map<String, Value>,
    items: &[Value],
    path: &mut Vec<String>,
    out: &mut Vec<Found>,
    depth: usize,
) {
    let count = items.len() as u64;
    if let Some(n) = s
        .get("minItems")
        .and_then(Value::as_u64)
        .filter(|n| count < *n)
    {
        invalid(
            out,
            path,
            format!("{} has less than {n} items", Value::Array(items.to_vec())),
        );
    }
    if let Some(n) = s
        .get("maxItems")
        .and_then(Value::as_u64)
        .filter(|n| count > *n)
    {
        invalid(
            out,
            path,
            format!("{} has more than {n} items", Value::Array(items.to_vec())),
        );
    }
    let prefix = s.get("prefixItems").and_then(Value::as_array);
    let prefix_len = prefix.map_or(0, Vec::len);
    for (i, item) in items.iter().enumerate() {
        let sub = match prefix.and_then(|p| p.get(i)) {
            Some(sub) => Some(sub),
            None if i >= prefix_len => s.get("items"),
            None => None,
        };
        if let Some(sub) = sub {
            path.push(i.to_string());
            walk(root, sub, item, path, out, depth + 1);
            path.pop();
        }
    }
}

fn check_object(
    root: &Value,
    s: &Map<String, Value>,
    fields: &Map<String, Value>,
    path: &mut Vec<String>,
    out: &mut Vec<Found>,
    depth: usize,
) {
    for name in s
        .get("required")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
    {
        let Some(name) = name.as_str().filter(|n| !fields.contains_key(*n)) else {
            continue;
        };
        let mut at = path.clone();
        at.push(name.to_string());
        out.push(Found {
            path: at,
            problem: Problem::Missing(name.to_string()),
        });
    }
    let properties = s.get("properties").and_then(Value::as_object);
    let extra = s.get("additionalProperties");
    for (name, field) in fields {
        path.push(name.clone());
        match (properties.and_then(|p| p.get(name)), extra) {
            (Some(sub), _) => walk(root, sub, field, path, out, depth + 1),
            (None, Some(Value::Bool(false))) => out.push(Found {
                path: path.clone(),
                problem: Problem::Unknown(name.clone()),
            }),
            (None, Some(sub)) => walk(root, sub, field, path, out, depth + 1),
            (None, None) => {}
        }
        path.pop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn pointers(schema: &Value, value: &Value) -> Vec<String> {
        let mut found: Vec<String> = check(schema, value)
            .iter()
            .map(|f| f.path.iter().map(|t| format!("/{t}")).collect())
            .collect();
        found.sort();
        found
    }

    #[test]
    fn finds_each_problem_at_its_place() {
        let schema = json!({
            "type": "object",
            "properties": {
                "speed": {"type": "number", "minimum": 0},
                "path": {"type": "array", "items": {"$ref": "#/$defs/Point"}},
                "mode": {"anyOf": [{"type": "integer"}, {"enum": ["a", "b"]}]},
            },
            "required": ["speed"],
            "additionalProperties": false,
            "$defs": {"Point": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}},
        });
        assert!(check(
            &schema,
            &json!({"speed": 1.0, "path": [[0, 1, 2]], "mode": 2.0})
        )
        .is_empty());
        let found = check(
            &schema,
            &json!({"sped": 1, "path": [[0, "x", 2], [1]], "mode": "c"}),
        );
        let mut problems: Vec<(String, &Problem)> = found
            .iter()
            .map(|f| (f.path.join("/"), &f.problem))
            .collect();
        problems.sort_by(|a, b| a.0.cmp(&b.0));
        let any_of = "\"c\" is not valid under any of the schemas listed in the 'anyOf' keyword";
        assert_eq!(
            problems,
            vec![
                ("mode".to_string(), &Problem::Invalid(any_of.into())),
                (
                    "path/0/1".to_string(),
                    &Problem::Invalid("\"x\" is not of type \"number\"".into())
                ),
                (
                    "path/1".to_string(),
                    &Problem::Invalid("[1] has less than 3 items".into())
                ),
                ("sped".to_string(), &Problem::Unknown("sped".into())),
                ("speed".to_string(), &Problem::Missing("speed".into())),
            ]
        );
        assert_eq!(pointers(&schema, &json!({"speed": -1})), vec!["/speed"]);
    }

    /// Every keyword in a registered behavior's schema is one this checker knows.
    #[test]
    fn every_behavior_schema_uses_known_keywords() {
        fn walk(schema: &Value, at: &str, unknown: &mut Vec<String>) {
            let Some(s) = schema.as_object() else {
                return;
            };
            for (key, sub) in s {
                if !KEYWORDS.contains(&key.as_str()) && !ANNOTATIONS.contains(&key.as_str()) {
                    unknown.push(format!("{at}/{key}"));
                }
                match key.as_str() {
                    "properties" | "$defs" => {
                        for (name, sub) in sub.as_object().into_iter().flatten() {
                            walk(sub, &format!("{at}/{key}/{name}"), unknown);
                        }
                    }
                    "prefixItems" | "anyOf" | "oneOf" | "allOf" => {
                        for (i, sub) in sub.as_array().into_iter().flatten().enumerate() {
                            walk(sub, &format!("{at}/{key}/{i}"), unknown);
                        }
                    }
                    "items" | "additionalProperties" => walk(sub, &format!("{at}/{key}"), unknown),
                    _ => {}
                }
            }
        }
        let registry = crate::behavior::payload::registry();
        let mut unknown = Vec::new();
        for spec in registry.iter() {
            walk(&spec.args_schema, spec.name, &mut unknown);
        }
        assert!(unknown.is_empty(), "keywords not checked: {unknown:?}");
        assert!(registry.iter().count() >= 12);
    }

    /// Where a general validator finds problems in wrong goals of every behavior, this finds
    /// them too, at the same pointers.
    #[test]
    fn agrees_with_a_general_validator_on_every_behavior() {
        let wrong = [
            json!("x"),
            json!(-1e9),
            json!(1.5),
            json!(null),
            json!([1, "a"]),
            json!([[0, 0, "z"]]),
            json!({"q": 1}),
        ];
        let mut compared = 0;
        for spec in crate::behavior::payload::registry().iter() {
            let validator = jsonschema::validator_for(&spec.args_schema).unwrap();
            let names: Vec<String> = spec.args_schema["properties"]
                .as_object()
                .map(|p| p.keys().cloned().collect())
                .unwrap_or_default();
            let mut goals = vec![json!({}), json!({"zzz": 1}), json!([])];
            for name in &names {
                goals.extend(wrong.iter().map(|w| json!({ name.clone(): w.clone() })));
            }
            for goal in goals {
                let mut theirs: Vec<String> = validator
                    .iter_errors(&goal)
                    .flat_map(|e| {
                        let base = e.instance_path.as_str().to_string();
                        match &e.kind {
                            jsonschema::error::ValidationErrorKind::Required { property } => {
                                vec![format!("{base}/{}", property.as_str().unwrap_or_default())]
                            }
                            jsonschema::error::ValidationErrorKind::AdditionalProperties {
                                unexpected,
                            } => unexpected.iter().map(|u| format!("{base}/{u}")).collect(),
                            _ => vec![base],
                        }
                    })
                    .collect();
                theirs.sort();
                assert_eq!(
                    pointers(&spec.args_schema, &goal),
                    theirs,
                    "{}: {goal}",
                    spec.name
                );
                compared += 1;
            }
        }
        assert!(compared > 100, "{compared} goals compared");
    }
}
