//! The HTTP + websocket server.

use std::collections::HashMap;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::{Arc, Mutex, PoisonError, mpsc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use axum::Router;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Request, State as Extract};
use axum::http::{StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use tokio::sync::{Semaphore, oneshot, watch};

use crate::state::{MapView, PageAction, State};

/// The page: plain JS and a canvas, no build step.
const INDEX_HTML: &str = include_str!("../static/index.html");

/// Longest action the page may send, bytes; longer frames are refused.
const MAX_ACTION_BYTES: usize = 4096;

/// Actions one page may send at once after a quiet spell, and per second sustained. A page
/// sends a drive input per pointer move (60-120 Hz) and every 100 ms while held; more is a
/// flood, each action of which becomes a bus message. Over it, actions are dropped and the page
/// told so.
pub const ACTIONS_BURST: f64 = 200.0;
/// See [`ACTIONS_BURST`].
pub const ACTIONS_PER_S: f64 = 100.0;

/// Errors of the dashboard server.
#[derive(Debug, thiserror::Error)]
pub enum DashboardError {
    /// A non-loopback bind without a token.
    #[error(
        "binding {addr} (not loopback) needs a token: pass one (e.g. --token) or bind 127.0.0.1"
    )]
    TokenRequired { addr: SocketAddr },
    /// The listening socket could not be set up.
    #[error("binding the dashboard on {addr}: {source}")]
    Bind {
        addr: SocketAddr,
        source: std::io::Error,
    },
    /// The state could not be encoded.
    #[error("encoding the dashboard state: {0}")]
    Encode(#[from] serde_json::Error),
}

/// Where the dashboard listens.
#[derive(Debug, Clone)]
pub struct DashboardConfig {
    /// Address and port (port 0: any free port). Default 127.0.0.1:0.
    pub bind: SocketAddr,
    /// Access token; required when `bind` is not a loopback address.
    pub token: Option<String>,
}

impl Default for DashboardConfig {
    fn default() -> Self {
        Self {
            bind: SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 0),
            token: None,
        }
    }
}

/// What one client may hold before it is authenticated (the token is checked only once a
/// request's headers are in): a flood of half-open connections or a slowloris otherwise holds
/// file descriptors and memory without bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConnectionLimits {
    /// Connections served at once before they upgrade to a websocket; more are closed at accept.
    pub max_connections: usize,
    /// Time a client has to send a request's headers, from when the server waits for them.
    pub header_timeout: Duration,
    /// Longest a connection stays in plain HTTP (headers, a body, keep-alive) before it is
    /// closed; a websocket that upgraded in time is not bound by it.
    pub http_timeout: Duration,
    /// Connections one source address may open at once after a quiet spell.
    pub per_source_burst: u32,
    /// Connections one source address may open per second, sustained.
    pub per_source_per_s: f64,
}

impl Default for ConnectionLimits {
    fn default() -> Self {
        Self {
            max_connections: 256,
            header_timeout: Duration::from_secs(5),
            http_timeout: Duration::from_secs(30),
            per_source_burst: 64,
            per_source_per_s: 16.0,
        }
    }
}

#[derive(Clone)]
struct Shared {
    map: Arc<str>,
    frames: watch::Receiver<Arc<str>>,
    actions: Arc<Mutex<mpsc::Sender<PageAction>>>,
    token: Option<Arc<str>>,
}

