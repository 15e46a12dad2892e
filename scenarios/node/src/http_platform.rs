//! A whole FIPA platform reachable over HTTP in one call: the AMS, the DF and the caller's
//! agents on an in-process bus, stepped on their own thread, behind an `iw_mtp_http` [`Gateway`].
//! What the `acl send` tests, the JADE-capture tests and the round-trip bench talk to, and what a
//! foreign platform such as JADE can use. It lives here, beside the services container's
//! gateway, because the transport crate hosts no agents.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use iw_acl::{AclMessage, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_ams_df::{Ams, Df, WhitePages};
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, Stack};
use iw_sl::{ActionOp, ActionOperand, Content, ContentExpression, Formula, Level, Term};

use iw_mtp_http::{Error, Gateway, GatewayConfig};

/// A running platform; dropping it stops its agents and its server.
pub struct HttpPlatform {
    bus: Arc<Bus>,
    gateway: Arc<Gateway>,
    pages: WhitePages,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for HttpPlatform {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HttpPlatform")
            .field("gateway", &self.gateway)
            .finish_non_exhaustive()
    }
}

impl HttpPlatform {
    /// Starts platform `config.platform` hosting `ams`, `df` and `agents` (local name, agent),
    /// each named `local@platform` with the gateway's address, stepped every `period`. The bus
    /// runs no EN 50159 layers: the HTTP side is for interoperability (use TLS for secrecy).
    pub async fn start(
        config: GatewayConfig,
        agents: Vec<(String, Box<dyn Agent>)>,
        period: Duration,
    ) -> Result<Self, Error> {
        let network = InProcNetwork::new();
        let transport = network
            .endpoint(&config.platform)
            .map_err(|e| Error::Attach {
                agent: config.platform.clone(),
                what: "in-process transport",
                source: Box::new(e),
            })?;
        let bus = Bus::start(
            Stack::new(),
            Arc::new(transport),
            Clock::system(),
            BusConfig::default(),
        )
        .map_err(|e| Error::Attach {
            agent: config.platform.clone(),
            what: "starting its bus",
            source: Box::new(e),
        })?;
        let bus = Arc::new(bus);
        let gateway = Gateway::start(config, bus.clone()).await?;
        let mut host = AgentHost::new(bus.clone());
        let pages = WhitePages::new();
        let services: Vec<(String, Box<dyn Agent>)> = vec![
            ("ams".into(), Box::new(Ams::new(pages.clone()))),
            ("df".into(), Box::new(Df::new())),
        ];
        for (local, agent) in services.into_iter().chain(agents) {
            let aid = gateway.aid(&local);
            pages
                .host(&mut host, aid, agent)
                .map_err(|e| Error::Attach {
                    agent: local,
                    what: "hosting it on the bus",
                    source: Box::new(e),
                })?;
        }
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = stop.clone();
            std::thread::Builder::new()
                .name(format!("platform-{}", gateway.platform()))
                .spawn(move || host.run_until(period, &stop))
                .map_err(|source| Error::Io {
                    peer: "agent host thread".into(),
                    source,
                })?
        };
        Ok(Self {
            bus,
            gateway,
            pages,
            stop,
            thread: Some(thread),
        })
    }

    /// The gateway (address, foreign agents).
    pub fn gateway(&self) -> &Arc<Gateway> {
        &self.gateway
    }

    /// The platform's bus (to register mailboxes beside the hosted agents).
    pub fn bus(&self) -> &Arc<Bus> {
        &self.bus
    }

    /// The AMS's agent list.
    pub fn pages(&self) -> &WhitePages {
        &self.pages
    }
}

impl Drop for HttpPlatform {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(thread) = self.thread.take()
            && thread.join().is_err()
        {
            tracing::error!("agent host thread panicked");
        }
    }
}

