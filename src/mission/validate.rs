//! Mission validation: everything is checked before anything moves.
//!
//! In: mission JSON (text or value) and a [`ValidationContext`] (registry, limits, frames,
//! home). Out: a [`ValidMission`], or every error found as a JSON pointer into the mission plus
//! a message. Checks: JSON form, target, known behavior and method, argument names and types
//! (located with the behavior's JSON Schema), the behavior's own range checks, speeds against
//! the vehicle's limit, heights against the ceiling, known frames, and the geofence.

use super::methods::{canonicalize, escape_token, unescape_token, Canonical};
use super::model::{MissionItem, PlanItem, ValidMission, CALL};
use crate::behavior::ParsedGoal;
use crate::behavior::{GoalSummary, Registry};
use crate::estimator::frames::FrameTree;
use crate::estimator::geodetic::{GeoPoint, GeodeticOrigin};
use crate::safety::GeofenceSection;
use crate::types::Vec3;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::time::Duration;

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

/// What missions may ask of the vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// Fastest speed an item may ask for (m/s): the vehicle's horizontal speed limit.
    pub max_speed_mps: f64,
    pub geofence: GeofenceSection,
    pub max_items: usize,
    pub max_waypoints: usize,
}

/// What validation checks a mission against, for one drone at one instant.
pub struct ValidationContext<'a> {
    pub drone_id: &'a str,
    pub registry: &'a Registry,
    pub limits: &'a Limits,
    pub frames: &'a FrameTree,
    /// Time used to place points given in moving frames.
    pub now: Duration,
    /// Centre of the geofence and zero of its altitudes (`earth`, m).
    pub home_enu_m: Vec3,
    pub geo_origin: &'a GeodeticOrigin,
}

/// How far home may move between a snapshot and the upload's arrival on the loop (m).
pub const HOME_TOLERANCE_M: f64 = 0.05;

/// A [`ValidationContext`] that owns its parts: taken from the host in one tick, then used to
/// validate on another thread (a large upload must not cost the control loop its tick).
#[derive(Clone)]
pub struct ContextSnapshot {
    pub drone_id: String,
    pub registry: Registry,
    pub limits: Limits,
    pub frames: FrameTree,
    pub now: Duration,
    pub home_enu_m: Vec3,
    pub geo_origin: GeodeticOrigin,
}

impl std::fmt::Debug for ContextSnapshot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ContextSnapshot")
            .field("drone_id", &self.drone_id)
            .field("now", &self.now)
            .field("home_enu_m", &self.home_enu_m)
            .finish_non_exhaustive()
    }
}

impl ContextSnapshot {
    pub fn of(ctx: &ValidationContext) -> Self {
        Self {
            drone_id: ctx.drone_id.to_string(),
            registry: ctx.registry.clone(),
            limits: ctx.limits.clone(),
            frames: ctx.frames.clone(),
            now: ctx.now,
            home_enu_m: ctx.home_enu_m,
            geo_origin: *ctx.geo_origin,
        }
    }

    pub fn context(&self) -> ValidationContext<'_> {
        ValidationContext {
            drone_id: &self.drone_id,
            registry: &self.registry,
            limits: &self.limits,
            frames: &self.frames,
            now: self.now,
            home_enu_m: self.home_enu_m,
            geo_origin: &self.geo_origin,
        }
    }

    /// Whether a mission validated with this snapshot is still valid in `now_ctx`: same
    /// drone, limits, origin and frames (the vehicle's own pose aside), and home within
    /// [`HOME_TOLERANCE_M`] (before takeoff home is where the vehicle stands, which the
    /// estimate moves by noise).
    pub fn still_holds(&self, now_ctx: &ValidationContext) -> bool {
        self.drone_id == now_ctx.drone_id
            && &self.limits == now_ctx.limits
            && &self.geo_origin == now_ctx.geo_origin
            && (self.home_enu_m - now_ctx.home_enu_m).norm() <= HOME_TOLERANCE_M
            && self.frames.same_frames_as(now_ctx.frames)
    }
}

const TOP_LEVEL: [&str; 2] = ["target", "plan"];
const ITEM_KEYS: [&str; 3] = ["behavior", "method", "args"];
const SPEED_KEYS: [&str; 6] = [
    "speed",
    "land_speed",
    "speed_x",
    "speed_y",
    "speed_z",
    "max_speed",
];

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
    let mut warnings = Vec::new();
    let Some(obj) = value.as_object() else {
        return Err(vec![at(
            "",
            "a mission is a JSON object {\"target\": .., \"plan\": [..]}",
        )]);
    };
    for key in obj.keys().filter(|k| !TOP_LEVEL.contains(&k.as_str())) {
        warnings.push(format!("unknown top-level field `{key}` ignored"));
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
            warnings,
        })
    } else {
        Err(errors)
    }
}

