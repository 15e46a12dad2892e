//! The Directory Facilitator: the platform's yellow pages (who offers which service), answering
//! `register`, `deregister`, `modify` and `search` of df-agent-descriptions, and notifying
//! subscribers (fipa-subscribe) of registrations that match their search.

use std::collections::BTreeMap;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context};
use iw_ontology::OntologyContent;
use iw_ontology::fipa::{
    AgentDescription, DfAgentDescription, FipaError, ManagementAction, ManagementContent,
    ManagementRequest, ServiceDescription,
};

use crate::service::{self, Answer};

/// Most live subscriptions; further SUBSCRIBEs are refused so no one can exhaust the DF.
pub const MAX_SUBSCRIPTIONS: usize = 1024;

/// Whether `entry` matches the search `template` (FIPA SC00023 matching): every slot the
/// template sets is in the entry; set-valued slots are subsets; each template service matches
/// one of the entry's services. Agent names are compared, not their addresses.
pub fn matches(template: &DfAgentDescription, entry: &DfAgentDescription) -> bool {
    let name_ok = template
        .name
        .as_ref()
        .is_none_or(|t| entry.name.as_ref().is_some_and(|e| e.name == t.name));
    name_ok
        && subset(&template.protocols, &entry.protocols)
        && subset(&template.ontologies, &entry.ontologies)
        && subset(&template.languages, &entry.languages)
        && template
            .services
            .iter()
            .all(|t| entry.services.iter().any(|e| service_matches(t, e)))
}

fn service_matches(template: &ServiceDescription, entry: &ServiceDescription) -> bool {
    let same = |t: &Option<String>, e: &Option<String>| t.is_none() || t == e;
    same(&template.name, &entry.name)
        && same(&template.service_type, &entry.service_type)
        && same(&template.ownership, &entry.ownership)
        && subset(&template.protocols, &entry.protocols)
        && subset(&template.ontologies, &entry.ontologies)
        && subset(&template.languages, &entry.languages)
        && template
            .properties
            .iter()
            .all(|t| entry.properties.contains(t))
}

fn subset<T: PartialEq>(wanted: &[T], offered: &[T]) -> bool {
    wanted.iter().all(|w| offered.contains(w))
}

/// One live subscription: who, to which search, and the SUBSCRIBE its notifications reply to.
#[derive(Debug)]
struct Subscription {
    subscribe: AclMessage,
    request: ManagementRequest,
    template: DfAgentDescription,
}

impl Subscription {
    fn is(&self, subscriber: &str, conversation_id: Option<&str>) -> bool {
        self.subscribe
            .sender
            .as_ref()
            .is_some_and(|s| s.name == subscriber)
            && self.subscribe.conversation_id.as_deref() == conversation_id
    }
}

/// The DF agent (`df@platform`).
///
/// An agent registers, modifies and deregisters only its own description (others get REFUSE
/// `unauthorised`); anyone may search or subscribe. A subscriber gets an INFORM with the current
/// matches when it subscribes (if any), then one per registration or modification that matches,
/// and one naming the agent alone when a matching agent deregisters (as JADE's DF does), until
/// it sends CANCEL in the same conversation.
#[derive(Debug, Default)]
pub struct Df {
    entries: BTreeMap<String, DfAgentDescription>,
    subscriptions: Vec<Subscription>,
}

impl Df {
    /// An empty DF.
    pub fn new() -> Self {
        Self::default()
    }

    /// Registered descriptions, by agent name.
    pub fn entries(&self) -> impl Iterator<Item = &DfAgentDescription> {
        self.entries.values()
    }

    /// Number of live subscriptions.
    pub fn subscription_count(&self) -> usize {
        self.subscriptions.len()
    }

    fn search(&self, template: &DfAgentDescription, limit: usize) -> Vec<AgentDescription> {
        self.entries
            .values()
            .filter(|e| matches(template, e))
            .take(limit)
            .cloned()
            .map(AgentDescription::Df)
            .collect()
    }

