//! `foxglove.SceneUpdate` messages of a flight log: goals and planned paths, frontiers, and the
//! simulated world's obstacles.
//!
//! In: behavior records (their `goal`: a `path` of [x, y, z] points, or an `x`, `y`, `z`
//! target, in the shared ENU frame, i.e. without a `frame_id` or with `earth`) and the
//! header's world. Out, on `/<drone>/plan`: a line strip of the planned path and a sphere at
//! its goal when a behavior starts or is modified (entities `<id>/path`, `<id>/goal`), deleted
//! when it finishes; on `/world`, once: the world's poles, cylinders and boxes. From each
//! `frontiers` record ([`FrontierScenes`]): on `/frontiers`, the entity `frontiers` (each
//! frontier a line along its long axis, through its centroid, and a sphere at its goal); on
//! `/<drone>/frontier`, the entity `<drone>/frontier`, a sphere at the goal the drone holds,
//! deleted when it holds none. Plain data in, JSON out: the world is loaded by the caller.

use crate::sim::world::{Shape, World};
use serde_json::{json, Value};

/// RGBA of paths, goals and obstacles.
const PATH_RGBA: [f64; 4] = [0.1, 0.6, 1.0, 1.0];
const GOAL_RGBA: [f64; 4] = [1.0, 0.55, 0.0, 1.0];
const OBSTACLE_RGBA: [f64; 4] = [0.55, 0.55, 0.55, 0.8];
const FRONTIER_RGBA: [f64; 4] = [0.9, 0.1, 0.8, 1.0];
const CLAIM_RGBA: [f64; 4] = [0.2, 0.9, 0.2, 1.0];
/// Height (m) frontiers are drawn at, just above the map.
const FRONTIER_Z_M: f64 = 0.1;

fn color([r, g, b, a]: [f64; 4]) -> Value {
    json!({ "r": r, "g": g, "b": b, "a": a })
}

fn pose_at(x: f64, y: f64, z: f64, yaw_rad: f64) -> Value {
    let h = yaw_rad / 2.0;
    json!({
        "position": { "x": x, "y": y, "z": z },
        "orientation": { "x": 0.0, "y": 0.0, "z": h.sin(), "w": h.cos() },
    })
}

/// An entity with `primitives` (e.g. `"lines"`) filled and every other list empty.
fn entity(stamp: &Value, id: &str, primitives: &[(&str, Vec<Value>)]) -> Value {
    let mut e = json!({
        "timestamp": stamp, "frame_id": super::foxglove::WORLD_FRAME, "id": id,
        "lifetime": { "sec": 0, "nsec": 0 }, "frame_locked": false, "metadata": [],
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "lines": [],
        "triangles": [], "texts": [], "models": [],
    });
    for (kind, list) in primitives {
        e[*kind] = Value::Array(list.clone());
    }
    e
}

/// The plan update of a behavior record, if it shows or ends a goal or a path.
pub fn plan(record: &Value, stamp: &Value) -> Option<Value> {
    let id = record.get("id")?.as_u64()?;
    let (path_id, goal_id) = (format!("{id}/path"), format!("{id}/goal"));
    match record.get("event")?.as_str()? {
        "started" | "modified" => {
            let goal = record.get("goal")?;
            let frame = goal.get("frame_id").and_then(Value::as_str);
            if frame.is_some_and(|f| f != "earth") {
                return None;
            }
            let points = goal_points(goal)?;
            let last = points.last()?;
            let mut entities = vec![entity(
                stamp,
                &goal_id,
                &[(
                    "spheres",
                    vec![json!({ "pose": pose_at(last[0], last[1], last[2], 0.0),
                        "size": { "x": 0.4, "y": 0.4, "z": 0.4 }, "color": color(GOAL_RGBA) })],
                )],
            )];
            if points.len() > 1 {
                let pts: Vec<Value> = points
                    .iter()
                    .map(|p| json!({ "x": p[0], "y": p[1], "z": p[2] }))
                    .collect();
                entities.push(entity(
                    stamp,
                    &path_id,
                    &[(
                        "lines",
                        vec![json!({ "type": 0, "pose": pose_at(0.0, 0.0, 0.0, 0.0),
                            "thickness": 0.08, "scale_invariant": false, "points": pts,
                            "color": color(PATH_RGBA), "colors": [], "indices": [] })],
                    )],
                ));
            }
            Some(json!({ "deletions": [], "entities": entities }))
        }
        "finished" => {
            let deletions: Vec<Value> = [path_id, goal_id]
                .iter()
                .map(|id| json!({ "timestamp": stamp, "type": 0, "id": id }))
                .collect();
            Some(json!({ "deletions": deletions, "entities": [] }))
        }
        _ => None,
    }
}

