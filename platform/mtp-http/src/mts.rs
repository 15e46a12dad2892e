//! The AMS's report of a message the platform could not deliver.

use iw_acl::{AclMessage, AgentId, Performative};
use iw_ontology::Concept;
use iw_ontology::fipa::{FipaError, ManagementContent};
use iw_sl::{ActionExpression, Term};

/// The FAILURE the AMS `ams` sends the sender of `message` when `receiver` cannot be reached,
/// as JADE's AMS words it: `((action sender (ACLMessage)) (MTS-error receiver
/// (internal-error "reason")))` in fipa-sl, conversation id kept.
pub fn delivery_failure(
    message: &AclMessage,
    receiver: &AgentId,
    ams: AgentId,
    reason: &str,
) -> AclMessage {
    let sender = message.sender.clone().unwrap_or_default();
    let content = ManagementContent::Failure {
        action: ActionExpression::Action {
            agent: sender.to_term(),
            act: Term::positional("ACLMessage", vec![]),
        },
        reason: FipaError::MtsError {
            receiver: receiver.clone(),
            reason: Box::new(FipaError::InternalError {
                message: reason.to_owned(),
            }),
        },
    };
    let mut failure = AclMessage::new(Performative::Failure)
        .with_sender(ams)
        .with_content(content.to_content().to_string())
        .with_language("fipa-sl");
    failure.receivers = vec![sender];
    failure.conversation_id.clone_from(&message.conversation_id);
    failure.in_reply_to.clone_from(&message.reply_with);
    failure
}
