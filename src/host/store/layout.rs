//! Where each piece of state lives in the state directory, and reading it all back at start.
//!
//! ```text
//! STATE_DIR/frames.json                       frames registered over the API
//! STATE_DIR/drones/DRONE/executor.json        the executor's small state (ExecutorMeta)
//! STATE_DIR/drones/DRONE/missions/ID.json     one loaded mission with its progress
//! STATE_DIR/quarantine/                       files that could not be read, moved aside
//! STATE_DIR/state.json                        the old single-file state, migrated at start
//! ```
//!
//! In: the directory and the drone ids of this Kestrel. Out: the [`PersistedState`] to restore
//! and a [`LoadReport`]: every file that could not be read is quarantined and named there, and
//! the rest loads. A [`Change`] names its own file and content.

use super::files::{self, FileError};
use crate::host::engine::{FrameRegistration, PersistedState};
use crate::mission::executor::{ExecutorMeta, ExecutorSnapshot, Loaded};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One piece of state to save; the latest change of a file replaces any earlier one not yet
/// written.
#[derive(Debug, Clone, PartialEq)]
pub enum Change {
    /// A mission loaded or changed (`Some`), or unloaded (`None`).
    Mission {
        drone: String,
        id: u32,
        loaded: Option<Box<Loaded>>,
    },
    Meta {
        drone: String,
        meta: ExecutorMeta,
    },
    Frames(Vec<FrameRegistration>),
}

impl Change {
    /// The file it goes to, relative to the state directory.
    pub fn file(&self) -> PathBuf {
        match self {
            Change::Mission { drone, id, .. } => missions_dir(drone).join(format!("{id}.json")),
            Change::Meta { drone, .. } => drone_dir(drone).join(META),
            Change::Frames(_) => PathBuf::from(FRAMES),
        }
    }

    /// The file's content; `None`: the file is removed.
    pub fn content(&self) -> Result<Option<Vec<u8>>, serde_json::Error> {
        match self {
            Change::Mission { loaded: None, .. } => Ok(None),
            Change::Mission {
                loaded: Some(l), ..
            } => json(l).map(Some),
            Change::Meta { meta, .. } => json(meta).map(Some),
            Change::Frames(f) => json(f).map(Some),
        }
    }
}

fn json<T: Serialize>(value: &T) -> Result<Vec<u8>, serde_json::Error> {
    serde_json::to_vec_pretty(value)
}

const FRAMES: &str = "frames.json";
const META: &str = "executor.json";
/// The file older Kestrels kept everything in.
pub const LEGACY: &str = "state.json";
pub const QUARANTINE: &str = "quarantine";

/// A drone id as a directory name: letters, digits, `_`, `-` and `.` kept (no leading `.`),
/// anything else as `%XX`, so no id can leave `drones/`.
fn drone_dir(drone: &str) -> PathBuf {
    let mut name = String::new();
    for (i, b) in drone.bytes().enumerate() {
        let plain = b.is_ascii_alphanumeric() || b == b'_' || b == b'-' || (b == b'.' && i > 0);
        if plain {
            name.push(char::from(b));
        } else {
            name.push_str(&format!("%{b:02X}"));
        }
    }
    if name.is_empty() {
        name.push('%');
    }
    Path::new("drones").join(name)
}

fn missions_dir(drone: &str) -> PathBuf {
    drone_dir(drone).join("missions")
}

/// A file that could not be read at start, and where it went.
#[derive(Debug, Clone, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct Problem {
    /// The file, relative to the state directory.
    pub file: String,
    pub reason: String,
    /// Where it was moved (relative to the state directory); `None`: it could not be moved.
    pub quarantined_as: Option<String>,
}

/// What loading found besides the state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadReport {
    pub problems: Vec<Problem>,
    /// The old `state.json` was migrated to one file per mission (renamed to this).
    pub migrated: Option<String>,
    /// Missions loaded, all drones together.
    pub missions: usize,
}

struct Loader<'a> {
    root: &'a Path,
    report: LoadReport,
}

