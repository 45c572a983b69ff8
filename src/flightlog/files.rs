//! Flight-log files: one per run, named by its start time, never overwritten, pruned to a limit.
//!
//! In: a directory, a kind (`kestrel-sim`, `kestrel-run`, ...), the format's extension (`jsonl`
//! or `mcap`) and the wall-clock start. Out: a file created exclusively as
//! `<kind>-YYYY-MM-DDTHH-MM-SSZ.<ext>` (UTC; `-2`, `-3` ... appended
//! when two runs start in the same second), the oldest logs of that kind beyond the limit
//! deleted (never the current one), and the list `GET /api/logs` serves. PX4 and ArduPilot keep
//! their logs the same way: a new file per flight, the oldest removed when too many.

use serde::Serialize;
use std::fs::{File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

/// Logs of one kind kept in a directory when the config does not say (`[drone] log_keep`).
pub const DEFAULT_KEEP: usize = 100;

/// Length of `YYYY-MM-DDTHH-MM-SSZ`.
const STAMP_LEN: usize = 20;

/// `t` as `YYYY-MM-DDTHH-MM-SSZ` (UTC; file-name safe, sorts by time).
pub fn stamp(t: SystemTime) -> String {
    let (date, [h, m, s]) = civil(t);
    format!("{date}T{h:02}-{m:02}-{s:02}Z")
}

/// `t` as RFC 3339 (`YYYY-MM-DDTHH:MM:SSZ`, UTC).
pub fn rfc3339(t: SystemTime) -> String {
    let (date, [h, m, s]) = civil(t);
    format!("{date}T{h:02}:{m:02}:{s:02}Z")
}

/// The UTC date (`YYYY-MM-DD`) and time of day of `t` (Howard Hinnant's days-to-civil).
fn civil(t: SystemTime) -> (String, [u64; 3]) {
    let secs = t.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    (
        format!("{year:04}-{month:02}-{day:02}"),
        [rem / 3600, rem % 3600 / 60, rem % 60],
    )
}

/// Seconds since 1970 of an RFC 3339 UTC time as [`rfc3339`] writes it (`YYYY-MM-DDTHH:MM:SSZ`).
pub fn parse_rfc3339(s: &str) -> Option<u64> {
    let b = s.as_bytes();
    let shape = b.len() == 20
        && [4, 7].iter().all(|&i| b.get(i) == Some(&b'-'))
        && b.get(10) == Some(&b'T')
        && [13, 16].iter().all(|&i| b.get(i) == Some(&b':'))
        && b.get(19) == Some(&b'Z');
    if !shape {
        return None;
    }
    let num = |r: std::ops::Range<usize>| s.get(r)?.parse::<i64>().ok();
    let (year, month, day) = (num(0..4)?, num(5..7)?, num(8..10)?);
    let (h, m, sec) = (num(11..13)?, num(14..16)?, num(17..19)?);
    if !(1..=12).contains(&month) || !(1..=31).contains(&day) || h > 23 || m > 59 || sec > 60 {
        return None;
    }
    // Days from civil (the inverse of `civil`).
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (month + 9) % 12;
    let doy = (153 * mp + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    u64::try_from(days * 86_400 + h * 3600 + m * 60 + sec).ok()
}

/// Creates a new log of `kind` in `dir` (made if missing), exclusively: an existing file is
/// never opened. `ext` is the format's extension (`jsonl`, `mcap`); logs of both formats count
/// as one kind for naming and pruning. Returns the file and its path.
pub fn create(dir: &Path, kind: &str, ext: &str, start: SystemTime) -> io::Result<(File, PathBuf)> {
    if !dir.as_os_str().is_empty() {
        std::fs::create_dir_all(dir)?;
    }
    let base = format!("{kind}-{}", stamp(start));
    for n in 1..1000 {
        let name = if n == 1 {
            format!("{base}.{ext}")
        } else {
            format!("{base}-{n}.{ext}")
        };
        if taken_in_other_format(dir, &name, ext) {
            continue;
        }
        let path = dir.join(name);
        match OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(file) => return Ok((file, path)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(io::Error::new(
        io::ErrorKind::AlreadyExists,
        format!("999 logs named {base} already in {}", dir.display()),
    ))
}

/// Whether the same-second name `name` is already used by a log of the other format (so that
/// `-2`, `-3` ... number a second's runs whatever their formats).
fn taken_in_other_format(dir: &Path, name: &str, ext: &str) -> bool {
    let Some(stem) = name.strip_suffix(ext) else {
        return false;
    };
    ["jsonl", "mcap"]
        .iter()
        .filter(|&&other| other != ext)
        .any(|other| dir.join(format!("{stem}{other}")).exists())
}

/// Opens a log at a path the user chose: a new file, or with `overwrite` the file truncated.
pub fn create_at(path: &Path, overwrite: bool) -> io::Result<File> {
    if overwrite {
        return File::create(path);
    }
    OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(|e| {
            if e.kind() == io::ErrorKind::AlreadyExists {
                io::Error::new(
                    e.kind(),
                    "the file exists (pass --log-overwrite to replace it, or leave out --log \
                     for a new log named by the start time)",
                )
            } else {
                e
            }
        })
}

/// A log named by [`create`]: its kind, start stamp and same-second number.
fn parse(name: &str) -> Option<(&str, &str, u32)> {
    let stem = name
        .strip_suffix(".jsonl")
        .or_else(|| name.strip_suffix(".mcap"))?;
    let (head, n) = match stem.rsplit_once('-') {
        Some((head, n)) if head.ends_with('Z') && n.bytes().all(|b| b.is_ascii_digit()) => {
            (head, n.parse().ok()?)
        }
        _ => (stem, 1),
    };
    let split = head.len().checked_sub(STAMP_LEN)?;
    let (kind, stamp) = (head.get(..split)?, head.get(split..)?);
    let kind = kind.strip_suffix('-')?;
    let b = stamp.as_bytes();
    let shape = b.len() == STAMP_LEN
        && b.get(10) == Some(&b'T')
        && b.get(19) == Some(&b'Z')
        && [4, 7, 13, 16].iter().all(|&i| b.get(i) == Some(&b'-'));
    (shape && kind.starts_with("kestrel")).then_some((kind, stamp, n))
}

/// One log file, as `GET /api/logs` lists it.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize, utoipa::ToSchema)]
pub struct LogEntry {
    pub name: String,
    pub size_bytes: u64,
    /// Wall-clock start (RFC 3339, UTC), from the name; `None` for a log named by `--log`.
    pub start_time: Option<String>,
    /// The log this run is writing.
    pub current: bool,
}

/// The logs in `dir` named by [`create`], plus `current`, newest first.
pub fn list(dir: &Path, current: Option<&Path>) -> io::Result<Vec<LogEntry>> {
    let read = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let mut out = Vec::new();
    let current_name = current.and_then(|p| p.file_name());
    for entry in std::fs::read_dir(read)? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let is_current = current_name.is_some_and(|c| *c == *name);
        let parsed = parse(&name);
        if parsed.is_none() && !is_current {
            continue;
        }
        let start_time = parsed.map(|(_, s, _)| {
            // YYYY-MM-DDTHH-MM-SSZ -> YYYY-MM-DDTHH:MM:SSZ
            let mut t = s.to_string();
            t.replace_range(13..14, ":");
            t.replace_range(16..17, ":");
            t
        });
        out.push(LogEntry {
            name,
            size_bytes: entry.metadata().map_or(0, |m| m.len()),
            start_time,
            current: is_current,
        });
    }
    out.sort_by(|a, b| {
        let key = |e: &LogEntry| parse(&e.name).map(|(_, s, n)| (s.to_string(), n));
        key(b).cmp(&key(a)).then_with(|| b.name.cmp(&a.name))
    });
    Ok(out)
}

/// Deletes the oldest logs of `kind` in `dir` so that at most `keep` remain, never `current`.
/// Returns what it deleted.
pub fn prune(dir: &Path, kind: &str, keep: usize, current: &Path) -> io::Result<Vec<PathBuf>> {
    let mut logs: Vec<(String, u32, PathBuf)> = list(dir, None)?
        .into_iter()
        .filter_map(|e| {
            let (k, s, n) = parse(&e.name)?;
            (k == kind).then(|| (s.to_string(), n, dir.join(&e.name)))
        })
        .collect();
    logs.sort();
    let excess = logs.len().saturating_sub(keep.max(1));
    let mut deleted = Vec::new();
    for (_, _, path) in logs.into_iter().take(excess) {
        if path.file_name() == current.file_name() {
            continue;
        }
        std::fs::remove_file(&path)?;
        deleted.push(path);
    }
    Ok(deleted)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use std::time::Duration;

    fn at(secs: u64) -> SystemTime {
        UNIX_EPOCH + Duration::from_secs(secs)
    }

    #[test]
    fn stamps_are_utc_and_file_name_safe() {
        assert_eq!(stamp(at(0)), "1970-01-01T00-00-00Z");
        assert_eq!(rfc3339(at(1_709_210_096)), "2024-02-29T12:34:56Z");
        assert_eq!(
            parse("kestrel-sim-2024-02-29T12-34-56Z-3.jsonl"),
            Some(("kestrel-sim", "2024-02-29T12-34-56Z", 3))
        );
        assert_eq!(parse("flight.jsonl"), None);
        assert_eq!(parse("kestrel-sim-0.jsonl"), None);
    }

    #[test]
    fn same_second_starts_get_their_own_files_and_pruning_keeps_the_current() {
        let dir = tempfile::tempdir().unwrap();
        let (_, a) = create(dir.path(), "kestrel-sim", "jsonl", at(100)).unwrap();
        let (_, b) = create(dir.path(), "kestrel-sim", "jsonl", at(100)).unwrap();
        let (_, c) = create(dir.path(), "kestrel-sim", "jsonl", at(200)).unwrap();
        let (_, run) = create(dir.path(), "kestrel-run", "jsonl", at(50)).unwrap();
        assert_ne!(a, b);
        let names: Vec<String> = list(dir.path(), Some(&c))
            .unwrap()
            .into_iter()
            .map(|e| e.name)
            .collect();
        assert_eq!(names.len(), 4);
        assert!(names[0].ends_with("00-03-20Z.jsonl"), "{names:?}");
        let deleted = prune(dir.path(), "kestrel-sim", 1, &c).unwrap();
        assert_eq!(deleted, vec![a.clone(), b.clone()]);
        assert!(c.exists() && run.exists());
        // The current log survives even when older than the limit allows.
        let (_, d) = create(dir.path(), "kestrel-sim", "jsonl", at(300)).unwrap();
        prune(dir.path(), "kestrel-sim", 1, &c).unwrap();
        assert!(c.exists() && d.exists());
    }

    #[test]
    fn an_explicit_path_is_not_overwritten_unless_asked() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("flight.jsonl");
        std::fs::write(&path, "{}\n").unwrap();
        let e = create_at(&path, false).unwrap_err();
        assert!(e.to_string().contains("--log-overwrite"), "{e}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "{}\n");
        create_at(&path, true).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "");
    }

    #[test]
    fn both_formats_share_the_names_of_a_kind() {
        let dir = tempfile::tempdir().unwrap();
        let (_, a) = create(dir.path(), "kestrel-sim", "jsonl", at(100)).unwrap();
        let (_, b) = create(dir.path(), "kestrel-sim", "mcap", at(100)).unwrap();
        assert!(b.to_string_lossy().ends_with("00-01-40Z-2.mcap"), "{b:?}");
        let (_, c) = create(dir.path(), "kestrel-sim", "mcap", at(200)).unwrap();
        let names: Vec<String> = list(dir.path(), None)
            .unwrap()
            .into_iter()
            .map(|e| e.name)
            .collect();
        assert_eq!(names.len(), 3, "{names:?}");
        let deleted = prune(dir.path(), "kestrel-sim", 1, &c).unwrap();
        assert_eq!(deleted, vec![a, b]);
    }

    #[test]
    fn rfc3339_reads_back_what_it_wrote() {
        for secs in [0u64, 951_782_400, 1_767_323_045, 4_102_444_799] {
            let t = UNIX_EPOCH + std::time::Duration::from_secs(secs);
            assert_eq!(parse_rfc3339(&rfc3339(t)), Some(secs));
        }
        assert_eq!(parse_rfc3339("2026-13-01T00:00:00Z"), None);
        assert_eq!(parse_rfc3339("2026-01-01 00:00:00Z"), None);
    }
}
