//! End to end: the real `kestrel run` process against the fake autopilots, and someone else takes
//! the vehicle mid-go_to, as in the field (QGC sent DO_SET_MODE AUTO.LOITER to PX4 on PX4's own
//! ground-station link; on ArduPilot a pilot flips the RC mode switch to LOITER). Within 1 s the
//! mission is PAUSED with `pilot_takeover`, Kestrel sends nothing more to the vehicle (the fake
//! records what it receives), RESUME takes it back and the go_to reaches its goal, STOP leaves it
//! in the pilot's mode.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::{alongside, closest_approaches, Api, Fake, Kestrel, Personality, LISTEN_ANY};
use serde_json::{json, Value};
use std::time::{Duration, Instant};

const GOAL: [f64; 3] = [16.0, 0.0, 3.0];

fn mission() -> Value {
    json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": GOAL[2], "speed": 1.0}},
        {"behavior": "go_to", "args": {"x": GOAL[0], "y": GOAL[1], "z": GOAL[2], "speed": 2.0}},
        {"behavior": "land", "args": {"speed": 0.7}}]})
}

/// The mode the pilot takes the vehicle into, and how.
fn take_over(p: Personality, fake: &Fake) -> &'static str {
    let (mode, reply) = match p {
        Personality::Px4 => (
            "AUTO.LOITER",
            fake.cmd(json!({"cmd": "gcs_set_mode", "mode": "AUTO.LOITER"})),
        ),
        Personality::Ardupilot => (
            "LOITER",
            fake.cmd(json!({"cmd": "rc_mode", "mode": "LOITER"})),
        ),
    };
    assert_eq!(reply["mode"], mode, "{reply}");
    mode
}

struct Taken {
    fake: Fake,
    kestrel: Kestrel,
    api: Api,
    mode: &'static str,
    /// The fake's clock when the API showed the mission paused.
    paused_at_s: f64,
}

fn local_x(state: &Value) -> f64 {
    state["position_enu_m"][0].as_f64().unwrap() - state["local_origin_enu_m"][0].as_f64().unwrap()
}

fn mission_of(api: &Api) -> Value {
    api.get("/api/status")["drones"][0]["mission"].clone()
}

/// Flies the mission until the go_to is a quarter of the way, lets the pilot take over, and
/// checks the mission is paused for it within 1 s.
fn taken_mid_go_to(p: Personality) -> Taken {
    let fake = Fake::start(p, &[]);
    let kestrel = Kestrel::run(p, &fake.connection, "", &["--listen", LISTEN_ANY]);
    let api = kestrel.api();
    api.fly(&mission());
    kestrel.wait_line("go_to #2 started", Duration::from_secs(90));
    let deadline = Instant::now() + Duration::from_secs(30);
    while local_x(&fake.state()) < GOAL[0] / 4.0 {
        assert!(Instant::now() < deadline, "{}", fake.diagnostics());
        std::thread::sleep(Duration::from_millis(50));
    }
    let switched = Instant::now();
    let mode = take_over(p, &fake);
    let mission = loop {
        let m = mission_of(&api);
        if m["state"] == 2 {
            break m;
        }
        assert!(
            switched.elapsed() < Duration::from_secs(3),
            "not paused: {m}\n{}",
            kestrel.output()
        );
        std::thread::sleep(Duration::from_millis(10));
    };
    let took = switched.elapsed();
    let paused_at_s = fake.cmd(json!({"cmd": "ping"}))["time_s"].as_f64().unwrap();
    println!("{p:?}: mission paused {took:?} after the switch to {mode}");
    assert!(took < Duration::from_secs(1), "paused after {took:?}");
    let reason = format!("pilot took over (mode {mode})");
    assert_eq!(mission["last_error_code"], "pilot_takeover", "{mission}");
    assert_eq!(mission["last_error"], reason.as_str(), "{mission}");
    let item = mission["done_results"]
        .as_array()
        .unwrap()
        .last()
        .unwrap()
        .clone();
    assert_eq!(
        (&item["item"], &item["code"], &item["reason"]),
        (&json!(1), &json!("pilot_takeover"), &json!(reason)),
        "{mission}"
    );
    let drone = &api.get("/api/status")["drones"][0];
    assert_eq!(drone["last_error"], reason.as_str(), "{drone}");
    kestrel.wait_line(
        &format!("go_to #2 failed (pilot_takeover): {reason}"),
        Duration::from_secs(2),
    );
    assert!(
        drone["active_behaviors"].as_array().unwrap().is_empty(),
        "{drone}"
    );
    Taken {
        fake,
        kestrel,
        api,
        mode,
        paused_at_s,
    }
}

