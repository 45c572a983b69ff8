//! One drone's deterministic core: estimator → frames → map → behavior server → controller.
//!
//! In (each tick): the time since start and what the platform reported ([`PlatformFeedback`]).
//! Out: a [`TickOutput`] with the setpoint and platform requests for this tick, the service
//! calls the behaviors filed (plans, run by the host off the tick; the answers come back through
//! [`DroneCore::deliver`] before a later tick), plus the behavior events that happened. The core never reads the clock and never does I/O, so a
//! real-time driver, the simulator and tests tick exactly the same code.

use crate::behavior::fleet::FleetInput;
use crate::behavior::services::{ServiceAnswer, ServiceCall, ServiceDesk};
use crate::behavior::{
    BehaviorConfig, BehaviorContext, BehaviorEvent, BehaviorId, BehaviorServer, Failure,
    FailureCode, ParsedGoal, Registry, ServerError,
};
use crate::control::{Controller, ControllerConfig, MotionReference, Setpoint};
use crate::estimator::frames::{FrameError, FrameMotion, FrameTree};
use crate::estimator::geodetic::GeodeticOrigin;
use crate::estimator::map_correction::{MapCorrection, MapCorrectionSettings};
use crate::estimator::{self, Estimator, EstimatorPlugin};
use crate::exploration::online::settings::ExplorationSettings;
use crate::mapping::config::MapConfig;
use crate::mapping::history::ScanHistory;
use crate::mapping::registration::Reference;
use crate::mapping::server::MapServer;
use crate::planning::worker::PlanAnswer;
use crate::safety::{
    Around, Flight, LowestHeight, Obstacles, Override, SafetyConfig, SafetyStage, Seen, SeenHits,
};
use crate::types::{Capabilities, PlatformEvent, PlatformFeedback, PlatformRequest};
use crate::types::{DroneView, FleetView};
use crate::types::{EstimatedState, LinkHealth, PlatformStatus, Vec3, VehicleState};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

mod map_frame;

/// Settings of one drone core.
#[derive(Debug, Clone)]
pub struct CoreConfig {
    pub drone_id: String,
    pub estimator: EstimatorPlugin,
    /// The estimate corrected against the fleet's map (`[estimator.map_correction]`).
    pub map_correction: MapCorrectionSettings,
    pub controller: ControllerConfig,
    pub behaviors: BehaviorConfig,
    /// The exploration's weights, for the `explore` behavior (config `[exploration]`).
    pub exploration: ExplorationSettings,
    pub geo_origin: GeodeticOrigin,
    /// Mapping (`None` = off): the drone's scans build its grid, which `navigate_to` plans on.
    pub map: Option<MapConfig>,
    /// What every setpoint is checked against before it leaves the core.
    pub safety: SafetyConfig,
}

impl CoreConfig {
    pub fn new(drone_id: &str) -> Self {
        Self {
            drone_id: drone_id.to_string(),
            estimator: EstimatorPlugin::GroundTruth,
            map_correction: MapCorrectionSettings::default(),
            controller: ControllerConfig::default(),
            behaviors: BehaviorConfig::default(),
            exploration: ExplorationSettings::default(),
            geo_origin: GeodeticOrigin::default(),
            // The default section is a fixed, valid 40 m x 40 m grid.
            map: MapConfig::open_field().ok(),
            safety: SafetyConfig::default(),
        }
    }
}

/// What one tick produces for the platform and the outside world.
#[derive(Debug, Default)]
pub struct TickOutput {
    /// In the map's frame: [`DroneCore::to_vehicle_frame`] gives what the vehicle is sent.
    pub setpoint: Option<Setpoint>,
    pub requests: Vec<PlatformRequest>,
    pub service_calls: Vec<ServiceCall>,
    pub events: Vec<BehaviorEvent>,
    /// The safety stage changed the setpoint (reported once per episode).
    pub safety: Option<Override>,
    /// The vehicle was taken from Kestrel this tick (why, in words): every behavior ended with
    /// `pilot_takeover` and nothing commands it until a new order.
    pub takeover: Option<String>,
}

