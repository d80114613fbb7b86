//! `rattle explore`'s HTTP server: one page (HTML, JavaScript and CSS embedded in the binary)
//! and a small JSON API over the library ([`rattle::explore`]). Every request is checked by the
//! command line's own request path before anything is computed (a bad one gets that message
//! as a 400 with JSON); one computation runs at a time, each under its own
//! [`rattle::progress::Stop`]: a new view interrupts the one running, a new click the point
//! running, a client that goes away its own; nothing a request says names a file: exports are
//! written to a directory of the server's own once per map and handed out from memory.

use anyhow::{Context, Result};
use axum::Router;
use axum::body::Bytes;
use axum::extract::{Path as UrlPath, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use rattle::config::Config;
use rattle::engine::Engine;
use rattle::explore::{Explorer, View, coarse, map_view};
use rattle::map::MapResult;
use rattle::progress::Stop;
use serde::Deserialize;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

const PAGE: &str = include_str!("serve/page.html");
const SCRIPT: &str = include_str!("serve/page.js");
const STYLE: &str = include_str!("serve/page.css");

/// The server's state.
struct App {
    explorer: Explorer,
    engine: Engine,
    /// Held by the computation running (one at a time).
    running: Mutex<()>,
    /// The running computation's kind and stop: a newer request of a kind that replaces it
    /// stops it.
    active: Mutex<Option<(Kind, Stop)>>,
    /// The newest map request's number: an older one gives way.
    newest: AtomicU64,
    /// The newest point request's number.
    newest_point: AtomicU64,
    /// Work done and to do of the computation running.
    done: AtomicU64,
    total: AtomicU64,
    busy: AtomicBool,
    /// The last map computed at the configured grid, for the exports.
    last: Mutex<Option<Arc<MapResult>>>,
    /// The maps computed at the configured grid, by view, newest last (at most [`KEPT`]): a
    /// view shown before (a volume's slice the slider comes back to) is not computed again.
    kept: Mutex<Vec<(View, Arc<MapResult>)>>,
    /// The boundaries located on the last map at the configured grid (its view's).
    bounds: Mutex<Option<(View, Arc<rattle::map::boundaries::Boundaries>)>>,
    /// The last clicked point's figure (PNG).
    point_png: Mutex<Option<Vec<u8>>>,
    /// The files of the last full map's set, written once and kept in memory: an export is
    /// then read from here (a second ask of any file of that set writes nothing).
    exports: Mutex<Option<Exports>>,
    /// The server's own directory for the files of one reply: private (mode 0700, a random
    /// name, made at the start), so that no other user can plant a file or a link there.
    scratch: PathBuf,
}

impl rattle::progress::Progress for App {
    fn advance(&self, n: u64) {
        self.done.fetch_add(n, Ordering::Relaxed);
    }

    fn more(&self, n: u64) {
        self.total.fetch_add(n, Ordering::Relaxed);
    }
}

/// Full-grid maps kept for views shown again.
const KEPT: usize = 64;

/// What a computation is: a view's (a map, its boundaries) or a clicked point's.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    View,
    Point,
}

/// A map's set as written for the exports: the map and the boundaries it was written with
/// (compared by identity) and each file's name and bytes.
struct Exports {
    map: Arc<MapResult>,
    bounds: Option<Arc<rattle::map::boundaries::Boundaries>>,
    files: Vec<(String, Vec<u8>)>,
}

/// What a computation came to.
enum Outcome<T> {
    Done(T),
    /// A newer request took its place, or its client went away.
    Cancelled,
    Failed(String),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MapRequest {
    view: View,
    #[serde(default)]
    coarse: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ViewRequest {
    view: View,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PointRequest {
    view: View,
    x: f64,
    y: f64,
}

/// A JSON error reply.
fn error(status: StatusCode, message: impl std::fmt::Display) -> Response {
    let body = serde_json::json!({ "error": message.to_string() });
    (status, axum::Json(body)).into_response()
}

/// A request refused: its status and message (the reply is [`error`]'s).
struct Refusal(StatusCode, String);

impl IntoResponse for Refusal {
    fn into_response(self) -> Response {
        error(self.0, self.1)
    }
}

/// An internal failure as a refusal.
fn internal(e: impl std::fmt::Display) -> Refusal {
    Refusal(StatusCode::INTERNAL_SERVER_ERROR, e.to_string())
}

fn json_reply(value: &impl serde::Serialize) -> Response {
    match serde_json::to_vec(value) {
        Ok(v) => ([(header::CONTENT_TYPE, "application/json")], v).into_response(),
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, e),
    }
}

fn parse<T: serde::de::DeserializeOwned>(body: &[u8]) -> Result<T, Refusal> {
    serde_json::from_slice(body)
        .map_err(|e| Refusal(StatusCode::BAD_REQUEST, format!("malformed request: {e}")))
}

/// Stops a request's computation if its client goes away before it ends (the future awaiting
/// it is dropped).
struct CancelOnDrop {
    stop: Stop,
    armed: bool,
}

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        if self.armed {
            self.stop.stop();
        }
    }
}

