//! Kestrel's own STATUSTEXT: what it tells the ground station, without I/O.
//!
//! In: texts with a [`Severity`] (behavior and mission events, alerts: `host::announce` words
//! them) and the time. Out: STATUSTEXT messages from Kestrel's component, `Kestrel: ` first,
//! ASCII only, split into 50-byte chunks that share one nonzero MAVLink 2 `id` and count up in
//! `chunk_seq` (a text of 50 bytes or less is one chunk with `id` 0, as the spec says). At most
//! [`RATE_PER_S`] frames a second on average (a [`TokenBucket`] of [`BURST`]); texts wait in a
//! queue of [`QUEUE`] that drops its oldest text when full, counted. QGroundControl shows them
//! in its message list, reassembled, with the sender's component.

use mavlink::dialects::ardupilotmega::{MavSeverity, STATUSTEXT_DATA};
use std::collections::VecDeque;
use std::time::Duration;

/// Put before every text, so the operator tells Kestrel's words from the autopilot's.
pub const PREFIX: &str = "Kestrel: ";
/// Bytes of text in one STATUSTEXT.
pub const CHUNK: usize = 50;
/// Longest text sent, in bytes (four chunks); a longer one is cut and ends in `...`.
pub const MAX_TEXT: usize = 4 * CHUNK;
/// Frames a second on average: a few, so the texts never crowd the autopilot link.
pub const RATE_PER_S: f64 = 4.0;
/// Frames sent at once after a quiet spell (one longest text and its terminating chunk fit).
pub const BURST: f64 = 8.0;
/// Texts waiting for the bucket; the oldest goes when a new one finds the queue full.
pub const QUEUE: usize = 16;

/// How much a text matters, as the ground station colours it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Severity {
    /// A failure: a behavior or mission that failed.
    Error,
    /// An alert (safety override, collision) or a behavior aborted.
    Warning,
    /// A mission's state: started, paused, resumed, finished.
    Notice,
    /// A behavior started, paused, resumed or succeeded.
    Info,
}

impl Severity {
    pub fn mav(self) -> MavSeverity {
        match self {
            Self::Error => MavSeverity::MAV_SEVERITY_ERROR,
            Self::Warning => MavSeverity::MAV_SEVERITY_WARNING,
            Self::Notice => MavSeverity::MAV_SEVERITY_NOTICE,
            Self::Info => MavSeverity::MAV_SEVERITY_INFO,
        }
    }
}

/// One text for the ground station, without the prefix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StatusText {
    pub severity: Severity,
    pub text: String,
}

/// `Kestrel: ` and the text, as ASCII of at most [`MAX_TEXT`] bytes (`…` becomes `...`,
/// control characters a space, anything else outside ASCII `?`): a chunk boundary then never
/// splits a character, and every chunk reads on its own too.
pub fn wording(text: &str) -> Vec<u8> {
    let mut out: Vec<u8> = PREFIX.bytes().collect();
    for c in text.chars() {
        match c {
            '…' => out.extend_from_slice(b"..."),
            c if c.is_ascii_control() || c.is_whitespace() => out.push(b' '),
            c if c.is_ascii() => out.push(c as u8),
            _ => out.push(b'?'),
        }
    }
    if out.len() > MAX_TEXT {
        out.truncate(MAX_TEXT - 3);
        out.extend_from_slice(b"...");
    }
    out
}

/// The STATUSTEXT chunks of `text` (bytes, as [`wording`] makes them). One chunk: `id` 0.
/// Several: all with `id` (nonzero), `chunk_seq` 0, 1, ...; the last is shorter than
/// [`CHUNK`] and so NUL-terminated, or, when the text fills its chunks exactly, an empty chunk
/// follows to end it (a receiver takes a NUL as the end of the text).
pub fn chunks(text: &[u8], severity: MavSeverity, id: u16) -> Vec<STATUSTEXT_DATA> {
    let frame = |part: &[u8], id: u16, seq: usize| {
        let mut bytes = [0u8; CHUNK];
        for (b, p) in bytes.iter_mut().zip(part) {
            *b = *p;
        }
        STATUSTEXT_DATA {
            severity,
            text: bytes.into(),
            id,
            chunk_seq: u8::try_from(seq).unwrap_or(u8::MAX),
        }
    };
    if text.len() <= CHUNK {
        return vec![frame(text, 0, 0)];
    }
    let mut out: Vec<STATUSTEXT_DATA> = text
        .chunks(CHUNK)
        .enumerate()
        .map(|(seq, part)| frame(part, id, seq))
        .collect();
    if text.len().is_multiple_of(CHUNK) {
        out.push(frame(&[], id, out.len()));
    }
    out
}

