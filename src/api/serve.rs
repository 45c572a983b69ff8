//! Serving the API over TCP with bounds on what a client can hold before it is authenticated.
//!
//! In: the listener, the router, the `[api]` limits, a stop signal. Out: HTTP/1.1 connections
//! (WebSocket upgrades included), at most `max_connections` at once: further clients wait in
//! the kernel's listen backlog, holding no descriptor of Kestrel's. A request's head must arrive
//! within `header_read_timeout_s` of the connection opening or of the previous answer (idle
//! and slowloris connections are closed), and a connection quiet for `idle_timeout_s` is
//! closed (`api::quiet`). On stop: no new connections, open ones finish their request.

use super::quiet::Quiet;
use crate::config::ApiSection;
use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::{watch, Semaphore};

/// How long stopping waits for open connections to finish.
const STOP_GRACE: Duration = Duration::from_secs(5);
/// After a failed accept (out of descriptors, say), wait this long before the next one.
const ACCEPT_BACKOFF: Duration = Duration::from_millis(100);

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConnLimits {
    pub max_connections: usize,
    pub header_read_timeout: Duration,
    pub idle_timeout: Duration,
}

impl From<&ApiSection> for ConnLimits {
    fn from(api: &ApiSection) -> Self {
        Self {
            max_connections: api.max_connections.max(1),
            header_read_timeout: Duration::from_secs_f64(api.header_read_timeout_s),
            idle_timeout: Duration::from_secs_f64(api.idle_timeout_s),
        }
    }
}

/// Serves `app` on `listener` until `stop` becomes true.
pub async fn serve(
    listener: TcpListener,
    app: Router,
    limits: ConnLimits,
    mut stop: watch::Receiver<bool>,
) {
    let slots = Arc::new(Semaphore::new(limits.max_connections));
    let mut full = false;
    loop {
        if slots.available_permits() == 0 && !full {
            tracing::warn!(
                "API: {} connections open, the most served at once ([api] max_connections); \
                 new clients wait",
                limits.max_connections
            );
        }
        full = slots.available_permits() == 0;
        let slot = tokio::select! {
            slot = slots.clone().acquire_owned() => match slot {
                Ok(s) => s,
                Err(_) => break,
            },
            () = stopped(&mut stop) => break,
        };
        let tcp = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((tcp, _)) => tcp,
                Err(e) => {
                    tracing::warn!("API: accepting a connection: {e}");
                    tokio::time::sleep(ACCEPT_BACKOFF).await;
                    continue;
                }
            },
            () = stopped(&mut stop) => break,
        };
        let io = Quiet::new(tcp, limits.idle_timeout, slot);
        tokio::spawn(connection(io, app.clone(), limits, stop.clone()));
    }
    let all = u32::try_from(limits.max_connections).unwrap_or(u32::MAX);
    if tokio::time::timeout(STOP_GRACE, slots.acquire_many(all))
        .await
        .is_err()
    {
        tracing::warn!("API: stopping with connections still open");
    }
}

/// One connection, from its first request to its last (or to its upgrade).
async fn connection(io: Quiet, app: Router, limits: ConnLimits, mut stop: watch::Receiver<bool>) {
    let mut builder = http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(limits.header_read_timeout);
    let conn = builder
        .serve_connection(TokioIo::new(io), TowerToHyperService::new(app))
        .with_upgrades();
    tokio::pin!(conn);
    let ended = tokio::select! {
        ended = conn.as_mut() => Some(ended),
        () = stopped(&mut stop) => None,
    };
    let ended = match ended {
        Some(ended) => ended,
        None => {
            conn.as_mut().graceful_shutdown();
            conn.await
        }
    };
    if let Err(e) = ended {
        // A client that went away or was timed out: its business, not an error of Kestrel's.
        tracing::debug!("API connection ended: {e}");
    }
}

/// Resolves once `stop` is true (or its sender is gone).
async fn stopped(stop: &mut watch::Receiver<bool>) {
    let _ = stop.wait_for(|s| *s).await;
}
