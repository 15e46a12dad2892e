//! The hostile suite: what a hostile tester did to the platform, replayed; each test asserts that
//! nothing is obeyed, nothing is lost and the refusal is a clear error (issue 20).
//!
//! | attack                                     | module       |
//! |--------------------------------------------|--------------|
//! | forged control frames, impostor services,  | [`control`]  |
//! | a restart after `kill -9`                  |              |
//! | free ids, forged `Duplicate`, foreign      |              |
//! | agents under a roster                      |              |
//! | flipped bytes, torn tails, spliced records | [`log`]      |
//! | connection flood, slowloris on dashboard   | [`dashboard`]|
//! | extreme flags, a FIFO as input             | [`flags`]    |
//! | oversize and token-bomb SL content         | [`sl`]       |
//!
//! Tests that run the `intellwheels` binary find it beside this test's target directory (`cargo
//! test --workspace` builds it); without it they print SKIP and check the libraries only.

mod control;
mod dashboard;
mod flags;
mod log;
mod sl;

use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The `intellwheels` binary of this build, if it was built (SKIP printed otherwise).
pub fn intellwheels() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    // target/<profile>/deps/hostile-<hash> -> target/<profile>/intellwheels
    let bin = exe.parent()?.parent()?.join("intellwheels");
    if bin.is_file() {
        Some(bin)
    } else {
        println!(
            "SKIP: {} is not built (cargo build -p intellwheels, or cargo test --workspace); \
             only the library checks ran",
            bin.display()
        );
        None
    }
}

/// Runs `bin args` with `stdin` fed, killed after `limit`: (output, whether it finished).
pub fn run(bin: &PathBuf, args: &[&str], stdin: &[u8], limit: Duration) -> (Output, bool) {
    let mut child = Command::new(bin)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start intellwheels");
    let mut input = child.stdin.take().expect("stdin");
    let stdin = stdin.to_vec();
    // A refusing child may close stdin early: a write error then is expected.
    let feeder = std::thread::spawn(move || {
        let _ = input.write_all(&stdin);
    });
    // Drained as the child writes, or a full pipe would stall it.
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut pipe) = pipe {
                let _ = pipe.read_to_end(&mut bytes);
            }
            bytes
        })
    };
    let stdout = drain(
        child
            .stdout
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    let stderr = drain(
        child
            .stderr
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    let started = Instant::now();
    let finished = loop {
        if child.try_wait().expect("wait").is_some() {
            break true;
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            break false;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let status = child.wait().expect("wait");
    let _ = feeder.join();
    let output = Output {
        status,
        stdout: stdout.join().expect("stdout reader"),
        stderr: stderr.join().expect("stderr reader"),
    };
    (output, finished)
}

/// Asserts a clean refusal: finished, exit status `code`, stderr mentions `needle`, no panic.
pub fn assert_refused(what: &str, (output, finished): &(Output, bool), code: i32, needle: &str) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        *finished,
        "{what}: still running at the limit (a hang); stderr: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{what}: panicked: {stderr}");
    assert_eq!(output.status.code(), Some(code), "{what}: stderr: {stderr}");
    assert!(
        stderr.contains(needle),
        "{what}: the error should say `{needle}`: {stderr}"
    );
    println!("{what}: refused: {}", stderr.lines().next().unwrap_or(""));
}
