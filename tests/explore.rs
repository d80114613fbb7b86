//! `rattle explore`'s library half without a browser (the page is tested in one:
//! python/tests/test_explore.py): a view is checked by the command line's own request path,
//! the command line it exports computes that very view, and the page's map carries
//! `rattle map`'s class layer with a legend that counts every cell.

use rattle::config::Command;
use rattle::explore::{Explorer, View, coarse, map_view};
use rattle::request::{Request, Source};

mod common;

/// Configurations compared by their JSON (every key).
fn same(a: &rattle::config::Config, b: &rattle::config::Config) -> bool {
    serde_json::to_value(a).unwrap() == serde_json::to_value(b).unwrap()
}

fn explorer(sets: &[&str]) -> Explorer {
    let root = env!("CARGO_MANIFEST_DIR");
    let r = Request::new(
        Source::File(format!("{root}/configs/r_lambda.toml").into()),
        sets.iter().map(|s| s.to_string()).collect(),
    );
    Explorer::new(r).unwrap().0
}

#[test]
fn a_view_is_checked_as_the_command_line_checks_it() {
    let e = explorer(&["method.backend=cpu"]);
    let home = View::of(&e.cfg);
    assert!(same(&e.map_config(&home).unwrap(), &e.cfg));
    // The same message as `rattle map --set map.x_from=1.5` (R lies in [0, 1]).
    let bad = View {
        x_from: 1.5,
        ..home
    };
    let said = e.map_config(&bad).unwrap_err().to_string();
    let mut r = e.base.clone();
    r.sets.push("map.x_from=1.5".into());
    let cli = r.load(Command::Map).unwrap_err().to_string();
    assert_eq!(said, cli);
    assert!(
        said.contains("`map.x_from` = 1.5") && said.contains("[0, 1]"),
        "{said}"
    );
    // A point outside its parameter's range too.
    let p = e.point_config(&home, (-0.1, 0.05)).unwrap_err().to_string();
    assert!(p.contains("`model.R` = -0.1"), "{p}");
    // A point's parameters are the clicked ones.
    let c = e.point_config(&home, (0.6125, 0.0375)).unwrap();
    assert_eq!((c.model.restitution, c.model.lambda), (0.6125, 0.0375));
}

#[test]
fn the_exported_command_line_computes_that_view() {
    let e = explorer(&["method.backend=cpu", "run.look=400"]);
    let v = View {
        x_from: 0.55,
        x_to: 0.6125,
        y_from: 0.01,
        y_to: 0.0375,
        z: None,
    };
    let line = e.command_line(&v, "out dir/view").unwrap();
    // The served configuration itself, in a here-document, then the map on it.
    assert!(
        line.starts_with("cat > 'out dir/view.toml' <<'RATTLE_CONFIG'\n"),
        "{line}"
    );
    assert!(
        line.ends_with(
            "RATTLE_CONFIG\nrattle map --config 'out dir/view.toml' --out 'out dir/view'\n"
        ),
        "{line}"
    );
    assert!(same(&carried(&line), &e.map_config(&v).unwrap()));
}

/// The configuration an exported command carries (its here-document), as `rattle map` reads it.
fn carried(line: &str) -> rattle::config::Config {
    let body = line.split_once('\n').unwrap().1;
    let toml = body.split("\nRATTLE_CONFIG\n").next().unwrap();
    rattle::config::Config::from_toml(toml, &[]).unwrap()
}

