//! Services a behavior asks for on one tick and reads the answer of on a later tick, so that
//! slow work (path planning, the fleet's frontier allocator) never runs on the control tick.
//!
//! In: calls filed by behaviors through the [`ServiceDesk`] in their context, and answers the
//! host delivers before a tick. Out: the calls of this tick (the core hands them to the host,
//! which runs them on its workers) and, for each behavior, the answer to its ticket.
//!
//! A ticket cancels its call when dropped, so a behavior that is stopped, preempted or replans
//! never waits for (or pays for) an answer it no longer wants.

use std::cell::{Cell, RefCell};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::exploration::online::service::{Allocation, ExploreError, ExploreRequest};
use crate::exploration::online::worker::ExploreJob;
use crate::mapping::server::MapSnapshot;
use crate::planning::worker::{PlanJob, PlanWorker};
use crate::planning::{PlanError, PlanRequest, PlannedPath};

/// Most answers kept for tickets not claimed yet (a paused behavior claims on resume).
const MAX_WAITING_ANSWERS: usize = 64;

/// A call to a service, filed this tick.
#[derive(Debug)]
pub enum ServiceCall {
    Plan(PlanJob),
    /// A question for the fleet's frontier allocator (answered by the host).
    Explore(ExploreJob),
}

impl ServiceCall {
    /// Hands a plan to the worker that runs it; other calls come back for the host to answer.
    pub fn submit(self, drone: usize, planner: &mut PlanWorker) -> Option<ExploreJob> {
        match self {
            ServiceCall::Plan(job) => {
                planner.submit(drone, job);
                None
            }
            ServiceCall::Explore(job) => Some(job),
        }
    }
}

/// The answer to a call.
#[derive(Debug, Clone, PartialEq)]
pub enum ServiceAnswer {
    Plan(Result<PlannedPath, PlanError>),
    Explore(Result<Allocation, ExploreError>),
}

/// A behavior's claim on one answer; dropping it cancels the call.
#[derive(Debug)]
pub struct Ticket {
    id: u64,
    cancel: Arc<AtomicBool>,
}

impl Drop for Ticket {
    fn drop(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
}

struct Waiting {
    ticket: u64,
    answer: ServiceAnswer,
    cancel: Arc<AtomicBool>,
}

/// Where a core's behaviors file calls and find answers. Behaviors only hold `&` to it (it is
/// in the [`super::BehaviorContext`]), hence the cells; it never leaves its core's thread.
#[derive(Default)]
pub struct ServiceDesk {
    next_ticket: Cell<u64>,
    calls: RefCell<Vec<ServiceCall>>,
    answers: RefCell<Vec<Waiting>>,
}

impl ServiceDesk {
    fn ticket(&self) -> Ticket {
        let id = self.next_ticket.get().wrapping_add(1);
        self.next_ticket.set(id);
        Ticket {
            id,
            cancel: Arc::new(AtomicBool::new(false)),
        }
    }

    /// Files a path request on `map`; the answer comes on a later tick.
    pub fn plan(&self, request: PlanRequest, map: Arc<MapSnapshot>) -> Ticket {
        let ticket = self.ticket();
        self.calls.borrow_mut().push(ServiceCall::Plan(PlanJob {
            ticket: ticket.id,
            request,
            map,
            cancel: ticket.cancel.clone(),
        }));
        ticket
    }

    /// Asks the fleet's frontier allocator; the answer comes on a later tick.
    pub fn explore(&self, request: ExploreRequest) -> Ticket {
        let ticket = self.ticket();
        self.calls
            .borrow_mut()
            .push(ServiceCall::Explore(ExploreJob {
                ticket: ticket.id,
                request,
                cancel: ticket.cancel.clone(),
            }));
        ticket
    }

    fn take(&self, ticket: &Ticket) -> Option<ServiceAnswer> {
        let mut answers = self.answers.borrow_mut();
        let at = answers.iter().position(|w| w.ticket == ticket.id)?;
        Some(answers.remove(at).answer)
    }

