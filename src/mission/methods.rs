//! Aerostack2 methods mapped onto canonical behavior goals.
//!
//! In: a plan item's behavior, method and arguments as written. Out: the goal the behavior gets
//! (method applied, yaw modes normalised, item options removed) and the item options, or every
//! problem found, each with the argument it is about.
//!
//! Every behavior answers `__call__` and its own name. `go_to` and `follow_path` also have
//! Aerostack2's helpers: `go_to_with_yaw` (`angle` rad → fixed yaw), `go_to_path_facing`,
//! `go_to_point` (`point: [x, y, z]`), `go_to_point_with_yaw`, `go_to_point_path_facing`,
//! `follow_path_with_keep_yaw`, `follow_path_with_yaw`, `follow_path_with_path_facing`.

use super::model::{ItemOptions, OnFailure, CALL};
use serde_json::{Map, Value};

/// A problem in one argument; `key` is the path below `args` (empty = the whole of `args`).
#[derive(Debug, Clone, PartialEq)]
pub struct ArgError {
    pub key: String,
    pub message: String,
}

fn err(key: &str, message: impl Into<String>) -> ArgError {
    ArgError {
        key: key.to_string(),
        message: message.into(),
    }
}

/// The item options every behavior accepts in `args`.
pub const OPTION_KEYS: [&str; 3] = ["wait", "on_failure", "run_for_s"];

/// The goal for the behavior, the item options, and where each goal key came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Canonical {
    pub goal: Map<String, Value>,
    pub options: ItemOptions,
    /// Goal key → JSON pointer below `args` as written (`x` → `point/0` for `go_to_point`).
    pub origins: Vec<(String, String)>,
}

impl Canonical {
    /// Where a goal key was written: a JSON pointer (escaped tokens) below `args`.
    pub fn origin_of(&self, key: &str) -> String {
        self.origins
            .iter()
            .find(|(k, _)| k == key)
            .map_or_else(|| escape_token(key), |(_, o)| o.clone())
    }
}

/// Escapes one JSON pointer reference token (RFC 6901).
pub fn escape_token(s: &str) -> String {
    s.replace('~', "~0").replace('/', "~1")
}

#[derive(Clone, Copy)]
enum Yaw {
    Keep,
    Fixed,
    PathFacing,
}

#[derive(Clone, Copy)]
struct Helper {
    name: &'static str,
    point: bool,
    yaw: Yaw,
}

const GO_TO_HELPERS: [Helper; 6] = [
    Helper {
        name: "go_to",
        point: false,
        yaw: Yaw::Keep,
    },
    Helper {
        name: "go_to_with_yaw",
        point: false,
        yaw: Yaw::Fixed,
    },
    Helper {
        name: "go_to_path_facing",
        point: false,
        yaw: Yaw::PathFacing,
    },
    Helper {
        name: "go_to_point",
        point: true,
        yaw: Yaw::Keep,
    },
    Helper {
        name: "go_to_point_with_yaw",
        point: true,
        yaw: Yaw::Fixed,
    },
    Helper {
        name: "go_to_point_path_facing",
        point: true,
        yaw: Yaw::PathFacing,
    },
];

const FOLLOW_PATH_HELPERS: [Helper; 3] = [
    Helper {
        name: "follow_path_with_keep_yaw",
        point: false,
        yaw: Yaw::Keep,
    },
    Helper {
        name: "follow_path_with_yaw",
        point: false,
        yaw: Yaw::Fixed,
    },
    Helper {
        name: "follow_path_with_path_facing",
        point: false,
        yaw: Yaw::PathFacing,
    },
];

fn helpers(behavior: &str) -> &'static [Helper] {
    match behavior {
        "go_to" => &GO_TO_HELPERS,
        "follow_path" => &FOLLOW_PATH_HELPERS,
        _ => &[],
    }
}

/// Methods a behavior answers, `__call__` first.
pub fn methods(behavior: &str) -> Vec<String> {
    let mut out = vec![CALL.to_string(), behavior.to_string()];
    for h in helpers(behavior) {
        if h.name != behavior {
            out.push(h.name.to_string());
        }
    }
    out
}

/// Aerostack2 runs these without waiting unless told otherwise.
pub fn default_wait(behavior: &str) -> bool {
    !matches!(behavior, "follow_reference" | "point_gimbal")
}

/// Maps a method call onto the behavior's goal. Every problem found is returned.
pub fn canonicalize(
    behavior: &str,
    method: &str,
    args: &Map<String, Value>,
) -> Result<Canonical, Vec<ArgError>> {
    let mut errors = Vec::new();
    let options = options(behavior, args, &mut errors);
    let mut goal: Map<String, Value> = args
        .iter()
        .filter(|(k, _)| !OPTION_KEYS.contains(&k.as_str()))
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let mut origins = Vec::new();
    if method != CALL && method != behavior {
        match helpers(behavior).iter().find(|h| h.name == method) {
            Some(h) => apply_helper(*h, &mut goal, &mut origins, &mut errors),
            None => errors.push(err(
                "",
                format!(
                    "unknown method `{method}` for behavior `{behavior}`; it has: {}",
                    methods(behavior).join(", ")
                ),
            )),
        }
    }
    normalise_yaw_mode(&mut goal);
    if errors.is_empty() {
        Ok(Canonical {
            goal,
            options,
            origins,
        })
    } else {
        Err(errors)
    }
}