impl App {
    /// Stops the computation running if it is of a kind in `kinds`.
    fn stop_running(&self, kinds: &[Kind]) {
        let active = self.active.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((k, stop)) = &*active
            && kinds.contains(k)
        {
            stop.stop();
        }
    }

    /// Runs `work` as the one computation, under `stop`, unless a newer request (`is_newest`
    /// false) took its place or its client left while it waited; a stop unwinds it.
    fn exclusive<T: Send>(
        &self,
        (kind, stop): (Kind, &Stop),
        is_newest: impl Fn() -> bool,
        total: u64,
        work: impl FnOnce() -> rattle::Result<T> + Send,
    ) -> Outcome<T> {
        let _one = self.running.lock().unwrap_or_else(|p| p.into_inner());
        // Shown as running before the check: a newer request either is seen by the check or
        // sees this one to stop it.
        *self.active.lock().unwrap_or_else(|p| p.into_inner()) = Some((kind, stop.clone()));
        if !is_newest() || stop.is_stopped() {
            *self.active.lock().unwrap_or_else(|p| p.into_inner()) = None;
            return Outcome::Cancelled;
        }
        self.done.store(0, Ordering::Relaxed);
        self.total.store(total, Ordering::Relaxed);
        self.busy.store(true, Ordering::Relaxed);
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            rattle::progress::stoppable(stop, work)
        }));
        self.busy.store(false, Ordering::Relaxed);
        *self.active.lock().unwrap_or_else(|p| p.into_inner()) = None;
        match r {
            Ok(Ok(v)) => Outcome::Done(v),
            Ok(Err(e)) => Outcome::Failed(e.to_string()),
            Err(p) if p.is::<rattle::progress::Interrupted>() => Outcome::Cancelled,
            Err(_) => Outcome::Failed("the computation failed (see the server's log)".into()),
        }
    }

    fn compute_map(
        &self,
        (ticket, stop): (u64, &Stop),
        cfg: Config,
        is_coarse: bool,
    ) -> Outcome<Arc<MapResult>> {
        let o = rattle::explore::EXPLORE;
        let total = rattle::map::work(&self.engine, &cfg, &o);
        let newest = || self.newest.load(Ordering::SeqCst) == ticket;
        let out = self.exclusive((Kind::View, stop), newest, total, || {
            rattle::map::compute_map(&self.engine, &cfg, &o, self).map(Arc::new)
        });
        if let Outcome::Done(m) = &out
            && !is_coarse
        {
            self.keep(m);
        }
        out
    }

    /// `m` (a map at the configured grid) is the last one, and kept for its view.
    fn keep(&self, m: &Arc<MapResult>) {
        *self.last.lock().unwrap_or_else(|p| p.into_inner()) = Some(m.clone());
        let view = self.explorer.view_of(&m.cfg);
        let mut kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
        kept.retain(|(v, _)| *v != view);
        kept.push((view, m.clone()));
        if kept.len() > KEPT {
            kept.remove(0);
        }
    }

    /// The map of `view` at the configured grid, if one was computed.
    fn kept(&self, view: &View) -> Option<Arc<MapResult>> {
        let kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
        kept.iter().find(|(v, _)| v == view).map(|(_, m)| m.clone())
    }

    /// The point `cfg` (at `xy` of the view's axes) as `rattle point` decides it, with its figure.
    fn compute_point(
        &self,
        (ticket, stop): (u64, &Stop),
        cfg: Config,
        xy: (f64, f64),
    ) -> Outcome<serde_json::Value> {
        let newest = || self.newest_point.load(Ordering::SeqCst) == ticket;
        let out = self.exclusive((Kind::Point, stop), newest, 0, || {
            let report = rattle::point::run(&self.engine, &cfg, &rattle::progress::Silent)?;
            Ok((report, self.point_figure(&cfg)))
        });
        match out {
            Outcome::Done((report, png)) => {
                let (png, why) = match png {
                    Ok(png) => (Some(png), None),
                    Err(e) => (None, Some(e)),
                };
                let figure = png.is_some();
                *self.point_png.lock().unwrap_or_else(|p| p.into_inner()) = png;
                Outcome::Done(serde_json::json!({
                    "x": xy.0,
                    "y": xy.1,
                    "x_param": self.explorer.cfg.map.x.name(),
                    "y_param": self.explorer.cfg.map.y.name(),
                    "report": report,
                    "figure": figure,
                    "figure_error": why,
                }))
            }
            Outcome::Cancelled => Outcome::Cancelled,
            Outcome::Failed(e) => Outcome::Failed(e),
        }
    }

    /// The point's figure as `point --plot` draws it (CPU, f64), or why there is none (a point
    /// the figure's checks refuse, a motion with nothing to plot, a file that could not be
    /// written): the report is given either way.
    fn point_figure(&self, cfg: &Config) -> Result<Vec<u8>, String> {
        use rattle::point::plot::{PlotOptions, compute, write_outputs};
        let o = PlotOptions::default();
        o.check(cfg).map_err(|e| e.to_string())?;
        let p = compute(cfg, &o, &rattle::progress::Silent).map_err(|e| e.to_string())?;
        let files = write_outputs(&self.scratch.join("point"), &p).map_err(|e| e.to_string())?;
        let png = files
            .iter()
            .find(|f| f.extension().is_some_and(|e| e == "png"))
            .map(|f| std::fs::read(f).map_err(|e| format!("{}: {e}", f.display())));
        remove(&files);
        png.unwrap_or_else(|| Err("no PNG written".into()))
    }

    /// The last full map's file `what` as `rattle map` writes it: (content type, file name,
    /// bytes). The set is written once per map (to the server's own directory, read into
    /// memory and removed), so that asking again, or for another file of it, costs nothing.
    fn export(&self, what: &str) -> Result<(&'static str, String, Vec<u8>), Refusal> {
        let last = self.last.lock().unwrap_or_else(|p| p.into_inner()).clone();
        let Some(m) = last else {
            let why = "no map computed at the full grid yet";
            return Err(Refusal(StatusCode::CONFLICT, why.into()));
        };
        let view = self.explorer.view_of(&m.cfg);
        let text = |s: String| Ok(("text/plain; charset=utf-8", String::new(), s.into_bytes()));
        match what {
            // The served map's own configuration, carried whole.
            "command" => return text(rattle::explore::command_for(&m.cfg, "view")),
            "toml" => {
                let t = toml::to_string(&m.cfg).map_err(internal)?;
                return Ok(("application/toml", "view.toml".into(), t.into_bytes()));
            }
            _ => {}
        }
        // The boundaries located on this very map, if any: files of its set.
        let bounds = self
            .bounds
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
            .filter(|(v, _)| *v == view)
            .map(|(_, b)| b);
        let (ext, kind) = match what {
            "png" => ("png", "image/png"),
            "json" => ("json", "application/json"),
            "boundaries.csv" | "boundaries.png" if bounds.is_some() => match what {
                "boundaries.csv" => ("boundaries.csv", "text/csv"),
                _ => ("boundaries.png", "image/png"),
            },
            _ => match what.strip_suffix(".npy") {
                Some(layer)
                    if rattle::map::Fields::LAYERS.iter().any(|l| l.0 == layer)
                        || (layer == "risk"
                            && rattle::map::risk_layer(&m.cfg, &m.fields).is_some()) =>
                {
                    ("npy", "application/octet-stream")
                }
                _ => {
                    let why = format!("no export {what:?}");
                    return Err(Refusal(StatusCode::NOT_FOUND, why));
                }
            },
        };
        let name = match ext {
            "npy" => format!("view-{what}"),
            "boundaries.csv" | "boundaries.png" => format!("view-{ext}"),
            _ => format!("view.{ext}"),
        };
        let mut exports = self.exports.lock().unwrap_or_else(|p| p.into_inner());
        let current = exports.as_ref().is_some_and(|e| {
            Arc::ptr_eq(&e.map, &m)
                && match (&e.bounds, &bounds) {
                    (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                    (None, None) => true,
                    _ => false,
                }
        });
        if !current {
            *exports = None;
            let prefix = self.scratch.join("view");
            // A view is a plane: its boundaries are one slice's.
            let b = bounds
                .as_deref()
                .map(|b| rattle::map::boundaries::MapBoundaries {
                    slices: vec![b.clone()],
                    across: None,
                    slices_s: None,
                });
            let files =
                rattle::map::write_outputs(&prefix, &m.cfg, &m.fields, &m.report, b.as_ref())
                    .map_err(internal)?;
            let read: std::io::Result<Vec<(String, Vec<u8>)>> = files
                .iter()
                .map(|f| {
                    let name = f.file_name().unwrap_or_default().to_string_lossy();
                    Ok((name.into_owned(), std::fs::read(f)?))
                })
                .collect();
            remove(&files);
            *exports = Some(Exports {
                map: m.clone(),
                bounds: bounds.clone(),
                files: read.map_err(internal)?,
            });
        }
        let files = exports.as_ref().map(|e| &e.files[..]).unwrap_or_default();
        match files.iter().find(|(n, _)| *n == name) {
            Some((_, bytes)) => Ok((kind, name, bytes.clone())),
            None => Err(internal(format!("{name} is not in the map's set"))),
        }
    }
}

