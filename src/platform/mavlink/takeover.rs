//! Who flies the vehicle: Kestrel, or someone who took it from Kestrel.
//!
//! In: every mode report of the autopilot (HEARTBEAT, PX4's CURRENT_MODE) with the armed flag
//! and whether the vehicle was airborne, the modes Kestrel's own requests put the vehicle in
//! ([`ControlWatch::commanded`]), its disarm requests and link losses. Out: a [`Takeover`], once,
//! when the vehicle leaves the mode Kestrel flies it in without Kestrel asking. Pure: no I/O, no
//! clock; the session feeds it.
//!
//! Kestrel flies the vehicle while it is armed in the mode Kestrel last asked for (the offboard
//! mode until it asks for another: PX4 OFFBOARD, ArduPilot GUIDED, or the land or takeoff mode of
//! its own requests). A different mode while Kestrel flies it is a takeover, whatever the cause:
//! a pilot's mode switch (ArduPilot in GUIDED ignores the sticks, so a mode switch is how a
//! pilot takes it; PX4 turns stick movement into POSCTL), a ground station's DO_SET_MODE or
//! NAV_LAND on the autopilot's own link, or the autopilot's failsafe while the link is up (PX4
//! leaves OFFBOARD when Kestrel's setpoints stop reaching it). A disarm in the air that Kestrel
//! did not ask for counts too. Not a takeover: a mode Kestrel asked for shown late, PX4 ending
//! its NAV_TAKEOFF in its hold mode, the mode change or disarm that ends Kestrel's landing on
//! the ground, the land mode or a disarm while Kestrel lands the vehicle on its own setpoints, a
//! disarm on the ground, and whatever happened while the link was down (the autopilot's link-loss failsafe flew the
//! vehicle; the mission's link-loss policy decides what follows, `mission::executor::link`).
//! Once taken, the vehicle is Kestrel's again only when it is back in Kestrel's mode (Kestrel
//! asked for it again on an operator's order, e.g. RESUME).

/// One mode report of the autopilot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModeReport {
    /// HEARTBEAT `custom_mode`.
    pub custom_mode: u32,
    pub armed: bool,
    /// The vehicle was in the air before this report (its landed state).
    pub was_airborne: bool,
}

/// The vehicle was taken from Kestrel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Takeover {
    /// It left Kestrel's mode for this one.
    Mode(u32),
    /// It was disarmed in the air.
    Disarmed,
}

/// The modes the watch needs from the profile (HEARTBEAT `custom_mode` values).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WatchedModes {
    pub offboard: u32,
    pub land: u32,
    pub hold: u32,
    /// The mode PX4's NAV_TAKEOFF flies in; it goes on to `hold` by itself.
    pub takeoff: Option<u32>,
}

#[derive(Debug, Clone)]
pub struct ControlWatch {
    modes: WatchedModes,
    /// The mode Kestrel last asked for.
    commanded: u32,
    /// Kestrel flies the vehicle.
    in_control: bool,
    /// Kestrel asked to disarm (since its last arm request).
    disarm_requested: bool,
    /// Kestrel flies a landing on its own setpoints (the session's hint is fresh).
    landing_on_setpoints: bool,
    last_mode: Option<u32>,
}

impl ControlWatch {
    pub fn new(modes: WatchedModes) -> Self {
        Self {
            modes,
            commanded: modes.offboard,
            in_control: false,
            disarm_requested: false,
            landing_on_setpoints: false,
            last_mode: None,
        }
    }

    /// Kestrel flies the vehicle now.
    pub fn in_control(&self) -> bool {
        self.in_control
    }

    /// Kestrel asked for `custom_mode` (a mode change, or a command that leads to it).
    pub fn commanded(&mut self, custom_mode: u32) {
        self.commanded = custom_mode;
    }

    /// Kestrel asked to arm (`true`) or to disarm (`false`).
    pub fn arming_requested(&mut self, arm: bool) {
        self.disarm_requested = !arm;
    }

