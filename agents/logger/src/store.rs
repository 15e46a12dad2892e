//! [`LogStore`]: checksummed records appended to one file, with an fsync policy and recovery.
//!
//! On-disk layout (all integers little-endian):
//!
//! ```text
//! file header, 16 bytes
//! +---------------------------+---------------------------+
//! | magic "IWLOG\0v2" (8 B)   | reserved, zero (8 B)      |
//! +---------------------------+---------------------------+
//! record, 16 + len bytes
//! +------------+------------+------------------------+-----------------+
//! | len: u32   | crc: u32   | seq: u64               | payload (len B) |
//! +------------+------------+------------------------+-----------------+
//! crc = CRC-32C (Castagnoli) of (seq bytes ++ payload); seq starts at 1 and grows by one per record
//! ```
//!
//! Logs written before the checksum was CRC-32C carry the magic `IWLOG\0v1` and a CRC-32 (IEEE);
//! they are still read and appended to with that checksum, so no existing log becomes unreadable.
//!
//! A record is valid when its header and payload are complete, `len` is within the configured
//! limit, the checksum matches and `seq` follows its predecessor. Recovery reads records until the
//! first invalid one. If no valid record follows it, that is a torn tail (a write cut short by a
//! crash, never acknowledged) and the file is truncated there; if a valid record follows, the log
//! was damaged in the middle and [`LogStore::open`] refuses with the offset instead of dropping
//! acknowledged records.
//!
//! Readers ([`read_log`]) never stop at damage: they report each damaged region (its offset, length
//! and what is wrong) and resynchronise on the next complete, checksummed record whose sequence
//! number is not behind, so the intact records after a flipped byte are still read.

use std::fs::{File, OpenOptions};
use std::io::{BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

const MAGIC_V1_IEEE: &[u8; 8] = b"IWLOG\0v1";
const MAGIC: &[u8; 8] = b"IWLOG\0v2";
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
    #[error(
        "{path}: not an intellwheels log (bad magic; the logger agent's store, `agents.log`, is one); refusing to touch it"
    )]
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
    /// A reader met damage (the strict readers [`read_records`] and [`crate::Query::run`]).
    #[error("{path}: {damage}")]
    Damaged {
        /// The file.
        path: PathBuf,
        /// The first damaged region.
        damage: Damage,
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

/// A stretch of a log that holds no valid record, as [`read_log`] found it.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Damage {
    /// Byte offset where the damage starts (where a record was expected).
    pub offset: u64,
    /// Bytes skipped before the next valid record (or the end of the file).
    pub len: u64,
    /// What is wrong with the record expected at `offset`.
    pub reason: String,
    /// No valid record follows: a write cut short (a crash, or an append still in progress).
    pub torn_tail: bool,
    /// Sequence numbers missing between the record before and the one after (0 for a torn tail).
    pub missing_records: u64,
}

impl std::fmt::Display for Damage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let end = self.offset + self.len;
        if self.torn_tail {
            write!(
                f,
                "torn tail at byte {}: {} bytes to the end of the file hold no complete record ({})",
                self.offset, self.len, self.reason
            )
        } else {
            write!(
                f,
                "damaged region at bytes {}..{end} ({} bytes, {} records lost): {}; \
                 reading resumed at byte {end}",
                self.offset, self.len, self.missing_records, self.reason
            )
        }
    }
}