#[test]
fn the_pages_map_is_the_maps_class_layer_with_every_cell_in_its_legend() {
    let e = explorer(&["method.backend=cpu", "map.x_points=12", "map.y_points=9"]);
    let cfg = coarse(&e.cfg);
    assert_eq!((cfg.map.x_points, cfg.map.y_points), (12, 9));
    let engine = rattle::engine::Engine::Cpu;
    let o = rattle::map::MapOptions::default();
    let m = rattle::map::compute_map(&engine, &cfg, &o, &rattle::progress::Silent).unwrap();
    let page = map_view(&m.cfg, &m.fields, false);
    assert_eq!(page.class, m.fields.class);
    assert_eq!(page.shown.len(), 12 * 9);
    assert_eq!(page.legend.iter().map(|l| l.cells).sum::<usize>(), 12 * 9);
    for (i, &s) in page.shown.iter().enumerate() {
        let label = &page.legend[s as usize].label;
        let class = rattle::class::Class::from_code(page.class[i]);
        let want = rattle::class::Shown::of(class, m.fields.attractors[i]).label();
        assert_eq!(label, &want, "cell {i}");
    }
    assert_eq!(
        page.layers.iter().map(|l| l.0.as_str()).collect::<Vec<_>>(),
        ["lyapunov", "multiplier", "settle"]
    );
    // With `map.risk`, the risk layer too: the values of the map's `-risk.npy`.
    let mut risky = m.cfg.clone();
    risky.map.risk = vec![0.02, 0.005];
    let page = map_view(&risky, &m.fields, false);
    let (name, risk) = page.layers.last().unwrap();
    assert_eq!(name, "risk");
    let npy = rattle::map::npy_layers(&risky, &m.fields);
    let bytes = &npy.iter().find(|l| l.0 == "risk").unwrap().1;
    let file: Vec<f64> = npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap();
    let page_risk: Vec<f64> = risk.iter().map(|v| v.unwrap()).collect();
    assert_eq!(page_risk, file);
    assert!(file.iter().any(|&r| r > 0.0) && file.iter().all(|&r| (0.0..=1.0).contains(&r)));
    // The coarse picture of the default grid has at most 16 cells a side, and no long look.
    let c = coarse(&explorer(&[]).cfg);
    assert_eq!((c.map.x_points, c.map.y_points, c.run.look), (16, 16, 0));
}

/// The server's scratch directory is its own (round 7 H1): made at the start inside TMPDIR
/// with a name no other user can guess (not the process id) and mode 0700, so that no one can
/// make it first and plant links that a click or an export would write through; removed when
/// an interrupt ends the server. (It was `$TMPDIR/rattle-explore-PID`, made on first use with
/// the default mode, any existing one taken over.)
/// `rattle explore --set map.x_from=..` (and the other ranges) gives the first view; a view
/// or a click replaces those ranges instead of being refused (round 7 M3: every view and click
/// was refused, "both set `map.x_from`"), and the exported command line carries the view's
/// ranges once.
/// A volume is explored one plane at a time: a view's z names the plane, whose configuration is
/// the slice `rattle map` computes at that z (any z of the volume's range; outside it refused
/// with the range), its points are at that z, and the exported command carries that plane.
#[test]
fn a_volume_is_explored_one_plane_at_a_time() {
    let root = env!("CARGO_MANIFEST_DIR");
    let r = Request::new(
        Source::File(format!("{root}/configs/atlas.toml").into()),
        vec!["method.backend=cpu".into()],
    );
    let e = Explorer::new(r).unwrap().0;
    let zs = e.cfg.z_axis().unwrap().values();
    let home = View::of(&e.cfg);
    assert_eq!(home.z, Some(zs[0]));
    let v = View {
        z: Some(zs[5]),
        ..home
    };
    let cfg = e.map_config(&v).unwrap();
    assert!(cfg.z_axis().is_none());
    assert_eq!(cfg.model.eta, zs[5]);
    assert!(same(&cfg, &e.cfg.slice(5)));
    assert_eq!(e.view_of(&cfg), v);
    assert!(same(&carried(&e.command_line(&v, "out").unwrap()), &cfg));
    let between = View {
        z: Some(1.5),
        ..home
    };
    assert_eq!(e.map_config(&between).unwrap().model.eta, 1.5);
    let outside = e
        .map_config(&View {
            z: Some(2.5),
            ..home
        })
        .unwrap_err()
        .to_string();
    assert!(
        outside.contains("eta = 2.5") && outside.contains("[1, 2]"),
        "{outside}"
    );
    let p = e.point_config(&v, (0.6, 0.02)).unwrap();
    assert_eq!(
        (p.model.restitution, p.model.lambda, p.model.eta),
        (0.6, 0.02, zs[5])
    );
}

