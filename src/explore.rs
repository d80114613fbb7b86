//! `rattle explore`'s library half: what a view of a map is, how a request for one becomes a
//! checked configuration (the command line's own request path: the same keys, ranges and
//! messages), what the page receives for a computed map, and the command line and TOML that
//! reproduce a view. The HTTP server is the binary's (`src/serve.rs`); nothing here knows of it.

use crate::class::{Class, Shown};
use crate::config::Config;
use crate::map::Fields;
use crate::map::MapOptions;
use crate::request::{Command, Loaded, Request, Source};
use serde::{Deserialize, Serialize};

/// How explore computes a view's map: the whole view in one run (no shards).
pub const EXPLORE: MapOptions = MapOptions {
    one_run: Some("explore computes each view in one run"),
    ..MapOptions::WHOLE
};

/// A view of the map: the ranges of its two axes (the grid stays the configured one) and, for
/// a volume, the value of its z parameter (the plane shown). A key it does not have is
/// refused, not ignored (`x_points` would say the grid changes).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct View {
    pub x_from: f64,
    pub x_to: f64,
    pub y_from: f64,
    pub y_to: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
}

impl View {
    /// The configured map's view (a volume's: its first slice).
    pub fn of(cfg: &Config) -> View {
        View {
            x_from: cfg.map.x_from,
            x_to: cfg.map.x_to,
            y_from: cfg.map.y_from,
            y_to: cfg.map.y_to,
            z: cfg.z_axis().map(|z| z.values()[0]),
        }
    }

    /// The view as `--set` overrides (Rust's shortest representation of each value reads back
    /// to the same f64; in `Debug`'s form, a TOML float always: `Display` writes 1e19 as a
    /// 20-digit integer, which TOML cannot hold).
    pub fn sets(&self) -> Vec<String> {
        vec![
            format!("map.x_from={:?}", self.x_from),
            format!("map.x_to={:?}", self.x_to),
            format!("map.y_from={:?}", self.y_from),
            format!("map.y_to={:?}", self.y_to),
        ]
    }
}

/// Cells per axis of the coarse first picture, at most.
pub const COARSE_POINTS: u32 = 16;

/// The explorer's base: the configuration and overrides it was started with.
#[derive(Clone, Debug)]
pub struct Explorer {
    /// The base request, its configuration file's text as read at the start: every view and
    /// click is of that configuration, whatever becomes of the file meanwhile.
    pub base: Request,
    /// The configuration file named at the start, for the command lines exported.
    pub config_path: Option<std::path::PathBuf>,
    /// The base configuration, checked as `rattle map` checks it.
    pub cfg: Config,
}

impl Explorer {
    /// The explorer of `base`, checked as `rattle map` checks it; with its notes and warnings.
    /// A configuration file is read here, once.
    pub fn new(mut base: Request) -> crate::Result<(Explorer, Loaded)> {
        let config_path = match &base.source {
            Source::File(p) => Some(p.clone()),
            Source::Text(_) => None,
        };
        if let Some(p) = &config_path {
            let text = crate::output::read_input(p).map_err(|source| {
                crate::config::ConfigError::Read {
                    path: p.display().to_string(),
                    source,
                }
            })?;
            base.source = Source::Text(text);
        }
        let loaded = base.load(Command::Map)?;
        // A volume is shown one plane at a time: each checked as `rattle map` at that z.
        EXPLORE.check(&loaded.cfg.slice(0))?;
        let cfg = loaded.cfg.clone();
        let e = Explorer {
            base,
            config_path,
            cfg,
        };
        Ok((e, loaded))
    }

