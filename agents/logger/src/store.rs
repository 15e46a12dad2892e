//! [`LogStore`]: checksummed records appended to one file, with an fsync policy and recovery.
//!
//! On-disk layout (all integers little-endian):
//!
//! ```text
//! file header, 16 bytes
//! +---------------------------+---------------------------+
//! | magic "IWLOG\0v1" (8 B)   | reserved, zero (8 B)      |
//! +---------------------------+---------------------------+
//! record, 16 + len bytes
//! +------------+------------+------------------------+-----------------+
//! | len: u32   | crc: u32   | seq: u64               | payload (len B) |
//! +------------+------------+------------------------+-----------------+
//! crc = CRC-32C of (seq bytes ++ payload); seq starts at 1 and grows by one per record
//! ```
//!
//! A record is valid when its header and payload are complete, `len` is within the configured
//! limit, the checksum matches and `seq` follows its predecessor. Recovery reads records until the
//! first invalid one. If no valid record follows it, that is a torn tail (a write cut short by a
//! crash, never acknowledged) and the file is truncated there; if a valid record follows, the log
//! was damaged in the middle and [`LogStore::open`] refuses with the offset instead of dropping
//! acknowledged records.

use std::fs::{File, OpenOptions};
use std::io::{BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"IWLOG\0v1";
const FILE_HEADER_LEN: u64 = 16;
const RECORD_HEADER_LEN: usize = 16;
/// Default largest payload, bytes: far above any ACL message the platform lets through.
pub const DEFAULT_MAX_RECORD_LEN: u32 = 1 << 20;

/// When appended records are forced to stable storage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SyncPolicy {
    /// `fsync` before every append returns: each acknowledged record is durable.
    Always,
    /// `fsync` after every `n` records; [`LogStore::sync`] covers the rest.
    EveryN(u32),
    /// `fsync` when the oldest unsynced record is older than this many ns (times are the
    /// caller's clock, passed to [`LogStore::append`]).
    IntervalNs(u64),
}

/// Why the log could not be opened, read or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LogError {
    /// An I/O error on the log file, with what was being done.
    #[error("{path}: {context}: {source}")]
    Io {
        /// The log file.
        path: PathBuf,
        /// What was being done.
        context: &'static str,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a log of this format.
    #[error("{path}: not an intellwheels log (bad magic); refusing to touch it")]
    NotALog {
        /// The file.
        path: PathBuf,
    },
    /// A damaged record sits before valid ones: truncating would lose acknowledged records.
    #[error(
        "{path}: record at byte {offset} is damaged ({reason}) but valid records follow it; \
         the log needs manual repair (copy it aside, then truncate at {offset} if the loss is acceptable)"
    )]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// Byte offset of the damaged record.
        offset: u64,
        /// What is wrong with it.
        reason: String,
    },
    /// A payload larger than the configured limit.
    #[error("record of {len} bytes exceeds the log's limit of {max} bytes")]
    RecordTooLarge {
        /// Offered length.
        len: usize,
        /// Limit.
        max: u32,
    },
}

/// One stored record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Record {
    /// Sequence number, from 1.
    pub seq: u64,
    /// The bytes appended.
    pub payload: Vec<u8>,
}

/// What [`LogStore::open`] found and repaired.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Recovery {
    /// Valid records kept.
    pub records: u64,
    /// Bytes of torn tail removed.
    pub truncated_bytes: u64,
}

/// An append-only, crash-safe log in one file.
#[derive(Debug)]
pub struct LogStore {
    path: PathBuf,
    file: File,
    policy: SyncPolicy,
    max_record_len: u32,
    next_seq: u64,
    /// Records appended since the last fsync, and the time of the oldest of them.
    unsynced: u32,
    oldest_unsynced_ns: Option<u64>,
    recovery: Recovery,
}

impl LogStore {
    /// Opens or creates the log at `path`, recovering from a crash as the module doc describes.
    pub fn open(path: impl AsRef<Path>, policy: SyncPolicy) -> Result<Self, LogError> {
        Self::open_with_limit(path, policy, DEFAULT_MAX_RECORD_LEN)
    }