#[test]
fn a_base_with_ranges_set_takes_the_views_ranges() {
    let e = explorer(&["map.x_from=0.55", "map.y_to=0.05"]);
    assert_eq!((e.cfg.map.x_from, e.cfg.map.y_to), (0.55, 0.05));
    let v = View {
        x_from: 0.6,
        x_to: 0.65,
        y_from: 0.01,
        y_to: 0.02,
        z: None,
    };
    let cfg = e.map_config(&v).unwrap();
    assert_eq!(View::of(&cfg), v);
    let p = e.point_config(&v, (0.61, 0.015)).unwrap();
    assert_eq!((p.model.restitution, p.model.lambda), (0.61, 0.015));
    let line = e.command_line(&v, "view").unwrap();
    assert_eq!(line.matches("x_from = ").count(), 1, "{line}");
    assert_eq!(View::of(&carried(&line)), v, "{line}");
}

/// The configuration file is read once, at the start (round 7 M4: every request read it
/// again, so an edit while serving changed the maps, even their axis, and a deleted file failed
/// every request): after the file is rewritten with another axis and then deleted, a view is
/// still of the configuration read at the start, and the exported command carries that
/// configuration.
#[test]
fn the_configuration_is_read_once() {
    let d = common::scratch("explore-once");
    let path = d.join("map.toml");
    let shipped = std::fs::read_to_string(common::config("r_lambda.toml")).unwrap();
    std::fs::write(&path, &shipped).unwrap();
    let r = Request::new(Source::File(path.clone()), Vec::new());
    let e = Explorer::new(r).unwrap().0;
    std::fs::write(&path, shipped.replace("x = \"R\"", "x = \"delta\"")).unwrap();
    let v = View::of(&e.cfg);
    assert_eq!(e.map_config(&v).unwrap().map.x.name(), "R");
    std::fs::remove_file(&path).unwrap();
    let cfg = e.map_config(&v).unwrap();
    assert!(same(&cfg, &e.cfg));
    assert!(e.point_config(&v, (0.6, 0.05)).is_ok());
    // The exported command carries the configuration read at the start (round 8 L4: it named
    // the file, so after the edit it computed another map).
    let line = e.command_line(&v, "view").unwrap();
    assert!(!line.contains(&path.display().to_string()), "{line}");
    assert!(same(&carried(&line), &e.cfg), "{line}");
}

/// A small map's server started with TMPDIR `tmp` on any free port: the process and its port.
#[cfg(unix)]
fn start_server(tmp: &std::path::Path) -> (std::process::Child, u16) {
    let (mut p, line) = spawn_server(tmp, &[]);
    let port = line
        .split("http://127.0.0.1:")
        .nth(1)
        .and_then(|r| r.split('/').next())
        .and_then(|n| n.parse().ok());
    match port {
        Some(port) => (p, port),
        None => {
            interrupt(&mut p);
            panic!("no address printed: {line:?}");
        }
    }
}

/// The server of a small map with TMPDIR `tmp`, any free port and the options `extra`: the
/// process (its stderr piped) and the first line it printed.
#[cfg(unix)]
fn spawn_server(tmp: &std::path::Path, extra: &[&str]) -> (std::process::Child, String) {
    spawn_with(common::rattle(), tmp, extra)
}