fn validate_item(
    raw: &Value,
    pointer: &str,
    ctx: &ValidationContext,
    warnings: &mut Vec<String>,
) -> Result<PlanItem, Vec<ValidationError>> {
    let Some(obj) = raw.as_object() else {
        return Err(vec![at(
            pointer,
            "an item is an object {\"behavior\", \"method\", \"args\"}",
        )]);
    };
    for key in obj.keys().filter(|k| !ITEM_KEYS.contains(&k.as_str())) {
        warnings.push(format!("{pointer}: unknown field `{key}` ignored"));
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
    Ok(PlanItem {
        item: MissionItem {
            behavior,
            method,
            args,
        },
        goal,
        options: canonical.options,
        parsed: Some(parsed),
    })
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
    let Ok(validator) = jsonschema::validator_for(schema) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for e in validator.iter_errors(goal) {
        let path = e.instance_path.as_str().trim_start_matches('/').to_string();
        let located = |key: &str| {
            let (first, rest) = key.split_once('/').unwrap_or((key, ""));
            let origin = canonical.origin_of(&unescape_token(first));
            let origin = if rest.is_empty() {
                origin
            } else {
                format!("{origin}/{rest}")
            };
            join(args_pointer, &origin)
        };
        match &e.kind {
            jsonschema::error::ValidationErrorKind::Required { property } => {
                let name = property.as_str().unwrap_or_default();
                out.push(at(
                    &located(&escape_token(name)),
                    format!("missing argument `{name}`"),
                ));
            }
            jsonschema::error::ValidationErrorKind::AdditionalProperties { unexpected } => {
                for name in unexpected {
                    out.push(at(
                        &located(&escape_token(name)),
                        format!("unknown argument `{name}`"),
                    ));
                }
            }
            _ => out.push(at(&located(&path), e.to_string())),
        }
    }
    out
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

/// Speeds, heights, frames and the geofence.
fn check_limits(
    goal: &Value,
    summary: &GoalSummary,
    canonical: &Canonical,
    args_pointer: &str,
    ctx: &ValidationContext,
) -> Result<(), Vec<ValidationError>> {
    let mut errors = Vec::new();
    let pointer_of = |key: &str| join(args_pointer, &canonical.origin_of(key));
    let limits = ctx.limits;
    let mut speed_flagged = false;
    for key in SPEED_KEYS {
        if let Some(v) = goal.get(key).and_then(Value::as_f64) {
            if v > limits.max_speed_mps {
                speed_flagged = true;
                errors.push(at(
                    &pointer_of(key),
                    format!(
                        "{key} = {v} m/s is above the vehicle's limit of {} m/s",
                        limits.max_speed_mps
                    ),
                ));
            }
        }
    }
    if !speed_flagged {
        if let Some(v) = summary
            .speeds_mps
            .iter()
            .find(|v| **v > limits.max_speed_mps)
        {
            errors.push(at(
                args_pointer,
                format!(
                    "speed {v} m/s is above the vehicle's limit of {} m/s",
                    limits.max_speed_mps
                ),
            ));
        }
    }
    if let Some(h) = goal.get("height").and_then(Value::as_f64) {
        if h > limits.geofence.max_altitude_m {
            errors.push(at(
                &pointer_of("height"),
                format!(
                    "height = {h} m is above the {} m ceiling",
                    limits.geofence.max_altitude_m
                ),
            ));
        }
    }
    let path_len = goal.get("path").and_then(Value::as_array).map(Vec::len);
    if let Some(n) = path_len.filter(|n| *n > limits.max_waypoints) {
        errors.push(at(
            &pointer_of("path"),
            format!(
                "path has {n} waypoints, more than the limit of {}",
                limits.max_waypoints
            ),
        ));
        return Err(errors);
    }
    if let Some(frame) = goal.get("frame_id").and_then(Value::as_str) {
        let known =
            frame.is_empty() || frame == crate::behavior::WGS84 || ctx.frames.contains(frame);
        if !known {
            errors.push(unknown_frame(&pointer_of("frame_id"), frame, ctx));
            return Err(errors);
        }
    }
    for (k, target) in summary.targets.iter().enumerate() {
        let (horizontal, vertical) = match path_len {
            Some(n) if n == summary.targets.len() => {
                let p = format!("{}/{k}", pointer_of("path"));
                (p.clone(), p)
            }
            _ if goal.get("x").is_some() => (pointer_of("x"), pointer_of("z")),
            _ if goal.get("lat").is_some() => (pointer_of("lat"), pointer_of("alt")),
            _ => (args_pointer.to_string(), args_pointer.to_string()),
        };
        let earth = if target.frame_id == crate::behavior::WGS84 {
            let geo = GeoPoint {
                lat_deg: target.position_m.x,
                lon_deg: target.position_m.y,
                alt_m: target.position_m.z,
            };
            ctx.geo_origin.to_enu(&geo).map_err(|e| e.to_string())
        } else if !ctx.frames.contains(&target.frame_id) {
            errors.push(unknown_frame(
                &pointer_of("frame_id"),
                &target.frame_id,
                ctx,
            ));
            break;
        } else {
            ctx.frames
                .point_to_earth(&target.position_m, &target.frame_id, ctx.now)
                .map_err(|e| e.to_string())
        };
        match earth {
            Ok(p) => errors.extend(geofence_errors(&p, ctx, &horizontal, &vertical)),
            Err(e) => errors.push(at(&pointer_of("frame_id"), e)),
        }
    }
    if errors.is_empty() {
        Ok(())
    } else {
        Err(errors)
    }
}

fn unknown_frame(pointer: &str, frame: &str, ctx: &ValidationContext) -> ValidationError {
    let known: Vec<&str> = ctx.frames.names().collect();
    at(
        pointer,
        format!(
            "unknown frame `{frame}`; known: {} (register frames with POST /api/frames)",
            known.join(", ")
        ),
    )
}

fn geofence_errors(
    p: &Vec3,
    ctx: &ValidationContext,
    horizontal: &str,
    vertical: &str,
) -> Vec<ValidationError> {
    let fence = &ctx.limits.geofence;
    let home = ctx.home_enu_m;
    let mut out = Vec::new();
    let where_ = format!("({:.1}, {:.1}, {:.1}) m in earth", p.x, p.y, p.z);
    let altitude = p.z - home.z;
    if altitude > fence.max_altitude_m {
        out.push(at(
            vertical,
            format!(
                "{where_} is {altitude:.1} m above home, over the {} m ceiling",
                fence.max_altitude_m
            ),
        ));
    }
    if altitude < fence.min_altitude_m {
        out.push(at(
            vertical,
            format!(
                "{where_} is {altitude:.1} m relative to home, below the {} m floor",
                fence.min_altitude_m
            ),
        ));
    }
    let distance = (p.xy() - home.xy()).norm();
    if let Some(r) = fence.radius_m.filter(|r| distance > *r) {
        out.push(at(
            horizontal,
            format!("{where_} is {distance:.0} m from home, outside the {r} m geofence"),
        ));
    }
    if let Some(poly) = &fence.polygon_enu_m {
        if !inside(poly, p.x, p.y) {
            out.push(at(
                horizontal,
                format!("{where_} is outside the geofence polygon"),
            ));
        }
    }
    out
}

/// Even-odd point-in-polygon test.
fn inside(poly: &[[f64; 2]], x: f64, y: f64) -> bool {
    let mut result = false;
    let n = poly.len();
    for i in 0..n {
        let [xi, yi] = poly[i];
        let [xj, yj] = poly[(i + n - 1) % n];
        if (yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi {
            result = !result;
        }
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::frames::FrameMotion;
    use crate::types::Pose;

    fn snapshot() -> ContextSnapshot {
        ContextSnapshot {
            drone_id: "drone_0".into(),
            registry: Registry::with_motion_behaviors(),
            limits: Limits::default(),
            frames: FrameTree::new(),
            now: Duration::from_secs(3),
            home_enu_m: Vec3::new(1.0, 2.0, 0.0),
            geo_origin: GeodeticOrigin::default(),
        }
    }

    #[test]
    fn a_snapshot_holds_while_only_the_vehicle_and_time_move() {
        let taken = snapshot();
        let mut now = taken.clone();
        now.now = Duration::from_secs(4);
        now.frames.set_base_link(
            Pose::from_position_yaw(Vec3::new(5.0, 0.0, 2.0), 1.0),
            now.now,
        );
        now.home_enu_m.x += 0.01;
        assert!(taken.still_holds(&now.context()));
    }

    #[test]
    fn a_snapshot_is_stale_once_frames_home_or_limits_change() {
        let taken = snapshot();
        let mut framed = taken.clone();
        framed
            .frames
            .set("panel", "earth", FrameMotion::fixed(Pose::identity()))
            .unwrap();
        assert!(!taken.still_holds(&framed.context()));
        let mut moved = taken.clone();
        moved.home_enu_m.x += 1.0;
        assert!(!taken.still_holds(&moved.context()));
        let mut slower = taken.clone();
        slower.limits.max_speed_mps /= 2.0;
        assert!(!taken.still_holds(&slower.context()));
        let mut other = taken.clone();
        other.drone_id = "drone_1".into();
        assert!(!taken.still_holds(&other.context()));
    }

    #[test]
    fn polygon_inside_and_outside() {
        let square = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        assert!(inside(&square, 5.0, 5.0));
        assert!(!inside(&square, 15.0, 5.0));
    }

    #[test]
    fn pointer_tokens_are_escaped() {
        assert_eq!(escape_token("a/b~c"), "a~1b~0c");
        assert_eq!(unescape_token("a~1b~0c"), "a/b~c");
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
