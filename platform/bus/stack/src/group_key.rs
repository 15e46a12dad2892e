//! The group key file that guards container control traffic ([`crate::GuardedTransport`]): 64
//! hex digits (32 bytes) and a newline, mode 0600, shared by every container of a deployment.

use std::path::Path;

use hex::FromHex;
use iw_layer_security::PreSharedKey;
use ring::rand::{SecureRandom, SystemRandom};

/// A group key file that cannot be written or read, or does not hold a key.
#[derive(Debug, thiserror::Error)]
#[error("control key {path}: {reason}")]
pub struct GroupKeyError {
    /// The file.
    pub path: String,
    /// Why.
    pub reason: String,
}

/// Writes a fresh random group key to `path` (mode 0600, fsynced); refuses to overwrite a file.
pub fn write_group_key(path: &Path) -> Result<(), GroupKeyError> {
    use std::io::Write;
    let bad = |reason: String| GroupKeyError {
        path: path.display().to_string(),
        reason,
    };
    let mut key: PreSharedKey = [0; 32];
    SystemRandom::new()
        .fill(&mut key)
        .map_err(|_| bad("the system random number generator failed".into()))?;
    let mut text = hex::encode(key);
    text.push('\n');
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options.open(path).map_err(|e| bad(e.to_string()))?;
    file.write_all(text.as_bytes())
        .and_then(|()| file.sync_all())
        .map_err(|e| bad(e.to_string()))
}

/// Reads the group key in `path`: 64 hex digits, surrounding white space ignored.
pub fn read_group_key(path: &Path) -> Result<PreSharedKey, GroupKeyError> {
    let bad = |reason: String| GroupKeyError {
        path: path.display().to_string(),
        reason,
    };
    let meta = std::fs::metadata(path).map_err(|e| bad(e.to_string()))?;
    if meta.len() > 1024 {
        return Err(bad(format!(
            "{} bytes; a key file holds 64 hex digits",
            meta.len()
        )));
    }
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    let digits = text.trim();
    if digits.len() != 64 {
        return Err(bad(format!(
            "expected 64 hex digits, found {} characters",
            digits.chars().count()
        )));
    }
    PreSharedKey::from_hex(digits).map_err(|e| bad(format!("not 64 hex digits: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_key_reads_back_and_is_never_overwritten() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("control.key");
        write_group_key(&path).unwrap();
        let key = read_group_key(&path).unwrap();
        assert_ne!(key, [0; 32]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o600);
        }
        let err = write_group_key(&path).unwrap_err().to_string();
        assert!(err.contains("control.key"), "{err}");
        assert_eq!(read_group_key(&path).unwrap(), key, "unchanged");
        let other = dir.path().join("other.key");
        write_group_key(&other).unwrap();
        assert_ne!(read_group_key(&other).unwrap(), key);
    }
}