/// Every intact record of a log and every damaged region between them, in file order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct LogRead {
    /// The valid records.
    pub records: Vec<Record>,
    /// The damaged regions, in file order; empty for an intact log.
    pub damage: Vec<Damage>,
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
    format: Format,
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
        let format = scan.format;
        let recovery = match scan.first_bad {
            None => Recovery {
                records: scan.records,
                truncated_bytes: 0,
            },
            Some((offset, reason)) => {
                if valid_record_after(
                    &mut file,
                    offset,
                    scan.records + 1,
                    format,
                    max_record_len,
                    &path,
                )? {
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
            format,
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
        frame.extend_from_slice(&self.format.checksum(seq, payload).to_le_bytes());
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

/// Reads every record of the log at `path` without opening it for writing, and fails with the
/// first damaged region if there is any (a torn tail included): for callers that must not work
/// on a partial log. [`read_log`] reads past damage instead.
pub fn read_records(path: &Path, max_record_len: u32) -> Result<Vec<Record>, LogError> {
    let read = read_log(path, max_record_len)?;
    match read.damage.into_iter().next() {
        None => Ok(read.records),
        Some(damage) => Err(LogError::Damaged {
            path: path.to_path_buf(),
            damage,
        }),
    }
}

/// Reads the log at `path` without opening it for writing (for queries and replay while the
/// logger agent runs), skipping and reporting each damaged region: after an invalid record it
/// resynchronises on the next complete, checksummed record whose sequence number is not behind.
///
/// Every record is kept in the answer; [`LogReader`] reads the same way one item at a time, in
/// memory bounded by the record limit whatever the log's size.
pub fn read_log(path: &Path, max_record_len: u32) -> Result<LogRead, LogError> {
    collect(LogReader::open(path, max_record_len)?)
}

/// [`read_log`] on a log's bytes already in memory; `path` only names it in errors.
pub fn parse_log(bytes: &[u8], path: &Path, max_record_len: u32) -> Result<LogRead, LogError> {
    collect(LogReader::new(bytes, path, max_record_len)?)
}

fn collect<R: Read>(reader: LogReader<R>) -> Result<LogRead, LogError> {
    let mut read = LogRead::default();
    for item in reader {
        match item? {
            LogItem::Record(record) => read.records.push(record),
            LogItem::Damage(damage) => read.damage.push(damage),
        }
    }
    Ok(read)
}

/// One item of a log read in file order: an intact record (or what a reader made of it), or a
/// damaged region read past.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LogItem<T = Record> {
    /// An intact record.
    Record(T),
    /// A stretch that holds no valid record.
    Damage(Damage),
}

/// Bytes asked of the file at a time.
const READ_CHUNK: usize = 64 * 1024;

/// Reads a log one [`LogItem`] at a time, as [`read_log`] describes, holding only a read-ahead
/// window of at most one largest record plus 64 KiB: a log of any size is read in
/// bounded memory. An I/O error ends the reading after it is returned.
#[derive(Debug)]
pub struct LogReader<R> {
    reader: R,
    path: PathBuf,
    format: Format,
    max_record_len: u32,
    /// Read but not yet consumed from `head` on; `buf[head]` is at byte `offset` of the log.
    buf: Vec<u8>,
    head: usize,
    offset: u64,
    eof: bool,
    expected_seq: u64,
    done: bool,
}

impl LogReader<File> {
    /// Opens the log at `path` for reading, if it is a regular file (a FIFO would block the
    /// open, a device never end) whose header is a log's: a large file that is not a log is
    /// refused from its first 16 bytes.
    pub fn open(path: &Path, max_record_len: u32) -> Result<Self, LogError> {
        let file = iw_file::open_regular(path).map_err(|source| LogError::Io {
            path: path.to_path_buf(),
            context: "opening the log",
            source,
        })?;
        Self::new(file, path, max_record_len)
    }
}

impl<R: Read> LogReader<R> {
    /// Reads a log from `reader`, checking its header first; `path` names it in errors.
    pub fn new(mut reader: R, path: &Path, max_record_len: u32) -> Result<Self, LogError> {
        let format = check_magic(&mut reader, path)?;
        Ok(Self::at(
            reader,
            path,
            format,
            max_record_len,
            FILE_HEADER_LEN,
            1,
        ))
    }

    /// Reads on from byte `offset` of a log (where `reader` stands), expecting `expected_seq`.
    fn at(
        reader: R,
        path: &Path,
        format: Format,
        max_record_len: u32,
        offset: u64,
        expected_seq: u64,
    ) -> Self {
        LogReader {
            reader,
            path: path.to_path_buf(),
            format,
            max_record_len,
            buf: Vec::new(),
            head: 0,
            offset,
            eof: false,
            expected_seq,
            done: false,
        }
    }

    /// Bytes the read-ahead window holds room for: at most one largest record, its header and
    /// one 64 KiB read, whatever the log's size.
    pub fn window_capacity(&self) -> usize {
        self.buf.capacity()
    }

    fn available(&self) -> &[u8] {
        &self.buf[self.head..]
    }

    fn consume(&mut self, n: usize) {
        self.head += n;
        self.offset += n as u64;
    }

    /// Reads until `want` bytes are available or the file ends.
    fn fill(&mut self, want: usize) -> Result<(), LogError> {
        while self.available().len() < want && !self.eof {
            // Consumed bytes are dropped before the window grows.
            self.buf.drain(..self.head);
            self.head = 0;
            let len = self.buf.len();
            let more = READ_CHUNK.max(want - len);
            self.buf.reserve_exact(more);
            self.buf.resize(len + more, 0);
            let got = loop {
                match self.reader.read(&mut self.buf[len..]) {
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    got => break got,
                }
            };
            let got = got.map_err(|source| {
                self.buf.truncate(len);
                LogError::Io {
                    path: self.path.clone(),
                    context: "reading the log",
                    source,
                }
            })?;
            self.buf.truncate(len + got);
            self.eof = got == 0;
        }
        Ok(())
    }

    /// The complete, checksummed record at the window's start, `Ok(None)` at the end of the
    /// file, or why there is none.
    fn record_here(&mut self) -> Result<Result<Option<Record>, String>, LogError> {
        self.fill(RECORD_HEADER_LEN)?;
        if let Some(header) = self.available().get(..RECORD_HEADER_LEN) {
            let (len, _, _) = split_header(header.try_into().unwrap_or(&[0; RECORD_HEADER_LEN]));
            if len <= self.max_record_len {
                self.fill(RECORD_HEADER_LEN + len as usize)?;
            }
        }
        Ok(read_record(
            &mut self.available(),
            self.format,
            self.max_record_len,
        ))
    }

    /// After an invalid record at the window's start: the damaged region up to the next
    /// complete, checksummed record not behind the expected number, or to the end (a torn tail).
    fn skip_damage(&mut self, reason: String) -> Result<Damage, LogError> {
        let start = self.offset;
        self.consume(1);
        loop {
            self.fill(RECORD_HEADER_LEN)?;
            let Some(header) = self.available().get(..RECORD_HEADER_LEN) else {
                let rest = self.available().len();
                self.consume(rest);
                self.done = true;
                return Ok(Damage {
                    offset: start,
                    len: self.offset - start,
                    reason,
                    torn_tail: true,
                    missing_records: 0,
                });
            };
            let (len, _, seq) = split_header(header.try_into().unwrap_or(&[0; RECORD_HEADER_LEN]));
            // Cheap tests first: most offsets fail them without a checksum.
            if len <= self.max_record_len
                && seq >= self.expected_seq
                && let Ok(Some(record)) = self.record_here()?
            {
                let damage = Damage {
                    offset: start,
                    len: self.offset - start,
                    reason,
                    torn_tail: false,
                    missing_records: record.seq - self.expected_seq,
                };
                self.expected_seq = record.seq;
                return Ok(damage);
            }
            self.consume(1);
        }
    }

    fn next_item(&mut self) -> Result<Option<LogItem>, LogError> {
        let reason = match self.record_here()? {
            Ok(None) => return Ok(None),
            Ok(Some(record)) if record.seq == self.expected_seq => {
                self.consume(RECORD_HEADER_LEN + record.payload.len());
                self.expected_seq += 1;
                return Ok(Some(LogItem::Record(record)));
            }
            Ok(Some(record)) if record.seq > self.expected_seq => {
                // Intact, but records are missing before it; it is read next.
                let damage = Damage {
                    offset: self.offset,
                    len: 0,
                    reason: format!(
                        "sequence number {} where {} was expected",
                        record.seq, self.expected_seq
                    ),
                    torn_tail: false,
                    missing_records: record.seq - self.expected_seq,
                };
                self.expected_seq = record.seq;
                return Ok(Some(LogItem::Damage(damage)));
            }
            Ok(Some(record)) => format!(
                "sequence number {} repeats (expected {})",
                record.seq, self.expected_seq
            ),
            Err(reason) => reason,
        };
        self.skip_damage(reason).map(|d| Some(LogItem::Damage(d)))
    }
}

impl<R: Read> Iterator for LogReader<R> {
    type Item = Result<LogItem, LogError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let item = self.next_item();
        if !matches!(item, Ok(Some(_))) {
            self.done = true;
        }
        item.transpose()
    }
}

struct Scan {
    format: Format,
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
    let format = check_magic(&mut reader, path)?;
    let mut offset = FILE_HEADER_LEN;
    let mut records = 0u64;
    let first_bad = loop {
        match read_record(&mut reader, format, max_record_len) {
            Ok(None) => break None,
            Ok(Some(record)) if record.seq == records + 1 => {
                records += 1;
                offset += (RECORD_HEADER_LEN + record.payload.len()) as u64;
            }
            Ok(Some(record)) => {
                let reason = format!(
                    "sequence number {} where {} was expected",
                    record.seq,
                    records + 1
                );
                break Some((offset, reason));
            }
            Err(reason) => break Some((offset, reason)),
        }
    };
    Ok(Scan {
        format,
        records,
        first_bad,
    })
}

fn check_magic(reader: &mut impl Read, path: &Path) -> Result<Format, LogError> {
    let mut header = [0u8; FILE_HEADER_LEN as usize];
    match reader.read_exact(&mut header) {
        Ok(()) if &header[..8] == MAGIC => Ok(Format::Castagnoli),
        Ok(()) if &header[..8] == MAGIC_V1_IEEE => Ok(Format::V1Ieee),
        _ => Err(LogError::NotALog {
            path: path.to_path_buf(),
        }),
    }
}

/// `Ok(None)` at a clean end of file, `Err(reason)` for an invalid or incomplete record; the
/// caller checks the sequence number.
fn read_record(
    reader: &mut impl Read,
    format: Format,
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
    if format.checksum(seq, &payload) != crc {
        return Err("checksum mismatch".to_string());
    }
    Ok(Some(Record { seq, payload }))
}

/// Whether a complete, checksummed record not behind `min_seq` starts at or after `offset`
/// (damage, not a torn tail).
fn valid_record_after(
    file: &mut File,
    offset: u64,
    min_seq: u64,
    format: Format,
    max_record_len: u32,
    path: &Path,
) -> Result<bool, LogError> {
    file.seek(SeekFrom::Start(offset))
        .map_err(|source| LogError::Io {
            path: path.to_path_buf(),
            context: "reading past a damaged record",
            source,
        })?;
    let reader = LogReader::at(file, path, format, max_record_len, offset, min_seq);
    for item in reader {
        if let LogItem::Record(_) = item? {
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

/// Which checksum a log's records carry, from its magic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    /// `IWLOG\0v1`: CRC-32 (IEEE), as logs were written before the format doc was followed.
    V1Ieee,
    /// `IWLOG\0v2`: CRC-32C, as the format doc says.
    Castagnoli,
}

impl Format {
    fn checksum(self, seq: u64, payload: &[u8]) -> u32 {
        match self {
            Format::V1Ieee => {
                let mut hasher = crc32fast::Hasher::new();
                hasher.update(&seq.to_le_bytes());
                hasher.update(payload);
                hasher.finalize()
            }
            Format::Castagnoli => crc32c(crc32c(0, &seq.to_le_bytes()), payload),
        }
    }
}

/// CRC-32C (Castagnoli, reflected polynomial 0x82F63B78) lookup table.
const CRC32C_TABLE: [u32; 256] = {
    let mut table = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut bit = 0;
        while bit < 8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0x82F6_3B78
            } else {
                c >> 1
            };
            bit += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
};

/// Continues the CRC-32C `crc` (0 to start) over `bytes`.
fn crc32c(crc: u32, bytes: &[u8]) -> u32 {
    let mut c = !crc;
    for &b in bytes {
        c = CRC32C_TABLE[((c ^ u32::from(b)) & 0xff) as usize] ^ (c >> 8);
    }
    !c
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

    #[test]
    fn a_device_or_folder_is_refused_and_a_large_non_log_is_refused_from_its_header() {
        let dir = tempfile::tempdir().unwrap();
        for path in [Path::new("/dev/zero"), dir.path()] {
            let err = read_log(path, DEFAULT_MAX_RECORD_LEN).unwrap_err();
            assert!(err.to_string().contains("not a regular file"), "{err}");
        }
        // 1 GiB of holes: refused from its first 16 bytes, not read whole first.
        let big = dir.path().join("big.bin");
        File::create(&big).unwrap().set_len(1 << 30).unwrap();
        let err = read_log(&big, DEFAULT_MAX_RECORD_LEN).unwrap_err();
        assert!(matches!(err, LogError::NotALog { .. }), "{err}");
    }
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
        torn.extend_from_slice(&Format::Castagnoli.checksum(3, &[7; 20]).to_le_bytes());
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

    #[test]
    fn crc32c_matches_the_published_check_values() {
        // The catalogue's check value and RFC 3720 (iSCSI) B.4 vectors.
        assert_eq!(crc32c(0, b"123456789"), 0xE306_9283);
        assert_eq!(crc32c(0, &[0; 32]), 0x8A91_36AA);
        assert_eq!(crc32c(0, &[0xFF; 32]), 0x62A8_AB43);
        let ascending: Vec<u8> = (0..32).collect();
        assert_eq!(crc32c(0, &ascending), 0x46DD_794E);
        assert_eq!(crc32c(crc32c(0, b"1234"), b"56789"), 0xE306_9283);
    }

    #[test]
    fn new_logs_carry_crc32c_and_old_crc32_logs_still_read_and_append() {
        let dir = tempfile::tempdir().unwrap();
        let path = log_with(dir.path(), &[b"payload"]);
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], MAGIC);
        let stored_crc = u32::from_le_bytes(bytes[20..24].try_into().unwrap());
        let mut covered = 1u64.to_le_bytes().to_vec();
        covered.extend_from_slice(b"payload");
        assert_eq!(stored_crc, crc32c(0, &covered));

        // A v1 log as the earlier writer left it: CRC-32 (IEEE).
        let old = dir.path().join("old.iwl");
        let mut v1 = MAGIC_V1_IEEE.to_vec();
        v1.extend_from_slice(&[0; 8]);
        v1.extend_from_slice(&7u32.to_le_bytes());
        v1.extend_from_slice(&crc32fast::hash(&covered).to_le_bytes());
        v1.extend_from_slice(&1u64.to_le_bytes());
        v1.extend_from_slice(b"payload");
        std::fs::write(&old, &v1).unwrap();
        let mut log = LogStore::open(&old, SyncPolicy::Always).unwrap();
        assert_eq!(log.len(), 1);
        log.append(b"more", 0).unwrap();
        let read = read_log(&old, DEFAULT_MAX_RECORD_LEN).unwrap();
        assert!(read.damage.is_empty(), "{:?}", read.damage);
        assert_eq!(read.records.len(), 2);
    }

    /// Byte offsets of every record of a log written by [`log_with`].
    fn record_offsets(payloads: &[Vec<u8>]) -> Vec<usize> {
        let mut at = FILE_HEADER_LEN as usize;
        payloads
            .iter()
            .map(|p| {
                let start = at;
                at += RECORD_HEADER_LEN + p.len();
                start
            })
            .collect()
    }

    #[test]
    fn a_flipped_byte_is_reported_and_the_records_after_it_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let payloads: Vec<Vec<u8>> = (0..2119)
            .map(|i| format!("message {i}").into_bytes())
            .collect();
        let refs: Vec<&[u8]> = payloads.iter().map(Vec::as_slice).collect();
        let path = dir.path().join("messages.iwl");
        let mut log = LogStore::open(&path, SyncPolicy::EveryN(1000)).unwrap();
        for p in &refs {
            log.append(p, 0).unwrap();
        }
        log.sync().unwrap();
        let damaged_at = record_offsets(&payloads)[1000];
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[damaged_at + RECORD_HEADER_LEN + 3] ^= 0x01;
        std::fs::write(&path, &bytes).unwrap();

        let read = read_log(&path, DEFAULT_MAX_RECORD_LEN).unwrap();
        assert_eq!(
            read.records.len(),
            2118,
            "every intact record, after the damage too"
        );
        assert_eq!(read.records[1000].seq, 1002);
        assert_eq!(read.records.last().unwrap().payload, b"message 2118");
        assert_eq!(
            read.damage,
            [Damage {
                offset: damaged_at as u64,
                len: (RECORD_HEADER_LEN + payloads[1000].len()) as u64,
                reason: "checksum mismatch".into(),
                torn_tail: false,
                missing_records: 1,
            }]
        );
        let strict = read_records(&path, DEFAULT_MAX_RECORD_LEN).unwrap_err();
        assert!(
            strict
                .to_string()
                .contains(&format!("bytes {damaged_at}..")),
            "{strict}"
        );
    }

    #[test]
    fn a_torn_tail_is_reported_by_readers() {
        let dir = tempfile::tempdir().unwrap();
        let path = log_with(dir.path(), &[b"kept", b"cut"]);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 2]).unwrap();
        let read = read_log(&path, DEFAULT_MAX_RECORD_LEN).unwrap();
        assert_eq!(read.records.len(), 1);
        let tail_at = (FILE_HEADER_LEN as usize + RECORD_HEADER_LEN + 4) as u64;
        assert_eq!(read.damage.len(), 1);
        assert!(read.damage[0].torn_tail);
        assert_eq!(read.damage[0].offset, tail_at);
        assert!(
            read.damage[0].reason.contains("cut short"),
            "{:?}",
            read.damage
        );
    }

    #[test]
    fn a_sequence_gap_and_a_repeated_record_are_reported() {
        let dir = tempfile::tempdir().unwrap();
        let payloads: Vec<Vec<u8>> = [b"a", b"b", b"c"].map(|p| p.to_vec()).to_vec();
        let refs: Vec<&[u8]> = payloads.iter().map(Vec::as_slice).collect();
        let path = log_with(dir.path(), &refs);
        let offsets = record_offsets(&payloads);
        let bytes = std::fs::read(&path).unwrap();
        // Record 2 cut out: 1 then 3.
        let mut gap = bytes[..offsets[1]].to_vec();
        gap.extend_from_slice(&bytes[offsets[2]..]);
        std::fs::write(&path, &gap).unwrap();
        let read = read_log(&path, DEFAULT_MAX_RECORD_LEN).unwrap();
        assert_eq!(
            read.records.iter().map(|r| r.seq).collect::<Vec<_>>(),
            [1, 3]
        );
        assert_eq!(read.damage.len(), 1);
        assert_eq!(read.damage[0].missing_records, 1);
        // Record 1 replayed after record 2: skipped, reported, record 3 still read.
        let mut replayed = bytes[..offsets[2]].to_vec();
        replayed.extend_from_slice(&bytes[offsets[0]..offsets[1]]);
        replayed.extend_from_slice(&bytes[offsets[2]..]);
        std::fs::write(&path, &replayed).unwrap();
        let read = read_log(&path, DEFAULT_MAX_RECORD_LEN).unwrap();
        assert_eq!(
            read.records.iter().map(|r| r.seq).collect::<Vec<_>>(),
            [1, 2, 3]
        );
        assert_eq!(read.damage.len(), 1);
        assert!(
            read.damage[0].reason.contains("repeats"),
            "{:?}",
            read.damage
        );
    }

    /// A log made as it is read, never held whole: `records` records of `payload_len` bytes,
    /// record `flipped` with one payload byte flipped.
    struct MadeLog {
        next_seq: u64,
        records: u64,
        payload_len: usize,
        flipped: u64,
        pending: Vec<u8>,
        pos: usize,
    }

    impl Read for MadeLog {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.pos == self.pending.len() {
                if self.next_seq > self.records {
                    return Ok(0);
                }
                let seq = self.next_seq;
                let payload = vec![seq as u8; self.payload_len];
                self.pending.clear();
                self.pending
                    .extend_from_slice(&(self.payload_len as u32).to_le_bytes());
                let crc = Format::Castagnoli.checksum(seq, &payload);
                self.pending.extend_from_slice(&crc.to_le_bytes());
                self.pending.extend_from_slice(&seq.to_le_bytes());
                self.pending.extend_from_slice(&payload);
                if seq == self.flipped {
                    self.pending[RECORD_HEADER_LEN + 7] ^= 0x20;
                }
                self.pos = 0;
                self.next_seq += 1;
            }
            let n = buf.len().min(self.pending.len() - self.pos);
            buf[..n].copy_from_slice(&self.pending[self.pos..self.pos + n]);
            self.pos += n;
            Ok(n)
        }
    }

    #[test]
    fn a_log_hundreds_of_times_the_window_is_read_in_bounded_memory_past_its_damage() {
        const RECORDS: u64 = 2048;
        const PAYLOAD: usize = 64 * 1024;
        const MAX_RECORD: u32 = 2 * PAYLOAD as u32;
        let mut header = MAGIC.to_vec();
        header.extend_from_slice(&[0; 8]);
        let made = MadeLog {
            next_seq: 1,
            records: RECORDS,
            payload_len: PAYLOAD,
            flipped: 1000,
            pending: header,
            pos: 0,
        };
        // 128 MiB of log; the window may hold one largest record and a chunk.
        let bound = RECORD_HEADER_LEN + MAX_RECORD as usize + READ_CHUNK;
        let log_len = FILE_HEADER_LEN + RECORDS * (RECORD_HEADER_LEN + PAYLOAD) as u64;
        assert!(log_len > 300 * bound as u64);
        let mut reader = LogReader::new(made, Path::new("made.iwl"), MAX_RECORD).unwrap();
        let (mut seqs, mut damage) = (Vec::new(), Vec::new());
        while let Some(item) = reader.next() {
            match item.unwrap() {
                LogItem::Record(r) => {
                    assert!(
                        r.payload.iter().all(|&b| b == r.seq as u8),
                        "record {}",
                        r.seq
                    );
                    seqs.push(r.seq);
                }
                LogItem::Damage(d) => damage.push(d),
            }
            assert!(
                reader.window_capacity() <= bound,
                "window of {} bytes",
                reader.window_capacity()
            );
        }
        let want: Vec<u64> = (1..=RECORDS).filter(|&s| s != 1000).collect();
        assert_eq!(seqs, want, "every intact record, in order");
        assert_eq!(damage.len(), 1, "{damage:?}");
        let record_len = (RECORD_HEADER_LEN + PAYLOAD) as u64;
        assert_eq!(damage[0].offset, FILE_HEADER_LEN + 999 * record_len);
        assert_eq!((damage[0].len, damage[0].missing_records), (record_len, 1));
    }

    /// A log of `payloads` in `dir` and its bytes with bit `bit` of the byte at `at` (after the
    /// file header) flipped, and that byte's offset; the file itself is left intact.
    fn flipped_log(
        dir: &Path,
        payloads: &[Vec<u8>],
        at: prop::sample::Index,
        bit: u8,
    ) -> (PathBuf, Vec<u8>, usize) {
        let refs: Vec<&[u8]> = payloads.iter().map(Vec::as_slice).collect();
        let path = log_with(dir, &refs);
        let mut bytes = std::fs::read(&path).unwrap();
        let flip = FILE_HEADER_LEN as usize + at.index(bytes.len() - FILE_HEADER_LEN as usize);
        bytes[flip] ^= 1 << bit;
        (path, bytes, flip)
    }

    /// Hands out at most `step` bytes per read, as a pipe or a slow disk may.
    struct Trickle<'a> {
        bytes: &'a [u8],
        step: usize,
    }

    impl Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = buf.len().min(self.step).min(self.bytes.len());
            buf[..n].copy_from_slice(&self.bytes[..n]);
            self.bytes = &self.bytes[n..];
            Ok(n)
        }
    }

    proptest! {
        /// Short reads change nothing: a damaged log read a few bytes at a time gives the same
        /// records and damage as read at once.
        #[test]
        fn short_reads_give_the_same_log(
            payloads in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..40), 1..10),
            at in any::<prop::sample::Index>(),
            step in 1usize..40,
        ) {
            let dir = tempfile::tempdir().unwrap();
            let (path, bytes, _) = flipped_log(dir.path(), &payloads, at, 2);
            let whole = parse_log(&bytes, &path, 64).unwrap();
            let trickled = collect(
                LogReader::new(Trickle { bytes: &bytes, step }, &path, 64).unwrap(),
            ).unwrap();
            prop_assert_eq!(trickled, whole);
        }
    }

    proptest! {
        /// Any bytes after a valid header: no panic, records in increasing order, damaged regions
        /// in file order, inside the file and not overlapping.
        #[test]
        fn arbitrary_bytes_read_without_panic_and_damage_is_consistent(
            body in prop::collection::vec(any::<u8>(), 0..600),
        ) {
            let mut bytes = MAGIC.to_vec();
            bytes.extend_from_slice(&[0; 8]);
            bytes.extend_from_slice(&body);
            let read = parse_log(&bytes, Path::new("fuzz.iwl"), 64).unwrap();
            prop_assert!(read.records.windows(2).all(|w| w[0].seq < w[1].seq));
            let mut end = FILE_HEADER_LEN;
            for d in &read.damage {
                prop_assert!(d.offset >= end && d.offset + d.len <= bytes.len() as u64);
                end = d.offset + d.len;
            }
        }

        /// Any one flipped byte loses at most the record that holds it; the damage is reported.
        #[test]
        fn one_flipped_byte_loses_only_its_record(
            payloads in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..40), 1..12),
            at in any::<prop::sample::Index>(),
            bit in 0u8..8,
        ) {
            let dir = tempfile::tempdir().unwrap();
            let (path, bytes, flip) = flipped_log(dir.path(), &payloads, at, bit);
            std::fs::write(&path, &bytes).unwrap();
            let hit = record_offsets(&payloads).iter().rposition(|&o| o <= flip).unwrap();
            let read = read_log(&path, DEFAULT_MAX_RECORD_LEN).unwrap();
            let kept: Vec<u64> = read.records.iter().map(|r| r.seq).collect();
            let want: Vec<u64> = (1..=payloads.len() as u64).filter(|&s| s != hit as u64 + 1).collect();
            prop_assert_eq!(kept, want);
            prop_assert_eq!(read.damage.len(), 1);
        }


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