/// Removes files written for a reply (nothing of the server's stays in its directory between
/// requests). The directory itself stays until the server ends: removed and made again, its
/// name, seen in the temporary directory's listing, could be taken by another user meanwhile.
fn remove(files: &[PathBuf]) {
    for f in files {
        let _ = std::fs::remove_file(f);
    }
}

async fn page() -> Response {
    ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], PAGE).into_response()
}

async fn script() -> Response {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        SCRIPT,
    )
        .into_response()
}

async fn style() -> Response {
    ([(header::CONTENT_TYPE, "text/css; charset=utf-8")], STYLE).into_response()
}

async fn base(State(app): State<Arc<App>>) -> Response {
    let c = &app.explorer.cfg;
    // A volume's z axis: the page's slider over its slices.
    let z = c.z_axis().map(|z| {
        serde_json::json!({
            "param": z.param.name(),
            "label": z.param.label(),
            "values": z.values(),
            "from": z.from,
            "to": z.to,
        })
    });
    json_reply(&serde_json::json!({
        "view": View::of(c),
        "z": z,
        "x_param": c.map.x.name(),
        "y_param": c.map.y.name(),
        "nx": c.map.x_points,
        "ny": c.map.y_points,
        "backend": app.engine.name(),
        "device": app.engine.device(),
        "precision": c.method.precision.name(),
    }))
}

