//! The Agent Management System: the platform's white pages (who is here, in which life-cycle
//! state), answering `register`, `deregister`, `modify` and `search` of ams-agent-descriptions.

use std::collections::BTreeMap;
use std::sync::{Arc, PoisonError, RwLock};

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentError, AgentHost, Context};
use iw_bus::Time;
use iw_ontology::fipa::{
    AgentDescription, AgentState, AmsAgentDescription, FipaError, ManagementAction,
    ManagementContent,
};

use crate::service::{self, Answer};

/// The platform's white pages: every agent the AMS lists, by name. Clones share one list.
///
/// The container puts the agents it hosts here ([`WhitePages::host`], so the AMS and the
/// container's Local Agent List name the same agents); agents of other platforms register
/// themselves through the AMS.
#[derive(Clone, Debug, Default)]
pub struct WhitePages(Arc<RwLock<BTreeMap<String, AmsAgentDescription>>>);

impl WhitePages {
    /// An empty list.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `agent` to `host` under `aid` and lists it `active`.
    pub fn host(
        &self,
        host: &mut AgentHost,
        aid: AgentId,
        agent: Box<dyn Agent>,
    ) -> Result<(), AgentError> {
        let description = AmsAgentDescription {
            name: Some(aid.clone()),
            ownership: None,
            state: Some(AgentState::Active),
        };
        host.add(aid, agent)?;
        self.write()
            .insert(name_of(&description).to_owned(), description);
        Ok(())
    }

    /// Removes agent `name` from `host` (its `take_down` runs) and from the list; returns
    /// whether the host had it.
    pub fn unhost(&self, host: &mut AgentHost, name: &str, now: Time) -> bool {
        self.write().remove(name);
        host.remove(name, now)
    }

    /// Lists `description` (`active` unless it says otherwise); `already-registered` if its
    /// name is listed.
    pub fn register(&self, mut description: AmsAgentDescription) -> Result<(), FipaError> {
        let name = required_name(&description)?.to_owned();
        let mut pages = self.write();
        if pages.contains_key(&name) {
            return Err(FipaError::AlreadyRegistered);
        }
        description.state.get_or_insert(AgentState::Active);
        pages.insert(name, description);
        Ok(())
    }

    /// Removes the entry named like `description`; `not-registered` if there is none.
    pub fn deregister(
        &self,
        description: &AmsAgentDescription,
    ) -> Result<AmsAgentDescription, FipaError> {
        let name = required_name(description)?;
        self.write().remove(name).ok_or(FipaError::NotRegistered)
    }

    /// Updates the slots `description` sets (ownership, state) of its entry.
    pub fn modify(&self, description: &AmsAgentDescription) -> Result<(), FipaError> {
        let name = required_name(description)?;
        let mut pages = self.write();
        let entry = pages.get_mut(name).ok_or(FipaError::NotRegistered)?;
        if description.ownership.is_some() {
            entry.ownership.clone_from(&description.ownership);
        }
        if description.state.is_some() {
            entry.state = description.state;
        }
        Ok(())
    }

    /// The entry of agent `name`.
    pub fn get(&self, name: &str) -> Option<AmsAgentDescription> {
        self.read().get(name).cloned()
    }

    /// Entries matching `template` (every slot it sets is equal), at most `limit`, by name.
    pub fn search(&self, template: &AmsAgentDescription, limit: usize) -> Vec<AmsAgentDescription> {
        self.read()
            .values()
            .filter(|entry| matches(template, entry))
            .take(limit)
            .cloned()
            .collect()
    }

    /// Number of listed agents.
    pub fn len(&self) -> usize {
        self.read().len()
    }

    /// Whether no agent is listed.
    pub fn is_empty(&self) -> bool {
        self.read().is_empty()
    }

    fn read(&self) -> std::sync::RwLockReadGuard<'_, BTreeMap<String, AmsAgentDescription>> {
        self.0.read().unwrap_or_else(PoisonError::into_inner)
    }

    fn write(&self) -> std::sync::RwLockWriteGuard<'_, BTreeMap<String, AmsAgentDescription>> {
        self.0.write().unwrap_or_else(PoisonError::into_inner)
    }
}

fn name_of(description: &AmsAgentDescription) -> &str {
    description
        .name
        .as_ref()
        .map_or("", |aid| aid.name.as_str())
}

fn required_name(description: &AmsAgentDescription) -> Result<&str, FipaError> {
    description
        .name
        .as_ref()
        .map(|aid| aid.name.as_str())
        .ok_or_else(|| FipaError::MissingParameter {
            object: "ams-agent-description".into(),
            parameter: "name".into(),
        })
}

/// Whether `entry` has every slot `template` sets (agent names compared, not addresses).
fn matches(template: &AmsAgentDescription, entry: &AmsAgentDescription) -> bool {
    let name_ok = template
        .name
        .as_ref()
        .is_none_or(|t| entry.name.as_ref().is_some_and(|e| e.name == t.name));
    let ownership_ok = template.ownership.is_none() || template.ownership == entry.ownership;
    let state_ok = template.state.is_none() || template.state == entry.state;
    name_ok && ownership_ok && state_ok
}

/// The AMS agent (`ams@platform`): serves its [`WhitePages`] over FIPA-ACL.
///
/// An agent may register, deregister and modify only itself (others get REFUSE
/// `unauthorised`); anyone may search.
#[derive(Debug)]
pub struct Ams {
    pages: WhitePages,
}

impl Ams {
    /// An AMS serving `pages`.
    pub fn new(pages: WhitePages) -> Self {
        Self { pages }
    }

    fn perform(&self, sender: &AgentId, action: &ManagementAction) -> Answer {
        let description = match action {
            ManagementAction::Register { description }
            | ManagementAction::Deregister { description }
            | ManagementAction::Modify { description }
            | ManagementAction::Search { description, .. } => description,
            ManagementAction::GetDescription => {
                return Answer::Refuse(FipaError::UnsupportedFunction {
                    function: "get-description".into(),
                });
            }
        };
        let AgentDescription::Ams(description) = description else {
            return Answer::Refuse(FipaError::UnexpectedArgument {
                argument: "df-agent-description".into(),
            });
        };
        if let ManagementAction::Search { constraints, .. } = action {
            let found = self
                .pages
                .search(description, service::result_limit(constraints));
            return Answer::Result(found.into_iter().map(AgentDescription::Ams).collect());
        }
        match description.name.as_ref() {
            Some(name) if name.name != sender.name => {
                return Answer::Refuse(FipaError::Unauthorised);
            }
            _ => {}
        }
        let done = match action {
            ManagementAction::Register { .. } => self.pages.register(description.clone()),
            ManagementAction::Deregister { .. } => self.pages.deregister(description).map(drop),
            _ => self.pages.modify(description),
        };
        match done {
            Ok(()) => Answer::Done,
            Err(reason @ FipaError::MissingParameter { .. }) => Answer::Refuse(reason),
            Err(reason) => Answer::Failure(reason),
        }
    }
}

impl Agent for Ams {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if message.performative != Performative::Request {
            let act = message.performative.to_string().to_ascii_lowercase();
            service::not_understood(ctx, &message, FipaError::UnsupportedAct { act });
            return;
        }
        let Some(content) = service::read_content(ctx, &message) else {
            return;
        };
        let ManagementContent::Request(request) = content else {
            service::not_understood(
                ctx,
                &message,
                FipaError::UnrecognisedValue {
                    value: "content".into(),
                },
            );
            return;
        };
        let sender = message.sender.clone().unwrap_or_default();
        let answer = self.perform(&sender, &request.action);
        service::answer(ctx, &message, &request, answer);
    }
}
