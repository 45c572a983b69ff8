//! Durable file operations of the state directory.
//!
//! In: a path and bytes (or a path to remove). Out: the file replaced atomically and durably:
//! written to a temporary file beside it, the file synced, renamed over the old one, then the
//! directory synced so the rename itself survives a power loss. A crash leaves the old or the
//! new content, never half of one. Bad files are moved aside (quarantined), never deleted.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
#[error("{path}: {source}")]
pub struct FileError {
    pub path: PathBuf,
    pub source: std::io::Error,
}

fn at(path: &Path) -> impl FnOnce(std::io::Error) -> FileError + '_ {
    move |source| FileError {
        path: path.to_path_buf(),
        source,
    }
}

/// Creates `dir` (and its parents) and syncs the parent of each directory it created.
pub fn create_dir(dir: &Path) -> Result<(), FileError> {
    if dir.is_dir() {
        return Ok(());
    }
    if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
        create_dir(parent)?;
    }
    match std::fs::create_dir(dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && dir.is_dir() => {}
        Err(e) => return Err(at(dir)(e)),
    }
    match dir.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(parent) => sync_dir(parent),
        None => Ok(()),
    }
}

/// Syncs a directory's entries (names created, renamed or removed in it) to the disk.
pub fn sync_dir(dir: &Path) -> Result<(), FileError> {
    File::open(dir).and_then(|d| d.sync_all()).map_err(at(dir))
}

/// Writes `bytes` to `path` atomically and durably (its directory synced too).
pub fn write(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    put(path, bytes)?;
    sync_dir(&parent(path))
}

/// Writes `bytes` to `path` atomically, the file synced but not yet its directory (so a batch
/// syncs each directory once): call [`sync_dir`] on [`parent`] before relying on it.
pub fn put(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    let dir = parent(path);
    create_dir(&dir)?;
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".tmp");
    let tmp = path.with_file_name(name);
    let mut file = File::create(&tmp).map_err(at(&tmp))?;
    file.write_all(bytes).map_err(at(&tmp))?;
    file.sync_all().map_err(at(&tmp))?;
    drop(file);
    std::fs::rename(&tmp, path).map_err(at(path))
}

/// Removes `path` (already gone is fine); its directory is not synced, as with [`put`].
pub fn remove(path: &Path) -> Result<(), FileError> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(at(path)(e)),
    }
}

/// Reads a file; `Ok(None)` when there is none.
pub fn read(path: &Path) -> Result<Option<Vec<u8>>, FileError> {
    match std::fs::read(path) {
        Ok(b) => Ok(Some(b)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(at(path)(e)),
    }
}

/// Moves a bad file into `quarantine` (created if needed) under a name that keeps where it came
/// from and never overwrites an earlier one; answers the new path.
pub fn quarantine(path: &Path, root: &Path, quarantine: &Path) -> Result<PathBuf, FileError> {
    create_dir(quarantine)?;
    let relative = path.strip_prefix(root).unwrap_or(path);
    let flat: String = relative
        .to_string_lossy()
        .chars()
        .map(|c| if c == '/' || c == '\\' { '_' } else { c })
        .collect();
    let mut target = quarantine.join(&flat);
    let mut n = 1;
    while target.exists() {
        target = quarantine.join(format!("{flat}.{n}"));
        n += 1;
    }
    std::fs::rename(path, &target).map_err(at(path))?;
    sync_dir(&parent(path))?;
    sync_dir(quarantine)?;
    Ok(target)
}

/// The directory `path` is in (`.` for a bare name).
pub fn parent(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn write_replaces_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a").join("b").join("x.json");
        assert_eq!(read(&path).unwrap(), None);
        write(&path, b"1").unwrap();
        write(&path, b"22").unwrap();
        assert_eq!(read(&path).unwrap().unwrap(), b"22");
        let names: Vec<_> = std::fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        remove(&path).unwrap();
        remove(&path).unwrap();
        assert_eq!(read(&path).unwrap(), None);
    }

    #[test]
    fn quarantine_keeps_every_bad_file() {
        let dir = tempfile::tempdir().unwrap();
        let q = dir.path().join("quarantine");
        for _ in 0..2 {
            let bad = dir.path().join("m").join("1.json");
            write(&bad, b"{").unwrap();
            quarantine(&bad, dir.path(), &q).unwrap();
            assert!(!bad.exists());
        }
        assert!(q.join("m_1.json").exists());
        assert!(q.join("m_1.json.1").exists());
    }
}
