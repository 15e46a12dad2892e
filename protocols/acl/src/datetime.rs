//! FIPA date-times (SC00070 `DateTime`): `[+|-]YYYYMMDDTHHMMSSmmm[TypeDesignator]`.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::Error;

/// A FIPA date-time as written on the wire, e.g. `20991231T235959000Z`.
///
/// Without a sign it is an absolute time; the type designator is a military time-zone letter
/// (`Z` = UTC, `A`..`M` east, `N`..`Y` west); none means local time, which this platform takes
/// as UTC. With a sign (`+00000000T000030000`) it is a time relative to "now", as FIPA allows
/// for `reply-by`: resolve it with [`FipaDateTime::to_unix_ms`] given the current time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub struct FipaDateTime {
    /// `Some('+')`/`Some('-')` for a relative time, `None` for an absolute one.
    pub sign: Option<char>,
    /// Year, 0..=9999 (or a count of years when relative).
    pub year: u16,
    /// Month 1..=12 (0..=99 when relative).
    pub month: u8,
    /// Day of month 1..=31 (0..=99 when relative).
    pub day: u8,
    /// Hour 0..=23.
    pub hour: u8,
    /// Minute 0..=59.
    pub minute: u8,
    /// Second 0..=59.
    pub second: u8,
    /// Millisecond 0..=999.
    pub millisecond: u16,
    /// The type designator letter (`Z` for UTC), upper case, if any.
    pub zone: Option<char>,
}

const MS_PER_DAY: i64 = 86_400_000;

impl FipaDateTime {
    /// The absolute UTC date-time (designator `Z`) of a Unix time in milliseconds.
    /// Saturates to years 0..=9999.
    pub fn from_unix_ms(unix_ms: i64) -> Self {
        let min = days_from_civil(0, 1, 1) * MS_PER_DAY;
        let max = (days_from_civil(10_000, 1, 1)) * MS_PER_DAY - 1;
        let unix_ms = unix_ms.clamp(min, max);
        let days = unix_ms.div_euclid(MS_PER_DAY);
        let ms_of_day = unix_ms.rem_euclid(MS_PER_DAY);
        let (year, month, day) = civil_from_days(days);
        // The clamp above keeps every narrowing below in range.
        Self {
            sign: None,
            year: year as u16,
            month: month as u8,
            day: day as u8,
            hour: (ms_of_day / 3_600_000) as u8,
            minute: (ms_of_day / 60_000 % 60) as u8,
            second: (ms_of_day / 1000 % 60) as u8,
            millisecond: (ms_of_day % 1000) as u16,
            zone: Some('Z'),
        }
    }

    /// Unix time in milliseconds. A relative time is resolved against `now_unix_ms`; years and
    /// months of a relative time count 365 and 30 days (FIPA leaves them undefined).
    pub fn to_unix_ms(&self, now_unix_ms: i64) -> i64 {
        let time_ms = ((i64::from(self.hour) * 60 + i64::from(self.minute)) * 60
            + i64::from(self.second))
            * 1000
            + i64::from(self.millisecond);
        match self.sign {
            Some(sign) => {
                let days = i64::from(self.year) * 365 + i64::from(self.month) * 30 + i64::from(self.day);
                let offset = days * MS_PER_DAY + time_ms;
                if sign == '-' { now_unix_ms - offset } else { now_unix_ms + offset }
            }
            None => {
                let days = days_from_civil(i64::from(self.year), i64::from(self.month), i64::from(self.day));
                days * MS_PER_DAY + time_ms - i64::from(zone_offset_hours(self.zone)) * 3_600_000
            }
        }
    }

    /// Checks field ranges; `text` is only used for the error message.
    fn validate(self, text: &str) -> Result<Self, Error> {
        let bad = |reason: &str| Error::InvalidDateTime { value: text.to_owned(), reason: reason.to_owned() };
        if self.sign.is_none() {
            if !(1..=12).contains(&self.month) {
                return Err(bad("month must be 01..12"));
            }
            if self.day == 0 || self.day > days_in_month(self.year, self.month) {
                return Err(bad("day out of range for the month"));
            }
        }
        if self.hour > 23 || self.minute > 59 || self.second > 59 {
            return Err(bad("time of day out of range"));
        }
        if self.zone.is_some_and(|zone| !zone.is_ascii_alphabetic()) {
            return Err(bad("type designator must be a letter such as Z"));
        }
        Ok(self)
    }
}

/// Hours east of UTC for a military time-zone letter; `J` (local) and none count as UTC.
fn zone_offset_hours(zone: Option<char>) -> i32 {
    match zone.map(|z| z.to_ascii_uppercase()) {
        Some(z @ 'A'..='I') => z as i32 - 'A' as i32 + 1,
        Some(z @ 'K'..='M') => z as i32 - 'K' as i32 + 10,
        Some(z @ 'N'..='Y') => -(z as i32 - 'N' as i32 + 1),
        _ => 0,
    }
}

