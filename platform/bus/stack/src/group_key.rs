//! The group key file that guards container control traffic ([`crate::GuardedTransport`]): 64
//! hex digits (32 bytes) and a newline, mode 0600, shared by every container of a deployment.

use std::path::Path;

use hex::FromHex;
use iw_layer_security::PreSharedKey;
use ring::rand::{SecureRandom, SystemRandom};

/// A group key file that cannot be written or read, or does not hold a key.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GroupKeyError {
    /// The file holds no key (too long, too short), or no random key could be drawn.
    #[error("control key {path}: {reason}")]
    Invalid {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// The file could not be written, read or synced.
    #[error("control key {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// 64 characters, but not hex digits.
    #[error("control key {path}: not 64 hex digits: {source}")]
    Hex {
        /// The file.
        path: String,
        /// What the hex decoder said.
        #[source]
        source: hex::FromHexError,
    },
}

/// Writes a fresh random group key to `path` (mode 0600, fsynced); refuses to overwrite a file.
pub fn write_group_key(path: &Path) -> Result<(), GroupKeyError> {
    use std::io::Write;
    let file_name = || path.display().to_string();
    let io = |source| GroupKeyError::Io {
        path: file_name(),
        source,
    };
    let mut key: PreSharedKey = [0; 32];
    SystemRandom::new()
        .fill(&mut key)
        .map_err(|_| GroupKeyError::Invalid {
            path: file_name(),
            reason: "the system random number generator failed".into(),
        })?;
    let mut text = hex::encode(key);
    text.push('\n');
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options.open(path).map_err(io)?;
    file.write_all(text.as_bytes())
        .and_then(|()| file.sync_all())
        .map_err(io)
}

/// Reads the group key in `path`: 64 hex digits, surrounding white space ignored.
pub fn read_group_key(path: &Path) -> Result<PreSharedKey, GroupKeyError> {
    let file_name = || path.display().to_string();
    let io = |source| GroupKeyError::Io {
        path: file_name(),
        source,
    };
    let bad = |reason: String| GroupKeyError::Invalid {
        path: file_name(),
        reason,
    };
    // A FIFO, a device or a folder is refused unread, and no more than the cap is read even if
    // the file grows meanwhile; both are keys that cannot be, not I/O failures.
    const MAX_KEY_FILE: u64 = 1024;
    let bytes = iw_file::read_file(path, MAX_KEY_FILE).map_err(|e| {
        if iw_file::is_refusal(&e) {
            bad(format!("{e}; a key file holds 64 hex digits"))
        } else {
            io(e)
        }
    })?;
    let text = String::from_utf8_lossy(&bytes);
    let digits = text.trim();
    if digits.len() != 64 {
        return Err(bad(format!(
            "expected 64 hex digits, found {} characters",
            digits.chars().count()
        )));
    }
    PreSharedKey::from_hex(digits).map_err(|source| GroupKeyError::Hex {
        path: file_name(),
        source,
    })
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
        let err = write_group_key(&path).unwrap_err();
        assert!(err.to_string().contains("control.key"), "{err}");
        // the OS's refusal is kept, not only its text
        let io = std::error::Error::source(&err)
            .and_then(|s| s.downcast_ref::<std::io::Error>())
            .unwrap_or_else(|| panic!("no io::Error under `{err}`"));
        assert_eq!(io.kind(), std::io::ErrorKind::AlreadyExists);
        assert_eq!(read_group_key(&path).unwrap(), key, "unchanged");
        let other = dir.path().join("other.key");
        write_group_key(&other).unwrap();
        assert_ne!(read_group_key(&other).unwrap(), key);
    }

    #[test]
    fn a_key_of_64_non_hex_characters_keeps_the_hex_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("control.key");
        std::fs::write(&path, "z".repeat(64)).unwrap();
        let err = read_group_key(&path).unwrap_err();
        let hex = std::error::Error::source(&err)
            .and_then(|s| s.downcast_ref::<hex::FromHexError>())
            .unwrap_or_else(|| panic!("no hex error under `{err}`"));
        assert!(err.to_string().ends_with(&hex.to_string()), "{err}");
    }

    #[test]
    fn a_device_or_a_folder_as_the_key_file_is_refused_unread() {
        let dir = tempfile::tempdir().unwrap();
        for path in [Path::new("/dev/zero"), dir.path()] {
            let err = read_group_key(path).unwrap_err();
            assert!(
                matches!(&err, GroupKeyError::Invalid { reason, .. } if reason.contains("not a regular file")),
                "{}: {err}",
                path.display()
            );
        }
    }
}
