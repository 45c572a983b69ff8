//! Who speaks on the fleet bus: each node signs what it publishes with its own Ed25519 key, and
//! every node checks each message against the key the fleet's roster gives the node whose key
//! expression it came on. A node can then only ever speak for itself: a message on another
//! node's keys does not verify.
//!
//! In: this node's key file (`[fleet] key_file`: one line, the base64 of a 32-byte secret seed,
//! made by `kestrel fleet-key`), the roster's public keys (base64 of 32 bytes), the bytes to
//! send or that arrived. Out: [`Signer::seal`]: `KSG1`, a little-endian `u64` counter, the
//! 64-byte signature, then the message; [`open`]: the counter and the message, or why not.
//!
//! What is signed binds the message to where it may be heard: the fleet, the node, the kind
//! (`state` or `map`), the counter and the bytes. The counter starts at the sender's wall clock
//! in microseconds and only counts up (a restarted node starts above where it stopped as long as
//! its clock did not go back); receivers keep the highest counter each node used per kind and
//! refuse anything not above it, so a recorded message cannot be played again.

use std::path::Path;

use base64::Engine as _;
use ring::rand::SecureRandom as _;
use ring::signature::{Ed25519KeyPair, KeyPair as _, UnparsedPublicKey, ED25519};

const MAGIC: &[u8; 4] = b"KSG1";
/// What the signature covers starts with this, so that a Kestrel fleet signature means nothing
/// anywhere else.
const CONTEXT: &[u8] = b"kestrel fleet bus v1\0";
const SIGNATURE_BYTES: usize = 64;
/// Bytes before the message.
pub const ENVELOPE_BYTES: usize = MAGIC.len() + 8 + SIGNATURE_BYTES;
/// Largest key file read (bytes).
const MAX_KEY_FILE_BYTES: u64 = 1024;

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum KeyError {
    #[error("fleet.key_file {path}: {message}")]
    File { path: String, message: String },
    #[error("not an Ed25519 secret key")]
    Seed,
    #[error("`{0}` is not a fleet public key (the base64 of 32 bytes, as `kestrel fleet-key` prints it)")]
    Public(String),
}

/// Why a message from the bus was not opened.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum OpenError {
    #[error("not signed (no KSG1 envelope)")]
    Unsigned,
    #[error("the signature is not node `{0}`'s (another node's key, or altered on the way)")]
    BadSignature(String),
}

/// A public key of the roster.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PublicKey([u8; 32]);

impl PublicKey {
    pub fn parse(text: &str) -> Result<Self, KeyError> {
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(text.trim())
            .map_err(|_| KeyError::Public(text.to_string()))?;
        let key: [u8; 32] = bytes
            .try_into()
            .map_err(|_| KeyError::Public(text.to_string()))?;
        Ok(Self(key))
    }

    pub fn to_base64(&self) -> String {
        base64::engine::general_purpose::STANDARD.encode(self.0)
    }
}

/// What the signature covers.
fn signed_bytes(fleet: &str, node: &str, kind: &str, counter: u64, message: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(
        CONTEXT.len() + fleet.len() + node.len() + kind.len() + 11 + message.len(),
    );
    out.extend_from_slice(CONTEXT);
    for part in [fleet, node, kind] {
        out.extend_from_slice(part.as_bytes());
        out.push(0);
    }
    out.extend_from_slice(&counter.to_le_bytes());
    out.extend_from_slice(message);
    out
}

/// This node's key, and the counter of what it sent.
pub struct Signer {
    key: Ed25519KeyPair,
    counter: u64,
}

impl std::fmt::Debug for Signer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Signer({})", self.public().to_base64())
    }
}

fn unix_us() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

impl Signer {
    pub fn from_seed(seed: &[u8; 32]) -> Result<Self, KeyError> {
        let key = Ed25519KeyPair::from_seed_unchecked(seed).map_err(|_| KeyError::Seed)?;
        Ok(Self { key, counter: 0 })
    }

    /// Reads a key file (`kestrel fleet-key`'s).
    pub fn read(path: &Path) -> Result<Self, KeyError> {
        let bad = |message: String| KeyError::File {
            path: path.display().to_string(),
            message,
        };
        let meta = std::fs::metadata(path).map_err(|e| bad(e.to_string()))?;
        if meta.len() > MAX_KEY_FILE_BYTES {
            return Err(bad("larger than 1 KiB: not a key file".into()));
        }
        let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
        let seed = base64::engine::general_purpose::STANDARD
            .decode(text.trim())
            .ok()
            .and_then(|b| <[u8; 32]>::try_from(b).ok())
            .ok_or_else(|| bad("not a key (one line, the base64 of 32 bytes: make one with `kestrel fleet-key FILE`)".into()))?;
        Self::from_seed(&seed)
    }

