//! The HTTP side: the embedded page, the Server-Sent Events stream, and the command endpoints.

use std::collections::VecDeque;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::body::Bytes;
use axum::extract::{ConnectInfo, DefaultBodyLimit, Path, Query, Request, State};
use axum::http::{header, HeaderMap, Method, StatusCode};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use base64::Engine as _;
use cetratus_proto::{BrokerUrl, Command, LoadArgs, PlcId, Verb};
use futures_util::Stream;
use serde::Deserialize;
use serde_json::{json, Value};
use tokio::sync::{broadcast, watch};

use crate::access::{self, Access, LoginError};
use crate::hub::{run_mqtt, unix_ms, Hub, Push};
use crate::rollouts::{Refusal, RolloutConfig, Rollouts};

const INDEX_HTML: &str = include_str!("../assets/index.html");
const LOGIN_HTML: &str = include_str!("../assets/login.html");
const LOGIN_JS: &str = include_str!("../assets/login.js");
const APP_JS: &str = include_str!("../assets/app.js");
const STYLE_CSS: &str = include_str!("../assets/style.css");
const FLEET_JS: &str = include_str!("../assets/fleet.js");

/// The PLC refuses command payloads over 1 MiB (docs/mqtt.md); base64 grows a package by 4/3, so
/// this is the largest package worth forwarding.
const MAX_PACKAGE: usize = (1 << 20) / 4 * 3 - 1024;

#[derive(Clone)]
struct App {
    hub: Arc<Hub>,
    access: Arc<Access>,
    shutdown: watch::Receiver<bool>,
    rollouts: Arc<Rollouts>,
}

/// The address a request came from, over TCP or TLS.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Peer(std::net::SocketAddr);

impl
    axum::extract::connect_info::Connected<axum::serve::IncomingStream<'_, tokio::net::TcpListener>>
    for Peer
{
    fn connect_info(s: axum::serve::IncomingStream<'_, tokio::net::TcpListener>) -> Self {
        Peer(*s.remote_addr())
    }
}

impl
    axum::extract::connect_info::Connected<axum::serve::IncomingStream<'_, crate::tls::TlsListener>>
    for Peer
{
    fn connect_info(s: axum::serve::IncomingStream<'_, crate::tls::TlsListener>) -> Self {
        Peer(*s.remote_addr())
    }
}

/// Serves until `shutdown` turns true, with the MQTT client on the same runtime. The pair after
/// `shutdown` is what the page's operators may command besides watching: single PLCs (signed by
/// the signer, when there is one) and rollouts (when configured).
pub(crate) async fn run(
    listener: std::net::TcpListener,
    broker: BrokerUrl,
    shutdown: watch::Receiver<bool>,
    (signer, rollouts): (Option<crate::CommandSigner>, Option<RolloutConfig>),
    token: String,
    access: Arc<Access>,
    tls: Option<tokio_rustls::TlsAcceptor>,
) {
    let listener = match tokio::net::TcpListener::from_std(listener) {
        Ok(l) => l,
        Err(e) => {
            tracing::error!(error = %e, "the dashboard cannot use its listening socket");
            return;
        }
    };
    let (hub, eventloop) = Hub::new(&broker, signer, &token);
    let mqtt = tokio::spawn(run_mqtt(hub.clone(), eventloop, shutdown.clone()));
    let rollouts = Arc::new(Rollouts::new(rollouts, hub.sender()));
    let app = App {
        hub,
        access,
        shutdown: shutdown.clone(),
        rollouts,
    };
    let router = Router::new()
        .route("/", get(index))
        .route("/login", get(login_link))
        .route("/app.js", get(app_js))
        .route("/fleet.js", get(fleet_js))
        .route("/login.js", get(login_js))
        .route("/style.css", get(style_css))
        .route("/api/login", post(login))
        .route("/api/logout", post(logout))
        .route("/api/plcs", get(plcs))
        .route("/api/plc/{plc}", get(snapshot))
        .route("/api/stream", get(stream))
        .route("/api/fleet", get(fleet))
        .route("/api/rollout/{action}", post(rollout))
        .route("/api/{plc}/{verb}", post(command))
        .layer(middleware::from_fn_with_state(app.clone(), guard))
        .layer(DefaultBodyLimit::max(2 << 20))
        .with_state(app)
        .into_make_service_with_connect_info::<Peer>();
    let mut stop = shutdown.clone();
    let graceful = async move {
        let _ = stop.wait_for(|s| *s).await;
    };
    let mut stop = shutdown.clone();
    // Graceful shutdown waits for open connections; a browser that does not let go must not keep
    // the process alive, so give up after two seconds.
    let deadline = async move {
        let _ = stop.wait_for(|s| *s).await;
        tokio::time::sleep(Duration::from_secs(2)).await;
    };
    let served = async move {
        let r = match tls {
            None => {
                axum::serve(listener, router)
                    .with_graceful_shutdown(graceful)
                    .await
            }
            Some(acceptor) => match crate::tls::TlsListener::start(listener, acceptor) {
                Ok(l) => {
                    axum::serve(l, router)
                        .with_graceful_shutdown(graceful)
                        .await
                }
                Err(e) => Err(e),
            },
        };
        if let Err(e) = r {
            tracing::error!(error = %e, "the dashboard's HTTP server stopped");
        }
    };
    tokio::select! {
        _ = served => {}
        _ = deadline => {}
    }
    let _ = tokio::time::timeout(Duration::from_secs(1), mqtt).await;
}