    /// [`LogStore::open`] with an explicit largest payload, bytes.
    pub fn open_with_limit(
        path: impl AsRef<Path>,
        policy: SyncPolicy,
        max_record_len: u32,
    ) -> Result<Self, LogError> {
        let path = path.as_ref().to_path_buf();
        let io = |context: &'static str| {
            let path = path.clone();
            move |source| LogError::Io {
                path,
                context,
                source,
            }
        };
        let existed = path.exists();
        let mut file = OpenOptions::new()
            .read(true)
            .append(true)
            .create(true)
            .open(&path)
            .map_err(io("opening the log"))?;
        let len = file.metadata().map_err(io("reading the log's size"))?.len();
        if len == 0 {
            let mut header = [0u8; FILE_HEADER_LEN as usize];
            header[..8].copy_from_slice(MAGIC);
            file.write_all(&header)
                .map_err(io("writing the file header"))?;
            file.sync_all().map_err(io("syncing the new log"))?;
            if !existed {
                sync_parent_dir(&path).map_err(io("syncing the log's directory"))?;
            }
        }
        let scan = scan(&path, &mut file, max_record_len)?;
        let recovery = match scan.first_bad {
            None => Recovery {
                records: scan.records,
                truncated_bytes: 0,
            },
            Some((offset, reason)) => {
                if valid_record_after(&mut file, offset, max_record_len, &path)? {
                    return Err(LogError::Corrupt {
                        path,
                        offset,
                        reason,
                    });
                }
                let file_len = file.metadata().map_err(io("reading the log's size"))?.len();
                file.set_len(offset)
                    .map_err(io("truncating the torn tail"))?;
                file.sync_all().map_err(io("syncing the truncation"))?;
                Recovery {
                    records: scan.records,
                    truncated_bytes: file_len - offset,
                }
            }
        };
        Ok(LogStore {
            path,
            file,
            policy,
            max_record_len,
            next_seq: scan.records + 1,
            unsynced: 0,
            oldest_unsynced_ns: None,
            recovery,
        })
    }

    /// What opening found and repaired.
    pub fn recovery(&self) -> Recovery {
        self.recovery
    }

    /// The log file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Number of records in the log.
    pub fn len(&self) -> u64 {
        self.next_seq - 1
    }

    /// True when the log holds no record.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Appends one record at the caller's time `now_ns` and returns its sequence number and
    /// whether it is already durable (always true under [`SyncPolicy::Always`]).
    pub fn append(&mut self, payload: &[u8], now_ns: u64) -> Result<(u64, bool), LogError> {
        if payload.len() > self.max_record_len as usize {
            return Err(LogError::RecordTooLarge {
                len: payload.len(),
                max: self.max_record_len,
            });
        }
        let seq = self.next_seq;
        let mut frame = Vec::with_capacity(RECORD_HEADER_LEN + payload.len());
        frame.extend_from_slice(&(payload.len() as u32).to_le_bytes());
        frame.extend_from_slice(&checksum(seq, payload).to_le_bytes());
        frame.extend_from_slice(&seq.to_le_bytes());
        frame.extend_from_slice(payload);
        self.file.write_all(&frame).map_err(|source| LogError::Io {
            path: self.path.clone(),
            context: "appending a record",
            source,
        })?;
        self.next_seq += 1;
        self.unsynced += 1;
        let oldest = *self.oldest_unsynced_ns.get_or_insert(now_ns);
        let due = match self.policy {
            SyncPolicy::Always => true,
            SyncPolicy::EveryN(n) => self.unsynced >= n.max(1),
            SyncPolicy::IntervalNs(ns) => now_ns.saturating_sub(oldest) >= ns,
        };
        if due {
            self.sync()?;
        }
        Ok((seq, due))
    }

    /// Forces every appended record to stable storage; returns the last durable sequence number.
    pub fn sync(&mut self) -> Result<u64, LogError> {
        if self.unsynced > 0 {
            self.file.sync_data().map_err(|source| LogError::Io {
                path: self.path.clone(),
                context: "syncing records",
                source,
            })?;
            self.unsynced = 0;
            self.oldest_unsynced_ns = None;
        }
        Ok(self.len())
    }

    /// Reads every record from the start, in order.
    pub fn records(&self) -> Result<Vec<Record>, LogError> {
        read_records(&self.path, self.max_record_len)
    }
}