/// [`spawn_server`], the server started by `launcher` (the binary, or a shell that starts it).
#[cfg(unix)]
fn spawn_with(
    mut launcher: std::process::Command,
    tmp: &std::path::Path,
    extra: &[&str],
) -> (std::process::Child, String) {
    use std::io::BufRead;
    let cfg = tmp.join("map.toml");
    std::fs::write(
        &cfg,
        "[model]\neta = 1.26\n[method]\nsteps_per_period = 64\n[run]\ntransient_periods = 4\n\
         sample_periods = 8\n[map]\nx = \"R\"\nx_from = 0.5\nx_to = 0.7\nx_points = 8\n\
         y = \"lambda\"\ny_from = 0.0\ny_to = 0.1\ny_points = 8\n",
    )
    .unwrap();
    let mut p = launcher
        .args(["explore", "--backend", "cpu", "--port", "0", "--config"])
        .arg(&cfg)
        .args(extra)
        .env("TMPDIR", tmp)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(p.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    (p, line)
}

/// One request (`head`: its request line and headers, without the last line break) to the
/// server at `port` on a connection of its own: the reply's status code and its whole text.
#[cfg(unix)]
fn ask(port: u16, head: &str, body: &str) -> (u16, String) {
    let (code, bytes) = ask_bytes(port, head, body);
    (code, String::from_utf8_lossy(&bytes).into_owned())
}

/// [`ask`], the reply as bytes.
#[cfg(unix)]
fn ask_bytes(port: u16, head: &str, body: &str) -> (u16, Vec<u8>) {
    use std::io::{Read, Write};
    let mut c = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    let req = format!(
        "{head}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    c.write_all(req.as_bytes()).unwrap();
    let mut out = Vec::new();
    c.read_to_end(&mut out).unwrap();
    let code = String::from_utf8_lossy(&out[..out.len().min(16)])
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (code, out)
}

/// The body of a reply's bytes (after the header).
#[cfg(unix)]
fn body(reply: &[u8]) -> &[u8] {
    let at = reply.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    &reply[at + 4..]
}

/// The port in the first line a server printed.
#[cfg(unix)]
fn port_of(line: &str) -> u16 {
    line.split("http://")
        .nth(1)
        .and_then(|r| r.rsplit_once(':'))
        .map(|(_, r)| r)
        .and_then(|r| r.split('/').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no address printed: {line:?}"))
}

/// A JSON POST's head to the server at `port`.
#[cfg(unix)]
fn post(port: u16, path: &str) -> String {
    format!("POST {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json")
}

/// The small map's whole view (spawn_server's config).
#[cfg(unix)]
const HOME: &str = "{\"x_from\": 0.5, \"x_to\": 0.7, \"y_from\": 0.0, \"y_to\": 0.1}";

/// The small map's whole view computed at its grid by the server at `port`.
#[cfg(unix)]
fn home_map(port: u16) -> (u16, String) {
    let body = format!("{{\"view\": {HOME}}}");
    ask(port, &post(port, "/api/map"), &body)
}

/// Whether the server at `port` is busy computing.
#[cfg(unix)]
fn busy(port: u16) -> bool {
    let head = format!("GET /api/progress HTTP/1.1\r\nHost: 127.0.0.1:{port}");
    ask(port, &head, "").1.contains("\"busy\":true")
}

/// SIGINT, as Ctrl-C: the server's exit status.
#[cfg(unix)]
fn interrupt(p: &mut std::process::Child) -> std::process::ExitStatus {
    let _ = std::process::Command::new("kill")
        .args(["-INT", &p.id().to_string()])
        .status();
    p.wait().unwrap()
}

/// The server's scratch directory is its own (round 7 H1): made at the start inside TMPDIR
/// with a name no other user can guess (not the process id) and mode 0700, so that no one can
/// make it first and plant links that a click or an export would write through; removed when
/// an interrupt ends the server. (It was `$TMPDIR/rattle-explore-PID`, made on first use with
/// the default mode, any existing one taken over.)
#[cfg(unix)]
#[test]
fn the_servers_scratch_directory_is_private() {
    use std::os::unix::fs::PermissionsExt;
    let tmp = common::scratch("explore-private");
    let (mut p, _) = start_server(&tmp);
    let dirs: Vec<std::path::PathBuf> = std::fs::read_dir(&*tmp)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|d| d.is_dir())
        .collect();
    let ours = match dirs.as_slice() {
        [d] => d.clone(),
        _ => {
            interrupt(&mut p);
            panic!("one directory of the server's expected in TMPDIR: {dirs:?}");
        }
    };
    let name = ours.file_name().unwrap().to_string_lossy().into_owned();
    let mode = std::fs::metadata(&ours).unwrap().permissions().mode() & 0o777;
    let status = interrupt(&mut p);
    assert!(name.starts_with("rattle-explore-"), "{name}");
    assert!(
        !name.contains(&p.id().to_string()),
        "a predictable name: {name}"
    );
    assert_eq!(mode, 0o700, "{name}: mode {mode:o}");
    assert_eq!(status.code(), Some(130));
    assert!(!ours.exists(), "{name} left after the interrupt");
}

/// Only the server's own page talks to it (round 7 M1): a Host other than the address it
/// listens on (DNS rebinding: a foreign name resolved to the loopback) and an Origin other than
/// its own are refused with 403, a POST whose body is not declared JSON (a `text/plain` POST
/// any page may send without asking) with 415, each with the JSON error shape; the page's own
/// requests are answered. (All four were answered before.)
#[cfg(unix)]
#[test]
fn only_the_servers_own_page_talks_to_it() {
    let tmp = common::scratch("explore-gate");
    let (mut p, port) = start_server(&tmp);
    let ask = |head: &str, body: &str| ask(port, head, body);
    let host = format!("Host: 127.0.0.1:{port}");
    let answers = [
        ask(&format!("GET /api/base HTTP/1.1\r\n{host}"), ""),
        ask(
            &format!("GET /api/base HTTP/1.1\r\nHost: localhost:{port}"),
            "",
        ),
        ask(
            &format!("GET /api/base HTTP/1.1\r\nHost: rebound.example:{port}"),
            "",
        ),
        ask(
            &format!("GET /api/base HTTP/1.1\r\n{host}\r\nOrigin: http://elsewhere.example"),
            "",
        ),
        ask(
            &format!("POST /api/map HTTP/1.1\r\n{host}\r\nContent-Type: text/plain"),
            "{}",
        ),
        ask(
            &format!(
                "POST /api/map HTTP/1.1\r\n{host}\r\nOrigin: http://127.0.0.1:{port}\r\n\
                 Content-Type: application/json"
            ),
            "{\"view\": 1}",
        ),
        // Media types are case-insensitive (RFC 9110, 8.3.1; round 8 L3: this was 415).
        ask(
            &format!("POST /api/map HTTP/1.1\r\n{host}\r\nContent-Type: Application/JSON"),
            "{\"view\": 1}",
        ),
    ];
    interrupt(&mut p);
    let codes: Vec<u16> = answers.iter().map(|a| a.0).collect();
    assert_eq!(codes, [200, 200, 403, 403, 415, 400, 400], "{answers:#?}");
    for (_, text) in &answers[2..5] {
        assert!(text.contains("\"error\""), "{text}");
    }
}

/// Listening beyond the loopback says so on stderr (round 7 L7: `--host 0.0.0.0` started
/// without a word): anyone who reaches the address can start computations.
#[cfg(unix)]
#[test]
fn listening_beyond_the_loopback_warns() {
    use std::io::Read;
    let tmp = common::scratch("explore-host");
    let (mut p, line) = spawn_server(&tmp, &["--host", "0.0.0.0"]);
    let status = interrupt(&mut p);
    let mut err = String::new();
    p.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert!(line.contains("http://0.0.0.0:"), "{line:?}");
    assert_eq!(status.code(), Some(130));
    assert!(
        err.contains("warning: rattle explore listens on 0.0.0.0"),
        "{err:?}"
    );
}

/// A negative port is read as the port's value and refused by it, exit code 2 (round 7 L8: it
/// was "unexpected argument '-1'"), as every option's negative value.
#[test]
fn a_negative_port_is_refused_by_its_option() {
    let out = common::rattle()
        .args(["explore", "--port", "-1", "--config"])
        .arg(common::config("r_lambda.toml"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--port") && err.contains("0..=65535"), "{err}");
}

/// Coordinates of 1e19 and more (valid for lambda) make a view and a point as any other (round
/// 7 L3: written back as 20-digit integers, TOML refused them: "invalid type: string").
#[test]
fn very_large_coordinates_are_values() {
    let e = explorer(&[]);
    let v = View {
        x_from: 0.5,
        x_to: 0.7,
        y_from: 0.0,
        y_to: 1e19,
        z: None,
    };
    assert_eq!(e.map_config(&v).unwrap().map.y_to, 1e19);
    let p = e.point_config(&v, (0.6, 2.5e19)).unwrap();
    assert_eq!(p.model.lambda, 2.5e19);
}

/// Waits up to `secs` seconds for `what` to hold; whether it did.
#[cfg(unix)]
fn within(secs: u64, what: impl Fn() -> bool) -> bool {
    let t = std::time::Instant::now();
    while t.elapsed().as_secs() < secs {
        if what() {
            return true;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    what()
}

/// A newer click stops the point running, and a click whose client goes away stops its own
/// (round 7 L6: neither did; with a large `run.look` the next click waited 103 s). The point
/// (eta 1.72, Fig. 2's R and lambda: chaotic) with a look of 10^7 periods runs 25 s alone.
#[cfg(unix)]
#[test]
fn a_newer_click_or_a_client_leaving_stops_the_point() {
    use std::io::Write;
    let tmp = common::scratch("explore-clicks");
    let sets = [
        "--set",
        "model.eta=1.72",
        "--set",
        "run.look=10000000",
        "--set",
        "run.transient_periods=500",
        "--set",
        "run.sample_periods=200",
    ];
    let (mut p, line) = spawn_server(&tmp, &sets);
    let port = port_of(&line);
    let click = format!("{{\"view\": {HOME}, \"x\": 0.6, \"y\": 0.02}}");
    let first = {
        let click = click.clone();
        std::thread::spawn(move || ask(port, &post(port, "/api/point"), &click))
    };
    let started = within(30, || busy(port));
    // The second click, on a connection this test closes later.
    let mut second = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    let req = format!(
        "{}\r\nContent-Length: {}\r\n\r\n{click}",
        post(port, "/api/point"),
        click.len()
    );
    second.write_all(req.as_bytes()).unwrap();
    let t = std::time::Instant::now();
    let (code, text) = first.join().unwrap();
    let gave_way = t.elapsed().as_secs_f64();
    let second_runs = within(30, || busy(port));
    drop(second);
    let stopped = within(10, || !busy(port));
    interrupt(&mut p);
    assert!(started, "the first point never ran");
    assert_eq!(code, 409, "{text}");
    assert!(text.contains("newer point"), "{text}");
    assert!(
        gave_way < 10.0,
        "the first point gave way after {gave_way:.1} s"
    );
    assert!(second_runs, "the second point never ran");
    assert!(stopped, "the second point ran on after its client left");
}

/// A click whose motion fails gets `rattle point`'s report (`failed`) with no figure and the
/// figure's reason (round 7 L2: a 400 "nothing to plot" and no report).
#[cfg(unix)]
#[test]
fn a_failed_point_gets_its_report() {
    let tmp = common::scratch("explore-failed-point");
    let (mut p, line) = spawn_server(&tmp, &["--set", "model.b1=1e30"]);
    let port = port_of(&line);
    let click = format!("{{\"view\": {HOME}, \"x\": 0.6, \"y\": 0.02}}");
    let (code, text) = ask(port, &post(port, "/api/point"), &click);
    interrupt(&mut p);
    assert_eq!(code, 200, "{text}");
    let v: serde_json::Value = serde_json::from_slice(body(text.as_bytes())).unwrap();
    assert_eq!(v["report"]["class"], "failed", "{v}");
    assert_eq!(v["figure"], false, "{v}");
    let why = v["figure_error"].as_str().unwrap_or("");
    assert!(why.contains("nothing to plot"), "{v}");
}

/// An export writes the map's set once and answers every later ask of that map from memory
/// (round 7 M7: each export rewrote the whole set, 31 files, under the computation's lock, so
/// abandoned exports delayed the next view). Here the scratch directory is replaced by a file
/// after the first export: later exports, of that file and of others, are still answered, the
/// same bytes.
#[cfg(unix)]
#[test]
fn an_export_writes_the_set_once() {
    let tmp = common::scratch("explore-exports");
    let (mut p, port) = start_server(&tmp);
    let (code, text) = home_map(port);
    let get = |what: &str| {
        let head = format!("GET /api/export/{what} HTTP/1.1\r\nHost: 127.0.0.1:{port}");
        ask_bytes(port, &head, "")
    };
    let png = get("png");
    let scratch: Vec<std::path::PathBuf> = std::fs::read_dir(&*tmp)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|d| d.is_dir())
        .collect();
    for d in &scratch {
        std::fs::remove_dir_all(d).unwrap();
        std::fs::write(d, "not a directory").unwrap();
    }
    let again = get("png");
    let npy = get("lyapunov.npy");
    let json = get("json");
    interrupt(&mut p);
    assert_eq!(code, 200, "{text}");
    assert_eq!(scratch.len(), 1, "{scratch:?}");
    assert_eq!(png.0, 200);
    assert!(body(&png.1).starts_with(b"\x89PNG"));
    assert_eq!(again.0, 200, "{}", String::from_utf8_lossy(&again.1));
    assert_eq!(body(&again.1), body(&png.1));
    assert_eq!(npy.0, 200, "{}", String::from_utf8_lossy(&npy.1));
    assert!(body(&npy.1).starts_with(b"\x93NUMPY"));
    assert_eq!(json.0, 200, "{}", String::from_utf8_lossy(&json.1));
}

/// Clients that open connections and never finish a request no longer starve everyone (round 7
/// L5: 150 of them, at `ulimit -n 128`, made the server answer no one): at most 64 connections
/// are served at once and one whose request header is not read within 5 s is closed, so a
/// request made after 150 stalled ones is answered, and the stalled ones are closed.
#[cfg(unix)]
#[test]
fn stalled_connections_do_not_starve_the_server() {
    use std::io::{Read, Write};
    let tmp = common::scratch("explore-stalled");
    let mut sh = std::process::Command::new("sh");
    sh.args(["-c", "ulimit -n 128 && exec \"$0\" \"$@\""])
        .arg(common::rattle().get_program());
    let (mut p, line) = spawn_with(sh, &tmp, &[]);
    let port = port_of(&line);
    let stalled: Vec<std::net::TcpStream> = (0..150)
        .map(|_| {
            let mut c = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
            c.write_all(b"GET /api/base HTTP/1.1\r\n").unwrap();
            c
        })
        .collect();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let head = format!("GET /api/base HTTP/1.1\r\nHost: 127.0.0.1:{port}");
        let _ = tx.send(ask(port, &head, ""));
    });
    let answer = rx.recv_timeout(std::time::Duration::from_secs(60));
    let closed = stalled
        .into_iter()
        .take(64)
        .filter(|c| {
            let mut c = c;
            c.set_read_timeout(Some(std::time::Duration::from_secs(1)))
                .unwrap();
            let mut b = [0u8; 64];
            matches!(c.read(&mut b), Ok(0) | Err(_)) || b.starts_with(b"HTTP/1.1 408")
        })
        .count();
    interrupt(&mut p);
    let (code, text) = answer.expect("no answer within 60 s of 150 stalled connections");
    assert_eq!(code, 200, "{text}");
    assert_eq!(
        closed, 64,
        "the first 64 stalled connections are closed by the server"
    );
}

/// An interrupt while an export is being written leaves nothing of the server's on disk
/// (round 7 L1: the scratch directory stayed in 5 of 7 tries).
#[cfg(unix)]
#[test]
fn an_interrupt_during_an_export_leaves_nothing() {
    use std::io::Write;
    let tmp = common::scratch("explore-export-interrupt");
    let (mut p, port) = start_server(&tmp);
    let (code, text) = home_map(port);
    let mut c = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    let head = format!("GET /api/export/json HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n");
    c.write_all(head.as_bytes()).unwrap();
    std::thread::sleep(std::time::Duration::from_millis(20));
    let status = interrupt(&mut p);
    let left: Vec<String> = std::fs::read_dir(&*tmp)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "map.toml")
        .collect();
    assert_eq!(code, 200, "{text}");
    assert_eq!(status.code(), Some(130));
    assert!(left.is_empty(), "left in TMPDIR: {left:?}");
}

/// Clients that send a whole header and never the body no longer hold every slot (round 8 M1:
/// 64 of them with `Content-Length: 100000`, `/api/base` unanswered in 120 s): a body that has
/// not arrived within 5 s is answered 408 and its connection closed, so a request made after
/// 64 such clients is answered.
#[cfg(unix)]
#[test]
fn unfinished_bodies_do_not_stall_the_server() {
    use std::io::{Read, Write};
    let tmp = common::scratch("explore-bodies");
    let (mut p, port) = start_server(&tmp);
    let stalled: Vec<std::net::TcpStream> = (0..64)
        .map(|_| {
            let mut c = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
            let head = format!(
                "POST /api/map HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\
                 Content-Type: application/json\r\nContent-Length: 100000\r\n\r\n{{"
            );
            c.write_all(head.as_bytes()).unwrap();
            c
        })
        .collect();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let head = format!("GET /api/base HTTP/1.1\r\nHost: 127.0.0.1:{port}");
        let _ = tx.send(ask(port, &head, ""));
    });
    let answer = rx.recv_timeout(std::time::Duration::from_secs(30));
    let timed_out = stalled
        .into_iter()
        .filter(|c| {
            let mut c = c;
            c.set_read_timeout(Some(std::time::Duration::from_secs(10)))
                .unwrap();
            let mut b = [0u8; 64];
            matches!(c.read(&mut b), Ok(n) if b[..n].starts_with(b"HTTP/1.1 408"))
        })
        .count();
    interrupt(&mut p);
    let (code, text) = answer.expect("no answer within 30 s of 64 unfinished bodies");
    assert_eq!(code, 200, "{text}");
    assert_eq!(timed_out, 64, "every unfinished body is answered 408");
}