    /// The request of `view`: the base's, with the view's ranges (and `more`) set last, in
    /// place of the base's overrides of the same keys (`rattle explore --set map.x_from=..`
    /// gives the first view's range, which a zoom then replaces).
    fn request(&self, view: &View, more: &[String]) -> Request {
        use crate::request::full_key;
        let mut r = self.base.clone();
        let last: Vec<String> = view
            .sets()
            .into_iter()
            .chain(more.iter().cloned())
            .collect();
        let replaced: Vec<String> = last.iter().map(|s| full_key(s)).collect();
        r.sets.retain(|s| !replaced.contains(&full_key(s)));
        r.sets.extend(last);
        r
    }

    /// The map configuration of `view`, checked as `rattle map` checks its own (ranges, the
    /// grid's memory): a bad view gets the command line's message. Of a volume, the plane at
    /// the view's z (its first slice where the view has none), as `rattle map` computes it
    /// with that value set.
    pub fn map_config(&self, view: &View) -> crate::Result<Config> {
        let cfg = self.request(view, &[]).load(Command::Map)?.cfg;
        let cfg = self.plane(cfg, view)?;
        EXPLORE.check(&cfg)?;
        Ok(cfg)
    }

    /// `cfg`'s plane at `view`'s z where the base is a volume (a z outside the volume's range
    /// refused, naming it and the range); `cfg` itself otherwise.
    fn plane(&self, cfg: Config, view: &View) -> crate::Result<Config> {
        let Some(z) = self.cfg.z_axis() else {
            return Ok(cfg);
        };
        let v = view.z.unwrap_or(z.values()[0]);
        let (lo, hi) = (z.from.min(z.to), z.from.max(z.to));
        if !(lo..=hi).contains(&v) {
            return Err(crate::error::OptionError::Unsuitable {
                option: "view z",
                why: format!(
                    "{} = {v:?} lies outside the volume's map.z_from .. map.z_to, [{lo}, {hi}]",
                    z.param
                ),
            }
            .into());
        }
        Ok(cfg.plane_at(v))
    }

    /// The view of `cfg` (a view's map configuration: [`Explorer::map_config`]), with its z
    /// where the base is a volume.
    pub fn view_of(&self, cfg: &Config) -> View {
        let mut v = View::of(cfg);
        v.z = self.cfg.z_axis().map(|z| z.param.get(&cfg.model.given()));
        v
    }

    /// The point at (`x`, `y`) of `view`'s axes (at its z, in a volume), as `rattle point`
    /// reads it.
    pub fn point_config(&self, view: &View, (x, y): (f64, f64)) -> crate::Result<Config> {
        let (px, py) = (self.cfg.map.x, self.cfg.map.y);
        let sets = [
            format!("model.{}={x:?}", px.name()),
            format!("model.{}={y:?}", py.name()),
        ];
        let cfg = self.request(view, &sets).load(Command::Point)?.cfg;
        self.plane(cfg, view)
    }

    /// The shell commands that compute `view` as `rattle map` does, its files at `out`
    /// ([`command_for`]): they carry the served configuration itself, so that they reproduce
    /// the view whatever becomes of the file the server was started with.
    pub fn command_line(&self, view: &View, out: &str) -> crate::Result<String> {
        Ok(command_for(&self.map_config(view)?, out))
    }
}

/// Shell commands that write `cfg` as `OUT.toml` (a here-document) and run `rattle map` on it,
/// its files at `out`: the configuration a map was computed with, carried whole (a command
/// naming the server's config file computed another map once the file was edited).
pub fn command_for(cfg: &Config, out: &str) -> String {
    let toml = toml::to_string(cfg).unwrap_or_default();
    let mut end = "RATTLE_CONFIG".to_string();
    while toml.lines().any(|l| l == end) {
        end.push('_');
    }
    let path = format!("{out}.toml");
    format!(
        "cat > {p} <<'{end}'\n{toml}{nl}{end}\nrattle map --config {p} --out {o}\n",
        p = shell_word(&path),
        o = shell_word(out),
        nl = if toml.ends_with('\n') { "" } else { "\n" },
    )
}