/// What the page may load and run: its own files only. No inline script or style, so that
/// markup that slipped into the page could neither run nor restyle it (defence in depth: the
/// page never inserts markup from the broker).
const CSP: &str = "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; \
                   connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; \
                   frame-ancestors 'none'";

fn asset(content_type: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-cache"),
            (header::CONTENT_SECURITY_POLICY, CSP),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
        ],
        body,
    )
        .into_response()
}

/// Every request: the `Host` (and a POST's `Origin`) must be the dashboard's own; every `/api/`
/// request but the login needs a session.
async fn guard(State(app): State<App>, req: Request, next: Next) -> Response {
    let post = req.method() == Method::POST;
    if let Err(why) = app.access.check_origin(req.headers(), post) {
        return error(StatusCode::FORBIDDEN, "not_allowed", why);
    }
    let path = req.uri().path();
    if path.starts_with("/api/")
        && path != "/api/login"
        && app.access.account(req.headers()).is_none()
    {
        return error(
            StatusCode::UNAUTHORIZED,
            "unauthorised",
            "log in first: open the login link that `cetratus run`, `demo` or `mct` printed, or \
             log in with an account of the `[dashboard]` configuration"
                .into(),
        );
    }
    next.run(req).await
}

/// The page, or the login page for a browser without a session.
async fn index(State(app): State<App>, headers: HeaderMap) -> Response {
    if app.access.account(&headers).is_some() {
        asset("text/html; charset=utf-8", INDEX_HTML)
    } else {
        asset("text/html; charset=utf-8", LOGIN_HTML)
    }
}

async fn login_js() -> Response {
    asset("text/javascript; charset=utf-8", LOGIN_JS)
}

#[derive(Deserialize)]
struct LinkQuery {
    token: String,
}