    /// Performs `action` for `sender`; returns the answer and the description subscribers should
    /// hear about.
    fn perform(
        &mut self,
        sender: &AgentId,
        action: &ManagementAction,
    ) -> (Answer, Option<DfAgentDescription>) {
        let description = match action {
            ManagementAction::Register { description }
            | ManagementAction::Deregister { description }
            | ManagementAction::Modify { description }
            | ManagementAction::Search { description, .. } => description,
            ManagementAction::GetDescription => {
                let function = "get-description".into();
                return (
                    Answer::Refuse(FipaError::UnsupportedFunction { function }),
                    None,
                );
            }
        };
        let AgentDescription::Df(description) = description else {
            let argument = "ams-agent-description".into();
            return (
                Answer::Refuse(FipaError::UnexpectedArgument { argument }),
                None,
            );
        };
        if let ManagementAction::Search { constraints, .. } = action {
            return (
                Answer::Result(self.search(description, service::result_limit(constraints))),
                None,
            );
        }
        let Some(name) = description.name.as_ref().map(|aid| aid.name.clone()) else {
            let missing = FipaError::MissingParameter {
                object: "df-agent-description".into(),
                parameter: "name".into(),
            };
            return (Answer::Refuse(missing), None);
        };
        if name != sender.name {
            return (Answer::Refuse(FipaError::Unauthorised), None);
        }
        let exists = self.entries.contains_key(&name);
        match action {
            ManagementAction::Register { .. } | ManagementAction::Modify { .. } => {
                let registering = matches!(action, ManagementAction::Register { .. });
                if registering && exists {
                    return (Answer::Failure(FipaError::AlreadyRegistered), None);
                }
                if !registering && !exists {
                    return (Answer::Failure(FipaError::NotRegistered), None);
                }
                self.entries.insert(name, description.clone());
                (Answer::Done, Some(description.clone()))
            }
            _ => match self.entries.remove(&name) {
                Some(gone) => (
                    Answer::Done,
                    Some(DfAgentDescription {
                        name: gone.name,
                        ..DfAgentDescription::default()
                    }),
                ),
                None => (Answer::Failure(FipaError::NotRegistered), None),
            },
        }
    }

    /// Tells every subscriber whose search `changed` matches (a deregistration is announced by
    /// the bare name, which matches a subscription when its registration did).
    fn notify(
        &self,
        ctx: &mut Context<'_>,
        changed: &DfAgentDescription,
        before: Option<&DfAgentDescription>,
    ) {
        for subscription in &self.subscriptions {
            let relevant = matches(&subscription.template, changed)
                || before.is_some_and(|b| matches(&subscription.template, b));
            if relevant {
                notify(
                    ctx,
                    subscription,
                    vec![AgentDescription::Df(changed.clone())],
                );
            }
        }
    }

    fn subscribe(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let Some(content) = service::read_content(ctx, &message) else {
            return;
        };
        let ManagementContent::Subscribe(request) = content else {
            service::not_understood(
                ctx,
                &message,
                FipaError::UnrecognisedValue {
                    value: "content".into(),
                },
            );
            return;
        };
        let ManagementAction::Search {
            description: AgentDescription::Df(template),
            constraints,
        } = &request.action
        else {
            let function = "subscription to anything but a DF search".into();
            return service::answer(
                ctx,
                &message,
                &request,
                Answer::Refuse(FipaError::UnsupportedFunction { function }),
            );
        };
        if self.subscriptions.len() >= MAX_SUBSCRIPTIONS {
            let message_text =
                format!("the DF holds its limit of {MAX_SUBSCRIPTIONS} subscriptions");
            return service::answer(
                ctx,
                &message,
                &request,
                Answer::Refuse(FipaError::InternalError {
                    message: message_text,
                }),
            );
        }
        let subscriber = message
            .sender
            .as_ref()
            .map_or("", |s| s.name.as_str())
            .to_owned();
        self.subscriptions
            .retain(|s| !s.is(&subscriber, message.conversation_id.as_deref()));
        let subscription = Subscription {
            template: template.clone(),
            request: request.clone(),
            subscribe: message,
        };
        let current: Vec<AgentDescription> = self
            .entries
            .values()
            .filter(|e| matches(template, e))
            .take(service::result_limit(constraints))
            .cloned()
            .map(AgentDescription::Df)
            .collect();
        if !current.is_empty() {
            notify(ctx, &subscription, current);
        }
        self.subscriptions.push(subscription);
    }

    fn cancel(&mut self, message: &AclMessage) {
        let subscriber = message.sender.as_ref().map_or("", |s| s.name.as_str());
        let before = self.subscriptions.len();
        self.subscriptions
            .retain(|s| !s.is(subscriber, message.conversation_id.as_deref()));
        if self.subscriptions.len() == before {
            tracing::info!(%subscriber, conversation = ?message.conversation_id, "CANCEL of no subscription");
        }
    }
}