async fn progress(State(app): State<Arc<App>>) -> Response {
    json_reply(&serde_json::json!({
        "busy": app.busy.load(Ordering::Relaxed),
        "done": app.done.load(Ordering::Relaxed),
        "total": app.total.load(Ordering::Relaxed),
    }))
}

async fn map(State(app): State<Arc<App>>, body: Bytes) -> Response {
    let req: MapRequest = match parse(&body) {
        Ok(r) => r,
        Err(e) => return e.into_response(),
    };
    let cfg = match app.explorer.map_config(&req.view) {
        Ok(c) => c,
        Err(e) => return error(StatusCode::BAD_REQUEST, e),
    };
    let view = app.explorer.view_of(&cfg);
    // A view shown before at the configured grid is answered from its map (the coarse picture
    // is still the coarse picture: it costs little, and the API says what it is).
    if let Some(m) = (!req.coarse).then(|| app.kept(&view)).flatten() {
        app.newest.fetch_add(1, Ordering::SeqCst);
        app.stop_running(&[Kind::View, Kind::Point]);
        app.keep(&m);
        return out_map(Outcome::Done(m), false, view);
    }
    let cfg = if req.coarse { coarse(&cfg) } else { cfg };
    let is_coarse = req.coarse;
    let out = newest_view(&app, move |worker, run| {
        out_map(worker.compute_map(run, cfg, is_coarse), is_coarse, view)
    })
    .await;
    out.unwrap_or_else(|e| error(StatusCode::INTERNAL_SERVER_ERROR, e))
}

/// Runs `work` (given the app, its ticket and its stop) as the newest view's computation: the
/// computation running (a view's or a point's) gives way to it.
async fn newest_view<T: Send + 'static>(
    app: &Arc<App>,
    work: impl FnOnce(&App, (u64, &Stop)) -> T + Send + 'static,
) -> Result<T, tokio::task::JoinError> {
    let ticket = app.newest.fetch_add(1, Ordering::SeqCst) + 1;
    app.stop_running(&[Kind::View, Kind::Point]);
    own_run(app, ticket, work).await
}