    /// The plan answering `ticket`, once it has arrived.
    pub fn take_plan(&self, ticket: &Ticket) -> Option<Result<PlannedPath, PlanError>> {
        match self.take(ticket)? {
            ServiceAnswer::Plan(result) => Some(result),
            ServiceAnswer::Explore(_) => None,
        }
    }

    /// The allocation answering `ticket`, once it has arrived.
    pub fn take_allocation(&self, ticket: &Ticket) -> Option<Result<Allocation, ExploreError>> {
        match self.take(ticket)? {
            ServiceAnswer::Explore(result) => Some(result),
            ServiceAnswer::Plan(_) => None,
        }
    }

    /// The calls filed since the last drain.
    pub fn drain_calls(&self) -> Vec<ServiceCall> {
        std::mem::take(&mut *self.calls.borrow_mut())
    }

    /// Hands an answer to the behavior holding `ticket`; answers nobody waits for any more
    /// (cancelled tickets) are dropped, and only the newest are kept.
    pub fn deliver(&self, ticket: u64, answer: ServiceAnswer, cancel: Arc<AtomicBool>) {
        let mut answers = self.answers.borrow_mut();
        answers.retain(|w| !w.cancel.load(Ordering::Relaxed));
        if cancel.load(Ordering::Relaxed) {
            return;
        }
        if answers.len() >= MAX_WAITING_ANSWERS {
            answers.remove(0);
        }
        answers.push(Waiting {
            ticket,
            answer,
            cancel,
        });
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::mapping::config::MapConfig;
    use crate::mapping::server::MapServer;
    use crate::planning::{PlannerKind, UnknownPolicy};
    use nalgebra::Vector3;

    fn request() -> PlanRequest {
        PlanRequest {
            start_enu_m: Vector3::zeros(),
            goal_enu_m: Vector3::new(1.0, 0.0, 0.0),
            flight_height_m: 0.0,
            safety_distance_m: 0.0,
            unknown: UnknownPolicy::Blocked,
            kind: PlannerKind::AStar,
            max_map_age_s: None,
            shadow_m: 0.0,
        }
    }

    fn answer_to(desk: &ServiceDesk, call: ServiceCall) {
        let ServiceCall::Plan(job) = call else {
            panic!("not a plan");
        };
        desk.deliver(
            job.ticket,
            ServiceAnswer::Plan(Err(PlanError::NoPath)),
            job.cancel,
        );
    }

    #[test]
    fn an_answer_reaches_its_ticket_once() {
        let desk = ServiceDesk::default();
        let map = MapServer::new(&MapConfig::open_field().unwrap()).snapshot();
        let a = desk.plan(request(), map.clone());
        let b = desk.plan(request(), map);
        let calls = desk.drain_calls();
        assert_eq!(calls.len(), 2);
        assert!(desk.drain_calls().is_empty());
        for c in calls.into_iter().rev() {
            answer_to(&desk, c);
        }
        assert_eq!(desk.take_plan(&a), Some(Err(PlanError::NoPath)));
        assert_eq!(desk.take_plan(&a), None, "taken");
        assert!(desk.take_plan(&b).is_some());
    }

    #[test]
    fn a_dropped_ticket_cancels_its_call_and_its_answer_is_not_kept() {
        let desk = ServiceDesk::default();
        let map = MapServer::new(&MapConfig::open_field().unwrap()).snapshot();
        let ticket = desk.plan(request(), map);
        drop(ticket);
        let Some(ServiceCall::Plan(job)) = desk.drain_calls().pop() else {
            panic!("not a plan");
        };
        assert!(job.cancel.load(Ordering::Relaxed));
        desk.deliver(
            job.ticket,
            ServiceAnswer::Plan(Err(PlanError::Cancelled)),
            job.cancel,
        );
        assert!(desk.answers.borrow().is_empty());
    }
}
