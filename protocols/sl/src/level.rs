//! SL levels (profiles) and what each lets through.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::SlError;

/// An SL profile as named in the `:language` slot (`fipa-sl0`, `fipa-sl1`, `fipa-sl2`, `fipa-sl`).
///
/// Acceptance follows JADE 4.6.5's `SLCodec` for each profile, which is what FIPA platforms
/// actually exchange (checked row by row against JADE in `sl-decode.jsonl`):
///
/// | construct                                   | SL0 | SL1 | SL2 | full |
/// |---------------------------------------------|-----|-----|-----|------|
/// | predicates, `action`, `done`, `feasible`, sets, sequences, constants, variables | yes | yes | yes | yes |
/// | `not`, `and`, `or`, `implies`, `equiv`      | no  | yes | yes | yes  |
/// | `forall`/`exists`, `B`/`U`/`PG`/`I`, `iota`/`any`/`all`, action alternative and sequence | no | yes | no | yes |
///
/// Known JADE quirk reproduced on purpose: JADE's SL1 codec accepts the full grammar while its
/// SL2 codec rejects quantifiers, modal operators and identifying expressions (SC00008 puts them
/// in SL2). Names of the slots in the JADE tree ([`crate::jade_tree`]) follow each level's
/// ontology (SL1 names `and`/`or`/`not` slots, SL2 and full also `implies`, `forall`, `B`, ...).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Level {
    /// `fipa-sl0`: the minimal subset used by the FIPA-Agent-Management ontology.
    Sl0,
    /// `fipa-sl1`.
    Sl1,
    /// `fipa-sl2`.
    Sl2,
    /// `fipa-sl`: full SL.
    Full,
}

/// Grammar features a level may or may not accept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Feature {
    /// `not`, `and`, `or`, `implies`, `equiv`.
    Connectives,
    /// Quantifiers, modal operators, identifying expressions, action composition.
    Higher,
}

impl Level {
    /// All levels, lowest first.
    pub const ALL: [Level; 4] = [Level::Sl0, Level::Sl1, Level::Sl2, Level::Full];

    /// The `:language` name, e.g. `fipa-sl0`.
    pub fn language(self) -> &'static str {
        match self {
            Level::Sl0 => "fipa-sl0",
            Level::Sl1 => "fipa-sl1",
            Level::Sl2 => "fipa-sl2",
            Level::Full => "fipa-sl",
        }
    }

    /// The short name used on the command line: `sl0`, `sl1`, `sl2`, `full`.
    pub fn short_name(self) -> &'static str {
        match self {
            Level::Sl0 => "sl0",
            Level::Sl1 => "sl1",
            Level::Sl2 => "sl2",
            Level::Full => "full",
        }
    }

    /// Whether this level's parser accepts `feature`.
    pub(crate) fn allows(self, feature: Feature) -> bool {
        match feature {
            Feature::Connectives => self != Level::Sl0,
            Feature::Higher => matches!(self, Level::Sl1 | Level::Full),
        }
    }

    /// The lowest level accepting `feature` (for error hints).
    pub(crate) fn lowest_allowing(feature: Feature) -> Level {
        Level::ALL
            .into_iter()
            .find(|l| l.allows(feature))
            .unwrap_or(Level::Full)
    }

    /// Ontology tier used to name slots in the JADE tree: 0 (SL0) .. 3 (full).
    pub(crate) fn ontology_tier(self) -> u8 {
        match self {
            Level::Sl0 => 0,
            Level::Sl1 => 1,
            Level::Sl2 => 2,
            Level::Full => 3,
        }
    }
}

impl fmt::Display for Level {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.short_name())
    }
}

impl FromStr for Level {
    type Err = SlError;

    /// Accepts the short names (`sl0`, `full`) and the `:language` names (`fipa-sl0`, `fipa-sl`).
    fn from_str(s: &str) -> Result<Self, SlError> {
        let lower = s.to_ascii_lowercase();
        let short = lower.strip_prefix("fipa-").unwrap_or(&lower);
        match short {
            "sl0" => Ok(Level::Sl0),
            "sl1" => Ok(Level::Sl1),
            "sl2" => Ok(Level::Sl2),
            "sl" | "full" => Ok(Level::Full),
            _ => Err(SlError::UnknownLevel { name: s.to_owned() }),
        }
    }
}