fn is_leap(year: u16) -> bool {
    (year.is_multiple_of(4) && !year.is_multiple_of(100)) || year.is_multiple_of(400)
}

fn days_in_month(year: u16, month: u8) -> u8 {
    match month {
        2 if is_leap(year) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm).
fn days_from_civil(year: i64, month: i64, day: i64) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (month + 9) % 12;
    let doy = (153 * mp + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Inverse of [`days_from_civil`].
fn civil_from_days(days: i64) -> (i64, i64, i64) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

impl fmt::Display for FipaDateTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(sign) = self.sign {
            write!(f, "{sign}")?;
        }
        write!(
            f,
            "{:04}{:02}{:02}T{:02}{:02}{:02}{:03}",
            self.year, self.month, self.day, self.hour, self.minute, self.second, self.millisecond
        )?;
        if let Some(zone) = self.zone {
            write!(f, "{zone}")?;
        }
        Ok(())
    }
}

impl FromStr for FipaDateTime {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self, Error> {
        let bad = |reason: &str| Error::InvalidDateTime { value: text.to_owned(), reason: reason.to_owned() };
        let bytes = text.as_bytes();
        let (sign, rest) = match bytes.first() {
            Some(&b) if b == b'+' || b == b'-' => (Some(b as char), &bytes[1..]),
            _ => (None, bytes),
        };
        let (digits, zone) = match rest.len() {
            18 => (rest, None),
            19 => (&rest[..18], rest.last().map(|&z| (z as char).to_ascii_uppercase())),
            _ => return Err(bad("expected 18 or 19 characters after the sign")),
        };
        if !digits[8].eq_ignore_ascii_case(&b'T') {
            return Err(bad("expected `T` between date and time"));
        }
        let num = |range: std::ops::Range<usize>| -> Result<u16, Error> {
            digits[range].iter().try_fold(0u16, |acc, &d| {
                if d.is_ascii_digit() { Ok(acc * 10 + u16::from(d - b'0')) } else { Err(bad("expected a digit")) }
            })
        };
        // Each field has at most 4 digits, so the narrowing casts cannot truncate.
        FipaDateTime {
            sign,
            year: num(0..4)?,
            month: num(4..6)? as u8,
            day: num(6..8)? as u8,
            hour: num(9..11)? as u8,
            minute: num(11..13)? as u8,
            second: num(13..15)? as u8,
            millisecond: num(15..18)?,
            zone,
        }
        .validate(text)
    }
}

impl From<FipaDateTime> for String {
    fn from(t: FipaDateTime) -> Self {
        t.to_string()
    }
}

impl TryFrom<String> for FipaDateTime {
    type Error = Error;

    fn try_from(text: String) -> Result<Self, Error> {
        text.parse()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_prints_jade_form() {
        let t: FipaDateTime = "20991231T235959000Z".parse().unwrap();
        assert_eq!((t.year, t.month, t.day, t.hour, t.zone), (2099, 12, 31, 23, Some('Z')));
        assert_eq!(t.to_string(), "20991231T235959000Z");
    }

    #[test]
    fn unix_ms_round_trips() {
        for ms in [0, 1, 951_782_400_123, 4_102_444_799_999, -86_400_000] {
            assert_eq!(FipaDateTime::from_unix_ms(ms).to_unix_ms(0), ms);
        }
        let t: FipaDateTime = "20000229T120000000Z".parse().unwrap();
        assert_eq!(t.to_unix_ms(0), 951_825_600_000);
    }

    #[test]
    fn zone_letters_shift_to_utc() {
        let a: FipaDateTime = "20001211T100025100A".parse().unwrap();
        let z: FipaDateTime = "20001211T090025100Z".parse().unwrap();
        assert_eq!(a.to_unix_ms(0), z.to_unix_ms(0));
    }

    #[test]
    fn relative_time_resolves_against_now() {
        let t: FipaDateTime = "+00000000T000030000".parse().unwrap();
        assert_eq!(t.to_unix_ms(1_000), 31_000);
        assert_eq!(t.to_string(), "+00000000T000030000");
    }

    #[test]
    fn rejects_bad_fields_with_the_value() {
        for bad in ["20991331T000000000Z", "20990230T000000000", "2099123123595900Z", "20991231X235959000", "20991231T245959000"] {
            let err = bad.parse::<FipaDateTime>().unwrap_err();
            assert!(err.to_string().contains(bad), "{err}");
        }
    }
}