/// A token bucket: `rate_per_s` tokens a second, at most `capacity` kept.
#[derive(Debug, Clone)]
pub struct TokenBucket {
    rate_per_s: f64,
    capacity: f64,
    tokens: f64,
    last: Option<Duration>,
}

impl TokenBucket {
    /// Starts full.
    pub fn new(rate_per_s: f64, capacity: f64) -> Self {
        Self {
            rate_per_s,
            capacity,
            tokens: capacity,
            last: None,
        }
    }

    /// Takes `n` tokens if there are that many now; otherwise takes none.
    pub fn try_take(&mut self, now: Duration, n: usize) -> bool {
        let elapsed = self
            .last
            .map_or(0.0, |t| now.saturating_sub(t).as_secs_f64());
        self.last = Some(now);
        self.tokens = (self.tokens + elapsed * self.rate_per_s).min(self.capacity);
        let n = n as f64;
        if self.tokens >= n {
            self.tokens -= n;
            true
        } else {
            false
        }
    }
}

/// The texts waiting to go out, and the bucket that lets them.
#[derive(Debug, Clone)]
pub struct Outbox {
    queue: VecDeque<StatusText>,
    bucket: TokenBucket,
    last_id: u16,
    dropped: u64,
}

impl Default for Outbox {
    fn default() -> Self {
        Self {
            queue: VecDeque::with_capacity(QUEUE),
            bucket: TokenBucket::new(RATE_PER_S, BURST),
            last_id: 0,
            dropped: 0,
        }
    }
}

impl Outbox {
    /// Queues a text; when the queue is full the oldest text is dropped (returns false).
    pub fn push(&mut self, text: StatusText) -> bool {
        let room = self.queue.len() < QUEUE;
        if !room {
            self.queue.pop_front();
            self.dropped += 1;
        }
        self.queue.push_back(text);
        room
    }

    /// The frames the bucket lets out now, whole texts in order.
    pub fn poll(&mut self, now: Duration) -> Vec<STATUSTEXT_DATA> {
        let mut out = Vec::new();
        while let Some(next) = self.queue.front() {
            let bytes = wording(&next.text);
            let frames = chunks(&bytes, next.severity.mav(), self.next_id());
            if !self.bucket.try_take(now, frames.len()) {
                break;
            }
            if frames.len() > 1 {
                self.last_id = self.next_id();
            }
            self.queue.pop_front();
            out.extend(frames);
        }
        out
    }

