//! FIPA date-times (SC00070 `DateTime`): `[+|-]YYYYMMDDTHHMMSSmmm[TypeDesignator]`.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use time::macros::date;
use time::{Date, Month};

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
        let first = days_since_epoch(date!(0000 - 01 - 01)) * MS_PER_DAY;
        let last = (days_since_epoch(date!(9999 - 12 - 31)) + 1) * MS_PER_DAY - 1;
        let unix_ms = unix_ms.clamp(first, last);
        let days = unix_ms.div_euclid(MS_PER_DAY);
        let ms_of_day = unix_ms.rem_euclid(MS_PER_DAY);
        // The clamp above keeps the date and every narrowing below in range.
        let date = i32::try_from(days + UNIX_EPOCH_JULIAN_DAY)
            .ok()
            .and_then(|jd| Date::from_julian_day(jd).ok())
            .unwrap_or(Date::MIN);
        Self {
            sign: None,
            year: date.year() as u16,
            month: u8::from(date.month()),
            day: date.day(),
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
                let days =
                    i64::from(self.year) * 365 + i64::from(self.month) * 30 + i64::from(self.day);
                let offset = days * MS_PER_DAY + time_ms;
                if sign == '-' {
                    now_unix_ms - offset
                } else {
                    now_unix_ms + offset
                }
            }
            None => {
                // Fields out of range (only possible in a value built by hand: parsing checks
                // them) saturate to the nearest real date.
                let month = Month::try_from(self.month.clamp(1, 12)).unwrap_or(Month::January);
                let year = i32::from(self.year);
                let day = self.day.clamp(1, month.length(year));
                let days = Date::from_calendar_date(year, month, day).map_or(0, days_since_epoch);
                days * MS_PER_DAY + time_ms - i64::from(zone_offset_hours(self.zone)) * 3_600_000
            }
        }
    }

    /// Checks field ranges; `text` is only used for the error message.
    fn validate(self, text: &str) -> Result<Self, Error> {
        let bad = |reason: &str| Error::InvalidDateTime {
            value: text.to_owned(),
            reason: reason.to_owned(),
        };
        if self.sign.is_none() {
            if !(1..=12).contains(&self.month) {
                return Err(bad("month must be 01..12"));
            }
            let month = Month::try_from(self.month).map_err(|_| bad("month must be 01..12"))?;
            if self.day == 0 || self.day > month.length(i32::from(self.year)) {
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

/// Julian day number of 1970-01-01 (`time` counts dates in Julian days).
const UNIX_EPOCH_JULIAN_DAY: i64 = 2_440_588;

fn days_since_epoch(date: Date) -> i64 {
    i64::from(date.to_julian_day()) - UNIX_EPOCH_JULIAN_DAY
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
        let bad = |reason: &str| Error::InvalidDateTime {
            value: text.to_owned(),
            reason: reason.to_owned(),
        };
        let bytes = text.as_bytes();
        let (sign, rest) = match bytes.first() {
            Some(&b) if b == b'+' || b == b'-' => (Some(b as char), &bytes[1..]),
            _ => (None, bytes),
        };
        let (digits, zone) = match rest.len() {
            18 => (rest, None),
            19 => (
                &rest[..18],
                rest.last().map(|&z| (z as char).to_ascii_uppercase()),
            ),
            _ => return Err(bad("expected 18 or 19 characters after the sign")),
        };
        if !digits[8].eq_ignore_ascii_case(&b'T') {
            return Err(bad("expected `T` between date and time"));
        }
        let num = |range: std::ops::Range<usize>| -> Result<u16, Error> {
            digits[range].iter().try_fold(0u16, |acc, &d| {
                if d.is_ascii_digit() {
                    Ok(acc * 10 + u16::from(d - b'0'))
                } else {
                    Err(bad("expected a digit"))
                }
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
        assert_eq!(
            (t.year, t.month, t.day, t.hour, t.zone),
            (2099, 12, 31, 23, Some('Z'))
        );
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
        for bad in [
            "20991331T000000000Z",
            "20990230T000000000",
            "2099123123595900Z",
            "20991231X235959000",
            "20991231T245959000",
        ] {
            let err = bad.parse::<FipaDateTime>().unwrap_err();
            assert!(err.to_string().contains(bad), "{err}");
        }
    }
}