/// The echo agent of the JADE captures, for interoperability tests: REQUEST `((action …))` gets
/// AGREE then INFORM `((done (action …)))` (JADE's echo wraps the whole content tuple,
/// `((done ((action …))))`, which is not SL), another REQUEST NOT-UNDERSTOOD; QUERY-REF gets
/// INFORM `(echo "<content>")`, as JADE's: an SL term (not SL content, which would be enclosed
/// in parentheses), built through the SL types. A query that is one bare word comes back
/// unquoted, `(echo word)`, the same term JADE writes quoted. At setup it registers service `echo-service` of type
/// `wheelchair-echo` with the platform's DF.
#[derive(Debug, Default)]
pub struct Echo;

impl Agent for Echo {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        // A failure is logged and counted by the host; the echo works without the DF.
        if let Some(request) = ctx.df_registration("echo-service", "wheelchair-echo") {
            let _ = ctx.send(request);
        }
    }

    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let content = message.content_text().unwrap_or_default().to_owned();
        let reply = message.create_reply();
        let replies = match message.performative {
            Performative::Request => match done(&content) {
                Ok(done) => vec![
                    reply.clone().with_performative(Performative::Agree),
                    reply
                        .with_performative(Performative::Inform)
                        .with_content(done.to_string()),
                ],
                // The bus boundary: the typed refusal becomes the NOT-UNDERSTOOD's reason, the
                // text the other platform reads (`(error-message "…")`).
                Err(why) => {
                    let _ = ctx.not_understood(&message, &why.to_string());
                    Vec::new()
                }
            },
            Performative::QueryRef => vec![
                reply
                    .with_performative(Performative::Inform)
                    .with_content(echoed(content).to_string()),
            ],
            _ => Vec::new(),
        };
        for reply in replies {
            let _ = ctx.send(reply);
        }
    }
}

/// `(echo "<query>")`: the echo's answer to a query, the query text as an SL string.
fn echoed(query: String) -> Term {
    Term::positional("echo", vec![Term::string(query)])
}

/// Why the echo does not do a request; sent as the NOT-UNDERSTOOD's reason.
#[derive(Debug, thiserror::Error)]
enum NotDone {
    /// The content is not SL (the parser's message is the reason).
    #[error(transparent)]
    Sl(#[from] iw_sl::SlError),
    /// SL, but not one action.
    #[error("the echo agent does requests of one action: ((action agent act))")]
    NotOneAction,
}

/// `((done α))` for a request `(α)` that is one action.
fn done(request: &str) -> Result<Content, NotDone> {
    let content = iw_sl::parse(request, Level::Full)?;
    match <[ContentExpression; 1]>::try_from(content.expressions) {
        Ok([ContentExpression::Action(action)]) => Ok(Content::single(Formula::ActionCondition {
            op: ActionOp::Done,
            action: Box::new(ActionOperand::Expression(action)),
            condition: None,
        })),
        _ => Err(NotDone::NotOneAction),
    }
}

#[cfg(test)]
mod tests {
    use iw_sl::Constant;

    use super::*;

    #[test]
    fn the_echo_of_a_query_reads_back_as_the_query() {
        for query in [
            "((iota ?x (battery-level wheelchair1 ?x)))",
            "a \"quoted\" word \\ and a backslash",
            "bare-word",
            "ends in a backslash \\",
        ] {
            let echo = echoed(query.to_owned()).to_string();
            // As the one proposition of SL content, `(echo "…")` is an atomic formula.
            let content = iw_sl::parse(&format!("({echo})"), Level::Full).unwrap();
            let [ContentExpression::Formula(Formula::Atomic { predicate, args })] =
                content.expressions.as_slice()
            else {
                panic!("not one proposition: {echo}");
            };
            assert_eq!(predicate, "echo");
            let text = match args.as_slice() {
                [Term::Constant { value }] => match value {
                    Constant::String(s) | Constant::ByteString(s) => s.as_str(),
                    other => panic!("{other:?}"),
                },
                other => panic!("{other:?}"),
            };
            assert_eq!(text, query, "{echo}");
        }
    }
}