/// Reads every valid record of the log at `path` without opening it for writing (for queries
/// and replay while the logger agent runs). Stops quietly at a torn tail.
pub fn read_records(path: &Path, max_record_len: u32) -> Result<Vec<Record>, LogError> {
    let io = |context: &'static str| {
        move |source| LogError::Io {
            path: path.to_path_buf(),
            context,
            source,
        }
    };
    let file = File::open(path).map_err(io("opening the log for reading"))?;
    let mut reader = BufReader::new(file);
    check_magic(&mut reader, path)?;
    let mut records = Vec::new();
    while let Ok(Some(record)) = read_record(&mut reader, records.len() as u64 + 1, max_record_len)
    {
        records.push(record);
    }
    Ok(records)
}

struct Scan {
    records: u64,
    first_bad: Option<(u64, String)>,
}

fn scan(path: &Path, file: &mut File, max_record_len: u32) -> Result<Scan, LogError> {
    file.seek(SeekFrom::Start(0))
        .map_err(|source| LogError::Io {
            path: path.to_path_buf(),
            context: "rewinding the log",
            source,
        })?;
    let mut reader = BufReader::new(&mut *file);
    check_magic(&mut reader, path)?;
    let mut offset = FILE_HEADER_LEN;
    let mut records = 0u64;
    loop {
        match read_record(&mut reader, records + 1, max_record_len) {
            Ok(None) => {
                return Ok(Scan {
                    records,
                    first_bad: None,
                });
            }
            Ok(Some(record)) => {
                records += 1;
                offset += (RECORD_HEADER_LEN + record.payload.len()) as u64;
            }
            Err(reason) => {
                return Ok(Scan {
                    records,
                    first_bad: Some((offset, reason)),
                });
            }
        }
    }
}

fn check_magic(reader: &mut impl Read, path: &Path) -> Result<(), LogError> {
    let mut header = [0u8; FILE_HEADER_LEN as usize];
    match reader.read_exact(&mut header) {
        Ok(()) if &header[..8] == MAGIC => Ok(()),
        _ => Err(LogError::NotALog {
            path: path.to_path_buf(),
        }),
    }
}

/// `Ok(None)` at a clean end of file, `Err(reason)` for an invalid or incomplete record.
fn read_record(
    reader: &mut impl Read,
    expected_seq: u64,
    max_record_len: u32,
) -> Result<Option<Record>, String> {
    let mut header = [0u8; RECORD_HEADER_LEN];
    let got = read_up_to(reader, &mut header);
    if got == 0 {
        return Ok(None);
    }
    if got < RECORD_HEADER_LEN {
        return Err(format!(
            "record header cut short after {got} of {RECORD_HEADER_LEN} bytes"
        ));
    }
    let (len, crc, seq) = split_header(&header);
    if len > max_record_len {
        return Err(format!(
            "length {len} exceeds the limit of {max_record_len}"
        ));
    }
    let mut payload = vec![0u8; len as usize];
    let got = read_up_to(reader, &mut payload);
    if got < payload.len() {
        return Err(format!("payload cut short after {got} of {len} bytes"));
    }
    if checksum(seq, &payload) != crc {
        return Err("checksum mismatch".to_string());
    }
    if seq != expected_seq {
        return Err(format!(
            "sequence number {seq} where {expected_seq} was expected"
        ));
    }
    Ok(Some(Record { seq, payload }))
}

