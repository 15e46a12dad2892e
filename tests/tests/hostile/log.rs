//! Damaged message logs: every intact record is still read, each damaged region is reported
//! with its offset, and the tools exit 1 as `log query --help` promises.

use std::path::{Path, PathBuf};
use std::time::Duration;

use iw_logger::{DEFAULT_MAX_RECORD_LEN, LogStore, LoggedMessage, SyncPolicy, read_log};

const RECORDS: u64 = 2119;

fn message(i: u64) -> LoggedMessage {
    LoggedMessage {
        time_ns: i * 1_000,
        sender: "cognitive@chair-a".into(),
        receivers: vec!["control@chair-a".into()],
        performative: "request".into(),
        conversation_id: Some(format!("c{i}")),
        acl: format!("(request :content \"step {i}\")"),
    }
}

/// A log of [`RECORDS`] messages and the byte offset of each record.
fn write_log(dir: &Path) -> (PathBuf, Vec<u64>) {
    let path = dir.join("messages.iwl");
    let mut log = LogStore::open(&path, SyncPolicy::EveryN(512)).unwrap();
    let mut offsets = Vec::new();
    for i in 0..RECORDS {
        offsets.push(std::fs::metadata(&path).unwrap().len());
        log.append(&message(i).to_payload(), i).unwrap();
    }
    log.sync().unwrap();
    (path, offsets)
}

fn flip(path: &Path, at: u64) {
    let mut bytes = std::fs::read(path).unwrap();
    bytes[at as usize] ^= 0x20;
    std::fs::write(path, bytes).unwrap();
}

/// The step number a printed message carries.
fn step_of(line: &str) -> Option<u64> {
    let after = &line[line.find("step ")? + 5..];
    let digits: String = after.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().ok()
}

#[test]
fn a_flipped_byte_in_record_1001_hides_nothing_after_it() {
    let dir = tempfile::tempdir().unwrap();
    let (path, offsets) = write_log(dir.path());
    let damaged_at = offsets[1000];
    flip(&path, damaged_at + 40);
    let before = std::fs::read(&path).unwrap();

    let read = read_log(&path, DEFAULT_MAX_RECORD_LEN).unwrap();
    assert_eq!(read.records.len() as u64, RECORDS - 1);
    assert_eq!(read.damage.len(), 1);
    assert_eq!(read.damage[0].offset, damaged_at);
    // The writer refuses to open it (it would otherwise truncate acknowledged records).
    assert!(LogStore::open(&path, SyncPolicy::Always).is_err());
    assert_eq!(std::fs::read(&path).unwrap(), before, "nothing was changed");

    let Some(bin) = crate::intellwheels() else {
        return;
    };
    let log = path.to_str().unwrap();
    for args in [
        &["log", "query", "--log", log, "--json"][..],
        &["log", "replay", "--log", log, "--speed", "0"][..],
    ] {
        let result = crate::run(&bin, args, b"", Duration::from_secs(30));
        crate::assert_refused(
            &args[..2].join(" "),
            &result,
            1,
            &format!("damaged region at bytes {damaged_at}.."),
        );
        let stdout = String::from_utf8_lossy(&result.0.stdout);
        let shown: Vec<u64> = stdout.lines().filter_map(step_of).collect();
        let intact: Vec<u64> = (0..RECORDS).filter(|&i| i != 1000).collect();
        assert_eq!(
            shown, intact,
            "every intact record is shown, in order, and only those"
        );
    }
}

/// `intellwheels log query --log path`, bounded in time.
fn query(bin: &PathBuf, path: &Path) -> (std::process::Output, bool) {
    let args = ["log", "query", "--log", path.to_str().unwrap()];
    crate::run(bin, &args, b"", Duration::from_secs(30))
}

#[test]
fn a_torn_tail_is_reported_with_its_offset() {
    let dir = tempfile::tempdir().unwrap();
    let (path, offsets) = write_log(dir.path());
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 7]).unwrap();
    let tail_at = *offsets.last().unwrap();

    let read = read_log(&path, DEFAULT_MAX_RECORD_LEN).unwrap();
    assert_eq!(read.records.len() as u64, RECORDS - 1);
    assert!(read.damage[0].torn_tail);

    let Some(bin) = crate::intellwheels() else {
        return;
    };
    let result = query(&bin, &path);
    crate::assert_refused(
        "log query (torn tail)",
        &result,
        1,
        &format!("torn tail at byte {tail_at}"),
    );
}

#[test]
fn a_file_that_is_no_log_exits_1_and_prints_nothing() {
    let Some(bin) = crate::intellwheels() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("notes.iwl");
    std::fs::write(&path, b"shopping list").unwrap();
    let result = query(&bin, &path);
    crate::assert_refused(
        "log query (not a log)",
        &result,
        1,
        "not an intellwheels log",
    );
    assert!(result.0.stdout.is_empty());
}
