//! The `[fleet] credentials_file`: `user:password` lines, the first one this node's, every one
//! accepted from peers (Zenoh's user/password dictionary).
//!
//! In: the file's path. Out: this node's [`Credentials`], or why the file cannot be used, with
//! the line. The rules are Zenoh's own (each non-empty line trimmed, split at its first `:`,
//! user and password trimmed and non-empty), checked here so that `kestrel check-config` refuses
//! what the bus would refuse at start.

use std::path::{Path, PathBuf};

/// Largest credentials file read (bytes).
pub const MAX_CREDENTIALS_BYTES: u64 = 64 * 1024;

/// This node's user and password: the file's first `user:password` line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Credentials {
    pub user: String,
    pub password: String,
}

#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum CredentialsError {
    #[error("fleet.credentials_file {path}: {message}")]
    Unreadable { path: PathBuf, message: String },
    #[error("fleet.credentials_file {path}: larger than 64 KiB")]
    TooLarge { path: PathBuf },
    #[error("fleet.credentials_file {path}: empty (one `user:password` line per node)")]
    Empty { path: PathBuf },
    #[error("fleet.credentials_file {path}: line {line}: {message}")]
    Line {
        path: PathBuf,
        line: usize,
        message: &'static str,
    },
}

/// Reads and checks the whole file; returns the first line's credentials.
pub fn read_credentials(path: &Path) -> Result<Credentials, CredentialsError> {
    let unreadable = |e: std::io::Error| CredentialsError::Unreadable {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let meta = std::fs::metadata(path).map_err(unreadable)?;
    if meta.len() > MAX_CREDENTIALS_BYTES {
        return Err(CredentialsError::TooLarge {
            path: path.to_path_buf(),
        });
    }
    let text = std::fs::read_to_string(path).map_err(unreadable)?;
    let mut own = None;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let bad = |message| CredentialsError::Line {
            path: path.to_path_buf(),
            line: i + 1,
            message,
        };
        let (user, password) = line.split_once(':').ok_or(bad("not `user:password`"))?;
        let (user, password) = (user.trim(), password.trim());
        if user.is_empty() {
            return Err(bad("empty user"));
        }
        if password.is_empty() {
            return Err(bad("empty password"));
        }
        own.get_or_insert_with(|| Credentials {
            user: user.to_string(),
            password: password.to_string(),
        });
    }
    own.ok_or(CredentialsError::Empty {
        path: path.to_path_buf(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Credentials, CredentialsError> {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let path = dir.path().join("creds");
        std::fs::write(&path, text).unwrap_or_else(|e| panic!("{e}"));
        read_credentials(&path)
    }

    #[test]
    fn the_first_line_is_this_nodes_trimmed() {
        assert_eq!(
            read("\n kestrel-a : s3cret \nb:c\n"),
            Ok(Credentials {
                user: "kestrel-a".into(),
                password: "s3cret".into()
            })
        );
    }

    #[test]
    fn a_malformed_line_anywhere_is_refused_with_its_number() {
        let line = |r: Result<Credentials, CredentialsError>| match r {
            Err(CredentialsError::Line { line, message, .. }) => Some((line, message)),
            _ => None,
        };
        assert_eq!(
            line(read("a:b\n\nnocolon\n")),
            Some((3, "not `user:password`"))
        );
        assert_eq!(line(read("a:b\n :c\n")), Some((2, "empty user")));
        assert_eq!(line(read("a: \n")), Some((1, "empty password")));
        assert!(matches!(read(" \n\n"), Err(CredentialsError::Empty { .. })));
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        assert!(matches!(
            read_credentials(&dir.path().join("missing")),
            Err(CredentialsError::Unreadable { .. })
        ));
    }
}