/// A request to the behavior server from outside the core (mission executor, API).
#[derive(Debug, Clone, PartialEq)]
pub enum BehaviorCommand {
    Start {
        behavior: String,
        goal: serde_json::Value,
    },
    /// Start a goal parsed and checked before (a validated mission item).
    StartParsed(ParsedGoal),
    Pause(BehaviorId),
    Resume(BehaviorId),
    Stop(BehaviorId),
    /// End a behavior as done (a mission item's `run_for_s` is over): it finishes succeeded.
    Complete(BehaviorId),
    Modify {
        id: BehaviorId,
        goal: serde_json::Value,
    },
}

pub struct DroneCore {
    config: CoreConfig,
    capabilities: Capabilities,
    estimator: Box<dyn Estimator>,
    /// From the reported position to the map's frame (`None`: off, or no map).
    correction: Option<MapCorrection>,
    /// What the range sensor hit in the last seconds (the vehicle's reported frame), kept off
    /// by the safety stage where the estimate drifts (with the map correction on).
    seen: SeenHits,
    /// The scans the map is drawn from, to draw it again when the correction finds the offsets
    /// of the past were others (`None`: no correction, or an estimate that does not drift).
    history: Option<ScanHistory>,
    /// Whether a fit ran this tick (the history is checked against the smoothed track then).
    fitted: bool,
    frames: FrameTree,
    server: BehaviorServer,
    services: ServiceDesk,
    /// The fleet as the host last showed it (what commands between ticks see).
    fleet: Arc<FleetView>,
    map: Option<MapServer>,
    controller: Controller,
    safety: SafetyStage,
    state: EstimatedState,
    platform: PlatformStatus,
    home_enu_m: Option<Vec3>,
    /// The point the last motion reference held the vehicle at (position references only).
    held_at_enu_m: Option<Vec3>,
    last_tick: Option<Duration>,
    now: Duration,
    /// When the estimate last had a valid position; `None` before the first.
    position_at: Option<Duration>,
}

impl DroneCore {
    pub fn new(mut config: CoreConfig, capabilities: Capabilities, registry: Registry) -> Self {
        // The config's velocity lag, else the platform's: the controller's feed-forward and the
        // safety stage's reaction time use the same one.
        let lag = config
            .controller
            .velocity_lag_s
            .or(capabilities.velocity_lag_s);
        config.controller.velocity_lag_s = lag;
        config.safety.limits.velocity_lag_s = lag;
        // The same for the vehicle's overshoot: behaviors plan with it, the controller caps
        // with it.
        let overshoot = config
            .controller
            .velocity_overshoot
            .or(capabilities.velocity_overshoot);
        config.controller.velocity_overshoot = overshoot;
        let yaw_overshoot = config
            .controller
            .yaw_rate_overshoot
            .or(capabilities.yaw_rate_overshoot);
        config.controller.yaw_rate_overshoot = yaw_overshoot;
        // The vehicle flies its estimate: it moves up to the estimate's drift faster than
        // commanded, which the controller's caps allow for.
        config.controller.estimate_drift_mps = config.map_correction.drift_mps();
        let capabilities = Capabilities {
            velocity_overshoot: overshoot,
            yaw_rate_overshoot: yaw_overshoot,
            height_error_m: config.safety.height_error_m.or(capabilities.height_error_m),
            ..capabilities
        };
        Self {
            estimator: estimator::build(config.estimator),
            seen: SeenHits::default(),
            correction: config
                .map
                .as_ref()
                .filter(|_| config.map_correction.enabled)
                .map(|_| MapCorrection::new(config.map_correction)),
            history: config
                .map
                .as_ref()
                .filter(|_| {
                    let c = &config.map_correction;
                    c.enabled && c.redraw && c.drift_mps() > 0.0
                })
                .map(|m| ScanHistory::new((*m.initial).clone(), map_frame::MAX_KEPT_SCANS)),
            fitted: false,
            controller: Controller::new(config.controller, capabilities.setpoints),
            safety: SafetyStage::new(config.safety.clone(), capabilities.setpoints.position_loop),
            server: BehaviorServer::new(registry),
            services: ServiceDesk::default(),
            fleet: Arc::default(),
            map: config.map.as_ref().map(MapServer::new),
            frames: FrameTree::new(),
            capabilities,
            state: EstimatedState::default(),
            platform: PlatformStatus::default(),
            home_enu_m: None,
            held_at_enu_m: None,
            last_tick: None,
            now: Duration::ZERO,
            position_at: None,
            config,
        }
    }