/// The running dashboard; stops (and joins its thread) when dropped.
pub struct Dashboard {
    addr: SocketAddr,
    token: Option<String>,
    frames: watch::Sender<Arc<str>>,
    actions: mpsc::Receiver<PageAction>,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl Dashboard {
    /// Binds and starts serving `map` and the frames [`Dashboard::publish`]ed, with the default
    /// [`ConnectionLimits`].
    pub fn start(config: DashboardConfig, map: &MapView) -> Result<Self, DashboardError> {
        Self::start_with_limits(config, map, ConnectionLimits::default())
    }

    /// [`Dashboard::start`] with explicit bounds on unauthenticated clients.
    pub fn start_with_limits(
        config: DashboardConfig,
        map: &MapView,
        limits: ConnectionLimits,
    ) -> Result<Self, DashboardError> {
        let addr = config.bind;
        let token = config.token.filter(|t| !t.is_empty());
        if !addr.ip().is_loopback() && token.is_none() {
            return Err(DashboardError::TokenRequired { addr });
        }
        let listener = std::net::TcpListener::bind(addr)
            .map_err(|source| DashboardError::Bind { addr, source })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| DashboardError::Bind { addr, source })?;
        let local = listener
            .local_addr()
            .map_err(|source| DashboardError::Bind { addr, source })?;
        let (frames, frames_rx) = watch::channel(Arc::<str>::from("{}"));
        let (actions_tx, actions) = mpsc::channel();
        let shared = Shared {
            map: Arc::from(serde_json::to_string(map)?),
            frames: frames_rx,
            actions: Arc::new(Mutex::new(actions_tx)),
            token: token.as_deref().map(Arc::from),
        };
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|source| DashboardError::Bind { addr, source })?;
        let (stop, stopped) = oneshot::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("dashboard".into())
            .spawn(move || {
                runtime.block_on(async move {
                    let listener = match tokio::net::TcpListener::from_std(listener) {
                        Ok(l) => l,
                        Err(e) => return tracing::error!("dashboard listener: {e}"),
                    };
                    serve(listener, router(shared), limits, stopped).await;
                })
            })
            .map_err(|source| DashboardError::Bind { addr, source })?;
        Ok(Self {
            addr: local,
            token,
            frames,
            actions,
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's URL (with the token, when there is one).
    pub fn url(&self) -> String {
        match &self.token {
            Some(t) => format!("http://{}/?token={t}", self.addr),
            None => format!("http://{}/", self.addr),
        }
    }

    /// Hands `state` to every connected page; returns the frame's size, bytes.
    pub fn publish(&self, state: &State) -> Result<usize, DashboardError> {
        let text = serde_json::to_string(state)?;
        let len = text.len();
        self.frames.send_replace(Arc::from(text));
        Ok(len)
    }

    /// The next thing a page asked for, if any.
    pub fn try_action(&self) -> Option<PageAction> {
        self.actions.try_recv().ok()
    }
}

impl Drop for Dashboard {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Accepts connections under `limits` until `stopped`: each source's rate first, then the cap,
/// then hyper with a header timeout, the whole plain-HTTP phase under `http_timeout`.
async fn serve(
    listener: tokio::net::TcpListener,
    app: Router,
    limits: ConnectionLimits,
    mut stopped: oneshot::Receiver<()>,
) {
    let slots = Arc::new(Semaphore::new(limits.max_connections.max(1)));
    let mut sources = SourceLimiter::new(limits);
    let mut refused = Refusals::default();
    loop {
        let (stream, peer) = tokio::select! {
            _ = &mut stopped => break,
            accepted = listener.accept() => match accepted {
                Ok(accepted) => accepted,
                Err(e) => {
                    // Out of descriptors (EMFILE) or a connection reset before accept: back off
                    // instead of spinning; the timeouts free descriptors.
                    refused.note(&format!("accept failed: {e}"));
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
        };
        if !sources.allow(peer.ip(), Instant::now()) {
            refused.note("source over its connection rate");
            continue;
        }
        let Ok(slot) = slots.clone().try_acquire_owned() else {
            refused.note("connection cap reached");
            continue;
        };
        let service = hyper_util::service::TowerToHyperService::new(app.clone());
        tokio::spawn(async move {
            let mut http = hyper::server::conn::http1::Builder::new();
            http.timer(hyper_util::rt::TokioTimer::new())
                .header_read_timeout(limits.header_timeout);
            let connection = http
                .serve_connection(hyper_util::rt::TokioIo::new(stream), service)
                .with_upgrades();
            // Dropping the connection at the deadline closes it; an upgrade ends this future.
            let _ = tokio::time::timeout(limits.http_timeout, connection).await;
            drop(slot);
        });
    }
}

/// Per-source token buckets: `per_source_burst` connections, refilled at `per_source_per_s`.
struct SourceLimiter {
    limits: ConnectionLimits,
    buckets: HashMap<IpAddr, (f64, Instant)>,
}

/// Sources remembered at most; past it, the full buckets (quiet sources) are forgotten.
const MAX_TRACKED_SOURCES: usize = 4096;

impl SourceLimiter {
    fn new(limits: ConnectionLimits) -> Self {
        Self {
            limits,
            buckets: HashMap::new(),
        }
    }

    fn allow(&mut self, source: IpAddr, now: Instant) -> bool {
        let burst = f64::from(self.limits.per_source_burst.max(1));
        let rate = self.limits.per_source_per_s.max(0.0);
        let refill = |(tokens, at): (f64, Instant)| {
            (
                burst.min(tokens + now.duration_since(at).as_secs_f64() * rate),
                now,
            )
        };
        if self.buckets.len() >= MAX_TRACKED_SOURCES && !self.buckets.contains_key(&source) {
            self.buckets.retain(|_, bucket| refill(*bucket).0 < burst);
        }
        let bucket = self.buckets.entry(source).or_insert((burst, now));
        *bucket = refill(*bucket);
        if bucket.0 >= 1.0 {
            bucket.0 -= 1.0;
            true
        } else {
            false
        }
    }
}

/// Connections refused, reported as one WARN per kind at most every [`REFUSAL_REPORT`].
#[derive(Default)]
struct Refusals {
    counts: HashMap<String, u64>,
    last_report: Option<Instant>,
}

const REFUSAL_REPORT: Duration = Duration::from_secs(10);

impl Refusals {
    fn note(&mut self, why: &str) {
        *self.counts.entry(why.to_string()).or_default() += 1;
        let now = Instant::now();
        if self
            .last_report
            .is_none_or(|at| now.duration_since(at) >= REFUSAL_REPORT)
        {
            for (why, n) in self.counts.drain() {
                tracing::warn!("dashboard: {n} connection(s) refused: {why}");
            }
            self.last_report = Some(now);
        }
    }
}

fn router(shared: Shared) -> Router {
    Router::new()
        .route("/", get(|| async { Html(INDEX_HTML) }))
        .route(
            "/map.json",
            get(|Extract(s): Extract<Shared>| async move {
                (
                    [(header::CONTENT_TYPE, "application/json")],
                    s.map.to_string(),
                )
            }),
        )
        .route("/ws", get(websocket))
        .layer(middleware::from_fn_with_state(shared.clone(), authorise))
        .with_state(shared)
}

/// Lets a request through when no token is set, or when it carries the token.
async fn authorise(Extract(s): Extract<Shared>, request: Request, next: Next) -> Response {
    let Some(token) = &s.token else {
        return next.run(request).await;
    };
    let from_query = request
        .uri()
        .query()
        .into_iter()
        .flat_map(|q| q.split('&'))
        .filter_map(|kv| kv.strip_prefix("token="))
        .any(|t| same(t.as_bytes(), token.as_bytes()));
    let from_header = request
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
        .is_some_and(|t| same(t.trim().as_bytes(), token.as_bytes()));
    if from_query || from_header {
        next.run(request).await
    } else {
        (
            StatusCode::UNAUTHORIZED,
            "401: this dashboard needs its token (?token= or Authorization: Bearer)\n",
        )
            .into_response()
    }
}

/// Compares in time independent of where the first difference is.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn websocket(Extract(s): Extract<Shared>, upgrade: WebSocketUpgrade) -> Response {
    upgrade
        .max_message_size(MAX_ACTION_BYTES)
        .on_upgrade(move |socket| session(socket, s))
}

/// One page: frames out as they are published, actions in.
async fn session(mut socket: WebSocket, s: Shared) {
    let mut frames = s.frames.clone();
    let mut budget = (ACTIONS_BURST, Instant::now());
    let mut dropped = 0u64;
    let first = frames.borrow_and_update().clone();
    if socket
        .send(Message::Text(first.to_string().into()))
        .await
        .is_err()
    {
        return;
    }
    loop {
        tokio::select! {
            changed = frames.changed() => {
                if changed.is_err() {
                    break;
                }
                let frame = frames.borrow_and_update().clone();
                if socket.send(Message::Text(frame.to_string().into())).await.is_err() {
                    break;
                }
            }
            incoming = socket.recv() => {
                let Some(Ok(message)) = incoming else { break };
                let Message::Text(text) = message else { continue };
                let now = Instant::now();
                let tokens = ACTIONS_BURST.min(budget.0 + now.duration_since(budget.1).as_secs_f64() * ACTIONS_PER_S);
                if tokens < 1.0 {
                    budget = (tokens, now);
                    dropped += 1;
                    // Told once per 100 dropped, so the replies are no flood of their own.
                    if dropped % 100 == 1 {
                        let reply = serde_json::json!({ "error": format!(
                            "too many actions: more than {ACTIONS_PER_S} per second; {dropped} dropped"
                        ) });
                        if socket.send(Message::Text(reply.to_string().into())).await.is_err() {
                            break;
                        }
                    }
                    continue;
                }
                budget = (tokens - 1.0, now);
                match serde_json::from_str::<PageAction>(&text) {
                    Ok(action) => {
                        let sent = s.actions.lock().unwrap_or_else(PoisonError::into_inner).send(action);
                        if sent.is_err() {
                            break;
                        }
                    }
                    Err(e) => {
                        let reply = serde_json::json!({ "error": format!("action not understood: {e}") });
                        if socket.send(Message::Text(reply.to_string().into())).await.is_err() {
                            break;
                        }
                    }
                }
            }
        }
    }
}
