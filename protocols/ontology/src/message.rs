//! Ontology content inside ACL messages: `:content`, `:language` and `:ontology` set together,
//! and read back with the SL level the message's `:language` names.

use iw_acl::AclMessage;
use iw_sl::{Content, Level};

use crate::error::OntologyError;
use crate::fipa::ManagementContent;
use crate::wheelchair::{Subscription, WheelchairContent};
use crate::world::WorldContent;

/// A content type of one ontology.
pub trait OntologyContent: Sized {
    /// The `:ontology` name.
    const ONTOLOGY: &'static str;

    /// The lowest SL level able to carry this value.
    fn level(&self) -> Level;

    /// As SL content.
    fn to_content(&self) -> Content;

    /// From SL content.
    fn from_content(content: &Content) -> Result<Self, OntologyError>;

    /// `message` with this value as its content, `:language` the lowest SL level that carries
    /// it (`fipa-sl0` when it fits, as JADE's DF expects) and `:ontology` set.
    fn fill(&self, message: AclMessage) -> AclMessage {
        message
            .with_content(self.to_content().to_string())
            .with_language(self.level().language())
            .with_ontology(Self::ONTOLOGY)
    }

    /// The value in `message`'s content, parsed at the level its `:language` names (full SL
    /// when absent). A message naming another ontology is refused.
    fn from_message(message: &AclMessage) -> Result<Self, OntologyError> {
        if let Some(found) = message
            .ontology
            .as_ref()
            .filter(|o| !o.eq_ignore_ascii_case(Self::ONTOLOGY))
        {
            return Err(OntologyError::WrongOntology {
                expected: Self::ONTOLOGY,
                found: found.clone(),
            });
        }
        let level = match &message.language {
            Some(language) => language.parse()?,
            None => Level::Full,
        };
        let text = message.content_text().ok_or(OntologyError::NoTextContent)?;
        Self::from_content(&iw_sl::parse(text, level)?)
    }
}

/// [`OntologyContent`] for a type with inherent `to_content` / `from_content`, in `$ontology`,
/// at the level `$level` gives for a value `$v`.
macro_rules! sl_content {
    ($type:ty, $ontology:expr, |$v:ident| $level:expr) => {
        impl OntologyContent for $type {
            const ONTOLOGY: &'static str = $ontology;

            fn level(&self) -> Level {
                let $v = self;
                $level
            }

            fn to_content(&self) -> Content {
                <$type>::to_content(self)
            }

            fn from_content(content: &Content) -> Result<Self, OntologyError> {
                <$type>::from_content(content)
            }
        }
    };
}

sl_content!(ManagementContent, crate::fipa::ONTOLOGY, |v| v.level());
sl_content!(WheelchairContent, crate::wheelchair::ONTOLOGY, |_v| {
    WheelchairContent::LEVEL
});
sl_content!(Subscription, crate::wheelchair::ONTOLOGY, |_v| {
    WheelchairContent::LEVEL
});
sl_content!(WorldContent, crate::world::ONTOLOGY, |_v| {
    WorldContent::LEVEL
});
