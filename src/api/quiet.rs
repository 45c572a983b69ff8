//! A TCP connection that closes itself when quiet for too long, and holds its slot of the
//! connection limit while it lives.
//!
//! In: the accepted stream, the idle limit, the limit's permit. Out: the same stream (read and
//! write) whose pending read or write fails with `TimedOut` once nothing was read or written
//! for the idle limit; dropping it (the connection ended, or a WebSocket upgraded from it
//! ended) gives the slot back.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tokio::sync::OwnedSemaphorePermit;
use tokio::time::{Instant, Sleep};

pub struct Quiet {
    io: TcpStream,
    limit: Duration,
    deadline: Pin<Box<Sleep>>,
    _slot: OwnedSemaphorePermit,
}

impl Quiet {
    pub fn new(io: TcpStream, limit: Duration, slot: OwnedSemaphorePermit) -> Self {
        Self {
            io,
            limit,
            deadline: Box::pin(tokio::time::sleep(limit)),
            _slot: slot,
        }
    }

    /// Something moved: the quiet time starts again.
    fn moved(&mut self) {
        let next = Instant::now() + self.limit;
        self.deadline.as_mut().reset(next);
    }

    /// What a pending operation answers: still pending, or an error once quiet too long.
    fn pending<T>(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<T>> {
        match self.deadline.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(io::Error::new(
                io::ErrorKind::TimedOut,
                format!("nothing read or written for {:?}", self.limit),
            ))),
            Poll::Pending => Poll::Pending,
        }
    }

    fn after<T>(
        &mut self,
        cx: &mut Context<'_>,
        polled: Poll<io::Result<T>>,
    ) -> Poll<io::Result<T>> {
        match polled {
            Poll::Ready(r) => {
                self.moved();
                Poll::Ready(r)
            }
            Poll::Pending => self.pending(cx),
        }
    }
}

impl AsyncRead for Quiet {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let polled = Pin::new(&mut this.io).poll_read(cx, buf);
        this.after(cx, polled)
    }
}

impl AsyncWrite for Quiet {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let polled = Pin::new(&mut this.io).poll_write(cx, buf);
        this.after(cx, polled)
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let polled = Pin::new(&mut this.io).poll_flush(cx);
        this.after(cx, polled)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let polled = Pin::new(&mut this.io).poll_shutdown(cx);
        this.after(cx, polled)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    use tokio::sync::Semaphore;

    #[tokio::test]
    async fn a_connection_quiet_for_the_limit_fails_and_traffic_keeps_it_open() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let mut client = TcpStream::connect(listener.local_addr().unwrap())
            .await
            .unwrap();
        let (server, _) = listener.accept().await.unwrap();
        let slots = Arc::new(Semaphore::new(1));
        let slot = slots.clone().acquire_owned().await.unwrap();
        // No test clock in this build: the limit is real time, short.
        let limit = Duration::from_millis(300);
        let mut quiet = Quiet::new(server, limit, slot);
        let mut buf = [0u8; 4];
        for _ in 0..3 {
            tokio::time::sleep(limit * 2 / 3).await;
            client.write_all(b"ping").await.unwrap();
            quiet.read_exact(&mut buf).await.unwrap();
        }
        let started = Instant::now();
        let e = quiet.read(&mut buf).await.unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::TimedOut);
        let quiet_for = started.elapsed();
        assert!(quiet_for >= limit && quiet_for < limit * 5, "{quiet_for:?}");
        assert_eq!(slots.available_permits(), 0);
        drop(quiet);
        assert_eq!(slots.available_permits(), 1);
    }
}