    pub fn drone_id(&self) -> &str {
        &self.config.drone_id
    }

    pub fn vehicle_state(&self) -> VehicleState {
        VehicleState {
            drone: self.config.drone_id.clone(),
            estimate: self.state,
            platform: self.platform.clone(),
        }
    }

    /// How old the last valid position is (core time); `None` before the first: until then
    /// the position is a placeholder, not the vehicle's.
    pub fn position_age(&self) -> Option<Duration> {
        self.position_at.map(|at| self.now.saturating_sub(at))
    }

    /// What the platform reported at the last tick.
    pub fn platform_status(&self) -> &PlatformStatus {
        &self.platform
    }

    /// The state estimate of the last tick.
    pub fn estimate(&self) -> &EstimatedState {
        &self.state
    }

    /// The fleet as the host last showed it.
    pub fn fleet_view(&self) -> &FleetView {
        &self.fleet
    }

    /// This drone as the fleet view shows it.
    pub fn fleet_entry(&self, stamp: Duration) -> DroneView {
        let motion = self.server.motion();
        DroneView {
            id: self.config.drone_id.as_str().into(),
            position_enu_m: self.state.pose.position_m,
            velocity_enu_mps: self.state.velocity_enu_mps,
            yaw_rad: self.state.pose.yaw_rad(),
            flying: self.platform.flight.is_airborne() && self.platform.armed,
            link: self.platform.link,
            motion_behavior: motion.map(|(name, _)| name.into()),
            goal_enu_m: motion.and_then(|(_, goal)| goal),
            stamp,
            local: true,
            uncertainty_m: self
                .correction
                .as_ref()
                .map_or(0.0, MapCorrection::uncertainty_m),
            silent: false,
            unaccounted: false,
        }
    }

    pub fn server(&self) -> &BehaviorServer {
        &self.server
    }

    /// The drone's map, `None` when mapping is off.
    pub fn map(&self) -> Option<&MapServer> {
        self.map.as_ref()
    }

    pub fn frames(&self) -> &FrameTree {
        &self.frames
    }

    pub fn geo_origin(&self) -> &GeodeticOrigin {
        &self.config.geo_origin
    }

    pub fn home_enu_m(&self) -> Option<Vec3> {
        self.home_enu_m
    }

    /// The lowest height above home a mission may fly this vehicle at (m): its height
    /// estimate's error plus [`crate::safety::GROUND_CLEARANCE_M`]; `None` where the height is
    /// taken as exact (the simulator, a profile or config that says 0).
    pub fn lowest_flight_height_m(&self) -> Option<LowestHeight> {
        self.capabilities
            .height_error_m
            .filter(|e| *e > 0.0)
            .map(|error_m| LowestHeight {
                height_m: error_m + crate::safety::GROUND_CLEARANCE_M,
                error_m,
            })
    }

    pub fn set_frame(
        &mut self,
        frame: &str,
        parent: &str,
        motion: FrameMotion,
    ) -> Result<(), FrameError> {
        self.frames.set(frame, parent, motion)
    }

    /// Hands a service's answer to the behavior holding `ticket`, before the next tick.
    pub fn deliver(&self, ticket: u64, answer: ServiceAnswer, cancel: Arc<AtomicBool>) {
        self.services.deliver(ticket, answer, cancel);
    }

    /// Hands a finished plan to the behavior that asked for it.
    pub fn deliver_plan(&self, answer: PlanAnswer) {
        self.deliver(
            answer.ticket,
            ServiceAnswer::Plan(answer.result),
            answer.cancel,
        );
    }