/// Listening on every address, the server answered any Host (round 8 L1: a DNS-rebound name,
/// `rebind.attacker.example:PORT`, got 200 with the map): only IP literals and `localhost` with
/// the port, and names given with `--allow-host`, are answered.
#[cfg(unix)]
#[test]
fn listening_everywhere_answers_ip_literals_and_allowed_names_only() {
    let tmp = common::scratch("explore-rebind");
    let (mut p, line) = spawn_server(&tmp, &["--host", "0.0.0.0", "--allow-host", "lab-pc.local"]);
    let port = port_of(&line);
    let code = |host: &str| ask(port, &format!("GET /api/base HTTP/1.1\r\nHost: {host}"), "").0;
    let codes = [
        code(&format!("rebind.attacker.example:{port}")),
        code(&format!("127.0.0.1:{port}")),
        code(&format!("[::1]:{port}")),
        code(&format!("localhost:{port}")),
        code(&format!("LAB-PC.local:{port}")),
        code("127.0.0.1:1"),
        code("lab-pc.local"),
    ];
    interrupt(&mut p);
    assert_eq!(codes, [403, 200, 200, 200, 200, 403, 403]);
    let out = common::rattle()
        .args(["explore", "--config"])
        .arg(tmp.join("map.toml"))
        .args(["--allow-host", "evil:80"])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