/// Nothing from Kestrel reached the vehicle since `since_s` (fake time): no setpoint, no command.
fn nothing_sent_since(t: &Taken, since_s: f64) {
    let got = t.fake.cmd(json!({"cmd": "received", "since_s": since_s}));
    assert_eq!(got["setpoints"], 0, "{got}\n{}", t.kestrel.output());
    let kestrels: Vec<&Value> = got["commands"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["src"] != json!([255, 190]))
        .collect();
    assert!(kestrels.is_empty(), "{kestrels:?}");
    assert_eq!(t.fake.state()["mode"], t.mode, "the mode stays the pilot's");
}

fn post_action(api: &Api, action: &str) -> Value {
    let body = json!({"drone_id": "drone_0", "action": action});
    let (status, answer) = api.post("/api/mission_update", &body);
    assert_eq!(status, 200, "{action}: {answer}");
    answer
}

fn resume_reaches_the_goal(p: Personality) {
    let _one = alongside();
    let t = taken_mid_go_to(p);
    std::thread::sleep(Duration::from_secs(3));
    nothing_sent_since(&t, t.paused_at_s);
    let poller = t.fake.poll_states();
    post_action(&t.api, "RESUME");
    let deadline = Instant::now() + Duration::from_secs(120);
    let mission = loop {
        let m = mission_of(&t.api);
        if m["state"] == 0 {
            break m;
        }
        assert!(
            Instant::now() < deadline,
            "the mission did not end: {m}\n{}\n{}",
            t.kestrel.output(),
            t.fake.diagnostics()
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    let samples = poller.finish();
    let out = t.kestrel.output();
    assert!(mission["last_error"].is_null(), "{mission}\n{out}");
    assert_eq!(mission["pending_items"], 0, "{mission}");
    let results: Vec<(&Value, &Value)> = mission["done_results"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| (&d["behavior"], &d["result"]))
        .collect();
    assert_eq!(
        results,
        [
            (&json!("takeoff"), &json!("succeeded")),
            (&json!("go_to"), &json!("failed")),
            (&json!("go_to"), &json!("succeeded")),
            (&json!("land"), &json!("succeeded")),
        ],
        "{mission}"
    );
    let reached = closest_approaches(&samples, &[GOAL])[0];
    assert!(
        reached <= 0.3,
        "the go_to missed its goal by {reached:.2} m\n{out}"
    );
    let end = t.fake.state();
    assert_eq!(
        (&end["armed"], &end["on_ground"]),
        (&json!(false), &json!(true)),
        "{end}"
    );
}

fn stop_leaves_it_with_the_pilot(p: Personality) {
    let _one = alongside();
    let t = taken_mid_go_to(p);
    let stopped = post_action(&t.api, "STOP");
    assert_eq!(stopped["status"]["state"], 0, "{stopped}");
    let stopped_at_s = t.fake.cmd(json!({"cmd": "ping"}))["time_s"]
        .as_f64()
        .unwrap();
    std::thread::sleep(Duration::from_secs(4));
    nothing_sent_since(&t, t.paused_at_s.min(stopped_at_s));
    let end = t.fake.state();
    assert_eq!(end["armed"], true, "{end}");
    assert!(
        end["position_enu_m"][2].as_f64().unwrap() > 2.0,
        "still holding in the air: {end}"
    );
    let drone = &t.api.get("/api/status")["drones"][0];
    assert!(
        drone["active_behaviors"].as_array().unwrap().is_empty(),
        "{drone}"
    );
}

#[test]
fn px4_gcs_mode_change_pauses_and_resume_reaches_the_goal() {
    resume_reaches_the_goal(Personality::Px4);
}

#[test]
fn ardupilot_rc_mode_switch_pauses_and_resume_reaches_the_goal() {
    resume_reaches_the_goal(Personality::Ardupilot);
}

#[test]
fn px4_stop_after_a_takeover_leaves_the_vehicle_in_the_pilots_mode() {
    stop_leaves_it_with_the_pilot(Personality::Px4);
}

#[test]
fn ardupilot_stop_after_a_takeover_leaves_the_vehicle_in_the_pilots_mode() {
    stop_leaves_it_with_the_pilot(Personality::Ardupilot);
}
