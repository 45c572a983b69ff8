//! What an acknowledgement promises: a change the API answers for (a mission uploaded, a
//! MissionUpdate, a deletion, a frame) is on disk before the answer, or the answer says it is
//! not.
//!
//! In: the API's state (its store, if any). Out: [`Durability`], flattened into the answers
//! (`"durable": true`, or `false` with `"not_durable": "why"`).

use super::ApiState;
use crate::host::store::Saved;
use serde::Serialize;
use std::time::Duration;

/// Longest wait for the disk before answering anyway, saying the change is not saved yet.
const SAVE_WAIT: Duration = Duration::from_secs(5);

#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Durability {
    /// The change is on disk (file and directory synced): it survives a crash or power loss.
    pub durable: bool,
    /// Why it is not (no state directory, the save failed and is retried, the disk is slow).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_durable: Option<String>,
}

/// Waits until every change made so far is saved (at most [`SAVE_WAIT`]). The host hands a
/// command's changes to the store before it answers, so a handler that calls this after the
/// host's answer waits for its own change.
pub async fn changes_saved(s: &ApiState) -> Durability {
    let reason = match &s.store {
        None => "no state directory: kept in memory only".to_string(),
        Some(store) => match store.saved(SAVE_WAIT).await {
            Saved::Durable => {
                return Durability {
                    durable: true,
                    not_durable: None,
                }
            }
            Saved::Failed(e) => format!("saving failed ({e}); retrying, see GET /api/health"),
            Saved::Pending => format!(
                "not on disk after {} s; still being saved, see GET /api/health",
                SAVE_WAIT.as_secs()
            ),
        },
    };
    Durability {
        durable: false,
        not_durable: Some(reason),
    }
}
