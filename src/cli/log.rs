//! `kestrel log`: flight-log files. `convert` turns a JSON-lines log into an MCAP log
//! (`flightlog::mcap_log`: the records on their own channel plus Foxglove's channels).

use anyhow::{bail, Context, Result};
use clap::Subcommand;
use kestrel::flightlog::files;
use kestrel::flightlog::mcap_log::McapLog;
use kestrel::flightlog::reader::{self, Format};
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum LogCommand {
    /// Convert a JSON-lines flight log to MCAP (for Foxglove): every record on
    /// /kestrel/records, plus poses, frames, events, goals and paths, maps (from the log's
    /// map records), frontiers, and a world's obstacles and known area, in Foxglove's schemas.
    Convert {
        /// The JSON-lines flight log.
        log: PathBuf,
        /// The MCAP file to write; must not exist yet (see --overwrite).
        #[arg(long)]
        out: PathBuf,
        /// Replace --out if it exists.
        #[arg(long)]
        overwrite: bool,
    },
}

pub fn run(command: LogCommand) -> Result<()> {
    match command {
        LogCommand::Convert {
            log,
            out,
            overwrite,
        } => {
            let records = convert(&log, &out, overwrite)?;
            println!(
                "{records} records of {} written to {}",
                log.display(),
                out.display()
            );
            Ok(())
        }
    }
}

/// Writes `out` from the records of `log` (a world its header names is looked for beside the
/// log, then in the working directory); returns how many there were.
fn convert(log: &Path, out: &Path, overwrite: bool) -> Result<usize> {
    let mut input = std::io::BufReader::new(
        std::fs::File::open(log).with_context(|| format!("opening {}", log.display()))?,
    );
    let mut head = Vec::new();
    (&mut input)
        .take(8)
        .read_to_end(&mut head)
        .with_context(|| format!("reading {}", log.display()))?;
    if reader::format_of(&head) == Format::Mcap {
        bail!("{} is already an MCAP log", log.display());
    }
    let file =
        files::create_at(out, overwrite).with_context(|| format!("creating {}", out.display()))?;
    let log_dir = log.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut mcap = McapLog::new(std::io::BufWriter::new(file))
        .with_context(|| format!("writing {}", out.display()))?
        .world_dirs(vec![log_dir, PathBuf::new()]);
    let mut records = 0;
    for line in std::io::Cursor::new(head).chain(input).split(b'\n') {
        let line = line.with_context(|| format!("reading {}", log.display()))?;
        if line.trim_ascii().is_empty() {
            continue;
        }
        mcap.record(line.trim_ascii())
            .with_context(|| format!("writing {}", out.display()))?;
        records += 1;
    }
    mcap.finish()
        .with_context(|| format!("finishing {}", out.display()))?;
    Ok(records)
}