/// The points of a goal: its `path`, or its `x`, `y`, `z` target.
fn goal_points(goal: &Value) -> Option<Vec<[f64; 3]>> {
    if let Some(path) = goal.get("path").and_then(Value::as_array) {
        let points: Option<Vec<[f64; 3]>> = path
            .iter()
            .map(|p| {
                let c = |i: usize| p.get(i).and_then(Value::as_f64);
                Some([c(0)?, c(1)?, c(2)?])
            })
            .collect();
        return points.filter(|p| !p.is_empty());
    }
    let c = |k: &str| goal.get(k).and_then(Value::as_f64);
    Some(vec![[c("x")?, c("y")?, c("z")?]])
}

/// The drones that held a goal at the last `frontiers` record, to delete what they no longer
/// hold.
#[derive(Default)]
pub struct FrontierScenes {
    claimed: std::collections::BTreeSet<String>,
}

impl FrontierScenes {
    /// The scene updates of a `frontiers` record: (topic, `foxglove.SceneUpdate`).
    pub fn update(&mut self, record: &Value, stamp: &Value) -> Vec<(String, Value)> {
        let list = |k: &str| {
            record
                .get(k)
                .and_then(Value::as_array)
                .cloned()
                .unwrap_or_default()
        };
        let xy = |v: &Value, k: &str| -> Option<[f64; 2]> {
            let a = v.get(k)?.as_array()?;
            Some([a.first()?.as_f64()?, a.get(1)?.as_f64()?])
        };
        let (mut points, mut goals) = (Vec::new(), Vec::new());
        for f in list("frontiers") {
            let (Some(c), Some(g)) = (xy(&f, "centroid_enu_m"), xy(&f, "goal_enu_m")) else {
                continue;
            };
            let half = f.get("size_m").and_then(Value::as_f64).unwrap_or(0.0) / 2.0;
            let a = f
                .get("orientation_rad")
                .and_then(Value::as_f64)
                .unwrap_or(0.0);
            let (dx, dy) = (half * a.cos(), half * a.sin());
            for (x, y) in [(c[0] - dx, c[1] - dy), (c[0] + dx, c[1] + dy)] {
                points.push(json!({ "x": x, "y": y, "z": FRONTIER_Z_M }));
            }
            goals.push(sphere(g, 0.25, FRONTIER_RGBA));
        }
        // Line list (type 2): each pair of points one frontier.
        let lines = vec![json!({ "type": 2, "pose": pose_at(0.0, 0.0, 0.0, 0.0),
            "thickness": 0.1, "scale_invariant": false, "points": points,
            "color": color(FRONTIER_RGBA), "colors": [], "indices": [] })];
        let all = entity(stamp, "frontiers", &[("lines", lines), ("spheres", goals)]);
        let mut out = vec![(
            "/frontiers".to_string(),
            json!({ "deletions": [], "entities": [all] }),
        )];
        let mut claimed = std::collections::BTreeSet::new();
        for c in list("claims") {
            let (Some(drone), Some(g)) =
                (c.get("drone").and_then(Value::as_str), xy(&c, "goal_enu_m"))
            else {
                continue;
            };
            let id = format!("{drone}/frontier");
            let held = entity(stamp, &id, &[("spheres", vec![sphere(g, 0.4, CLAIM_RGBA)])]);
            out.push((
                format!("/{id}"),
                json!({ "deletions": [], "entities": [held] }),
            ));
            claimed.insert(drone.to_string());
        }
        for gone in self.claimed.difference(&claimed) {
            let id = format!("{gone}/frontier");
            let deletion = json!({ "timestamp": stamp, "type": 0, "id": id });
            out.push((
                format!("/{id}"),
                json!({ "deletions": [deletion], "entities": [] }),
            ));
        }
        self.claimed = claimed;
        out
    }
}

fn sphere([x, y]: [f64; 2], size_m: f64, rgba: [f64; 4]) -> Value {
    json!({ "pose": pose_at(x, y, FRONTIER_Z_M, 0.0),
        "size": { "x": size_m, "y": size_m, "z": size_m }, "color": color(rgba) })
}