impl Loader<'_> {
    /// Reads and parses one file; a bad one is quarantined and reported, answering `None`.
    fn read<T: DeserializeOwned>(&mut self, relative: &Path) -> Option<T> {
        let path = self.root.join(relative);
        let reason = match files::read(&path) {
            Ok(None) => return None,
            Ok(Some(bytes)) => match serde_json::from_slice(&bytes) {
                Ok(v) => return Some(v),
                Err(e) => e.to_string(),
            },
            Err(e) => e.source.to_string(),
        };
        self.quarantine(relative, reason);
        None
    }

    fn quarantine(&mut self, relative: &Path, reason: String) {
        let path = self.root.join(relative);
        let moved = files::quarantine(&path, self.root, &self.root.join(QUARANTINE));
        self.report.problems.push(Problem {
            file: relative.display().to_string(),
            reason,
            quarantined_as: moved.ok().map(|p| {
                p.strip_prefix(self.root)
                    .unwrap_or(&p)
                    .display()
                    .to_string()
            }),
        });
    }

    fn drone(&mut self, drone: &str) -> Result<Option<ExecutorSnapshot>, FileError> {
        let meta: Option<ExecutorMeta> = self.read(&drone_dir(drone).join(META));
        let dir = missions_dir(drone);
        let mut missions = BTreeMap::new();
        let entries = match std::fs::read_dir(self.root.join(&dir)) {
            Ok(e) => e.flatten().collect::<Vec<_>>(),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
            Err(source) => {
                return Err(FileError {
                    path: self.root.join(&dir),
                    source,
                })
            }
        };
        for entry in entries {
            let name = entry.file_name().to_string_lossy().into_owned();
            let relative = dir.join(&name);
            if name.ends_with(".tmp") {
                // A write interrupted before its rename: the old file (if any) is intact.
                files::remove(&self.root.join(&relative))?;
                continue;
            }
            let Some(id) = name
                .strip_suffix(".json")
                .and_then(|n| n.parse::<u32>().ok())
            else {
                self.quarantine(&relative, "not a mission file name (ID.json)".into());
                continue;
            };
            if let Some(loaded) = self.read::<Loaded>(&relative) {
                missions.insert(id, loaded);
            }
        }
        if meta.is_none() && missions.is_empty() {
            return Ok(None);
        }
        let meta = meta.unwrap_or_default();
        self.report.missions += missions.len();
        Ok(Some(ExecutorSnapshot {
            missions,
            running: meta.running,
            shown: meta.shown,
            next_id: meta.next_id,
            last_error: meta.last_error,
        }))
    }

    /// Moves the old single file's content into the new layout (what the new layout has
    /// already wins: it is newer), then renames the old file.
    fn migrate(&mut self, state: &mut PersistedState) -> Result<(), FileError> {
        let Some(legacy) = self.read::<PersistedState>(Path::new(LEGACY)) else {
            return Ok(());
        };
        let mut changes = Vec::new();
        if !self.root.join(FRAMES).exists() {
            changes.push(Change::Frames(legacy.frames.clone()));
            state.frames = legacy.frames;
        }
        for (drone, snapshot) in legacy.drones {
            if state.drones.contains_key(&drone) || self.root.join(drone_dir(&drone)).exists() {
                continue;
            }
            changes.extend(snapshot.missions.iter().map(|(id, l)| Change::Mission {
                drone: drone.clone(),
                id: *id,
                loaded: Some(Box::new(l.clone())),
            }));
            changes.push(Change::Meta {
                drone: drone.clone(),
                meta: ExecutorMeta {
                    running: snapshot.running,
                    shown: snapshot.shown,
                    next_id: snapshot.next_id,
                    last_error: snapshot.last_error.clone(),
                },
            });
            self.report.missions += snapshot.missions.len();
            state.drones.insert(drone, snapshot);
        }
        write_all(self.root, &changes)?;
        let from = self.root.join(LEGACY);
        let to = self.root.join(format!("{LEGACY}.migrated"));
        std::fs::rename(&from, &to).map_err(|source| FileError { path: from, source })?;
        files::sync_dir(self.root)?;
        self.report.migrated = Some(format!("{LEGACY}.migrated"));
        Ok(())
    }
}

/// Writes `changes` durably: every file synced, then each directory touched synced once.
pub fn write_all(root: &Path, changes: &[Change]) -> Result<(), FileError> {
    let mut dirs = std::collections::BTreeSet::new();
    for change in changes {
        let path = root.join(change.file());
        match change.content() {
            Ok(Some(bytes)) => files::put(&path, &bytes)?,
            Ok(None) => files::remove(&path)?,
            Err(e) => {
                return Err(FileError {
                    path,
                    source: std::io::Error::other(e),
                })
            }
        }
        dirs.insert(files::parent(&path));
    }
    dirs.iter().try_for_each(|d| files::sync_dir(d))
}

