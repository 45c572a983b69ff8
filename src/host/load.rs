//! The handle's way to load a mission: validated off the control loop (a 1000-item mission
//! costs more than a tick), then loaded on it by [`Host::load_validated`], which ends where
//! [`Host::load_mission`] does.
//!
//! In: a mission (JSON) and [`LoadOptions`]. Out: the [`Uploaded`] answer, or the
//! [`HostError`] the loop's own path would have given (an unknown target at `/target`, every
//! validation problem, a refusal).
//!
//! [`Host::load_validated`]: super::Host::load_validated
//! [`Host::load_mission`]: super::Host::load_mission

use super::engine::{Command, HostError, LoadOptions, Uploaded, ValidatedUpload};
use super::runtime::HostHandle;
use crate::mission::validate::validate_value;
use crate::mission::{ContextSnapshot, ValidMission, ValidationError};
use serde_json::Value;

/// Missions validated at once (each on a blocking thread): more wait their turn.
static VALIDATIONS: tokio::sync::Semaphore = tokio::sync::Semaphore::const_new(2);

type Validated = (
    Value,
    Result<ValidMission, Vec<ValidationError>>,
    ContextSnapshot,
);

impl HostHandle {
    /// Validates `mission` off the loop against its target's context, then loads it (and
    /// starts it with `options.start`).
    pub async fn load_mission(
        &self,
        mission: Value,
        options: LoadOptions,
    ) -> Result<Uploaded, HostError> {
        let target = match mission.get("target") {
            Some(Value::String(t)) => Some(t.clone()),
            _ => None,
        };
        let (drone, snapshot) = self
            .call(|reply| Command::LoadContext {
                target: target.clone(),
                reply,
            })
            .await?;
        let (mission, valid, snapshot) = validate_off_loop(mission, snapshot).await?;
        let valid = valid.map_err(HostError::Invalid)?;
        if target.is_none() {
            return Err(HostError::Invalid(vec![ValidationError {
                pointer: "/target".into(),
                message: "missing target".into(),
            }]));
        }
        let upload = Box::new(ValidatedUpload {
            drone,
            mission,
            valid,
            snapshot,
            options,
        });
        self.call(|reply| Command::LoadValidated { upload, reply })
            .await
    }
}

async fn validate_off_loop(
    mission: Value,
    snapshot: ContextSnapshot,
) -> Result<Validated, HostError> {
    let _turn = VALIDATIONS
        .acquire()
        .await
        .map_err(|_| HostError::Unavailable("validation stopped".into()))?;
    tokio::task::spawn_blocking(move || {
        let valid = validate_value(&mission, &snapshot.context());
        (mission, valid, snapshot)
    })
    .await
    .map_err(|_| HostError::Unavailable("validating the mission failed".into()))
}