/// Runs `work` (given the app, `ticket` and a stop of its own) off the server's threads; a
/// client that goes away before it ends stops it.
async fn own_run<T: Send + 'static>(
    app: &Arc<App>,
    ticket: u64,
    work: impl FnOnce(&App, (u64, &Stop)) -> T + Send + 'static,
) -> Result<T, tokio::task::JoinError> {
    let stop = Stop::new();
    let mut guard = CancelOnDrop {
        stop: stop.clone(),
        armed: true,
    };
    let worker = app.clone();
    let out = tokio::task::spawn_blocking(move || work(&worker, (ticket, &stop))).await;
    guard.armed = false;
    out
}

/// The page's reply of a map computed for `view`.
fn out_map(out: Outcome<Arc<MapResult>>, is_coarse: bool, view: View) -> Response {
    match out {
        Outcome::Done(m) => {
            let mut mv = map_view(&m.cfg, &m.fields, is_coarse);
            mv.view = view;
            let mut v = serde_json::to_value(mv).unwrap_or_default();
            v["timings"] = serde_json::to_value(&m.report.timings).unwrap_or_default();
            json_reply(&v)
        }
        Outcome::Cancelled => error(StatusCode::CONFLICT, "cancelled: a newer view was asked"),
        Outcome::Failed(e) => error(StatusCode::INTERNAL_SERVER_ERROR, e),
    }
}

async fn point(State(app): State<Arc<App>>, body: Bytes) -> Response {
    let req: PointRequest = match parse(&body) {
        Ok(r) => r,
        Err(e) => return e.into_response(),
    };
    // Checked before anything waits: a bad point is refused at once.
    let xy = (req.x, req.y);
    let cfg = match app.explorer.point_config(&req.view, xy) {
        Ok(c) => c,
        Err(e) => return error(StatusCode::BAD_REQUEST, e),
    };
    // A newer click replaces an older point, running or waiting (not a view's map).
    let ticket = app.newest_point.fetch_add(1, Ordering::SeqCst) + 1;
    app.stop_running(&[Kind::Point]);
    let out = own_run(&app, ticket, move |worker, run| {
        worker.compute_point(run, cfg, xy)
    })
    .await;
    match out {
        Ok(Outcome::Done(v)) => json_reply(&v),
        Ok(Outcome::Cancelled) => error(
            StatusCode::CONFLICT,
            "cancelled: a newer point or view was asked",
        ),
        Ok(Outcome::Failed(e)) => error(StatusCode::INTERNAL_SERVER_ERROR, e),
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, e),
    }
}

/// The typed boundaries of the view's map (`rattle map --boundaries`'s), once the map of that
/// view has been computed at the configured grid; a new view interrupts them as it does a map.
async fn boundaries(State(app): State<Arc<App>>, body: Bytes) -> Response {
    let req: ViewRequest = match parse(&body) {
        Ok(r) => r,
        Err(e) => return e.into_response(),
    };
    let last = app.last.lock().unwrap_or_else(|p| p.into_inner()).clone();
    let Some(m) = last.filter(|m| app.explorer.view_of(&m.cfg) == req.view) else {
        let why = "the boundaries need that view's map at the configured grid first";
        return error(StatusCode::CONFLICT, why);
    };
    let out = newest_view(&app, move |worker, (ticket, stop)| {
        let newest = || worker.newest.load(Ordering::SeqCst) == ticket;
        worker.exclusive((Kind::View, stop), newest, 0, || {
            rattle::map::boundaries::of_fields(&worker.engine, &m.cfg, &m.fields)
        })
    })
    .await;
    match out {
        Ok(Outcome::Done(b)) => {
            let b = Arc::new(b);
            *app.bounds.lock().unwrap_or_else(|p| p.into_inner()) = Some((req.view, b.clone()));
            let mut v = serde_json::to_value(&*b).unwrap_or_default();
            v["view"] = serde_json::to_value(req.view).unwrap_or_default();
            v["colours"] = rattle::map::boundaries::Type::ALL
                .iter()
                .map(|t| (t.name().to_string(), serde_json::json!(t.rgb())))
                .collect::<serde_json::Map<_, _>>()
                .into();
            json_reply(&v)
        }
        Ok(Outcome::Cancelled) => error(StatusCode::CONFLICT, "cancelled: a newer view was asked"),
        Ok(Outcome::Failed(e)) => error(StatusCode::INTERNAL_SERVER_ERROR, e),
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, e),
    }
}