/// Whether any complete, checksummed record starts after `offset` (damage, not a torn tail).
fn valid_record_after(
    file: &mut File,
    offset: u64,
    max_record_len: u32,
    path: &Path,
) -> Result<bool, LogError> {
    let mut rest = Vec::new();
    file.seek(SeekFrom::Start(offset))
        .and_then(|_| file.read_to_end(&mut rest))
        .map_err(|source| LogError::Io {
            path: path.to_path_buf(),
            context: "reading past a damaged record",
            source,
        })?;
    for start in 1..rest.len() {
        let Some(header) = rest.get(start..start + RECORD_HEADER_LEN) else {
            break;
        };
        let header: &[u8; RECORD_HEADER_LEN] = header.try_into().expect("slice of header length");
        let (len, crc, seq) = split_header(header);
        if len > max_record_len || seq == 0 {
            continue;
        }
        let body = start + RECORD_HEADER_LEN;
        if let Some(payload) = rest.get(body..body + len as usize)
            && checksum(seq, payload) == crc
        {
            return Ok(true);
        }
    }
    Ok(false)
}

fn split_header(header: &[u8; RECORD_HEADER_LEN]) -> (u32, u32, u64) {
    let [l0, l1, l2, l3, c0, c1, c2, c3, s @ ..] = *header;
    (
        u32::from_le_bytes([l0, l1, l2, l3]),
        u32::from_le_bytes([c0, c1, c2, c3]),
        u64::from_le_bytes(s),
    )
}

fn read_up_to(reader: &mut impl Read, buf: &mut [u8]) -> usize {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(_) => break,
        }
    }
    filled
}

fn checksum(seq: u64, payload: &[u8]) -> u32 {
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(&seq.to_le_bytes());
    hasher.update(payload);
    hasher.finalize()
}

