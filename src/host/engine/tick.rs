//! One tick of the whole host, in named steps: the answers of the workers delivered, one
//! snapshot of the fleet, each drone's core, mission and reports, then the frontier allocator
//! asked, the exploration recorded, the changes handed to the store and the fleet advanced.
//!
//! In: the time of the tick. Out: setpoints and requests to the fleet, events and alerts for
//! operators, flight-log records (the maps and frontiers at the map rate), the merged map brought
//! up to date.

use super::Host;
use crate::behavior::fleet::FleetInput;
use crate::behavior::services::ServiceAnswer;
use crate::core::{DroneCore, TickOutput};
use crate::host::status::{link_word, EventBody};
use crate::mapping::merged::FleetMap;
use crate::mapping::scan::RangeScan;
use crate::safety::Override;
use crate::types::{FleetView, PlatformFeedback};
use serde_json::Value;
use std::sync::Arc;
use std::time::Duration;

impl Host {
    /// One control tick at the host's own clock.
    pub fn step(&mut self) {
        let now = self.now;
        self.step_at(now);
        self.now = now + self.tick;
    }

    /// One control tick at `now` (real-time drivers pass the wall-clock time since start).
    pub fn step_at(&mut self, now: Duration) {
        self.now = now;
        self.deliver_answers();
        let view = self.take_fleet_view(now);
        for i in 0..self.cores.len() {
            self.tick_drone(i, now, &view);
        }
        if let Some(map) = self.map.as_mut() {
            map.stamp(now);
        }
        self.exploration.ask(now, self.map.as_mut());
        self.record_exploration(now);
        let exploration = (self.exploration.frontiers(), self.exploration.claims());
        self.log
            .maps(now, &self.cores, self.map.as_mut(), exploration);
        self.commit();
        self.fleet.advance(now, self.tick);
        for (i, message) in self.fleet.take_alerts() {
            if let Some(core) = self.cores.get(i) {
                self.log.event(now, core.drone_id(), "collision", &message);
            }
            self.event(i, EventBody::Alert { message });
        }
    }

    /// Hands the planner's and the frontier allocator's answers to the cores that asked.
    fn deliver_answers(&mut self) {
        for answer in self.planner.collect() {
            if let Some(core) = self.cores.get(answer.drone) {
                core.deliver_plan(answer);
            }
        }
        for a in self.exploration.collect() {
            if let Some(core) = self.cores.get(a.drone) {
                core.deliver(a.ticket, ServiceAnswer::Explore(a.result), a.cancel);
            }
        }
    }

    /// One snapshot of the fleet for every core this tick, as the last tick left it.
    fn take_fleet_view(&mut self, now: Duration) -> Arc<FleetView> {
        let remote = self.peers.views(now);
        self.fleet_view = Arc::new(FleetView {
            drones: self
                .cores
                .iter()
                .map(|c| c.fleet_entry(now))
                .chain(remote)
                .collect(),
        });
        self.fleet_view.clone()
    }

    /// Drone `i`'s tick: its core on what its vehicle reported, its mission, and what operators
    /// are told.
    fn tick_drone(&mut self, i: usize, now: Duration, view: &Arc<FleetView>) {
        let mut feedback = self.fleet.poll(i, now);
        if let Some(scans) = self.api_scans.get_mut(i) {
            feedback.scans.append(scans);
        }
        let Some(out) = self.tick_core(i, now, &feedback, view) else {
            return;
        };
        let alerts = self.follow_mission(i, now, &out);
        for e in out.events {
            self.event(i, EventBody::Behavior(e));
        }
        self.report_alerts(i, now, alerts, out.safety);
        self.report_platform(i, &feedback);
    }

    /// Ticks core `i` and sends what it commands: the setpoint and requests to the vehicle,
    /// the service calls to the workers; its map's changes go into the merged map.
    fn tick_core(
        &mut self,
        i: usize,
        now: Duration,
        feedback: &PlatformFeedback,
        view: &Arc<FleetView>,
    ) -> Option<TickOutput> {
        let core = self.cores.get_mut(i)?;
        let map = self.map.as_ref().map(FleetMap::reference);
        let mut out = core.tick(now, feedback, FleetInput { view, map });
        let setpoint = out.setpoint.map(|s| core.to_vehicle_frame(s));
        self.fleet.command(i, now, setpoint, &out.requests);
        for call in std::mem::take(&mut out.service_calls) {
            if let Some(job) = call.submit(i, &mut self.planner) {
                self.exploration.queue(i, job);
            }
        }
        if let Some(map) = self.map.as_mut() {
            merge_into(map, core, &feedback.scans);
        }
        Some(out)
    }

