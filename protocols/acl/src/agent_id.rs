//! Agent identifiers (SC00023 `agent-identifier`): a globally unique name plus transport addresses.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

use crate::message::normalize_user_params;

/// An agent identifier: `name@platform`, the transport addresses it can be reached at (in order
/// of preference), name resolvers to ask when none works, and user-defined `X-` slots.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[non_exhaustive]
pub struct AgentId {
    /// Globally unique name, `local@platform` (e.g. `wheelchair1@RustPlatform`).
    pub name: String,
    /// Transport addresses (URLs such as `http://127.0.0.1:7778/acc`), preferred first.
    #[serde(default)]
    pub addresses: Vec<String>,
    /// Name resolution services (other agent identifiers) able to find this agent.
    #[serde(default)]
    pub resolvers: Vec<AgentId>,
    /// User-defined slots, keyed without the `X-` prefix.
    #[serde(default, deserialize_with = "normalize_user_params")]
    pub user_params: BTreeMap<String, String>,
}

impl AgentId {
    /// An identifier with a name only.
    pub fn new(name: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            ..Self::default()
        }
    }

    /// Adds a transport address (after the existing ones).
    pub fn with_address(mut self, address: impl Into<String>) -> Self {
        self.addresses.push(address.into());
        self
    }

    /// Adds a name resolver.
    pub fn with_resolver(mut self, resolver: AgentId) -> Self {
        self.resolvers.push(resolver);
        self
    }

    /// Sets a user-defined slot; a leading `X-` on `key` is dropped (it is the wire prefix).
    pub fn with_user_param(mut self, key: &str, value: impl Into<String>) -> Self {
        self.user_params
            .insert(crate::message::user_key(key).to_owned(), value.into());
        self
    }

    /// The local part of the name, before `@` (the whole name when there is no `@`).
    pub fn local_name(&self) -> &str {
        self.name
            .split_once('@')
            .map_or(&self.name, |(local, _)| local)
    }

    /// The platform part of the name, after `@`.
    pub fn platform(&self) -> Option<&str> {
        self.name.split_once('@').map(|(_, platform)| platform)
    }
}

impl fmt::Display for AgentId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn name_parts() {
        let aid = AgentId::new("echo@WheelchairTest");
        assert_eq!(
            (aid.local_name(), aid.platform()),
            ("echo", Some("WheelchairTest"))
        );
        assert_eq!(AgentId::new("df").platform(), None);
    }
}
