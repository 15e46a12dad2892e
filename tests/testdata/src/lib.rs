//! Internal: locates `shared/` (FIPA vectors, photographs, TUM RGB-D sequences) beside the clone.
//!
//! Tests and benches call [`shared`] or [`require`]; when the data is absent they print a clear
//! `SKIP` line and return, so a run without the data says so instead of silently passing.
#![warn(missing_docs)]

use std::path::{Path, PathBuf};

/// The shared data folder: `$INTELLWHEELS_SHARED` if set, else `shared/` beside the workspace.
pub fn shared() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("INTELLWHEELS_SHARED") {
        let dir = PathBuf::from(dir);
        return dir.is_dir().then_some(dir);
    }
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).ancestors().nth(2)?;
    let dir = workspace.parent()?.join("shared");
    dir.is_dir().then_some(dir)
}

/// `shared/<relative>` if it exists; otherwise prints `SKIP <test>: ...` to stderr and returns `None`.
pub fn require(test: &str, relative: &str) -> Option<PathBuf> {
    match shared().map(|dir| dir.join(relative)) {
        Some(path) if path.exists() => Some(path),
        _ => {
            skip(
                test,
                &format!(
                    "shared data `{relative}` not found (set INTELLWHEELS_SHARED or place shared/ beside the clone)"
                ),
            );
            None
        }
    }
}

/// Prints `SKIP <test>: <why>` on stderr where the test run's reader sees it: libtest captures
/// `println!`/`eprintln!` of a passing test, but not writes to the stderr handle itself.
pub fn skip(test: &str, why: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr().lock(), "SKIP {test}: {why}");
}

/// The cause of `err` as a `T`: its `source()`, downcast. Panics (for tests) when there is
/// none of that type, or when `err`'s message does not end with the cause's, which the
/// project's errors say too (`… : <cause>`).
pub fn cause<'a, T: std::error::Error + 'static>(
    err: &'a (dyn std::error::Error + 'static),
) -> &'a T {
    let cause = err
        .source()
        .and_then(|s| s.downcast_ref::<T>())
        .unwrap_or_else(|| panic!("no {} under `{err}`", std::any::type_name::<T>()));
    assert!(err.to_string().ends_with(&cause.to_string()), "{err}");
    cause
}