    /// Texts dropped so far because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Texts waiting for the bucket (or for the link).
    pub fn len(&self) -> usize {
        self.queue.len()
    }

    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    fn next_id(&self) -> u16 {
        self.last_id.checked_add(1).unwrap_or(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: fn(u64) -> Duration = Duration::from_millis;

    fn text_of(frames: &[STATUSTEXT_DATA]) -> String {
        let bytes: Vec<u8> = frames.iter().flat_map(|f| f.text.to_vec()).collect();
        let end = bytes.iter().position(|b| *b == 0).unwrap_or(bytes.len());
        String::from_utf8(bytes[..end].to_vec()).unwrap()
    }

    #[test]
    fn a_short_text_is_one_chunk_with_id_zero() {
        let frames = chunks(
            b"Kestrel: land #3 started",
            MavSeverity::MAV_SEVERITY_INFO,
            7,
        );
        assert_eq!(frames.len(), 1);
        assert_eq!((frames[0].id, frames[0].chunk_seq), (0, 0));
        assert_eq!(text_of(&frames), "Kestrel: land #3 started");
        let exact = [b'a'; CHUNK];
        let frames = chunks(&exact, MavSeverity::MAV_SEVERITY_INFO, 7);
        assert_eq!((frames.len(), frames[0].id), (1, 0));
    }

    #[test]
    fn a_long_text_splits_into_50_byte_chunks_that_reassemble() {
        let long = wording(&"go_to #2 started (x=10, y=0, z=5) ".repeat(3));
        assert_eq!(long.len(), 9 + 34 * 3);
        let frames = chunks(&long, MavSeverity::MAV_SEVERITY_INFO, 42);
        assert_eq!(frames.len(), 3);
        for (i, f) in frames.iter().enumerate() {
            assert_eq!((f.id, usize::from(f.chunk_seq)), (42, i));
        }
        // Full chunks before the last, which is shorter and so ends in NUL.
        assert!(frames[..2].iter().all(|f| !f.text.contains(&0)));
        assert!(frames[2].text.contains(&0));
        assert_eq!(text_of(&frames).as_bytes(), &long[..]);
    }

    #[test]
    fn a_text_that_fills_its_chunks_gets_an_empty_last_chunk() {
        let frames = chunks(&[b'x'; 2 * CHUNK], MavSeverity::MAV_SEVERITY_INFO, 5);
        assert_eq!(frames.len(), 3);
        assert_eq!(frames[2].chunk_seq, 2);
        assert!(frames[2].text.iter().all(|b| *b == 0));
    }

    #[test]
    fn wording_is_ascii_prefixed_and_bounded() {
        assert_eq!(wording("go_to (x=1, …)\n"), b"Kestrel: go_to (x=1, ...) ");
        assert_eq!(wording("héllo"), b"Kestrel: h?llo");
        let long = wording(&"y".repeat(1000));
        assert_eq!(long.len(), MAX_TEXT);
        assert!(long.ends_with(b"y..."));
    }

    #[test]
    fn the_bucket_lets_a_burst_then_the_rate() {
        let mut b = TokenBucket::new(4.0, 8.0);
        assert!(b.try_take(MS(0), 8));
        assert!(!b.try_take(MS(0), 1));
        assert!(!b.try_take(MS(200), 1)); // 0.8 of a token
        assert!(b.try_take(MS(250), 1));
        // Never more than the capacity after a long quiet spell.
        assert!(!b.try_take(MS(60_000), 9));
        assert!(b.try_take(MS(60_000), 8));
    }

    #[test]
    fn the_outbox_paces_whole_texts_and_drops_the_oldest() {
        let mut out = Outbox::default();
        let text = |i: usize| StatusText {
            severity: Severity::Info,
            text: format!("hover #{i} started"),
        };
        for i in 0..QUEUE + 2 {
            let kept = out.push(text(i));
            assert_eq!(kept, i < QUEUE);
        }
        assert_eq!(out.dropped(), 2);
        // A burst of 8 one-chunk texts at once, then 4 a second; the first two were dropped.
        let first = out.poll(MS(0));
        assert_eq!(first.len(), 8);
        assert_eq!(text_of(&first[..1]), "Kestrel: hover #2 started");
        assert_eq!(out.poll(MS(10)).len(), 0);
        assert_eq!(out.poll(MS(1_010)).len(), 4);
        assert_eq!(out.poll(MS(2_100)).len(), 4);
        assert!(out.poll(MS(9_000)).is_empty());
    }

    #[test]
    fn chunked_texts_get_fresh_nonzero_ids() {
        let mut out = Outbox::default();
        let long = "a fairly long reason that will need a second chunk".to_string();
        for _ in 0..2 {
            out.push(StatusText {
                severity: Severity::Error,
                text: long.clone(),
            });
        }
        let frames = out.poll(MS(0));
        assert_eq!(frames.len(), 4);
        assert_eq!(frames[0].severity, MavSeverity::MAV_SEVERITY_ERROR);
        let ids: Vec<u16> = frames.iter().map(|f| f.id).collect();
        assert_eq!(ids, [1, 1, 2, 2]);
    }
}
