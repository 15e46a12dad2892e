//! `intellwheels acl send`: one ACL message to an agent of another FIPA platform over the HTTP
//! MTP, then every reply printed until the conversation ends or the timeout.
//!
//! The command is a tiny platform of its own: a bus with one mailbox (the sender) behind a
//! gateway serving the reply endpoint, so replies come back exactly as they would to an agent.

use std::net::SocketAddr;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use iw_acl::{AclMessage, AgentId, Performative};
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, Stack};
use iw_interaction::Protocol;
use iw_mtp_http::{Gateway, GatewayConfig};

/// Platform name of the command's reply endpoint.
const PLATFORM: &str = "intellwheels-cli";
/// Local name of the sending agent.
const SENDER: &str = "acl-send";

/// Flags of `acl send`.
#[derive(clap::Args)]
pub struct SendArgs {
    /// The receiver's full name, `NAME@PLATFORM` (e.g. `echo@WheelchairTest`).
    #[arg(long)]
    to: String,
    /// The receiver's transport address (e.g. `http://127.0.0.1:7778/acc`).
    #[arg(long)]
    address: String,
    /// The performative, any case (`request`, `query-ref`, `subscribe`, ...).
    #[arg(long)]
    performative: String,
    /// The interaction protocol (`fipa-request`, `fipa-query`, `fipa-subscribe`, ...); it
    /// decides which reply ends the conversation.
    #[arg(long)]
    protocol: Option<String>,
    /// The content, as text.
    #[arg(long)]
    content: Option<String>,
    /// The content language (e.g. `fipa-sl0`).
    #[arg(long)]
    language: Option<String>,
    /// The ontology (e.g. `FIPA-Agent-Management`).
    #[arg(long)]
    ontology: Option<String>,
    /// Seconds to wait for the conversation to end.
    #[arg(long, default_value = "10", value_parser = crate::cmd::flags::seconds)]
    timeout: Duration,
    /// Where the reply endpoint listens (loopback unless the other platform is on another host).
    #[arg(long, default_value = "127.0.0.1:0")]
    bind: SocketAddr,
}

/// Whether `reply` ends a conversation of `protocol`: FAILURE, REFUSE and NOT-UNDERSTOOD end
/// any; INFORM ends a request or a query (AGREE does not); a subscription lasts until the
/// timeout; without a protocol the first reply ends it.
pub fn ends_conversation(protocol: Option<&str>, reply: Performative) -> bool {
    if matches!(
        reply,
        Performative::Failure | Performative::Refuse | Performative::NotUnderstood
    ) {
        return true;
    }
    match protocol.and_then(|p| p.parse::<Protocol>().ok()) {
        Some(Protocol::Subscribe) => false,
        Some(Protocol::Request | Protocol::RequestWhen | Protocol::Query) => {
            matches!(
                reply,
                Performative::Inform | Performative::InformIf | Performative::InformRef
            )
        }
        _ => true,
    }
}

pub fn run(args: &SendArgs) -> anyhow::Result<ExitCode> {
    let performative: Performative = args
        .performative
        .parse()
        .map_err(|e| anyhow::anyhow!("--performative {:?}: {e}", args.performative))?;
    anyhow::ensure!(
        args.to.contains('@'),
        "--to {:?} must be a full agent name, NAME@PLATFORM",
        args.to
    );
    iw_mtp_http::wire::Url::parse(&args.address)
        .with_context(|| format!("--address {:?}", args.address))?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    runtime.block_on(converse(args, performative))
}

async fn converse(args: &SendArgs, performative: Performative) -> anyhow::Result<ExitCode> {
    let network = InProcNetwork::new();
    let transport = network.endpoint(PLATFORM).context("in-process transport")?;
    let bus = Arc::new(Bus::start(
        Stack::new(),
        Arc::new(transport),
        Clock::system(),
        BusConfig::default(),
    )?);
    let mut config = GatewayConfig::new(PLATFORM);
    config.bind = args.bind;
    let gateway = Gateway::start(config, bus.clone())
        .await
        .context("starting the reply endpoint")?;
    let me = gateway.aid(SENDER);
    let mut inbox = bus.register(&me.name)?;
    let receiver = AgentId::new(&args.to).with_address(&args.address);
    gateway.add_foreign(&receiver)?;

    let stamp = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
        .as_millis();
    let mut message = AclMessage::new(performative)
        .with_sender(me.clone())
        .with_receiver(receiver.clone())
        .with_conversation_id(format!("{SENDER}-{}-{stamp}", std::process::id()))
        .with_reply_with(format!("{SENDER}-{stamp}"));
    message.protocol.clone_from(&args.protocol);
    message.language.clone_from(&args.language);
    message.ontology.clone_from(&args.ontology);
    if let Some(content) = &args.content {
        message = message.with_content(content.clone());
    }
    bus.send(
        &me.name,
        &receiver.name,
        iw_acl::codec::print(&message).into_bytes(),
    )?;

    let own_ams = format!("ams@{PLATFORM}");
    let deadline = tokio::time::Instant::now() + args.timeout;
    let mut replies = 0usize;
    loop {
        let Ok(next) = tokio::time::timeout_at(deadline, inbox.recv()).await else {
            let subscribed = args
                .protocol
                .as_deref()
                .is_some_and(|p| matches!(p.parse(), Ok(Protocol::Subscribe)));
            if subscribed && replies > 0 {
                return Ok(ExitCode::SUCCESS);
            }
            eprintln!(
                "no end of the conversation within {} s ({replies} replies)",
                args.timeout.as_secs_f64()
            );
            return Ok(ExitCode::from(1));
        };
        let envelope = next.context("the reply endpoint stopped")?;
        let text = envelope.payload_str().context("a reply that is not text")?;
        let reply = iw_acl::codec::parse(text).context("a reply that is not ACL")?;
        let content = reply
            .content_text()
            .unwrap_or_default()
            .replace('\n', "\\n");
        if reply.sender.as_ref().is_some_and(|s| s.name == own_ams) {
            anyhow::bail!(
                "the message could not be delivered to {} at {}: {content}",
                args.to,
                args.address
            );
        }
        replies += 1;
        if content.is_empty() {
            println!("{}", reply.performative);
        } else {
            println!("{} {content}", reply.performative);
        }
        if ends_conversation(args.protocol.as_deref(), reply.performative) {
            return Ok(ExitCode::SUCCESS);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn protocols_end_where_fipa_says() {
        assert!(!ends_conversation(
            Some("fipa-request"),
            Performative::Agree
        ));
        assert!(ends_conversation(
            Some("FIPA-Request"),
            Performative::Inform
        ));
        assert!(ends_conversation(
            Some("fipa-query"),
            Performative::InformRef
        ));
        assert!(!ends_conversation(
            Some("fipa-subscribe"),
            Performative::Inform
        ));
        assert!(ends_conversation(
            Some("fipa-subscribe"),
            Performative::Refuse
        ));
        assert!(ends_conversation(None, Performative::Agree));
        assert!(ends_conversation(
            Some("fipa-request"),
            Performative::NotUnderstood
        ));
    }
}
