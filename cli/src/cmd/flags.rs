//! Value parsers shared by every subcommand's flags, so a hostile or mistyped number is refused
//! by clap with the flag's name instead of panicking later (`Duration::from_secs_f64(1e300)`).

use std::time::Duration;

/// Longest time a duration flag accepts, s (a week: far beyond any run, far below `Duration`'s
/// range).
pub const MAX_FLAG_SECONDS: f64 = 7.0 * 24.0 * 3600.0;

/// Slowest and fastest `log replay --speed` besides 0: a gap of `u64::MAX` ns divided by the
/// slowest speed still fits a `Duration`.
pub const REPLAY_SPEED_RANGE: std::ops::RangeInclusive<f64> = 1e-3..=1e9;

fn number(text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .map_err(|_| format!("`{text}` is not a number"))
}

/// A positive, finite number of seconds up to [`MAX_FLAG_SECONDS`] (`--seconds`, `--timeout`,
/// `--max-time-s`, ...).
pub fn seconds(text: &str) -> Result<Duration, String> {
    let s = number(text)?;
    if !(s.is_finite() && s > 0.0) {
        return Err(format!(
            "must be a positive, finite number of seconds, got {text}"
        ));
    }
    if s > MAX_FLAG_SECONDS {
        return Err(format!(
            "{text} s is longer than the longest accepted, {MAX_FLAG_SECONDS} s (7 days)"
        ));
    }
    Duration::try_from_secs_f64(s).map_err(|e| format!("{text} s: {e}"))
}

/// A replay speed: 0 (no waiting) or a factor within [`REPLAY_SPEED_RANGE`].
pub fn replay_speed(text: &str) -> Result<f64, String> {
    let speed = number(text)?;
    if speed == 0.0 || REPLAY_SPEED_RANGE.contains(&speed) {
        Ok(speed)
    } else {
        Err(format!(
            "must be 0 (no waiting) or between {} and {}, got {text}",
            REPLAY_SPEED_RANGE.start(),
            REPLAY_SPEED_RANGE.end()
        ))
    }
}

/// A count of worker threads: 1 to [`MAX_THREADS`].
pub fn threads(text: &str) -> Result<usize, String> {
    let n: usize = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a whole number"))?;
    if (1..=MAX_THREADS).contains(&n) {
        Ok(n)
    } else {
        Err(format!("must be between 1 and {MAX_THREADS}, got {n}"))
    }
}

/// A count from 1 to `max` (`--drivers`, `--window`, ...): a count too large for the work it
/// sizes overflows arithmetic or never ends; clap names the flag and the range.
pub fn count(max: u64) -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(1..=max)
}

/// A count from 0 to `max` (`--seeds`, `--global-runs`, ...: 0 skips that part); a count past
/// `max` overflowed the progress total's arithmetic.
pub fn at_most(max: u64) -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(0..=max)
}

/// Most worker threads a flag accepts: more only thrashes two to a few dozen cores and can
/// exhaust the process's thread limit.
pub const MAX_THREADS: usize = 64;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_refuses_what_would_panic_or_never_end() {
        assert_eq!(seconds("0.6"), Ok(Duration::from_millis(600)));
        assert_eq!(seconds(" 10 "), Ok(Duration::from_secs(10)));
        for bad in ["1e300", "inf", "NaN", "0", "-1", "", "ten", "604801"] {
            let err = seconds(bad).unwrap_err();
            assert!(!err.is_empty(), "{bad}");
        }
        assert!(seconds("1e300").unwrap_err().contains("longest accepted"));
    }

    #[test]
    fn replay_speed_accepts_zero_and_a_sane_range() {
        assert_eq!(replay_speed("0"), Ok(0.0));
        assert_eq!(replay_speed("10"), Ok(10.0));
        for bad in ["1e-300", "-1", "inf", "NaN", "1e10", "fast"] {
            assert!(replay_speed(bad).is_err(), "{bad}");
        }
        // The slowest speed keeps the longest gap within Duration's range.
        let longest_s = u64::MAX as f64 * 1e-9 / REPLAY_SPEED_RANGE.start();
        assert!(Duration::try_from_secs_f64(longest_s).is_ok());
    }

    #[test]
    fn count_names_its_range() {
        use clap::builder::TypedValueParser;
        let cmd = clap::Command::new("t");
        let parse = |text: &str| count(1000).parse_ref(&cmd, None, std::ffi::OsStr::new(text));
        assert_eq!(parse("8").unwrap(), 8);
        for bad in ["0", "1001", "18446744073709551615", "-1"] {
            assert!(parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn at_most_takes_zero_and_names_its_range() {
        use clap::builder::TypedValueParser;
        let cmd = clap::Command::new("t");
        let parse = |text: &str| at_most(10).parse_ref(&cmd, None, std::ffi::OsStr::new(text));
        assert_eq!(parse("0").unwrap(), 0);
        assert_eq!(parse("10").unwrap(), 10);
        for bad in ["11", "18446744073709551615", "-1"] {
            assert!(parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn threads_is_bounded() {
        assert_eq!(threads("2"), Ok(2));
        for bad in ["0", "100000", "-1", "two"] {
            assert!(threads(bad).is_err(), "{bad}");
        }
    }
}
