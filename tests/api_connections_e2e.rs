#![allow(clippy::unwrap_used, clippy::expect_used)]
//! End to end: idle and slowloris connections, more than `[api] max_connections`, neither
//! take the API down nor pile up: a normal request is still answered, the process holds at most
//! the limit, and the idle ones are closed after `header_read_timeout_s`.

mod support;

use std::time::{Duration, Instant};
use support::Kestrel;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

const LIMIT: usize = 16;
/// Idle and slowloris connections each: together 2.5 times the limit.
const EACH: usize = 20;

fn open_descriptors(pid: u32) -> usize {
    std::fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .count()
}

/// Sends a request head one byte every 200 ms, never finishing it; answers when the server
/// closed the connection (or after `max`).
async fn slowloris(port: u16, max: Duration) -> Option<Duration> {
    let start = Instant::now();
    let mut s = TcpStream::connect(("127.0.0.1", port)).await.unwrap();
    let head = b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa";
    for byte in head.iter().cycle() {
        if start.elapsed() > max {
            return None;
        }
        if s.write_all(&[*byte]).await.is_err() {
            return Some(start.elapsed());
        }
        let mut buf = [0u8; 512];
        match tokio::time::timeout(Duration::from_millis(200), s.read(&mut buf)).await {
            Ok(Ok(0)) | Ok(Err(_)) => return Some(start.elapsed()),
            // An answer (408 or 400) before the close is a close too.
            Ok(Ok(_)) => return Some(start.elapsed()),
            Err(_) => {}
        }
    }
    None
}

/// Connects and sends nothing; answers when the server closed the connection (or after `max`).
async fn idle(port: u16, max: Duration) -> Option<Duration> {
    let start = Instant::now();
    let mut s = TcpStream::connect(("127.0.0.1", port)).await.unwrap();
    let mut buf = [0u8; 512];
    loop {
        match tokio::time::timeout(max.saturating_sub(start.elapsed()), s.read(&mut buf)).await {
            Ok(Ok(0)) | Ok(Err(_)) => return Some(start.elapsed()),
            Ok(Ok(_)) => continue,
            Err(_) => return None,
        }
    }
}

#[tokio::test]
async fn idle_and_slowloris_connections_beyond_the_limit_are_closed_and_the_api_answers() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("kestrel.toml");
    std::fs::write(
        &config,
        format!(
            "[api]\nmax_connections = {LIMIT}\nheader_read_timeout_s = 1.0\nidle_timeout_s = 5.0\n"
        ),
    )
    .unwrap();
    let k = Kestrel::sim(dir.path(), "", &["--config", config.to_str().unwrap()]).await;
    let pid = k.process.0.id();
    // Kestrel opens its last files (flight log, stores) in its first ticks: count from after.
    tokio::time::sleep(Duration::from_secs(1)).await;
    let before = open_descriptors(pid);
    let max = Duration::from_secs(20);
    let mut attackers = Vec::new();
    for _ in 0..EACH {
        attackers.push(tokio::spawn(idle(k.port, max)));
        attackers.push(tokio::spawn(slowloris(k.port, max)));
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    let held = open_descriptors(pid) - before;
    assert!(
        held <= LIMIT,
        "{held} descriptors for {LIMIT} connections at most"
    );

    let asked = Instant::now();
    let (code, health) = k.get("/api/health").await;
    assert_eq!(code, 200, "{health}");
    assert!(
        asked.elapsed() < Duration::from_secs(8),
        "answered only after {:?}",
        asked.elapsed()
    );

    for a in attackers {
        let closed = a.await.unwrap();
        let after = closed.expect("an idle or slowloris connection was never closed");
        assert!(after < Duration::from_secs(12), "closed after {after:?}");
    }
    // Every slot is back: a connection that stays idle after its request is closed too.
    let mut s = TcpStream::connect(("127.0.0.1", k.port)).await.unwrap();
    s.write_all(b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        .await
        .unwrap();
    let start = Instant::now();
    let mut answer = Vec::new();
    let read = tokio::time::timeout(Duration::from_secs(10), s.read_to_end(&mut answer)).await;
    assert!(read.is_ok(), "a keep-alive connection left open");
    assert!(String::from_utf8_lossy(&answer).starts_with("HTTP/1.1 200"));
    assert!(
        start.elapsed() >= Duration::from_millis(900),
        "{:?}",
        start.elapsed()
    );
}
