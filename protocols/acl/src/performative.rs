//! The 22 FIPA communicative acts (SC00037), named as FIPA spells them on the wire.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::Error;

/// A FIPA communicative act. `Display` gives the FIPA name in upper case (`ACCEPT-PROPOSAL`);
/// `FromStr` accepts any case, as JADE does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(into = "&'static str", try_from = "String")]
#[allow(missing_docs)] // The variants are the FIPA names themselves.
pub enum Performative {
    AcceptProposal,
    Agree,
    Cancel,
    Cfp,
    Confirm,
    Disconfirm,
    Failure,
    Inform,
    InformIf,
    InformRef,
    NotUnderstood,
    Propagate,
    Propose,
    Proxy,
    QueryIf,
    QueryRef,
    Refuse,
    RejectProposal,
    Request,
    RequestWhen,
    RequestWhenever,
    Subscribe,
}

impl Performative {
    /// All 22 performatives in FIPA (alphabetical) order.
    pub const ALL: [Performative; 22] = [
        Self::AcceptProposal,
        Self::Agree,
        Self::Cancel,
        Self::Cfp,
        Self::Confirm,
        Self::Disconfirm,
        Self::Failure,
        Self::Inform,
        Self::InformIf,
        Self::InformRef,
        Self::NotUnderstood,
        Self::Propagate,
        Self::Propose,
        Self::Proxy,
        Self::QueryIf,
        Self::QueryRef,
        Self::Refuse,
        Self::RejectProposal,
        Self::Request,
        Self::RequestWhen,
        Self::RequestWhenever,
        Self::Subscribe,
    ];

    /// The FIPA name, upper case: `INFORM-IF`.
    pub const fn fipa_name(self) -> &'static str {
        match self {
            Self::AcceptProposal => "ACCEPT-PROPOSAL",
            Self::Agree => "AGREE",
            Self::Cancel => "CANCEL",
            Self::Cfp => "CFP",
            Self::Confirm => "CONFIRM",
            Self::Disconfirm => "DISCONFIRM",
            Self::Failure => "FAILURE",
            Self::Inform => "INFORM",
            Self::InformIf => "INFORM-IF",
            Self::InformRef => "INFORM-REF",
            Self::NotUnderstood => "NOT-UNDERSTOOD",
            Self::Propagate => "PROPAGATE",
            Self::Propose => "PROPOSE",
            Self::Proxy => "PROXY",
            Self::QueryIf => "QUERY-IF",
            Self::QueryRef => "QUERY-REF",
            Self::Refuse => "REFUSE",
            Self::RejectProposal => "REJECT-PROPOSAL",
            Self::Request => "REQUEST",
            Self::RequestWhen => "REQUEST-WHEN",
            Self::RequestWhenever => "REQUEST-WHENEVER",
            Self::Subscribe => "SUBSCRIBE",
        }
    }

    /// Case-insensitive lookup of a FIPA name without allocating (the parser's hot path: one
    /// pass over a table of the names, most ruled out by their length).
    pub fn from_fipa_name(name: &str) -> Option<Self> {
        const NAMES: [&str; 22] = {
            let mut names = [""; 22];
            let mut i = 0;
            while i < names.len() {
                names[i] = Performative::ALL[i].fipa_name();
                i += 1;
            }
            names
        };
        NAMES
            .iter()
            .position(|known| known.eq_ignore_ascii_case(name))
            .map(|i| Self::ALL[i])
    }
}

impl fmt::Display for Performative {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.fipa_name())
    }
}

impl FromStr for Performative {
    type Err = Error;

    fn from_str(name: &str) -> Result<Self, Error> {
        Self::from_fipa_name(name).ok_or_else(|| Error::UnknownPerformativeName {
            name: name.to_owned(),
        })
    }
}

impl From<Performative> for &'static str {
    fn from(p: Performative) -> Self {
        p.fipa_name()
    }
}

impl TryFrom<String> for Performative {
    type Error = Error;

    fn try_from(name: String) -> Result<Self, Error> {
        name.parse()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_round_trips_in_any_case() {
        for p in Performative::ALL {
            assert_eq!(p.to_string().parse::<Performative>().unwrap(), p);
            assert_eq!(
                p.fipa_name()
                    .to_lowercase()
                    .parse::<Performative>()
                    .unwrap(),
                p
            );
        }
    }

    #[test]
    fn unknown_name_is_an_error_naming_it() {
        let err = "REQUESTX".parse::<Performative>().unwrap_err();
        assert!(err.to_string().contains("REQUESTX"), "{err}");
    }
}
