//! Reading a flight log of either format: JSON lines or MCAP, told apart by the file's magic.
//!
//! In: a path (or an MCAP file's bytes). Out: the log's records as JSON lines, the same bytes
//! the JSON-lines log of the run would hold, so `report` and `exploration::offline::evaluate` read one
//! format. Of an MCAP log only its `/kestrel/records` channel is read (`mcap_log`); one cut
//! short (a killed process: no summary, maybe a half-written chunk at the end) is read up to
//! the last record a reader can recover, and says so.

use super::mcap_log::RECORDS_TOPIC;
use std::io::{self, BufRead, Read};
use std::path::Path;

/// The two formats of a flight log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    JsonLines,
    Mcap,
}

/// The format of a file starting with `head` (its first bytes): MCAP by its magic, else JSON
/// lines.
pub fn format_of(head: &[u8]) -> Format {
    if head.starts_with(mcap::MAGIC) {
        Format::Mcap
    } else {
        Format::JsonLines
    }
}

/// The records of an MCAP log.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recovered {
    /// The records, one JSON line each, in file order.
    pub lines: Vec<u8>,
    /// The file ends before its summary (a process that did not close it), or in a damaged
    /// record: `lines` holds what came before.
    pub cut_short: bool,
}

/// The records channel of an MCAP file, as JSON lines (see [`Recovered`]).
pub fn records_from_mcap(bytes: &[u8]) -> Recovered {
    let mut out = Recovered::default();
    let options = mcap::read::Options::IgnoreEndMagic.into();
    let stream = match mcap::MessageStream::new_with_options(bytes, options) {
        Ok(s) => s,
        Err(_) => {
            out.cut_short = true;
            return out;
        }
    };
    for message in stream {
        match message {
            Ok(m) if m.channel.topic == RECORDS_TOPIC => {
                out.lines.extend_from_slice(&m.data);
                out.lines.push(b'\n');
            }
            Ok(_) => {}
            Err(_) => {
                out.cut_short = true;
                return out;
            }
        }
    }
    out.cut_short = mcap::read::footer(bytes).is_err();
    out
}

/// Opens a log of either format, refusing one larger than `max_bytes`, as a reader of JSON
/// lines. An MCAP log is read whole into memory; one cut short is logged as a warning and read
/// up to its cut.
pub fn open(path: &Path, max_bytes: u64) -> io::Result<Box<dyn BufRead + Send>> {
    let mut file = std::fs::File::open(path)?;
    let size = file.metadata()?.len();
    if size > max_bytes {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{size} bytes, more than the {max_bytes} read"),
        ));
    }
    let mut head = [0u8; 8];
    let n = read_head(&mut file, &mut head)?;
    let mut file = io::BufReader::new(file);
    if format_of(head.get(..n).unwrap_or_default()) == Format::JsonLines {
        let rest = io::Cursor::new(head.get(..n).unwrap_or_default().to_vec());
        return Ok(Box::new(io::BufReader::new(rest.chain(file))));
    }
    let mut bytes = head.get(..n).unwrap_or_default().to_vec();
    file.read_to_end(&mut bytes)?;
    let recovered = records_from_mcap(&bytes);
    if recovered.cut_short {
        tracing::warn!(
            "{} was not closed (no MCAP summary, or a damaged end): read up to its last \
             complete chunk",
            path.display()
        );
    }
    Ok(Box::new(io::Cursor::new(recovered.lines)))
}

/// A whole log of either format as JSON-lines text (see [`open`]).
pub fn read_to_string(path: &Path, max_bytes: u64) -> io::Result<String> {
    let mut text = String::new();
    open(path, max_bytes)?.read_to_string(&mut text)?;
    Ok(text)
}

/// Reads up to `head.len()` bytes (fewer only at the end of the file).
fn read_head(file: &mut std::fs::File, head: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < head.len() {
        match file.read(head.get_mut(n..).unwrap_or_default())? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_lines_are_read_as_they_are() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("f.jsonl");
        let text = "{\"t\":0,\"drone\":null,\"type\":\"header\"}\n{\"t\":1}\n";
        std::fs::write(&path, text).expect("write");
        assert_eq!(read_to_string(&path, 1 << 20).expect("read"), text);
        assert!(open(&path, 4).is_err());
        assert_eq!(format_of(b"{\"t\""), Format::JsonLines);
        assert_eq!(format_of(mcap::MAGIC), Format::Mcap);
    }

    #[test]
    fn garbage_after_the_magic_is_an_empty_log_cut_short() {
        let mut bytes = mcap::MAGIC.to_vec();
        bytes.extend_from_slice(b"not a record");
        let back = records_from_mcap(&bytes);
        assert!(back.lines.is_empty());
        assert!(back.cut_short);
    }
}