async fn point_png(State(app): State<Arc<App>>) -> Response {
    match app
        .point_png
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .clone()
    {
        Some(png) => ([(header::CONTENT_TYPE, "image/png")], png).into_response(),
        None => error(StatusCode::NOT_FOUND, "no point computed yet"),
    }
}

async fn export(State(app): State<Arc<App>>, UrlPath(what): UrlPath<String>) -> Response {
    let worker = app.clone();
    match tokio::task::spawn_blocking(move || worker.export(&what)).await {
        Ok(Ok((kind, name, bytes))) => {
            let mut r = ([(header::CONTENT_TYPE, kind)], bytes).into_response();
            if !name.is_empty()
                && let Ok(v) = format!("attachment; filename=\"{name}\"").parse()
            {
                r.headers_mut().insert(header::CONTENT_DISPOSITION, v);
            }
            r
        }
        Ok(Err(e)) => e.into_response(),
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, e),
    }
}

/// Who may talk to the server: a request whose Host names the address it listens on (by its
/// number, or `localhost` on the loopback; any Host where it listens on every address), whose
/// Origin, where a browser sends one, is the page's own, and whose POST body is declared JSON.
/// A page of another origin can then neither drive it (a `text/plain` POST needs no
/// permission of the server's, a JSON one does) nor read its replies through a name that
/// resolves to the loopback (DNS rebinding).
#[derive(Clone)]
struct Gate {
    /// The port it listens on: every Host accepted names it.
    port: u16,
    /// The Host values accepted by name (the address, `localhost` on the loopback, the names
    /// of `--allow-host`), each with the port.
    hosts: Arc<Vec<String>>,
    /// Listening on every address: any IP literal with the port is accepted too (a name is
    /// not, unless allowed: DNS rebinding points a foreign name at this machine).
    any_ip: bool,
}

impl Gate {
    fn new(at: std::net::SocketAddr, allowed: &[String]) -> Self {
        let ip = at.ip();
        let mut hosts = Vec::new();
        if !ip.is_unspecified() {
            hosts.push(at.to_string());
        }
        if ip.is_loopback() || ip.is_unspecified() {
            hosts.push(format!("localhost:{}", at.port()));
        }
        hosts.extend(allowed.iter().map(|h| format!("{h}:{}", at.port())));
        Gate {
            port: at.port(),
            hosts: Arc::new(hosts),
            any_ip: ip.is_unspecified(),
        }
    }

    /// Whether a request's Host is this server's.
    fn accepts(&self, host: &str) -> bool {
        if self.hosts.iter().any(|h| h.eq_ignore_ascii_case(host)) {
            return true;
        }
        // An IP literal with the port (`192.0.2.7:8750`, `[::1]:8750`) where it listens on
        // every address.
        self.any_ip
            && host
                .parse::<std::net::SocketAddr>()
                .is_ok_and(|a| a.port() == self.port)
    }

    /// Why `headers` of a request with `method` are refused, if they are.
    fn refusal(
        &self,
        method: &axum::http::Method,
        headers: &axum::http::HeaderMap,
    ) -> Option<Response> {
        let text = |h| headers.get(h).map(|v| v.to_str().unwrap_or("?"));
        let host = text(header::HOST).unwrap_or("");
        if !self.accepts(host) {
            let ips = if self.any_ip {
                ", or an IP address of this machine"
            } else {
                ""
            };
            let why = format!(
                "Host {host:?} is not this server's ({}{ips}, with the port; names given with \
                 --allow-host)",
                self.hosts.join(", ")
            );
            return Some(error(StatusCode::FORBIDDEN, why));
        }
        if let Some(origin) = text(header::ORIGIN)
            && origin != format!("http://{host}")
        {
            let why = format!("a request from another origin ({origin}) is refused");
            return Some(error(StatusCode::FORBIDDEN, why));
        }
        let json = text(header::CONTENT_TYPE).is_some_and(|t| {
            t.split(';')
                .next()
                // Media types are case-insensitive (RFC 9110, 8.3.1).
                .is_some_and(|m| m.trim().eq_ignore_ascii_case("application/json"))
        });
        if method == axum::http::Method::POST && !json {
            let why = "a POST body must be JSON, sent with Content-Type: application/json";
            return Some(error(StatusCode::UNSUPPORTED_MEDIA_TYPE, why));
        }
        None
    }
}

