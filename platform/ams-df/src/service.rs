//! What the AMS and the DF share: reading a FIPA-Agent-Management request and answering it the
//! way JADE's platform agents do (no AGREE; INFORM `done`/`result`, REFUSE or FAILURE with the
//! action and a FIPA exception, NOT-UNDERSTOOD for what is not a management request).

use iw_acl::{AclMessage, Performative};
use iw_agent::Context;
use iw_ontology::OntologyContent;
use iw_ontology::fipa::{
    AgentDescription, FipaError, ManagementContent, ManagementRequest, SearchConstraints,
};

/// Most descriptions one search returns (JADE's DF default); `:max-results` may ask for fewer.
pub const MAX_RESULTS: usize = 100;

/// The outcome of one management action.
#[derive(Debug)]
pub(crate) enum Answer {
    /// INFORM `((done (action ...)))`.
    Done,
    /// INFORM `((result (action ...) (sequence ...)))`.
    Result(Vec<AgentDescription>),
    /// REFUSE `((action ...) reason)`: the service will not try (not allowed, unsupported).
    Refuse(FipaError),
    /// FAILURE `((action ...) reason)`: it tried and could not (already or not registered).
    Failure(FipaError),
}

/// How many results `constraints` allow: `:max-results` when non-negative, at most
/// [`MAX_RESULTS`]; JADE's `-1` (and absence) mean the default.
pub(crate) fn result_limit(constraints: &SearchConstraints) -> usize {
    match constraints.max_results {
        Some(n) if n >= 0 => usize::try_from(n).unwrap_or(MAX_RESULTS).min(MAX_RESULTS),
        _ => MAX_RESULTS,
    }
}

/// Whether `performative` answers something: such messages are never answered, so two agents
/// cannot bounce NOT-UNDERSTOOD between them.
pub(crate) fn is_answer(performative: Performative) -> bool {
    matches!(
        performative,
        Performative::Agree
            | Performative::Confirm
            | Performative::Disconfirm
            | Performative::Failure
            | Performative::Inform
            | Performative::InformIf
            | Performative::InformRef
            | Performative::NotUnderstood
            | Performative::Refuse
    )
}

/// The management content of `message`, or `None` after answering NOT-UNDERSTOOD with the
/// reason (wrong ontology, unknown language, content that is not FIPA-Agent-Management).
pub(crate) fn read_content(
    ctx: &mut Context<'_>,
    message: &AclMessage,
) -> Option<ManagementContent> {
    match ManagementContent::from_message(message) {
        Ok(content) => Some(content),
        Err(error) => {
            tracing::info!(agent = %ctx.name(), %error, "management message not understood");
            let value = match error {
                iw_ontology::OntologyError::WrongOntology { .. } => "ontology",
                iw_ontology::OntologyError::Sl(iw_sl::SlError::UnknownLevel { .. }) => "language",
                _ => "content",
            };
            not_understood(
                ctx,
                message,
                FipaError::UnrecognisedValue {
                    value: value.into(),
                },
            );
            None
        }
    }
}

/// Answers NOT-UNDERSTOOD `(reason)`, unless `message` is itself an answer.
pub(crate) fn not_understood(ctx: &mut Context<'_>, message: &AclMessage, reason: FipaError) {
    if is_answer(message.performative) {
        tracing::debug!(agent = %ctx.name(), performative = %message.performative, "unexpected answer dropped");
        return;
    }
    let content = iw_sl::Content::single(reason.to_formula());
    let mut reply = message
        .create_reply()
        .with_performative(Performative::NotUnderstood);
    reply.content = None;
    send(
        ctx,
        reply
            .with_content(content.to_string())
            .with_ontology(iw_ontology::fipa::ONTOLOGY),
    );
}

/// Answers the REQUEST `message` that asked for `request` with `answer`.
pub(crate) fn answer(
    ctx: &mut Context<'_>,
    message: &AclMessage,
    request: &ManagementRequest,
    answer: Answer,
) {
    let reply = message.create_reply();
    let (performative, content) = match answer {
        Answer::Done => (
            Performative::Inform,
            ManagementContent::Done(request.clone()),
        ),
        Answer::Result(descriptions) => (
            Performative::Inform,
            ManagementContent::Result {
                request: request.clone(),
                descriptions,
            },
        ),
        Answer::Refuse(reason) => (Performative::Refuse, failure(request, reason)),
        Answer::Failure(reason) => (Performative::Failure, failure(request, reason)),
    };
    send(ctx, content.fill(reply.with_performative(performative)));
}

fn failure(request: &ManagementRequest, reason: FipaError) -> ManagementContent {
    ManagementContent::Failure {
        action: request.to_action(),
        reason,
    }
}

/// Sends `message`; a failure is already logged and counted by the agent host.
pub(crate) fn send(ctx: &mut Context<'_>, message: AclMessage) {
    let _ = ctx.send(message);
}