/// The world's obstacles as one entity, `obstacles`.
pub fn world(world: &World, stamp: &Value) -> Value {
    let (mut cylinders, mut cubes) = (Vec::new(), Vec::new());
    for shape in world.shapes() {
        match shape {
            Shape::Cylinder {
                center,
                radius_m,
                height_m,
            } => cylinders.push(json!({
                "pose": pose_at(center.x, center.y, height_m / 2.0, 0.0),
                "size": { "x": 2.0 * radius_m, "y": 2.0 * radius_m, "z": height_m },
                "bottom_scale": 1.0, "top_scale": 1.0, "color": color(OBSTACLE_RGBA),
            })),
            Shape::Box {
                center,
                half_size,
                yaw_rad,
                height_m,
            } => cubes.push(json!({
                "pose": pose_at(center.x, center.y, height_m / 2.0, yaw_rad),
                "size": { "x": 2.0 * half_size.x, "y": 2.0 * half_size.y, "z": height_m },
                "color": color(OBSTACLE_RGBA),
            })),
        }
    }
    json!({
        "deletions": [],
        "entities": [entity(stamp, "obstacles", &[("cylinders", cylinders), ("cubes", cubes)])],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_goal_is_drawn_until_its_behavior_finishes() {
        let stamp = json!({ "sec": 1, "nsec": 0 });
        let started = json!({ "type": "behavior", "event": "started", "id": 7,
            "behavior": "follow_path", "goal": { "path": [[0, 0, 2], [4, 0, 2]], "speed": 1 } });
        let update = plan(&started, &stamp).unwrap_or_default();
        let entities = update["entities"].as_array().cloned().unwrap_or_default();
        assert_eq!(entities.len(), 2);
        assert_eq!(entities[0]["id"], "7/goal");
        assert_eq!(entities[0]["spheres"][0]["pose"]["position"]["x"], 4.0);
        assert_eq!(
            entities[1]["lines"][0]["points"][1],
            json!({"x": 4.0, "y": 0.0, "z": 2.0})
        );
        let finished = json!({ "type": "behavior", "event": "finished", "id": 7 });
        let update = plan(&finished, &stamp).unwrap_or_default();
        assert_eq!(update["deletions"][0]["id"], "7/path");
        let elsewhere = json!({ "type": "behavior", "event": "started", "id": 8,
            "goal": { "x": 1, "y": 2, "z": 3, "frame_id": "panel_row" } });
        assert_eq!(plan(&elsewhere, &stamp), None);
    }

    /// Every frontier is a line and a goal; each drone's goal is shown until it holds none.
    #[test]
    fn frontiers_and_the_goals_held_follow_the_allocator() {
        let stamp = json!({ "sec": 1, "nsec": 0 });
        let record = json!({ "type": "frontiers", "frontiers": [
            { "centroid_enu_m": [1.0, 2.0], "goal_enu_m": [0.5, 2.0], "size_m": 2.0,
              "orientation_rad": std::f64::consts::FRAC_PI_2 },
            { "centroid_enu_m": [5.0, 5.0], "goal_enu_m": [4.0, 5.0], "size_m": 1.0,
              "orientation_rad": 0.0 }],
            "claims": [{ "drone": "drone_1", "goal_enu_m": [4.0, 5.0] }] });
        let mut scenes = FrontierScenes::default();
        let out = scenes.update(&record, &stamp);
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].0, "/frontiers");
        let all = &out[0].1["entities"][0];
        let points = all["lines"][0]["points"]
            .as_array()
            .cloned()
            .unwrap_or_default();
        assert_eq!(points.len(), 4);
        assert!((points[1]["y"].as_f64().unwrap_or(0.0) - 3.0).abs() < 1e-12);
        assert_eq!(points[3]["x"], 5.5);
        assert_eq!(all["spheres"][1]["pose"]["position"]["x"], 4.0);
        assert_eq!(out[1].0, "/drone_1/frontier");
        assert_eq!(out[1].1["entities"][0]["id"], "drone_1/frontier");
        let none = json!({ "type": "frontiers", "frontiers": [], "claims": [] });
        let out = scenes.update(&none, &stamp);
        assert_eq!(out[0].1["entities"][0]["lines"][0]["points"], json!([]));
        assert_eq!(out[1].0, "/drone_1/frontier");
        assert_eq!(out[1].1["deletions"][0]["id"], "drone_1/frontier");
        assert_eq!(scenes.update(&none, &stamp).len(), 1, "deleted once");
    }
}