async fn gate(
    State(g): State<Gate>,
    req: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    match g.refusal(req.method(), req.headers()) {
        Some(r) => r,
        None => {
            let r = next.run(req).await;
            // axum's own refusal of a body over its limit is plain text: the JSON shape here.
            if r.status() == StatusCode::PAYLOAD_TOO_LARGE {
                let why = "the request body is over the limit of 2 MB";
                return error(StatusCode::PAYLOAD_TOO_LARGE, why);
            }
            r
        }
    }
}

/// Serves `explorer` at `addr` until the process is interrupted (Ctrl-C ends it, as every
/// command: nothing of the server's is half-written on disk).
pub fn serve(explorer: Explorer, addr: (std::net::IpAddr, u16), allowed: &[String]) -> Result<()> {
    let engine = Engine::open(explorer.cfg.method.backend)?;
    // A fresh directory of a random name, mode 0700, removed when the server ends (returns or
    // is interrupted). A predictable name (the process id) could be made first by another
    // local user, with links in it that the server's writes would follow.
    let private = tempfile::Builder::new()
        .prefix("rattle-explore-")
        .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o700))
        .tempdir()
        .context("cannot make the server's scratch directory")?;
    let scratch = private.path().to_path_buf();
    rattle::output::remove_on_interrupt(scratch.clone());
    // An interrupt unwinds the computation it stops: not a crash, nothing to print.
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !info.payload().is::<rattle::progress::Interrupted>() {
            previous(info);
        }
    }));
    let app = Arc::new(App {
        explorer,
        engine,
        running: Mutex::new(()),
        active: Mutex::new(None),
        newest: AtomicU64::new(0),
        newest_point: AtomicU64::new(0),
        done: AtomicU64::new(0),
        total: AtomicU64::new(0),
        busy: AtomicBool::new(false),
        last: Mutex::new(None),
        kept: Mutex::new(Vec::new()),
        bounds: Mutex::new(None),
        point_png: Mutex::new(None),
        exports: Mutex::new(None),
        scratch,
    });
    let router = Router::new()
        .route("/", get(page))
        .route("/page.js", get(script))
        .route("/page.css", get(style))
        .route("/api/base", get(base))
        .route("/api/progress", get(progress))
        .route("/api/map", post(map))
        .route("/api/point", post(point))
        .route("/api/boundaries", post(boundaries))
        .route("/api/point.png", get(point_png))
        .route("/api/export/{what}", get(export))
        .with_state(app);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    rt.block_on(async move {
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .with_context(|| format!("cannot listen on {}:{}", addr.0, addr.1))?;
        let at = listener.local_addr()?;
        // The gate first (refused requests' bodies are not read), then the body within its time.
        let router = router.layer(axum::middleware::from_fn(whole_body)).layer(
            axum::middleware::from_fn_with_state(Gate::new(at, allowed), gate),
        );
        if !at.ip().is_loopback() {
            eprintln!(
                "warning: rattle explore listens on {}: anyone who can reach that address can \
                 start computations on this machine",
                at.ip()
            );
        }
        println!("rattle explore: http://{at}/ (Ctrl-C stops it)");
        use std::io::Write;
        std::io::stdout().flush()?;
        accept(listener, router).await
    })
}

/// Connections served at once; more wait in the kernel's queue until one ends.
const MAX_CONNECTIONS: usize = 64;
/// Connections one remote address may hold at once, so that a client of another address finds
/// a slot (clients on this machine share the loopback's address: for them the header's and the
/// body's timeouts free the slots).
const MAX_PER_PEER: usize = 48;
/// A request whose body has not arrived whole within this is answered 408 and its connection
/// closed, so that clients that send a header and never the body cannot hold the slots.
const BODY_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);
/// The largest request body read (the page's requests are a few hundred bytes).
const MAX_BODY: usize = 1 << 20;

/// Counts a new connection of `peer` in `held` unless a remote peer holds [`MAX_PER_PEER`]
/// already (clients on this machine share the loopback's address: they wait for a slot).
fn admit(
    held: &mut std::collections::HashMap<std::net::IpAddr, usize>,
    peer: std::net::IpAddr,
) -> bool {
    let n = held.entry(peer).or_insert(0);
    if *n >= MAX_PER_PEER && !peer.is_loopback() {
        return false;
    }
    *n += 1;
    true
}