/// INFORM `((= (iota ?x (result (action ...) ?x)) (sequence ...)))` to a subscriber.
fn notify(ctx: &mut Context<'_>, subscription: &Subscription, descriptions: Vec<AgentDescription>) {
    let content = ManagementContent::Notification {
        request: subscription.request.clone(),
        descriptions,
    };
    let reply = subscription
        .subscribe
        .create_reply()
        .with_performative(Performative::Inform);
    service::send(ctx, content.fill(reply));
}

impl Agent for Df {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match message.performative {
            Performative::Request => {}
            Performative::Subscribe => return self.subscribe(ctx, message),
            Performative::Cancel => return self.cancel(&message),
            other => {
                let act = other.to_string().to_ascii_lowercase();
                return service::not_understood(ctx, &message, FipaError::UnsupportedAct { act });
            }
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
        let before = sender_entry(&self.entries, &sender);
        let (answer, changed) = self.perform(&sender, &request.action);
        service::answer(ctx, &message, &request, answer);
        if let Some(changed) = changed {
            self.notify(ctx, &changed, before.as_ref());
        }
    }
}

fn sender_entry(
    entries: &BTreeMap<String, DfAgentDescription>,
    sender: &AgentId,
) -> Option<DfAgentDescription> {
    entries.get(&sender.name).cloned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use iw_ontology::fipa::Property;
    use proptest::prelude::*;

    fn words() -> impl Strategy<Value = Vec<String>> {
        proptest::collection::vec("[a-c]{1,2}", 0..3)
    }

    fn service() -> impl Strategy<Value = ServiceDescription> {
        (
            proptest::option::of("[a-c]"),
            proptest::option::of("[a-c]"),
            words(),
            words(),
            proptest::option::of(0i64..3),
        )
            .prop_map(|(name, service_type, protocols, languages, speed)| {
                ServiceDescription {
                    name,
                    service_type,
                    protocols,
                    languages,
                    properties: speed
                        .map(|s| Property {
                            name: "speed".into(),
                            value: iw_sl::Term::integer(s),
                        })
                        .into_iter()
                        .collect(),
                    ..ServiceDescription::default()
                }
            })
    }

    fn description() -> impl Strategy<Value = DfAgentDescription> {
        (
            "[a-c]",
            proptest::collection::vec(service(), 0..3),
            words(),
            words(),
        )
            .prop_map(
                |(name, services, protocols, ontologies)| DfAgentDescription {
                    name: Some(AgentId::new(name)),
                    services,
                    protocols,
                    ontologies,
                    ..DfAgentDescription::default()
                },
            )
    }

    /// `entry` with every slot kept or cleared by `keep`'s bits: a template it must match.
    fn weaken(entry: &DfAgentDescription, keep: u32) -> DfAgentDescription {
        let bit = |i: u32| keep & (1 << i) != 0;
        let services = entry
            .services
            .iter()
            .enumerate()
            .filter(|(i, _)| bit(4 + *i as u32))
            .map(|(i, s)| ServiceDescription {
                name: s.name.clone().filter(|_| bit(8 + i as u32)),
                properties: if bit(12 + i as u32) {
                    s.properties.clone()
                } else {
                    Vec::new()
                },
                ..s.clone()
            })
            .collect();
        DfAgentDescription {
            name: entry.name.clone().filter(|_| bit(0)),
            protocols: if bit(1) {
                entry.protocols.clone()
            } else {
                Vec::new()
            },
            ontologies: if bit(2) {
                entry.ontologies.clone()
            } else {
                Vec::new()
            },
            services,
            ..DfAgentDescription::default()
        }
    }

    proptest! {
        #[test]
        fn an_entry_matches_every_weakening_of_itself(entry in description(), keep in any::<u32>()) {
            prop_assert!(matches(&weaken(&entry, keep), &entry));
            prop_assert!(matches(&DfAgentDescription::default(), &entry));
        }

        #[test]
        fn a_template_asking_for_more_does_not_match(entry in description(), extra in "[x-z]{1,3}") {
            let mut more = entry.clone();
            more.protocols.push(extra.clone());
            prop_assert!(!matches(&more, &entry));
            let mut other_service = entry.clone();
            other_service.services.push(ServiceDescription { service_type: Some(extra), ..ServiceDescription::default() });
            prop_assert!(!matches(&other_service, &entry));
            let mut other_name = entry.clone();
            other_name.name = Some(AgentId::new("someone-else"));
            prop_assert!(!matches(&other_name, &entry));
        }
    }
}
