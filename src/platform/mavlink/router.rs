//! Routing for ground stations: Kestrel between the flight controller and a GCS.
//!
//! In: every frame from the autopilot (a broadcast channel filled by the link's reader) and the
//! frames a ground station sends. Out: the autopilot's frames, byte for byte, to each endpoint
//! (`udpout:127.0.0.1:14550` for QGroundControl on this machine), and the ground station's
//! frames to the autopilot, as mavlink-router does. A slow endpoint loses frames, never
//! slows the autopilot link.

use super::link::{open, Outbound};
use mavlink::{AsyncMavConnection, MAVLinkMessageRaw};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{broadcast, mpsc};

const RETRY: Duration = Duration::from_secs(1);

/// Frames kept for an endpoint that falls behind.
pub const ROUTER_QUEUE: usize = 1024;

/// Serves one endpoint until the autopilot link ends.
pub async fn endpoint_task(
    endpoint: String,
    mut from_autopilot: broadcast::Receiver<Arc<MAVLinkMessageRaw>>,
    to_autopilot: mpsc::Sender<Outbound>,
) {
    loop {
        let conn = match open(&endpoint).await {
            Ok(c) => Arc::new(c),
            Err(e) => {
                tracing::warn!(target: "mavlink", "ground station endpoint {endpoint}: {e}");
                tokio::time::sleep(RETRY).await;
                continue;
            }
        };
        tracing::info!(target: "mavlink", "forwarding to ground station endpoint {endpoint}");
        let reader_conn = conn.clone();
        let to_ap = to_autopilot.clone();
        let mut reader = tokio::spawn(async move {
            while let Ok(raw) = reader_conn.recv_raw().await {
                if to_ap.send(Outbound::Raw(Arc::new(raw))).await.is_err() {
                    break;
                }
            }
        });
        loop {
            tokio::select! {
                r = from_autopilot.recv() => match r {
                    Ok(raw) => {
                        if conn.send_raw(&raw).await.is_err() {
                            break;
                        }
                    }
                    Err(broadcast::error::RecvError::Lagged(n)) => {
                        tracing::debug!(target: "mavlink", "{endpoint}: {n} frames skipped");
                    }
                    Err(broadcast::error::RecvError::Closed) => {
                        reader.abort();
                        return;
                    }
                },
                _ = &mut reader => break,
            }
        }
        reader.abort();
        tokio::time::sleep(RETRY).await;
    }
}