    /// Applies a command to the behavior server with the state of the last tick.
    pub fn command(&mut self, cmd: BehaviorCommand) -> Result<Option<BehaviorId>, ServerError> {
        let ctx = BehaviorContext {
            drone_id: self.config.drone_id.as_str(),
            now: self.now,
            dt_s: 0.0,
            state: &self.state,
            platform: &self.platform,
            capabilities: self.capabilities,
            frames: &self.frames,
            geo_origin: &self.config.geo_origin,
            home_enu_m: self.home_enu_m,
            held_at_enu_m: self.held_at_enu_m,
            config: &self.config.behaviors,
            exploration: &self.config.exploration,
            map: self.map.as_ref(),
            request_results: &[],
            services: &self.services,
            fleet: &self.fleet,
            estimate_drift_mps: self.config.controller.estimate_drift_mps,
            safety_override: self.safety.active(),
            map_step_m: Vec3::zeros(),
        };
        match cmd {
            BehaviorCommand::Start { behavior, goal } => {
                self.server.start(&behavior, &goal, &ctx).map(Some)
            }
            BehaviorCommand::StartParsed(goal) => self.server.start_parsed(&goal, &ctx).map(Some),
            BehaviorCommand::Pause(id) => self.server.pause(id, &ctx).map(|_| None),
            BehaviorCommand::Resume(id) => self.server.resume(id, &ctx).map(|_| None),
            BehaviorCommand::Stop(id) => self.server.stop(id, &ctx).map(|_| None),
            BehaviorCommand::Complete(id) => self.server.complete(id, &ctx).map(|_| None),
            BehaviorCommand::Modify { id, goal } => {
                self.server.modify(id, &goal, &ctx).map(|_| None)
            }
        }
    }

    /// One control tick at time `now` (since the start of the run), with what the platform
    /// reported and what the fleet looks like.
    pub fn tick(
        &mut self,
        now: Duration,
        feedback: &PlatformFeedback,
        fleet: FleetInput<'_>,
    ) -> TickOutput {
        self.fleet = fleet.view.clone();
        let dt_s = self
            .last_tick
            .map_or(0.0, |t| now.saturating_sub(t).as_secs_f64());
        self.last_tick = Some(now);
        self.now = now;
        let was_armed = self.platform.armed;
        let previous_link = self.platform.link;
        self.platform = feedback.status.clone();
        let reported = self.estimator.update(now, &feedback.measurements);
        let offset_before = self.map_offset_m();
        let scans = self.correct_against_map(reported, &feedback.scans, fleet.map, dt_s);
        let map_step_m = self.map_offset_m() - offset_before;
        if self.state.valid.position {
            self.position_at = Some(now);
        }
        self.frames.set_base_link(self.state.pose, now);
        if let Some(map) = self.map.as_mut() {
            map.insert(now, &scans);
        }
        self.redraw_if_moved(&feedback.scans);
        if self.platform.armed && !was_armed && self.state.valid.position {
            self.home_enu_m = Some(self.state.pose.position_m);
        }
        let ctx = BehaviorContext {
            drone_id: self.config.drone_id.as_str(),
            now,
            dt_s,
            state: &self.state,
            platform: &self.platform,
            capabilities: self.capabilities,
            frames: &self.frames,
            geo_origin: &self.config.geo_origin,
            home_enu_m: self.home_enu_m,
            held_at_enu_m: self.held_at_enu_m,
            config: &self.config.behaviors,
            exploration: &self.config.exploration,
            map: self.map.as_ref(),
            request_results: &feedback.request_results,
            services: &self.services,
            fleet: &self.fleet,
            estimate_drift_mps: self.config.controller.estimate_drift_mps,
            safety_override: self.safety.active(),
            map_step_m,
        };
        let takeover = end_what_cannot_go_on(&mut self.server, &ctx, feedback, previous_link);
        let out = self.server.tick(&ctx);
        if out.reference.is_some() {
            self.held_at_enu_m = out.reference.as_ref().and_then(MotionReference::held_at);
        }
        let landing = out.requests.contains(&PlatformRequest::LandOnSetpoints);
        let (setpoint, safety) = self.setpoint_for(out.reference, landing, dt_s, fleet.map);
        TickOutput {
            setpoint,
            safety,
            requests: out.requests,
            service_calls: self.services.drain_calls(),
            events: self.server.drain_events(),
            takeover,
        }
    }