/// Uncounts an ended connection of `peer`.
fn release(held: &mut std::collections::HashMap<std::net::IpAddr, usize>, peer: std::net::IpAddr) {
    if let Some(n) = held.get_mut(&peer) {
        *n -= 1;
        if *n == 0 {
            held.remove(&peer);
        }
    }
}

/// Reads a request's whole body within [`BODY_TIMEOUT`] (at most [`MAX_BODY`] bytes) before
/// the handlers see it.
async fn whole_body(req: axum::extract::Request, next: axum::middleware::Next) -> Response {
    let (parts, body) = req.into_parts();
    match tokio::time::timeout(BODY_TIMEOUT, axum::body::to_bytes(body, MAX_BODY)).await {
        Ok(Ok(bytes)) => {
            next.run(axum::extract::Request::from_parts(
                parts,
                axum::body::Body::from(bytes),
            ))
            .await
        }
        Ok(Err(_)) => error(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("a request body is at most {MAX_BODY} bytes, sent whole"),
        ),
        Err(_) => {
            let mut r = error(
                StatusCode::REQUEST_TIMEOUT,
                format!(
                    "the request's body did not arrive within {} s",
                    BODY_TIMEOUT.as_secs()
                ),
            );
            // Its unread rest is not waited for: the connection ends with this answer.
            r.headers_mut().insert(
                header::CONNECTION,
                axum::http::HeaderValue::from_static("close"),
            );
            r
        }
    }
}
/// A connection that has not sent a request's whole header within this is closed.
const HEADER_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);

/// Serves each connection accepted on `listener` with `router`, at most [`MAX_CONNECTIONS`] at
/// once and each closed if a request's header is not read within [`HEADER_TIMEOUT`], so that
/// clients that open connections and never finish a request cannot hold every descriptor or
/// every slot (axum's own `serve` has neither bound).
async fn accept(listener: tokio::net::TcpListener, router: Router) -> Result<()> {
    use hyper_util::rt::{TokioIo, TokioTimer};
    let slots = Arc::new(tokio::sync::Semaphore::new(MAX_CONNECTIONS));
    let peers: Arc<Mutex<std::collections::HashMap<std::net::IpAddr, usize>>> = Arc::default();
    loop {
        let slot = slots.clone().acquire_owned().await?;
        let (stream, peer) = match listener.accept().await {
            Ok((stream, at)) => (stream, at.ip()),
            // Out of descriptors, or a connection reset before it was taken: wait, go on.
            Err(_) => {
                tokio::time::sleep(std::time::Duration::from_millis(50)).await;
                continue;
            }
        };
        if !admit(&mut peers.lock().unwrap_or_else(|p| p.into_inner()), peer) {
            // Closed at once: this peer holds its share of the slots already.
            continue;
        }
        let service = hyper_util::service::TowerToHyperService::new(router.clone());
        let peers = peers.clone();
        tokio::spawn(async move {
            let _ = hyper::server::conn::http1::Builder::new()
                .timer(TokioTimer::new())
                .header_read_timeout(HEADER_TIMEOUT)
                .serve_connection(TokioIo::new(stream), service)
                .await;
            release(&mut peers.lock().unwrap_or_else(|p| p.into_inner()), peer);
            drop(slot);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A remote address holds at most MAX_PER_PEER connections, another one is still admitted,
    /// and one ended frees a place; the loopback's clients are not limited (they share it).
    #[test]
    fn a_remote_peer_holds_at_most_its_share() {
        let mut held = std::collections::HashMap::new();
        let remote: std::net::IpAddr = "192.0.2.7".parse().unwrap();
        let other: std::net::IpAddr = "192.0.2.8".parse().unwrap();
        let local: std::net::IpAddr = "127.0.0.1".parse().unwrap();
        for _ in 0..MAX_PER_PEER {
            assert!(admit(&mut held, remote));
        }
        assert!(!admit(&mut held, remote));
        assert!(admit(&mut held, other));
        release(&mut held, remote);
        assert!(admit(&mut held, remote));
        for _ in 0..2 * MAX_PER_PEER {
            assert!(admit(&mut held, local));
        }
        for _ in 0..MAX_PER_PEER {
            release(&mut held, remote);
        }
        assert!(!held.contains_key(&remote));
    }
}