fn apply_helper(
    h: Helper,
    goal: &mut Map<String, Value>,
    origins: &mut Vec<(String, String)>,
    errors: &mut Vec<ArgError>,
) {
    if h.point {
        match goal.remove("point") {
            Some(Value::Array(p)) if p.len() == 3 => {
                for (i, (key, v)) in ["x", "y", "z"].iter().zip(p).enumerate() {
                    goal.insert(key.to_string(), v);
                    origins.push((key.to_string(), format!("point/{i}")));
                }
            }
            Some(_) => errors.push(err("point", "point must be [x, y, z] (three numbers, m)")),
            None => errors.push(err("", format!("{} needs point: [x, y, z] (m)", h.name))),
        }
    }
    if goal.contains_key("yaw_mode") {
        errors.push(err(
            "yaw_mode",
            format!(
                "{} sets yaw_mode itself; use method __call__ to choose one",
                h.name
            ),
        ));
        return;
    }
    let mode = match h.yaw {
        Yaw::Keep => "keep",
        Yaw::PathFacing => "path_facing",
        Yaw::Fixed => {
            if let Some(angle) = goal.remove("angle") {
                goal.insert("yaw_angle".into(), angle);
                origins.push(("yaw_angle".into(), "angle".into()));
            } else if !goal.contains_key("yaw_angle") {
                errors.push(err("", format!("{} needs angle (rad)", h.name)));
            }
            "fixed"
        }
    };
    goal.insert("yaw_mode".into(), Value::from(mode));
}

/// Aerostack2's numeric yaw modes (0 keep, 1 path facing, 2 fixed) as names.
fn normalise_yaw_mode(goal: &mut Map<String, Value>) {
    if let Some(v) = goal.get_mut("yaw_mode") {
        let name = match v.as_u64() {
            Some(0) => "keep",
            Some(1) => "path_facing",
            Some(2) => "fixed",
            _ => return,
        };
        *v = Value::from(name);
    }
}

fn options(behavior: &str, args: &Map<String, Value>, errors: &mut Vec<ArgError>) -> ItemOptions {
    let mut o = ItemOptions {
        wait: default_wait(behavior),
        ..ItemOptions::default()
    };
    match args.get("wait") {
        None => {}
        Some(Value::Bool(b)) => o.wait = *b,
        Some(other) => errors.push(err(
            "wait",
            format!("wait must be a JSON boolean (true or false), got {other}"),
        )),
    }
    match args.get("on_failure").map(Value::as_str) {
        None => {}
        Some(Some("abort")) => o.on_failure = OnFailure::Abort,
        Some(Some("continue")) => o.on_failure = OnFailure::Continue,
        Some(_) => errors.push(err(
            "on_failure",
            "on_failure must be \"abort\" or \"continue\"",
        )),
    }
    match args.get("run_for_s") {
        None | Some(Value::Null) => {}
        Some(v) => match v.as_f64() {
            Some(s) if s.is_finite() && s > 0.0 => o.run_for_s = Some(s),
            _ => errors.push(err(
                "run_for_s",
                format!("run_for_s must be a positive number of seconds, got {v}"),
            )),
        },
    }
    if o.run_for_s.is_some() && !o.wait {
        errors.push(err(
            "run_for_s",
            "run_for_s needs wait: true (the mission waits that long for the item)",
        ));
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn args(v: Value) -> Map<String, Value> {
        v.as_object().cloned().unwrap()
    }

    #[test]
    fn go_to_point_with_yaw_maps_point_and_angle() {
        let c = canonicalize(
            "go_to",
            "go_to_point_with_yaw",
            &args(json!({"point": [1.0, 2.0, 3.0], "speed": 1.0, "angle": 0.5, "wait": true})),
        )
        .unwrap();
        assert_eq!(
            Value::Object(c.goal),
            json!({"x": 1.0, "y": 2.0, "z": 3.0, "speed": 1.0, "yaw_angle": 0.5, "yaw_mode": "fixed"})
        );
        assert!(c.options.wait);
    }

    #[test]
    fn call_keeps_args_and_names_numeric_yaw_modes() {
        let c = canonicalize(
            "follow_path",
            CALL,
            &args(json!({"path": [[0, 0, 1]], "speed": 1, "yaw_mode": 1})),
        )
        .unwrap();
        assert_eq!(c.goal.get("yaw_mode"), Some(&json!("path_facing")));
    }

    #[test]
    fn parallel_by_default_for_gimbal_and_reference() {
        let c = canonicalize("point_gimbal", CALL, &args(json!({"x": 1}))).unwrap();
        assert!(!c.options.wait);
    }

    #[test]
    fn every_problem_is_reported() {
        let e = canonicalize(
            "go_to",
            "go_to_point",
            &args(json!({"point": [1, 2], "wait": "False", "on_failure": 3})),
        )
        .unwrap_err();
        let keys: Vec<&str> = e.iter().map(|e| e.key.as_str()).collect();
        assert_eq!(keys, ["wait", "on_failure", "point"]);
        let e = canonicalize("land", "go_to_point", &Map::new()).unwrap_err();
        assert!(e[0].message.contains("unknown method"), "{e:?}");
    }
}
