//! Commands from the API to the host and their answers: missions (upload, MissionUpdate,
//! list, get, delete), frames, simulator faults, the flight log, maps and explorations. Each is
//! carried out by the host's part for it (`missions`, `frames`, `maps`, `explore`).
//!
//! In: a [`Command`] with its one-shot reply. Out: the answer, and the changes in the host.

use super::frames::FrameRegistration;
use super::missions::{MissionView, Updated, Uploaded, ValidatedUpload};
use super::{Host, HostError};
use crate::mission::{ContextSnapshot, MissionUpdate};
use serde_json::Value;
use tokio::sync::oneshot;

pub type Reply<T> = oneshot::Sender<Result<T, HostError>>;
/// A request from the API (or the CLI) to the host.
#[derive(Debug)]
pub enum Command {
    /// What a mission for `target` is validated against (see [`Host::load_context`]).
    LoadContext {
        target: Option<String>,
        reply: Reply<(usize, ContextSnapshot)>,
    },
    /// Load a mission validated off the loop (see [`Host::load_validated`]).
    LoadValidated {
        upload: Box<ValidatedUpload>,
        reply: Reply<Uploaded>,
    },
    Update {
        update: MissionUpdate,
        reply: Reply<Updated>,
    },
    Delete {
        drone: Option<String>,
        mission_id: u32,
        reply: Reply<()>,
    },
    Missions {
        drone: Option<String>,
        reply: Reply<Vec<MissionView>>,
    },
    Mission {
        drone: Option<String>,
        mission_id: u32,
        reply: Reply<MissionView>,
    },
    SetFrame {
        frame: FrameRegistration,
        reply: Reply<()>,
    },
    Frames {
        reply: Reply<Vec<FrameRegistration>>,
    },
    /// Simulator only: cut or restore a drone's link.
    Fault {
        drone_id: String,
        link_lost: bool,
        reply: Reply<()>,
    },
    /// Flush the flight log so readers see every record.
    FlushLog { reply: Reply<()> },
    /// A copy of a drone's map (the one it plans on), or of the merged map when `drone` is
    /// absent.
    Map {
        drone: Option<String>,
        reply: Reply<super::MapView>,
    },
    /// The exploration as the frontier allocator last saw it: frontiers and the goal each
    /// drone holds.
    Exploration {
        reply: Reply<crate::exploration::online::service::ExplorationView>,
    },
    /// Start the `explore` behavior with `args` on `drones` (all or none).
    ExplorationStart {
        drones: Vec<String>,
        args: Value,
        reply: Reply<super::ExplorationStarted>,
    },
    /// Stop the exploration missions of `drones` (all or none); replies with the drones.
    ExplorationStop {
        drones: Vec<String>,
        reply: Reply<Vec<String>>,
    },
    /// What the exploration report is made of.
    ExplorationReport { reply: Reply<super::ReportInput> },
    /// Scans from outside (API) for a drone's next tick; replies with the number queued.
    Scans {
        drone: Option<String>,
        scans: Vec<crate::mapping::scan::RangeScan>,
        reply: Reply<usize>,
    },
}

impl Host {
    /// Simulator fault injection: cut (`true`) or restore drone `i`'s link.
    pub fn set_link_lost(&mut self, i: usize, lost: bool) -> Result<(), HostError> {
        self.fleet
            .set_link_lost(i, lost)
            .map_err(|e| HostError::NotSupported(e.to_string()))
    }

    /// Answers a command that may have changed what is saved: the change is handed to the
    /// store first, so by the time the API has the answer, `Sink::saved` covers it.
    fn answer<T>(&mut self, reply: Reply<T>, answer: Result<T, HostError>) {
        self.commit();
        let _ = reply.send(answer);
    }

    /// Carries out one command and answers it.
    pub fn handle(&mut self, command: Command) {
        // A client that gave up waiting dropped its receiver; nothing to answer then.
        match command {
            Command::LoadContext { target, reply } => {
                let _ = reply.send(self.load_context(target.as_deref()));
            }
            Command::LoadValidated { upload, reply } => {
                let answer = self.load_validated(*upload);
                self.answer(reply, answer);
            }
            Command::Update { update, reply } => {
                let answer = self.update(&update);
                self.answer(reply, answer);
            }
            Command::Delete {
                drone,
                mission_id,
                reply,
            } => {
                let answer = self.delete(drone.as_deref(), mission_id);
                self.answer(reply, answer);
            }
            Command::Missions { drone, reply } => {
                let _ = reply.send(self.views(drone.as_deref(), None, false));
            }
            Command::Mission {
                drone,
                mission_id,
                reply,
            } => {
                let _ = reply.send(self.mission_view(drone.as_deref(), mission_id));
            }
            Command::SetFrame { frame, reply } => {
                let answer = self.set_frame(frame);
                self.answer(reply, answer);
            }
            Command::Frames { reply } => {
                let _ = reply.send(Ok(self.frames.list().to_vec()));
            }
            Command::Fault {
                drone_id,
                link_lost,
                reply,
            } => {
                let result = self
                    .route(Some(&drone_id))
                    .and_then(|i| self.set_link_lost(i, link_lost));
                let _ = reply.send(result);
            }
            Command::FlushLog { reply } => {
                self.flush_log();
                let _ = reply.send(Ok(()));
            }
            Command::Map { drone, reply } => {
                let _ = reply.send(self.map_view(drone.as_deref()));
            }
            Command::Exploration { reply } => {
                let _ = reply.send(Ok(self.exploration_view()));
            }
            Command::ExplorationStart {
                drones,
                args,
                reply,
            } => {
                let answer = self.start_exploration(&drones, &args);
                self.answer(reply, answer);
            }
            Command::ExplorationStop { drones, reply } => {
                let answer = self.stop_exploration(&drones);
                self.answer(reply, answer);
            }
            Command::ExplorationReport { reply } => {
                let _ = reply.send(self.exploration_report());
            }
            Command::Scans {
                drone,
                scans,
                reply,
            } => {
                let _ = reply.send(self.queue_scans(drone.as_deref(), scans));
            }
        }
    }
}