    /// A new key, written to `path` (readable by its owner only); refuses to replace a file.
    pub fn generate(path: &Path) -> Result<Self, KeyError> {
        let bad = |message: String| KeyError::File {
            path: path.display().to_string(),
            message,
        };
        let mut seed = [0u8; 32];
        ring::rand::SystemRandom::new()
            .fill(&mut seed)
            .map_err(|_| bad("no randomness from the operating system".into()))?;
        let mut options = std::fs::OpenOptions::new();
        options.write(true).create_new(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
        let mut file = options.open(path).map_err(|e| bad(e.to_string()))?;
        let line = base64::engine::general_purpose::STANDARD.encode(seed);
        std::io::Write::write_all(&mut file, format!("{line}\n").as_bytes())
            .and_then(|()| file.sync_all())
            .map_err(|e| bad(e.to_string()))?;
        Self::from_seed(&seed)
    }

    pub fn public(&self) -> PublicKey {
        let mut key = [0u8; 32];
        key.copy_from_slice(self.key.public_key().as_ref());
        PublicKey(key)
    }

    /// `message`, signed for node `node`'s key expression of `kind` in `fleet`.
    pub fn seal(&mut self, fleet: &str, node: &str, kind: &str, message: &[u8]) -> Vec<u8> {
        self.counter = (self.counter + 1).max(unix_us());
        let signature = self
            .key
            .sign(&signed_bytes(fleet, node, kind, self.counter, message));
        let mut out = Vec::with_capacity(ENVELOPE_BYTES + message.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&self.counter.to_le_bytes());
        out.extend_from_slice(signature.as_ref());
        out.extend_from_slice(message);
        out
    }
}

/// Checks a message heard on node `node`'s key expression of `kind` against that node's keys
/// (a roster entry may list a new key beside the old while keys are rotated). Returns the
/// counter and the message.
pub fn open<'a>(
    keys: &[PublicKey],
    fleet: &str,
    node: &str,
    kind: &str,
    bytes: &'a [u8],
) -> Result<(u64, &'a [u8]), OpenError> {
    let rest = bytes.strip_prefix(MAGIC).ok_or(OpenError::Unsigned)?;
    let (counter, rest) = rest.split_first_chunk::<8>().ok_or(OpenError::Unsigned)?;
    let (signature, message) = rest
        .split_first_chunk::<SIGNATURE_BYTES>()
        .ok_or(OpenError::Unsigned)?;
    let counter = u64::from_le_bytes(*counter);
    let signed = signed_bytes(fleet, node, kind, counter, message);
    let verified = keys.iter().any(|k| {
        UnparsedPublicKey::new(&ED25519, &k.0)
            .verify(&signed, signature)
            .is_ok()
    });
    if !verified {
        return Err(OpenError::BadSignature(node.to_string()));
    }
    Ok((counter, message))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn only_the_nodes_own_key_opens_what_it_sealed_where_it_sealed_it() {
        let mut a = Signer::from_seed(&[1; 32]).unwrap();
        let b = Signer::from_seed(&[2; 32]).unwrap();
        let sealed = a.seal("farm", "node_a", "state", b"{}");
        let (counter, message) = open(&[a.public()], "farm", "node_a", "state", &sealed).unwrap();
        assert_eq!(message, b"{}");
        // Another node's key, another node's key expression, kind or fleet: refused.
        let refused =
            |keys: &[PublicKey], fleet, node, kind| open(keys, fleet, node, kind, &sealed);
        assert!(refused(&[b.public()], "farm", "node_a", "state").is_err());
        assert!(refused(&[a.public()], "farm", "node_b", "state").is_err());
        assert!(refused(&[a.public()], "farm", "node_a", "map").is_err());
        assert!(refused(&[a.public()], "farm2", "node_a", "state").is_err());
        // A new key beside the old one (rotation): either opens.
        assert!(refused(&[b.public(), a.public()], "farm", "node_a", "state").is_ok());
        // Altered in flight, cut, or never sealed.
        let mut altered = sealed.clone();
        *altered.last_mut().unwrap() = b']';
        assert!(open(&[a.public()], "farm", "node_a", "state", &altered).is_err());
        assert_eq!(
            open(&[a.public()], "farm", "node_a", "state", &sealed[..20]),
            Err(OpenError::Unsigned)
        );
        assert_eq!(
            open(&[a.public()], "farm", "node_a", "state", b"{}"),
            Err(OpenError::Unsigned)
        );
        // The counter only counts up, from the wall clock.
        let next = a.seal("farm", "node_a", "state", b"{}");
        let (later, _) = open(&[a.public()], "farm", "node_a", "state", &next).unwrap();
        assert!(later > counter && counter > 1_700_000_000_000_000);
    }

    #[test]
    fn key_files_are_made_once_and_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fleet.key");
        let made = Signer::generate(&path).unwrap();
        assert_eq!(Signer::read(&path).unwrap().public(), made.public());
        assert!(Signer::generate(&path).is_err(), "never replaces a key");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o600);
        }
        std::fs::write(&path, "not a key\n").unwrap();
        assert!(Signer::read(&path)
            .unwrap_err()
            .to_string()
            .contains("kestrel fleet-key"));
        let public = made.public().to_base64();
        assert_eq!(PublicKey::parse(&public).unwrap(), made.public());
        assert!(PublicKey::parse("c2hvcnQ=").is_err());
    }
}