    /// Drone `i`'s mission follows its behaviors' events (and a pilot's takeover); the tick is
    /// logged with the mission item each event belongs to. Returns the alerts for operators.
    fn follow_mission(&mut self, i: usize, now: Duration, out: &TickOutput) -> Vec<String> {
        let Some(core) = self.cores.get_mut(i) else {
            return Vec::new();
        };
        // The mission item each behavior event belongs to: the one running when it happened.
        let item = match self.executors.get(i) {
            Some(ex) if self.log.is_on() && !out.events.is_empty() => {
                let st = ex.status(core);
                (st.state != crate::mission::ExecState::Idle).then(|| {
                    serde_json::json!({
                        "mission_id": st.mission_id,
                        "item_index": st.item_index,
                        "item": st.current_item,
                    })
                })
            }
            _ => None,
        };
        let mut alerts = Vec::new();
        if let Some(ex) = self.executors.get_mut(i) {
            if let Some(reason) = &out.takeover {
                ex.pilot_took_over(reason);
            }
            ex.update(now, core, &out.events);
            alerts = ex.take_alerts();
        }
        if let Some(reason) = &out.takeover {
            tracing::warn!(
                "{}: {reason}: Kestrel stopped commanding it",
                core.drone_id()
            );
            alerts.push(reason.clone());
        }
        // A simulated drone whose estimate drifts: the truth beside it, for the evaluator.
        let truth = || self.fleet.truth_behind_estimate(i);
        self.log.tick(now, core, out, item.as_ref(), truth);
        alerts
    }

    /// The mission's alerts and the safety stage's override of drone `i`, logged and sent.
    fn report_alerts(
        &mut self,
        i: usize,
        now: Duration,
        alerts: Vec<String>,
        safety: Option<Override>,
    ) {
        for message in alerts {
            if let Some(core) = self.cores.get(i) {
                self.log.event(now, core.drone_id(), "mission", &message);
            }
            self.event(i, EventBody::Alert { message });
        }
        if let Some(o) = safety {
            if let Some(core) = self.cores.get(i) {
                self.log.event(now, core.drone_id(), "safety", &o.reason);
            }
            tracing::warn!("safety: {}", o.reason);
            self.event(
                i,
                EventBody::Alert {
                    message: format!("safety: {}", o.reason),
                },
            );
        }
    }

    /// What drone `i`'s vehicle said that operators hear of: refused requests, and a mode, a
    /// link or an autopilot error that changed.
    fn report_platform(&mut self, i: usize, feedback: &PlatformFeedback) {
        for r in &feedback.request_results {
            if let Err(reason) = &r.outcome {
                let request = serde_json::to_value(r.request)
                    .ok()
                    .and_then(|v| v.get("request").and_then(Value::as_str).map(str::to_string))
                    .unwrap_or_default();
                self.event(
                    i,
                    EventBody::Autopilot {
                        text: format!("{request} refused: {reason}"),
                    },
                );
            }
        }
        let status = &feedback.status;
        if self.modes.get(i) != Some(&status.mode) {
            if let Some(m) = self.modes.get_mut(i) {
                m.clone_from(&status.mode);
            }
            self.event(
                i,
                EventBody::Alert {
                    message: format!("mode {}", status.mode),
                },
            );
        }
        if self.links.get(i) != Some(&status.link) {
            if let Some(l) = self.links.get_mut(i) {
                *l = status.link;
            }
            self.event(
                i,
                EventBody::Alert {
                    message: format!("link {}", link_word(status.link)),
                },
            );
        }
        if status.last_error.is_some() && self.errors.get(i) != Some(&status.last_error) {
            if let Some(text) = status.last_error.clone() {
                self.event(i, EventBody::Autopilot { text });
            }
            if let Some(e) = self.errors.get_mut(i) {
                e.clone_from(&status.last_error);
            }
        }
    }
}

/// Brings a drone's new map data into the merged map: the cells its own map server changed this
/// tick, copied (the scans are ray-cast once), or its scans ray-cast again when its grid is not on
/// the merged spec (a drone configured with a map of its own).
fn merge_into(map: &mut FleetMap, core: &DroneCore, scans: &[RangeScan]) {
    let own = core.map().filter(|own| map.same_spec(own.grid().spec()));
    let Some(own) = own else {
        // In the map's frame, where the core's own map has them.
        map.insert_all(core.drone_id(), &core.to_map_frame(scans));
        return;
    };
    if let Some(region) = own.last_changed() {
        if let Err(e) = map.copy_from_drone(core.drone_id(), own.grid(), region) {
            tracing::warn!("{}: merged map not updated: {e}", core.drone_id());
        }
    }
}