/// Reads the state directory (created if missing) for `drones`: unreadable files quarantined,
/// an old `state.json` migrated. Fails only when the directory itself cannot be used.
pub fn load(root: &Path, drones: &[String]) -> Result<(PersistedState, LoadReport), FileError> {
    files::create_dir(root)?;
    let mut loader = Loader {
        root,
        report: LoadReport::default(),
    };
    let mut state = PersistedState {
        frames: loader.read(Path::new(FRAMES)).unwrap_or_default(),
        ..PersistedState::default()
    };
    for drone in drones {
        if let Some(snapshot) = loader.drone(drone)? {
            state.drones.insert(drone.clone(), snapshot);
        }
    }
    loader.migrate(&mut state)?;
    Ok((state, loader.report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::executor::Progress;
    use crate::mission::model::ValidMission;

    fn mission(height: f64) -> Loaded {
        Loaded {
            mission: ValidMission {
                target: "drone_0".into(),
                items: Vec::new(),
                warnings: vec![format!("h{height}")],
            },
            progress: Progress::default(),
        }
    }

    fn save(root: &Path, drone: &str, id: u32, l: &Loaded) {
        let change = Change::Mission {
            drone: drone.into(),
            id,
            loaded: Some(Box::new(l.clone())),
        };
        write_all(root, &[change]).unwrap();
    }

    #[test]
    fn drone_ids_cannot_leave_the_drones_directory() {
        assert_eq!(drone_dir("drone_0"), Path::new("drones/drone_0"));
        assert_eq!(drone_dir("../x"), Path::new("drones/%2E.%2Fx"));
        assert_eq!(drone_dir(""), Path::new("drones/%"));
    }

    #[test]
    fn a_bad_mission_file_is_quarantined_and_the_others_load() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        for id in 1..=3 {
            save(root, "drone_0", id, &mission(f64::from(id)));
        }
        std::fs::write(
            root.join("drones/drone_0/missions/2.json"),
            b"{\"mission\": ",
        )
        .unwrap();
        std::fs::write(root.join("drones/drone_0/missions/9.json.tmp"), b"half").unwrap();
        let (state, report) = load(root, &["drone_0".into()]).unwrap();
        let ids: Vec<u32> = state.drones["drone_0"].missions.keys().copied().collect();
        assert_eq!(ids, [1, 3]);
        assert_eq!(report.problems.len(), 1, "{report:?}");
        assert_eq!(report.problems[0].file, "drones/drone_0/missions/2.json");
        let moved = report.problems[0].quarantined_as.clone().unwrap();
        assert!(root.join(moved).exists());
        assert!(!root.join("drones/drone_0/missions/9.json.tmp").exists());
    }

    #[test]
    fn an_old_state_json_is_migrated_once_and_a_corrupt_one_quarantined() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        let mut old = PersistedState::default();
        let mut snapshot = ExecutorSnapshot {
            next_id: 8,
            ..ExecutorSnapshot::default()
        };
        snapshot.missions.insert(7, mission(7.0));
        old.drones.insert("drone_0".into(), snapshot);
        std::fs::write(root.join(LEGACY), serde_json::to_vec(&old).unwrap()).unwrap();
        let (state, report) = load(root, &["drone_0".into()]).unwrap();
        assert_eq!(state.drones["drone_0"].missions.len(), 1);
        assert_eq!(report.migrated.as_deref(), Some("state.json.migrated"));
        assert!(!root.join(LEGACY).exists());
        let (again, report) = load(root, &["drone_0".into()]).unwrap();
        assert_eq!(
            again.drones["drone_0"].missions,
            state.drones["drone_0"].missions
        );
        assert_eq!(again.drones["drone_0"].next_id, 8);
        assert_eq!(
            report,
            LoadReport {
                missions: 1,
                ..LoadReport::default()
            }
        );

        std::fs::write(root.join(LEGACY), b"\0\0\0").unwrap();
        let (state, report) = load(root, &["drone_0".into()]).unwrap();
        assert_eq!(state.drones["drone_0"].missions.len(), 1);
        assert_eq!(report.problems.len(), 1);
        assert_eq!(report.problems[0].file, "state.json");
    }
}