fn sync_parent_dir(path: &Path) -> std::io::Result<()> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => File::open(dir)?.sync_all(),
        _ => File::open(".")?.sync_all(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn log_with(dir: &Path, payloads: &[&[u8]]) -> PathBuf {
        let path = dir.join("messages.iwl");
        let mut log = LogStore::open(&path, SyncPolicy::Always).unwrap();
        for (i, p) in payloads.iter().enumerate() {
            log.append(p, i as u64).unwrap();
        }
        path
    }

    #[test]
    fn records_survive_reopen_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = log_with(dir.path(), &[b"one", b"two", b""]);
        let log = LogStore::open(&path, SyncPolicy::Always).unwrap();
        assert_eq!(log.len(), 3);
        let payloads: Vec<_> = log
            .records()
            .unwrap()
            .into_iter()
            .map(|r| r.payload)
            .collect();
        assert_eq!(payloads, vec![b"one".to_vec(), b"two".to_vec(), Vec::new()]);
        assert_eq!(
            log.recovery(),
            Recovery {
                records: 3,
                truncated_bytes: 0
            }
        );
    }

    #[test]
    fn torn_tail_is_truncated_and_appends_continue() {
        let dir = tempfile::tempdir().unwrap();
        let path = log_with(dir.path(), &[b"kept", b"also kept"]);
        // A crash in the middle of a third append: header and half the payload reach the disk.
        let mut torn = Vec::new();
        torn.extend_from_slice(&20u32.to_le_bytes());
        torn.extend_from_slice(&checksum(3, &[7; 20]).to_le_bytes());
        torn.extend_from_slice(&3u64.to_le_bytes());
        torn.extend_from_slice(&[7; 10]);
        OpenOptions::new()
            .append(true)
            .open(&path)
            .unwrap()
            .write_all(&torn)
            .unwrap();

        let mut log = LogStore::open(&path, SyncPolicy::Always).unwrap();
        assert_eq!(
            log.recovery(),
            Recovery {
                records: 2,
                truncated_bytes: torn.len() as u64
            }
        );
        assert_eq!(log.append(b"after", 9).unwrap(), (3, true));
        let reopened = LogStore::open(&path, SyncPolicy::Always).unwrap();
        assert_eq!(
            reopened.records().unwrap().last().unwrap().payload,
            b"after"
        );
    }

    #[test]
    fn damage_before_valid_records_is_refused_not_truncated() {
        let dir = tempfile::tempdir().unwrap();
        let path = log_with(dir.path(), &[b"first record", b"second record"]);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[FILE_HEADER_LEN as usize + RECORD_HEADER_LEN + 2] ^= 0x40;
        std::fs::write(&path, &bytes).unwrap();
        let err = LogStore::open(&path, SyncPolicy::Always).unwrap_err();
        assert!(
            matches!(
                err,
                LogError::Corrupt {
                    offset: FILE_HEADER_LEN,
                    ..
                }
            ),
            "{err}"
        );
        assert_eq!(
            std::fs::read(&path).unwrap(),
            bytes,
            "a refused log is left untouched"
        );
    }

    #[test]
    fn foreign_file_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("notes.txt");
        std::fs::write(&path, b"shopping list: milk, bread, eggs").unwrap();
        assert!(matches!(
            LogStore::open(&path, SyncPolicy::Always),
            Err(LogError::NotALog { .. })
        ));
    }

    #[test]
    fn batched_policies_sync_when_due() {
        let dir = tempfile::tempdir().unwrap();
        let mut every = LogStore::open(dir.path().join("a.iwl"), SyncPolicy::EveryN(3)).unwrap();
        let durable: Vec<bool> = (0..6).map(|t| every.append(b"x", t).unwrap().1).collect();
        assert_eq!(durable, [false, false, true, false, false, true]);
        let mut timed =
            LogStore::open(dir.path().join("b.iwl"), SyncPolicy::IntervalNs(1_000)).unwrap();
        assert!(!timed.append(b"x", 0).unwrap().1);
        assert!(!timed.append(b"x", 999).unwrap().1);
        assert!(timed.append(b"x", 1_000).unwrap().1);
        assert_eq!(timed.sync().unwrap(), 3);
    }

    #[test]
    fn oversized_record_is_rejected_and_nothing_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("small.iwl");
        let mut log = LogStore::open_with_limit(&path, SyncPolicy::Always, 8).unwrap();
        assert!(matches!(
            log.append(&[0; 9], 0),
            Err(LogError::RecordTooLarge { len: 9, max: 8 })
        ));
        assert!(log.is_empty());
        assert_eq!(std::fs::metadata(&path).unwrap().len(), FILE_HEADER_LEN);
    }

    proptest! {
        /// Cutting a log anywhere (a crash at any byte) keeps exactly the records wholly before
        /// the cut, and the log accepts appends afterwards.
        #[test]
        fn any_crash_point_keeps_every_complete_record(
            payloads in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..40), 1..12),
            cut in any::<prop::sample::Index>(),
        ) {
            let dir = tempfile::tempdir().unwrap();
            let refs: Vec<&[u8]> = payloads.iter().map(Vec::as_slice).collect();
            let path = log_with(dir.path(), &refs);
            let bytes = std::fs::read(&path).unwrap();
            let cut_at = FILE_HEADER_LEN as usize + cut.index(bytes.len() - FILE_HEADER_LEN as usize + 1);
            std::fs::write(&path, &bytes[..cut_at]).unwrap();
            let mut complete = 0;
            let mut end = FILE_HEADER_LEN as usize;
            for p in &payloads {
                end += RECORD_HEADER_LEN + p.len();
                if end <= cut_at { complete += 1; }
            }
            let mut log = LogStore::open(&path, SyncPolicy::Always).unwrap();
            prop_assert_eq!(log.len(), complete as u64);
            let kept: Vec<_> = log.records().unwrap().into_iter().map(|r| r.payload).collect();
            prop_assert_eq!(&kept[..], &payloads[..complete]);
            log.append(b"resumed", 0).unwrap();
        }

        /// Garbage after a valid log never panics the recovery: it is truncated or refused.
        #[test]
        fn garbage_tail_never_panics(garbage in prop::collection::vec(any::<u8>(), 0..200)) {
            let dir = tempfile::tempdir().unwrap();
            let path = log_with(dir.path(), &[b"a", b"bb"]);
            OpenOptions::new().append(true).open(&path).unwrap().write_all(&garbage).unwrap();
            if let Ok(log) = LogStore::open(&path, SyncPolicy::Always) {
                prop_assert!(log.len() >= 2);
            }
        }
    }
}