/// `GET /login?token=…`: a one-time login link; on to the page with a session.
async fn login_link(State(app): State<App>, Query(q): Query<LinkQuery>) -> Response {
    match app.access.redeem(&q.token) {
        Some(session) => (
            StatusCode::SEE_OTHER,
            [
                (header::SET_COOKIE, app.access.set_cookie(&session)),
                (header::LOCATION, "/".to_string()),
                (header::CACHE_CONTROL, "no-store".to_string()),
            ],
        )
            .into_response(),
        None => (
            StatusCode::FORBIDDEN,
            [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
            "This login link was used already or has expired: each link logs in once. Log in \
             with an account of the [dashboard] configuration, or restart the PLC (or the \
             dashboard) for a new link.\n",
        )
            .into_response(),
    }
}

#[derive(Deserialize)]
struct Credentials {
    account: String,
    password: String,
}

/// `POST /api/login` with `{"account": …, "password": …}`.
async fn login(
    State(app): State<App>,
    ConnectInfo(Peer(peer)): ConnectInfo<Peer>,
    headers: HeaderMap,
    body: Bytes,
) -> Response {
    if let Err(r) = require_type(&headers, &["application/json"]) {
        return r;
    }
    let Ok(c) = serde_json::from_slice::<Credentials>(&body) else {
        return error(
            StatusCode::BAD_REQUEST,
            "malformed",
            "send {\"account\": …, \"password\": …}".into(),
        );
    };
    if c.account.len() > access::MAX_NAME || c.password.len() > 1024 {
        return error(
            StatusCode::UNAUTHORIZED,
            "unauthorised",
            "wrong account name or password".into(),
        );
    }
    match app.access.login(peer.ip(), c.account, c.password).await {
        Ok(session) => (
            [(header::SET_COOKIE, app.access.set_cookie(&session))],
            Json(json!({"ok": true})),
        )
            .into_response(),
        Err(LoginError::TooMany) => error(
            StatusCode::TOO_MANY_REQUESTS,
            "busy",
            "too many login attempts; wait a few seconds".into(),
        ),
        Err(LoginError::Wrong) => error(
            StatusCode::UNAUTHORIZED,
            "unauthorised",
            "wrong account name or password".into(),
        ),
    }
}

/// `POST /api/logout`.
async fn logout(State(app): State<App>, headers: HeaderMap) -> Response {
    app.access.logout(&headers);
    (
        [(header::SET_COOKIE, access::clear_cookie())],
        Json(json!({"ok": true})),
    )
        .into_response()
}

/// Refuses a body whose `Content-Type` is not one of `types`: a form or `text/plain`, which a
/// page of another site may send without asking, never reaches a handler.
#[allow(clippy::result_large_err)]
fn require_type(headers: &HeaderMap, types: &[&str]) -> Result<(), Response> {
    let given = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let essence = given.split(';').next().unwrap_or("").trim();
    if types.iter().any(|t| essence.eq_ignore_ascii_case(t)) {
        return Ok(());
    }
    Err(error(
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "malformed",
        format!(
            "the body's Content-Type is `{}`; send {}",
            given.escape_debug(),
            types.join(" or ")
        ),
    ))
}

async fn app_js() -> Response {
    asset("text/javascript; charset=utf-8", APP_JS)
}

async fn fleet_js() -> Response {
    asset("text/javascript; charset=utf-8", FLEET_JS)
}

async fn style_css() -> Response {
    asset("text/css; charset=utf-8", STYLE_CSS)
}

async fn plcs(State(app): State<App>) -> Json<Vec<crate::store::Listed>> {
    Json(app.hub.fleet().list())
}

async fn snapshot(State(app): State<App>, Path(plc): Path<String>) -> Response {
    if app.hub.fleet().get(&plc).is_none() {
        return error(
            StatusCode::NOT_FOUND,
            "unknown_plc",
            format!("no PLC `{plc}` has published on this broker"),
        );
    }
    Json(app.hub.fleet().snapshot(&plc)).into_response()
}

/// `GET /api/fleet`: every PLC's row, and the page's rollout.
async fn fleet(State(app): State<App>) -> Json<Value> {
    let rows = app.hub.fleet().rows();
    Json(json!({ "plcs": rows, "rollout": app.rollouts.status() }))
}

#[derive(Deserialize)]
struct StartBody {
    plan: String,
}

/// `POST /api/rollout/<start|pause|resume|abort>`: `start` takes `{"plan": "<file name>"}`.
async fn rollout(
    State(app): State<App>,
    Path(action): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> Response {
    if let Err(r) = require_type(&headers, &["application/json"]) {
        return r;
    }
    let Some(account) = app.access.account(&headers) else {
        return error(
            StatusCode::UNAUTHORIZED,
            "unauthorised",
            "log in first".into(),
        );
    };
    let done = match action.as_str() {
        "start" => match serde_json::from_slice::<StartBody>(&body) {
            Ok(b) => app.rollouts.start(&b.plan, &account),
            Err(e) => Err(Refusal(
                400,
                format!("expected {{\"plan\": \"<file name>\"}}: {e}"),
            )),
        },
        "pause" => app
            .rollouts
            .request(cetratus_fleet::Request::Pause, &account),
        "resume" => app
            .rollouts
            .request(cetratus_fleet::Request::Resume, &account),
        "abort" => app
            .rollouts
            .request(cetratus_fleet::Request::Abort, &account),
        other => Err(Refusal(
            404,
            format!(
                "`{}` is not a rollout action; use start, pause, resume or abort",
                other.escape_debug()
            ),
        )),
    };
    match done {
        Ok(()) => (StatusCode::ACCEPTED, Json(json!({"ok": true}))).into_response(),
        Err(Refusal(status, message)) => error(
            StatusCode::from_u16(status).unwrap_or(StatusCode::BAD_REQUEST),
            "refused",
            message,
        ),
    }
}

fn error(status: StatusCode, code: &str, message: String) -> Response {
    (
        status,
        Json(json!({"ok": false, "error": {"code": code, "message": message}})),
    )
        .into_response()
}

#[derive(Deserialize)]
struct StreamQuery {
    plc: Option<String>,
}

fn sse(name: &str, data: &impl serde::Serialize) -> Event {
    let json = serde_json::to_string(data).unwrap_or_else(|_| "null".into());
    Event::default().event(name).data(json)
}

fn broker_event(hub: &Hub, up: bool) -> Event {
    sse("broker", &json!({"connected": up, "url": hub.broker()}))
}

struct Feed {
    hub: Arc<Hub>,
    plc: Option<String>,
    queue: VecDeque<Event>,
    rx: broadcast::Receiver<Push>,
    shutdown: watch::Receiver<bool>,
    // Set when updates were not pushed: the stream ends, and the browser reconnects to a
    // fresh snapshot.
    restart: bool,
}

impl Feed {
    fn push(&mut self, p: Push) {
        match p {
            Push::Plcs(list) => self.queue.push_back(sse("plcs", &list)),
            Push::Broker(up) => self.queue.push_back(broker_event(&self.hub, up)),
            Push::Plc(p) if self.plc.as_deref() == Some(p.update.plc.as_str()) => {
                let u = &p.update;
                let data = json!({"plc": u.plc, "recv_ms": u.recv_ms, "data": u.data});
                self.queue.push_back(sse(u.kind.name(), &data));
            }
            Push::Plc(_) => {}
            Push::Restart => self.restart = true,
            Push::Rollout(report) => self.queue.push_back(sse("rollout", &*report)),
            Push::RolloutEnded => self.queue.push_back(sse("rollout_ended", &json!({}))),
        }
    }
}

/// For each verb, the event kinds that end an accepted command and how (`done`, `failed`): the
/// page shows a command's outcome, not only the PLC's acceptance.
fn endings() -> Value {
    Verb::ALL
        .iter()
        .map(|v| {
            let kinds = cetratus_proto::endings(*v)
                .iter()
                .map(|(k, e)| (k.as_str().to_string(), json!(e)))
                .collect::<serde_json::Map<_, _>>();
            (v.as_str().to_string(), Value::Object(kinds))
        })
        .collect::<serde_json::Map<_, _>>()
        .into()
}

/// `GET /api/stream?plc=ID`: a `hello` event with the PLC list, the broker state and a snapshot of
/// the chosen PLC, then every change. A browser that falls behind is cut off; `EventSource`
/// reconnects by itself and gets a fresh snapshot.
async fn stream(
    State(app): State<App>,
    Query(q): Query<StreamQuery>,
) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    // Subscribe before taking the snapshot so nothing falls between the two.
    let rx = app.hub.subscribe();
    let plc = q.plc.filter(|p| PlcId::is_valid(p));
    let hello = {
        let fleet = app.hub.fleet();
        json!({
            "plcs": fleet.list(),
            "broker": {"connected": app.hub.connected(), "url": app.hub.broker()},
            "snapshot": plc.as_deref().map(|p| fleet.snapshot(p)),
            "now_ms": unix_ms(),
            "endings": endings(),
        })
    };
    let mut queue = VecDeque::new();
    queue.push_back(sse("hello", &hello).retry(Duration::from_secs(1)));
    let feed = Feed {
        hub: app.hub.clone(),
        plc,
        queue,
        rx,
        shutdown: app.shutdown.clone(),
        restart: false,
    };
    let s = futures_util::stream::unfold(feed, |mut f| async move {
        loop {
            if *f.shutdown.borrow() {
                return None;
            }
            if let Some(e) = f.queue.pop_front() {
                return Some((Ok(e), f));
            }
            if f.restart {
                return None;
            }
            tokio::select! {
                r = f.rx.recv() => match r {
                    Ok(p) => f.push(p),
                    Err(_) => return None,
                },
                _ = f.shutdown.changed() => return None,
            }
        }
    });
    Sse::new(s).keep_alive(KeepAlive::new().interval(Duration::from_secs(15)))
}

/// `POST /api/<plc>/<verb>`: the command goes out on MQTT; the PLC's reply is the response.
/// `load` takes the package file's bytes as the body (or a JSON object with `package_b64`);
/// the other verbs take a JSON object of arguments, or nothing.
async fn command(
    State(app): State<App>,
    Path((plc, verb)): Path<(String, String)>,
    headers: HeaderMap,
    body: Bytes,
) -> Response {
    let plc = match PlcId::new(plc) {
        Ok(p) => p,
        Err(e) => return error(StatusCode::BAD_REQUEST, "malformed", e.to_string()),
    };
    let Ok(verb) = verb.parse::<Verb>() else {
        return error(
            StatusCode::NOT_FOUND,
            "unknown_verb",
            format!(
                "`{verb}` is not a command; use one of {}",
                Verb::ALL
                    .iter()
                    .map(|v| v.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        );
    };
    let types: &[&str] = if verb == Verb::Load {
        &["application/json", "application/octet-stream"]
    } else {
        &["application/json"]
    };
    if let Err(r) = require_type(&headers, types) {
        return r;
    }
    let is_json = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json"));
    let args = if verb == Verb::Load && !is_json {
        if body.is_empty() {
            return error(
                StatusCode::BAD_REQUEST,
                "malformed",
                "no package: choose an update package file (.cpkg) and send its bytes".into(),
            );
        }
        if body.len() > MAX_PACKAGE {
            return error(
                StatusCode::PAYLOAD_TOO_LARGE,
                "too_large",
                format!(
                    "the package is {} bytes; the PLC takes at most {MAX_PACKAGE} over MQTT. \
                     Load it locally with `cetratus load` instead",
                    body.len()
                ),
            );
        }
        let package_b64 = base64::engine::general_purpose::STANDARD.encode(&body);
        cetratus_proto::command_body(&Command::Load(LoadArgs { package_b64 }))
    } else if body.iter().all(u8::is_ascii_whitespace) {
        json!({})
    } else {
        match serde_json::from_slice::<Value>(&body) {
            Ok(v @ Value::Object(_)) => v,
            Ok(_) => {
                return error(
                    StatusCode::BAD_REQUEST,
                    "malformed",
                    "the arguments must be a JSON object".into(),
                )
            }
            Err(e) => {
                return error(
                    StatusCode::BAD_REQUEST,
                    "malformed",
                    format!("the arguments are not JSON: {e}"),
                )
            }
        }
    };
    // A substitution that waits for a safe moment answers only when it happens (or gives up).
    let timeout = args
        .get("within_ms")
        .and_then(Value::as_u64)
        .map(|ms| Duration::from_millis(ms.saturating_add(15_000)));
    // Checked here, so that a browser learns at once what the PLC would refuse.
    let args = match cetratus_proto::command_from_body(verb, args) {
        Ok(c) => cetratus_proto::command_body(&c),
        Err(e) => return error(StatusCode::BAD_REQUEST, "malformed", e.to_string()),
    };
    // The guard let only sessions through; the account is who the signed command names.
    let Some(account) = app.access.account(&headers) else {
        return error(
            StatusCode::UNAUTHORIZED,
            "unauthorised",
            "log in first".into(),
        );
    };
    match app.hub.command(&plc, verb, args, timeout, &account).await {
        Ok(reply) => Json(reply).into_response(),
        Err(f) => (
            StatusCode::from_u16(f.status).unwrap_or(StatusCode::BAD_GATEWAY),
            Json(f.body),
        )
            .into_response(),
    }
}