    /// The setpoint for the behaviors' `reference` (none without a position or a link), after
    /// the safety stage, and the stage's override if it changed it. `landing`: the behaviors
    /// fly the vehicle down to touchdown on these setpoints. The stage keeps off the obstacles of
    /// the drone's own map and of the fleet's `merged` one.
    fn setpoint_for(
        &mut self,
        reference: Option<MotionReference>,
        landing: bool,
        dt_s: f64,
        merged: Option<Reference<'_>>,
    ) -> (Option<Setpoint>, Option<Override>) {
        let usable = self.state.valid.position && self.platform.link != LinkHealth::Lost;
        let caps = self.controller.caps(
            reference
                .as_ref()
                .map_or(f64::INFINITY, |r| r.max_speed_mps()),
        );
        let setpoint = match reference {
            Some(reference) if usable => {
                Some(self.controller.update(&self.state, &reference, dt_s))
            }
            _ => {
                self.controller.reset();
                None
            }
        };
        let home = self.home_enu_m.unwrap_or(self.state.pose.position_m);
        let flying = self.platform.flight.is_airborne() && self.platform.armed;
        let map_offset_m = self.map_offset_m();
        let (setpoint, safety) = self.safety.check(
            &self.config.drone_id,
            &self.state,
            home,
            match (flying, landing) {
                (false, _) => Flight::OnGround,
                (true, false) => Flight::Flying,
                (true, true) => Flight::Landing,
            },
            setpoint,
            caps,
            Around {
                fleet: &self.fleet,
                obstacles: match (self.map.as_ref(), merged) {
                    (Some(own), Some(fleet)) => Some(
                        Obstacles::new(own.grid(), own.occupied_threshold())
                            .and(fleet.grid, fleet.occupied_threshold),
                    ),
                    (Some(own), None) => Some(Obstacles::new(own.grid(), own.occupied_threshold())),
                    (None, Some(fleet)) => {
                        Some(Obstacles::new(fleet.grid, fleet.occupied_threshold))
                    }
                    (None, None) => None,
                },
                seen: (self.config.controller.estimate_drift_mps > 0.0).then_some(Seen {
                    hits: &self.seen,
                    map_offset_m,
                }),
            },
        );
        self.controller.sent(
            setpoint.as_ref(),
            flying && self.platform.flight == crate::types::FlightStatus::Flying,
        );
        (setpoint, safety)
    }
}

/// Ends what runs when Kestrel cannot go on flying the vehicle: the link just lost, a pilot's
/// takeover, a crash, a virtual collision. Returns the takeover's reason, if one happened.
fn end_what_cannot_go_on(
    server: &mut BehaviorServer,
    ctx: &BehaviorContext,
    feedback: &PlatformFeedback,
    previous_link: LinkHealth,
) -> Option<String> {
    // Never command blind: without a link or a position estimate, behaviors end and the
    // autopilot's own failsafe takes over.
    if ctx.platform.link == LinkHealth::Lost && previous_link != LinkHealth::Lost {
        server.stop_all(
            Failure::new(FailureCode::LinkLost, "link to the autopilot lost"),
            ctx,
        );
        server.clear_hold();
    }
    // Someone else flies the vehicle now: end everything and command nothing (no hold
    // either), so that Kestrel never fights the pilot; a new order takes it back.
    let mut takeover = None;
    for event in &feedback.events {
        match event {
            PlatformEvent::PilotTakeover { .. } => {
                let reason = event.reason();
                let failure = Failure::new(FailureCode::PilotTakeover, reason.clone());
                server.fail_all(failure, ctx);
                server.clear_hold();
                takeover = Some(reason);
            }
        }
    }
    if ctx.platform.flight == crate::types::FlightStatus::Crashed {
        let reason = ctx
            .platform
            .last_error
            .clone()
            .unwrap_or_else(|| "crashed".into());
        server.fail_all(Failure::new(FailureCode::Crashed, reason), ctx);
        server.clear_hold();
    }
    if let Some(reason) = &feedback.virtual_collision {
        // The vehicle is unharmed: what runs fails, and it holds where it is.
        server.fail_all(
            Failure::new(FailureCode::VirtualCollision, reason.clone()),
            ctx,
        );
    }
    takeover
}
