//! What a stored mission costs in memory against its JSON (issue 29, item 10): the bytes an
//! executor holds for a mission after it is loaded, and after it is read back from its file,
//! for the largest missions that validate within the API's default body limit.
//!
//! Counted with a counting global allocator: allocation sizes are deterministic, so the bound
//! is exact, not a timing. `cargo nextest run --test mission_memory --no-capture` prints the
//! figures recorded in BENCHMARKS.md ("Memory of a stored mission").

#![allow(clippy::unwrap_used, clippy::expect_used)]

use kestrel::behavior::Registry;
use kestrel::config::Config;
use kestrel::estimator::frames::FrameTree;
use kestrel::estimator::geodetic::GeodeticOrigin;
use kestrel::host::store::Change;
use kestrel::mission::executor::Loaded;
use kestrel::mission::validate::validate_text;
use kestrel::mission::{ContextSnapshot, Limits, MissionExecutor};
use kestrel::types::Vec3;
use stats_alloc::{StatsAlloc, INSTRUMENTED_SYSTEM};
use std::alloc::System;
use std::time::Duration;

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

/// Most bytes a stored mission may hold per byte of its JSON.
const MAX_MULTIPLE: f64 = 3.0;

/// Bytes allocated and not yet freed, by every thread (the test runs on one); a realloc counts
/// its growth as allocated and its shrinking as freed.
fn live_bytes() -> i128 {
    let s = GLOBAL.stats();
    s.bytes_allocated as i128 - s.bytes_deallocated as i128
}

fn context() -> ContextSnapshot {
    ContextSnapshot {
        drone_id: "drone_0".into(),
        registry: Registry::with_motion_behaviors(),
        limits: Limits::default(),
        frames: FrameTree::new(),
        now: Duration::ZERO,
        home_enu_m: Vec3::zeros(),
        geo_origin: GeodeticOrigin::default(),
        lowest_height: None,
    }
}

/// The API's default body limit: no upload is larger.
fn body_limit() -> usize {
    Config::default().api.max_body_bytes
}

/// A mission of `items` built by `item(k)`, as many as fit in `budget` bytes (at most
/// `max_items`).
fn mission_within(budget: usize, max_items: usize, item: impl Fn(usize) -> String) -> String {
    let head = r#"{"target":"drone_0","plan":["#;
    let mut text = String::from(head);
    for k in 0..max_items {
        let next = item(k);
        if text.len() + next.len() + 3 > budget {
            break;
        }
        if k > 0 {
            text.push(',');
        }
        text.push_str(&next);
    }
    text.push_str("]}");
    text
}

/// `follow_path` items of the most waypoints an item may have (`[0,0,1]`: the shortest
/// waypoint, so the most per byte), as many as fit in the body limit.
fn waypoints_mission() -> String {
    let limits = Limits::default();
    let path = vec!["[0,0,1]"; limits.max_waypoints].join(",");
    let item = format!(r#"{{"behavior":"follow_path","args":{{"path":[{path}],"speed":1}}}}"#);
    mission_within(body_limit(), limits.max_items, |_| item.clone())
}

/// The most items a plan may have, each the shortest item there is.
fn items_mission() -> String {
    mission_within(body_limit(), Limits::default().max_items, |_| {
        r#"{"behavior":"land"}"#.to_string()
    })
}

/// Items with unknown fields (ignored, each with a warning) up to the body limit.
fn unknown_fields_mission() -> String {
    let fields: Vec<String> = (0..2000).map(|k| format!(r#""u{k}":0"#)).collect();
    let item = format!(r#"{{"behavior":"land",{}}}"#, fields.join(","));
    mission_within(body_limit(), Limits::default().max_items, |_| item.clone())
}

struct Held {
    json_bytes: usize,
    loaded_bytes: i128,
    restored_bytes: i128,
}

impl Held {
    fn multiple(bytes: i128, json: usize) -> f64 {
        bytes as f64 / json as f64
    }

    fn print(&self, name: &str) {
        println!(
            "{name}: JSON {} bytes; held once loaded {} bytes ({:.2}x); read back from its file {} bytes ({:.2}x)",
            self.json_bytes,
            self.loaded_bytes,
            Self::multiple(self.loaded_bytes, self.json_bytes),
            self.restored_bytes,
            Self::multiple(self.restored_bytes, self.json_bytes),
        );
    }
}

/// Loads `text` as the API does (parsed, validated, loaded under a new id, its change taken
/// for the store and written), then reads its file back: the bytes held each time.
fn held(text: &str) -> Held {
    let snapshot = context();
    let ctx = snapshot.context();
    let config = Config::default().executor_config();
    // Warm up whatever is built once (schemas, lazy statics), so that only the mission counts.
    let mut warm = MissionExecutor::new(config);
    let small = r#"{"target":"drone_0","plan":[{"behavior":"land"}]}"#;
    warm.load_new(validate_text(small, &ctx).unwrap()).unwrap();
    drop(warm.take_changed());

    let mut executor = MissionExecutor::new(config);
    let before = live_bytes();
    let valid = validate_text(text, &ctx).unwrap();
    let id = executor.load_new(valid).unwrap();
    let changed = executor.take_changed();
    let file = Change::Mission {
        drone: "drone_0".into(),
        id,
        loaded: changed
            .into_iter()
            .next()
            .and_then(|(_, l)| l)
            .map(Box::new),
    }
    .content()
    .unwrap()
    .unwrap();
    let before_file = live_bytes();
    let loaded_bytes = before_file - before - file.capacity() as i128;

    let restored: Loaded = serde_json::from_slice(&file).unwrap();
    let restored_bytes = live_bytes() - before_file;
    let kept = executor.missions().get(&id).unwrap();
    assert!(restored.mission.as_written().unwrap() == kept.mission.as_written().unwrap());
    assert_eq!(restored.mission.items, kept.mission.items);
    Held {
        json_bytes: text.len(),
        loaded_bytes,
        restored_bytes,
    }
}

fn check(name: &str, text: &str) {
    assert!(text.len() <= body_limit());
    let held = held(text);
    held.print(name);
    for (what, bytes) in [
        ("loaded", held.loaded_bytes),
        ("read back", held.restored_bytes),
    ] {
        let multiple = Held::multiple(bytes, held.json_bytes);
        assert!(
            multiple <= MAX_MULTIPLE,
            "{name}: {what}, {bytes} bytes for {} bytes of JSON: {multiple:.2}x, over {MAX_MULTIPLE}x",
            held.json_bytes
        );
    }
}

#[test]
fn a_mission_of_the_most_waypoints_holds_at_most_three_times_its_json() {
    check("waypoints", &waypoints_mission());
}

#[test]
fn a_mission_of_the_most_items_holds_at_most_three_times_its_json() {
    check("items", &items_mission());
}

#[test]
fn a_mission_of_unknown_fields_holds_at_most_three_times_its_json() {
    check("unknown fields", &unknown_fields_mission());
}
