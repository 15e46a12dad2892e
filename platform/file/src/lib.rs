//! Files named by a user: opened only if they are regular files, read within a size cap.
//!
//! A FIFO blocks the open until a writer comes, a device such as `/dev/zero` never ends, and a
//! 2 GB file is read whole before a parser can refuse it; each was a hang or an unbounded
//! allocation. Every crate that opens a file it was given (maps, scenario and spawn
//! configuration files, group keys, rosters, message logs, image sequences) goes through
//! [`open_regular`] or [`read_file`]; this crate depends on nothing so that every layer can.

use std::fs::File;
use std::io::{Error, ErrorKind, Read};
use std::path::Path;

/// Why a FIFO, device or folder is refused, as every caller reports it.
pub const NOT_REGULAR: &str =
    "not a regular file (a folder, FIFO or device is refused: reading it could block or never end)";

/// Opens `path` for reading only if it is a regular file; otherwise an
/// [`ErrorKind::InvalidInput`] error saying [`NOT_REGULAR`].
pub fn open_regular(path: &Path) -> std::io::Result<File> {
    let not_regular = || Error::new(ErrorKind::InvalidInput, NOT_REGULAR);
    // Checked before the open: opening a FIFO for reading blocks until something writes to it.
    if !std::fs::metadata(path)?.is_file() {
        return Err(not_regular());
    }
    let file = File::open(path)?;
    // Checked again on the open file: the path may have been swapped in between.
    if !file.metadata()?.is_file() {
        return Err(not_regular());
    }
    Ok(file)
}

/// The bytes of `path` if it is a regular file of at most `max_bytes`; otherwise an
/// [`ErrorKind::InvalidInput`] or [`ErrorKind::FileTooLarge`] error that says why, read no
/// further than one byte past the cap.
pub fn read_file(path: &Path, max_bytes: u64) -> std::io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    open_regular(path)?
        .take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(Error::new(
            ErrorKind::FileTooLarge,
            format!("larger than the {max_bytes} bytes accepted; the rest was not read"),
        ));
    }
    Ok(bytes)
}

/// Whether `e` is a refusal of this crate (not a regular file, over the cap) rather than a
/// failure to read: callers report it as a file that cannot be what they wanted.
pub fn is_refusal(e: &Error) -> bool {
    matches!(e.kind(), ErrorKind::InvalidInput | ErrorKind::FileTooLarge)
}

/// [`read_file`] as UTF-8 text.
pub fn read_text(path: &Path, max_bytes: u64) -> std::io::Result<String> {
    String::from_utf8(read_file(path, max_bytes)?)
        .map_err(|e| Error::new(ErrorKind::InvalidData, e.utf8_error()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_folders_fifos_and_oversize_files_are_refused_with_why() {
        let dir = tempfile::tempdir().unwrap();
        let small = dir.path().join("small.txt");
        std::fs::write(&small, "name x\n").unwrap();
        assert_eq!(read_text(&small, 7).unwrap(), "name x\n");
        let big = read_text(&small, 6).unwrap_err();
        assert_eq!(big.kind(), ErrorKind::FileTooLarge);
        assert!(big.to_string().contains("6 bytes"), "{big}");
        // A device never ends: refused, not read until memory runs out.
        let zero = read_file(Path::new("/dev/zero"), 1 << 20).unwrap_err();
        assert_eq!(zero.kind(), ErrorKind::InvalidInput, "{zero}");
        assert!(zero.to_string().contains("not a regular file"), "{zero}");
        assert!(is_refusal(&zero) && is_refusal(&big));
        assert_eq!(
            open_regular(dir.path()).unwrap_err().kind(),
            ErrorKind::InvalidInput
        );
        assert_eq!(
            open_regular(&dir.path().join("absent")).unwrap_err().kind(),
            ErrorKind::NotFound,
            "a missing file keeps the OS error"
        );
        assert!(!is_refusal(
            &open_regular(&dir.path().join("absent")).unwrap_err()
        ));
        let bad = dir.path().join("bad.txt");
        std::fs::write(&bad, [b'a', 0xff]).unwrap();
        assert_eq!(
            read_text(&bad, 10).unwrap_err().kind(),
            ErrorKind::InvalidData
        );
        // A FIFO with no writer would block the open forever.
        let fifo = dir.path().join("fifo");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            let err = open_regular(&fifo).unwrap_err();
            assert_eq!(err.kind(), ErrorKind::InvalidInput, "{err}");
        } else {
            println!("SKIP: mkfifo is not available; the FIFO case was not tried");
        }
    }
}
