//! The HTTP + websocket server.

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::{Arc, Mutex, PoisonError, mpsc};
use std::thread::JoinHandle;

use axum::Router;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Request, State as Extract};
use axum::http::{StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use tokio::sync::{oneshot, watch};

use crate::state::{Action, MapView, State};

/// The page: plain JS and a canvas, no build step.
const INDEX_HTML: &str = include_str!("../static/index.html");

/// Longest action the page may send, bytes; longer frames are refused.
const MAX_ACTION_BYTES: usize = 4096;

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

#[derive(Clone)]
struct Shared {
    map: Arc<str>,
    frames: watch::Receiver<Arc<str>>,
    actions: Arc<Mutex<mpsc::Sender<Action>>>,
    token: Option<Arc<str>>,
}

/// The running dashboard; stops (and joins its thread) when dropped.
pub struct Dashboard {
    addr: SocketAddr,
    token: Option<String>,
    frames: watch::Sender<Arc<str>>,
    actions: mpsc::Receiver<Action>,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl Dashboard {
    /// Binds and starts serving `map` and the frames [`Dashboard::publish`]ed.
    pub fn start(config: DashboardConfig, map: &MapView) -> Result<Self, DashboardError> {
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
                    let app = router(shared);
                    let serve = axum::serve(listener, app).with_graceful_shutdown(async {
                        let _ = stopped.await;
                    });
                    if let Err(e) = serve.await {
                        tracing::error!("dashboard server: {e}");
                    }
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
    pub fn try_action(&self) -> Option<Action> {
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
                match serde_json::from_str::<Action>(&text) {
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