/// `a` as one word of a POSIX shell.
fn shell_word(a: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c);
    if !a.is_empty() && a.chars().all(plain) {
        a.to_string()
    } else {
        format!("'{}'", a.replace('\'', r"'\''"))
    }
}

/// The coarse first picture's configuration: `cfg` with at most [`COARSE_POINTS`] cells per
/// axis over the same ranges, and without the long look (a preview: the configured grid's map
/// that replaces it looks as the configuration says; with the look, the default map's preview
/// took 2 x as long, docs/explore.md).
pub fn coarse(cfg: &Config) -> Config {
    let mut c = cfg.clone();
    c.map.x_points = c.map.x_points.min(COARSE_POINTS);
    c.map.y_points = c.map.y_points.min(COARSE_POINTS);
    c.run.look = 0;
    c
}

/// What the page draws of a computed map: its axes, the class layer as `rattle map`'s NPY
/// holds it (`class`, row 0 at `y_from`), each cell's legend entry (`shown`), the legend
/// (label, colour, cells) in the PNG's order, and the scalar layers the page can show.
#[derive(Clone, Debug, Serialize)]
pub struct MapView {
    pub view: View,
    pub x_param: String,
    pub y_param: String,
    pub nx: u32,
    pub ny: u32,
    /// The coarse first picture (not the configured grid).
    pub coarse: bool,
    pub class: Vec<i32>,
    pub period: Vec<i32>,
    /// The period of a stable cycle carried from a neighbour that coexists with the cell's own
    /// attractor (0: none; the map's `coexist` layer).
    pub coexist: Vec<i32>,
    pub shown: Vec<u16>,
    pub legend: Vec<LegendEntry>,
    /// Scalar layers by name (null: no value): the exponent, the multiplier, the settle time,
    /// and the risk where `map.risk` is set.
    pub layers: Vec<(String, Vec<Option<f64>>)>,
}

#[derive(Clone, Debug, Serialize)]
pub struct LegendEntry {
    pub label: String,
    pub rgb: [u8; 3],
    pub cells: usize,
}

/// The page's map of `fields` computed for `cfg`.
pub fn map_view(cfg: &Config, fields: &Fields, coarse: bool) -> MapView {
    let kinds: Vec<Shown> = fields
        .class
        .iter()
        .zip(&fields.attractors)
        .map(|(&c, &a)| Shown::of(Class::from_code(c), a))
        .collect();
    let order = Shown::all();
    let present: Vec<Shown> = order
        .iter()
        .copied()
        .filter(|s| kinds.contains(s))
        .collect();
    let index = |s: Shown| present.iter().position(|&p| p == s).unwrap_or(0) as u16;
    let legend = present
        .iter()
        .map(|&s| LegendEntry {
            label: s.label(),
            rgb: s.rgb(crate::render::period_color),
            cells: kinds.iter().filter(|&&k| k == s).count(),
        })
        .collect();
    let as_f64 = |v: &[u32]| v.iter().map(|&x| Some(f64::from(x))).collect();
    MapView {
        view: View::of(cfg),
        x_param: cfg.map.x.name().to_string(),
        y_param: cfg.map.y.name().to_string(),
        nx: cfg.map.x_points,
        ny: cfg.map.y_points,
        coarse,
        class: fields.class.clone(),
        period: fields.period.clone(),
        coexist: fields.coexist.clone(),
        shown: kinds.into_iter().map(index).collect(),
        legend,
        layers: {
            let mut l = vec![
                ("lyapunov".into(), fields.lyapunov.clone()),
                ("multiplier".into(), fields.multiplier.clone()),
                ("settle".into(), as_f64(&fields.settle)),
            ];
            // The risk map where `map.risk` asks for it (the `-risk.npy` layer).
            if let Some(r) = crate::map::risk_layer(cfg, fields) {
                l.push(("risk".into(), r.into_iter().map(Some).collect()));
            }
            l
        },
    }
}
