//! The WebSocket `/api/ws`: telemetry at the client's rate, mission status on change and every
//! second, events, and MissionUpdates sent by the client.
//!
//! In: client messages `{"type":"subscribe","telemetry_rate_hz":10}` and
//! `{"type":"mission_update","request_id":1, ...MissionUpdate}`. Out: `telemetry`,
//! `mission_status`, `event` and `reply` messages (docs/API.md). Each client has its own task
//! reading the latest state and a lagging view of the events: a slow or dead client loses
//! messages or is dropped, and never slows the control loop or other clients.

use super::error::ApiError;
use super::routes::apply_update;
use super::ApiState;
use crate::host::status::HostEvent;
use axum::extract::ws::{Message, Utf8Bytes, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::response::{IntoResponse, Response};
use futures::{SinkExt, StreamExt};
use serde_json::{json, Value};
use std::sync::atomic::Ordering;
use std::time::Duration;
use tokio::sync::broadcast::error::RecvError;

const DEFAULT_RATE_HZ: f64 = 5.0;
const MAX_RATE_HZ: f64 = 50.0;
const MIN_RATE_HZ: f64 = 0.1;
/// A client that cannot take a message in this time is dropped.
const SEND_TIMEOUT: Duration = Duration::from_secs(2);
/// The largest client message, and frame: a frame's length is checked from its header, so a
/// client announcing more is dropped before anything of it is buffered (the frame limit alone
/// was 16 MiB, all read before the message limit was checked).
const MAX_CLIENT_MESSAGE: usize = 256 * 1024;

pub async fn upgrade(State(s): State<ApiState>, ws: WebSocketUpgrade) -> Response {
    let clients = s.ws_clients.fetch_add(1, Ordering::SeqCst);
    if clients >= s.max_ws_clients {
        s.ws_clients.fetch_sub(1, Ordering::SeqCst);
        return ApiError::TooManyClients(s.max_ws_clients).into_response();
    }
    let counter = s.ws_clients.clone();
    ws.max_message_size(MAX_CLIENT_MESSAGE)
        .max_frame_size(MAX_CLIENT_MESSAGE)
        .on_upgrade(move |socket| async move {
            serve(socket, s).await;
            counter.fetch_sub(1, Ordering::SeqCst);
        })
}

fn period(rate_hz: f64) -> Duration {
    Duration::from_secs_f64(1.0 / rate_hz.clamp(MIN_RATE_HZ, MAX_RATE_HZ))
}

fn ticker(every: Duration) -> tokio::time::Interval {
    let mut t = tokio::time::interval(every);
    t.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    t
}

async fn serve(socket: WebSocket, s: ApiState) {
    let (mut sink, mut stream) = socket.split();
    let state = s.host.watch_state();
    let mut events = s.host.subscribe_events();
    let mut telemetry = ticker(period(DEFAULT_RATE_HZ));
    let mut status_tick = ticker(Duration::from_secs(1));
    loop {
        // In this order: a periodic status read off the latest state after an older status
        // event still queued would show a client the mission going back (loaded, idle) between
        // two running statuses; the queued events go first.
        let out: Vec<Value> = tokio::select! {
            biased;
            message = stream.next() => match message {
                Some(Ok(Message::Text(text))) => {
                    let (reply, rate) = client_message(&s, text.as_str()).await;
                    if let Some(r) = rate {
                        telemetry = ticker(period(r));
                    }
                    vec![reply]
                }
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => break,
                Some(Ok(_)) => continue,
            },
            event = events.recv() => match event {
                Ok(e) => vec![event_frame(&e)],
                Err(RecvError::Lagged(missed)) => vec![json!({
                    "type": "event", "drone": null, "t": state.borrow().t,
                    "event": {"kind": "lagged", "missed": missed}
                })],
                Err(RecvError::Closed) => break,
            },
            _ = telemetry.tick() => vec![telemetry_frame(&state.borrow().clone())],
            _ = status_tick.tick() => {
                let snap = state.borrow().clone();
                snap.drones
                    .iter()
                    .map(|d| json!({"type": "mission_status", "drone": d.drone, "status": d.mission}))
                    .collect()
            }
        };
        for v in out {
            let text = Utf8Bytes::from(v.to_string());
            match tokio::time::timeout(SEND_TIMEOUT, sink.send(Message::Text(text))).await {
                Ok(Ok(())) => {}
                _ => return,
            }
        }
    }
}

fn telemetry_frame(snap: &crate::host::HostSnapshot) -> Value {
    let drones: Vec<Value> = snap
        .drones
        .iter()
        .map(|d| {
            let mut v = serde_json::to_value(d).unwrap_or(Value::Null);
            if let Value::Object(m) = &mut v {
                m.remove("mission");
            }
            v
        })
        .collect();
    let mut frame = json!({"type": "telemetry", "t": snap.t, "drones": drones});
    // Drones other Kestrels fly, heard over the fleet bus (only when there are any).
    if !snap.remote.is_empty() {
        frame["remote"] = serde_json::to_value(&snap.remote).unwrap_or(Value::Null);
    }
    frame
}

fn event_frame(e: &HostEvent) -> Value {
    serde_json::to_value(e).unwrap_or(Value::Null)
}

/// Answers one client message; the second value is a new telemetry rate.
async fn client_message(s: &ApiState, text: &str) -> (Value, Option<f64>) {
    let msg: Value = match serde_json::from_str(text) {
        Ok(v) => v,
        Err(e) => return (reply(Value::Null, Err(Refusal::NotJson(e))), None),
    };
    let request_id = msg.get("request_id").cloned().unwrap_or(Value::Null);
    match msg.get("type").and_then(Value::as_str) {
        Some("subscribe") => match msg.get("telemetry_rate_hz").and_then(Value::as_f64) {
            Some(r) if r.is_finite() && r > 0.0 => {
                let rate = r.clamp(MIN_RATE_HZ, MAX_RATE_HZ);
                (
                    reply(request_id, Ok(json!({"telemetry_rate_hz": rate}))),
                    Some(rate),
                )
            }
            _ => (reply(request_id, Err(Refusal::BadRate)), None),
        },
        Some("mission_update") => {
            let mut fields = msg.clone();
            if let Value::Object(m) = &mut fields {
                m.remove("type");
                m.remove("request_id");
            }
            let result = apply_update(s, fields.to_string().as_bytes())
                .await
                .map(|(u, saved)| json!({"drone": u.drone, "status": u.status, "durable": saved.durable}))
                .map_err(Refusal::Update);
            (reply(request_id, result), None)
        }
        other => (
            reply(
                request_id,
                Err(Refusal::UnknownType(other.map(str::to_string))),
            ),
            None,
        ),
    }
}

/// Why a client's message was refused; the words are the reply's `reason`.
#[derive(Debug, thiserror::Error)]
enum Refusal {
    #[error("not valid JSON: {0}")]
    NotJson(serde_json::Error),
    #[error("telemetry_rate_hz must be a positive number")]
    BadRate,
    /// The mission update was refused, in the words the HTTP API gives.
    #[error("{}", .0.message())]
    Update(ApiError),
    #[error("unknown message type {0:?}: use subscribe or mission_update")]
    UnknownType(Option<String>),
}

fn reply(request_id: Value, result: Result<Value, Refusal>) -> Value {
    match result {
        Ok(extra) => {
            let mut v = json!({"type": "reply", "request_id": request_id, "accepted": true, "reason": null});
            if let (Value::Object(m), Value::Object(e)) = (&mut v, extra) {
                m.extend(e);
            }
            v
        }
        Err(reason) => {
            json!({"type": "reply", "request_id": request_id, "accepted": false, "reason": reason.to_string()})
        }
    }
}
