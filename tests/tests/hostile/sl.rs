//! Oversize SL content: refused by size or token count before it can take memory.

use std::time::Duration;

use iw_sl::{Level, MAX_INPUT_BYTES, MAX_TOKENS, SlError};

#[test]
fn ten_megabytes_of_sl_are_refused_unread() {
    let input = format!("((f {}))", "(g a) ".repeat((10 << 20) / 6));
    assert!(input.len() > 1 << 20);
    assert!(matches!(
        iw_sl::parse(&input, Level::Full),
        Err(SlError::TooLarge { .. })
    ));
    let Some(bin) = crate::intellwheels() else {
        return;
    };
    let ten_mb = "1 ".repeat(5 << 20);
    let refused = crate::run(
        &bin,
        &["sl", "parse"],
        format!("((f {ten_mb}))").as_bytes(),
        Duration::from_secs(20),
    );
    crate::assert_refused(
        "sl parse <10 MB",
        &refused,
        2,
        &format!("{MAX_INPUT_BYTES} bytes"),
    );
    assert!(
        refused.0.stdout.is_empty(),
        "nothing is printed for refused content"
    );
}

#[test]
fn a_token_bomb_within_the_size_cap_is_refused_with_its_position() {
    let input = format!("((f {}))", "a ".repeat(MAX_TOKENS + 1));
    assert!(input.len() < MAX_INPUT_BYTES);
    let err = iw_sl::parse(&input, Level::Full).unwrap_err();
    assert!(
        matches!(err, SlError::TooManyTokens { line: 1, .. }),
        "{err}"
    );
    // Deep nesting stays refused too.
    let deep = format!("({}{})", "(f ".repeat(10_000), ")".repeat(10_000));
    assert!(matches!(
        iw_sl::parse(&deep, Level::Full),
        Err(SlError::TooDeep { .. })
    ));
}