    /// Whether Kestrel is flying a landing on its setpoints now: meanwhile the autopilot
    /// switching to its land mode (PX4 does at touchdown when the setpoints pause) or disarming
    /// ends that landing; a ground station's NAV_LAND lands the vehicle where Kestrel was
    /// landing it anyway. Any other mode is still a takeover.
    pub fn landing_on_setpoints(&mut self, landing: bool) {
        self.landing_on_setpoints = landing;
    }

    /// The link was lost or the autopilot rebooted: what it does meanwhile is not a takeover.
    pub fn link_lost(&mut self) {
        self.in_control = false;
    }

    /// One mode report; `Some` once when the vehicle was just taken from Kestrel.
    pub fn report(&mut self, r: ModeReport) -> Option<Takeover> {
        let previous = self.last_mode.replace(r.custom_mode);
        let in_kestrels_mode = r.armed && r.custom_mode == self.commanded;
        if !self.in_control {
            self.in_control = in_kestrels_mode;
            return None;
        }
        if in_kestrels_mode {
            return None;
        }
        if self.landing_on_setpoints && r.armed && r.custom_mode == self.modes.land {
            self.commanded = self.modes.land;
            return None;
        }
        if self.commanded == self.modes.land && !r.was_airborne {
            // Landed: PX4 leaves its land mode by itself as it disarms (AUTO.LOITER), and may
            // say so (CURRENT_MODE) before HEARTBEAT shows the disarm.
            self.in_control = false;
            return None;
        }
        if !r.armed {
            self.in_control = false;
            let expected = self.disarm_requested
                || self.landing_on_setpoints
                || self.commanded == self.modes.land
                || !r.was_airborne;
            return (!expected).then_some(Takeover::Disarmed);
        }
        if previous == Some(r.custom_mode) {
            return None; // the mode Kestrel asked for is not shown yet
        }
        if self.modes.takeoff == Some(self.commanded)
            && previous == Some(self.commanded)
            && r.custom_mode == self.modes.hold
        {
            self.commanded = self.modes.hold;
            return None;
        }
        self.in_control = false;
        Some(Takeover::Mode(r.custom_mode))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OFFBOARD: u32 = 0x0006_0000;
    const LOITER: u32 = 0x0304_0000;
    const LAND: u32 = 0x0604_0000;
    const TAKEOFF: u32 = 0x0204_0000;
    const POSCTL: u32 = 0x0003_0000;

    fn watch() -> ControlWatch {
        ControlWatch::new(WatchedModes {
            offboard: OFFBOARD,
            land: LAND,
            hold: LOITER,
            takeoff: Some(TAKEOFF),
        })
    }

    fn flying(mode: u32) -> ModeReport {
        ModeReport {
            custom_mode: mode,
            armed: true,
            was_airborne: true,
        }
    }

    /// A watch with Kestrel flying the vehicle in OFFBOARD.
    fn in_offboard() -> ControlWatch {
        let mut w = watch();
        assert_eq!(w.report(flying(LOITER)), None);
        assert!(!w.in_control(), "armed in the pilot's mode: not Kestrel's");
        w.commanded(OFFBOARD);
        assert_eq!(w.report(flying(LOITER)), None, "not switched yet");
        assert_eq!(w.report(flying(OFFBOARD)), None);
        assert!(w.in_control());
        w
    }

    #[test]
    fn a_mode_kestrel_did_not_ask_for_is_a_takeover_once() {
        let mut w = in_offboard();
        assert_eq!(w.report(flying(LOITER)), Some(Takeover::Mode(LOITER)));
        assert!(!w.in_control());
        assert_eq!(w.report(flying(LOITER)), None, "reported once");
        assert_eq!(w.report(flying(POSCTL)), None, "the pilot's to change now");
    }

    #[test]
    fn kestrels_own_mode_changes_are_not_takeovers() {
        let mut w = in_offboard();
        w.commanded(LAND);
        assert_eq!(w.report(flying(OFFBOARD)), None, "LAND not shown yet");
        assert_eq!(w.report(flying(LAND)), None);
        assert!(w.in_control());
        let landed = ModeReport {
            custom_mode: LAND,
            armed: false,
            was_airborne: true,
        };
        assert_eq!(
            w.report(landed),
            None,
            "the autopilot disarms after landing"
        );
        assert!(!w.in_control());
        // PX4 announces AUTO.LOITER (CURRENT_MODE) before HEARTBEAT shows the disarm.
        let mut w = in_offboard();
        w.commanded(LAND);
        assert_eq!(w.report(flying(LAND)), None);
        let touched_down = ModeReport {
            custom_mode: LOITER,
            armed: true,
            was_airborne: false,
        };
        assert_eq!(w.report(touched_down), None);
        // A pilot stopping Kestrel's landing in the air takes the vehicle.
        let mut w = in_offboard();
        w.commanded(LAND);
        assert_eq!(w.report(flying(LAND)), None);
        assert_eq!(w.report(flying(POSCTL)), Some(Takeover::Mode(POSCTL)));
    }

    #[test]
    fn a_landing_on_setpoints_may_end_in_the_land_mode_or_a_disarm() {
        let mut w = in_offboard();
        w.landing_on_setpoints(true);
        assert_eq!(w.report(flying(LAND)), None, "PX4 at touchdown");
        let disarmed = ModeReport {
            custom_mode: LAND,
            armed: false,
            was_airborne: true,
        };
        assert_eq!(w.report(disarmed), None);
        assert!(!w.in_control());
        // Disarmed by the autopilot's land detector while still in OFFBOARD.
        let mut w = in_offboard();
        w.landing_on_setpoints(true);
        let disarmed = ModeReport {
            custom_mode: OFFBOARD,
            armed: false,
            was_airborne: true,
        };
        assert_eq!(w.report(disarmed), None);
        // A pilot's own mode during the landing is still a takeover.
        let mut w = in_offboard();
        w.landing_on_setpoints(true);
        assert_eq!(w.report(flying(POSCTL)), Some(Takeover::Mode(POSCTL)));
        // Once the landing is over (the hint is stale), the land mode is a takeover again.
        let mut w = in_offboard();
        w.landing_on_setpoints(true);
        w.landing_on_setpoints(false);
        assert_eq!(w.report(flying(LAND)), Some(Takeover::Mode(LAND)));
    }

    #[test]
    fn px4_ends_its_takeoff_in_hold_by_itself() {
        let mut w = watch();
        w.commanded(TAKEOFF);
        assert_eq!(w.report(flying(TAKEOFF)), None);
        assert!(w.in_control());
        assert_eq!(w.report(flying(LOITER)), None);
        assert!(w.in_control());
        assert_eq!(w.report(flying(POSCTL)), Some(Takeover::Mode(POSCTL)));
    }

    #[test]
    fn a_disarm_in_the_air_kestrel_did_not_ask_for_is_a_takeover() {
        let mut w = in_offboard();
        let disarmed = ModeReport {
            custom_mode: OFFBOARD,
            armed: false,
            was_airborne: true,
        };
        assert_eq!(w.report(disarmed), Some(Takeover::Disarmed));
        let mut w = in_offboard();
        w.arming_requested(false);
        assert_eq!(w.report(disarmed), None, "Kestrel asked for it");
        let mut w = in_offboard();
        let on_ground = ModeReport {
            was_airborne: false,
            ..disarmed
        };
        assert_eq!(w.report(on_ground), None, "auto-disarm on the ground");
    }

    #[test]
    fn what_happens_while_the_link_is_down_is_not_a_takeover() {
        let mut w = in_offboard();
        w.link_lost();
        assert_eq!(w.report(flying(LAND)), None, "the failsafe landed it");
        assert!(!w.in_control());
        // Kestrel asks for offboard again (the mission resumed): its again.
        assert_eq!(w.report(flying(OFFBOARD)), None);
        assert!(w.in_control());
        assert_eq!(w.report(flying(LOITER)), Some(Takeover::Mode(LOITER)));
    }

    #[test]
    fn taken_back_only_in_kestrels_mode() {
        let mut w = in_offboard();
        assert!(w.report(flying(LOITER)).is_some());
        w.commanded(OFFBOARD);
        assert_eq!(w.report(flying(LOITER)), None);
        assert!(!w.in_control());
        assert_eq!(w.report(flying(OFFBOARD)), None);
        assert!(w.in_control());
    }
}
