//! The `[map]` and `[basin]` grids: their sections, validation and resolved ranges.

use super::*;

/// A 2-D map over two parameters.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct MapConfig {
    pub x: Param,
    pub x_from: f64,
    pub x_to: f64,
    pub x_points: u32,
    pub y: Param,
    pub y_from: f64,
    pub y_to: f64,
    pub y_points: u32,
    /// Figure title; empty => generated.
    pub title: String,
    /// Standard deviations (x, y) in parameter units of the risk map (`PREFIX-risk.png` and
    /// `.npy`: the probability that a Gaussian perturbation of the two parameters lands on
    /// another class); empty: no risk map.
    pub risk: Vec<f64>,
    /// The third axis of a volume (an atlas: one map of x and y per z value); unset: a plane.
    /// Unset keys are not written, so that a plane's config (its run identity) is unchanged.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z: Option<Param>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z_from: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z_to: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z_points: Option<u32>,
}

/// Most slices of a volume (`map.z_points`).
pub const MAX_Z_POINTS: u32 = 4096;

/// The z axis of a volume, resolved: (parameter, from, to, points).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZAxis {
    pub param: Param,
    pub from: f64,
    pub to: f64,
    pub points: u32,
}

impl ZAxis {
    /// The z values, at the grid's cell centres as the other axes' ([`Config::map_axis`]).
    pub fn values(&self) -> Vec<f64> {
        Config::map_axis(self.from, self.to, self.points)
    }
}

impl MapConfig {
    /// The first key of the grid (axes, ranges, points) in which `other` differs, or None:
    /// the title and the risk map's sigmas are not the grid.
    pub fn grid_difference(&self, other: &MapConfig) -> Option<&'static str> {
        [
            ("x", self.x == other.x),
            ("x_from", self.x_from == other.x_from),
            ("x_to", self.x_to == other.x_to),
            ("x_points", self.x_points == other.x_points),
            ("y", self.y == other.y),
            ("y_from", self.y_from == other.y_from),
            ("y_to", self.y_to == other.y_to),
            ("y_points", self.y_points == other.y_points),
            ("z", self.z == other.z),
            ("z_from", self.z_from == other.z_from),
            ("z_to", self.z_to == other.z_to),
            ("z_points", self.z_points == other.z_points),
        ]
        .into_iter()
        .find(|(_, same)| !same)
        .map(|(key, _)| key)
    }
}

impl Default for MapConfig {
    fn default() -> Self {
        MapConfig {
            x: Param::Restitution,
            x_from: 0.5,
            x_to: 0.7,
            x_points: 128,
            y: Param::Lambda,
            y_from: 0.0,
            y_to: 0.1,
            y_points: 128,
            title: String::new(),
            risk: Vec::new(),
            z: None,
            z_from: None,
            z_to: None,
            z_points: None,
        }
    }
}

/// A coordinate of the initial state that a basin grid varies. The others are zero: m1 at
/// rest at y1 = 0, m2 in the middle of the clearance, no relative velocity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StateCoord {
    /// m2's position in the clearance, z = y3 - y1 (within [-r, r]).
    Z0,
    /// Relative (slip) velocity v = y2 - y4.
    V0,
    /// m1's position.
    Y1,
    /// m1's velocity.
    Y2,
}

impl StateCoord {
    pub fn name(self) -> &'static str {
        match self {
            StateCoord::Z0 => "z0",
            StateCoord::V0 => "v0",
            StateCoord::Y1 => "y1",
            StateCoord::Y2 => "y2",
        }
    }

    /// Axis label of plots.
    pub fn label(self) -> &'static str {
        match self {
            StateCoord::Z0 => "z0 = y3 - y1 (initial position of m2 in the clearance)",
            StateCoord::V0 => "v0 = y2 - y4 (initial relative velocity)",
            StateCoord::Y1 => "y1 (initial position of m1)",
            StateCoord::Y2 => "y2 (initial velocity of m1)",
        }
    }

    /// The state (y1, y2, y3, y4) with this coordinate at `a` and `other` at `b`, the rest 0.
    pub fn state(self, a: f64, other: StateCoord, b: f64) -> [f64; 4] {
        let (mut y1, mut y2, mut z, mut v) = (0.0, 0.0, 0.0, 0.0);
        for (c, x) in [(self, a), (other, b)] {
            match c {
                StateCoord::Z0 => z = x,
                StateCoord::V0 => v = x,
                StateCoord::Y1 => y1 = x,
                StateCoord::Y2 => y2 = x,
            }
        }
        [y1, y2, y1 + z, y2 - v]
    }
}

/// A grid of initial states at one parameter point (basins of attraction).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct BasinConfig {
    pub x: StateCoord,
    /// Range of x; unset: [-r, r] for z0, [-1, 1] otherwise (same for y).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub x_from: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub x_to: Option<f64>,
    pub x_points: u32,
    pub y: StateCoord,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub y_from: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub y_to: Option<f64>,
    pub y_points: u32,
    /// Two refined cycles are one attractor when a section point of one lies within
    /// `tol * max(1, |point|)` of a section point of the other, in every coordinate.
    pub tol: f64,
    /// Figure title; empty => generated.
    pub title: String,
}

impl Default for BasinConfig {
    fn default() -> Self {
        BasinConfig {
            x: StateCoord::Z0,
            x_from: None,
            x_to: None,
            x_points: 101,
            y: StateCoord::V0,
            y_from: None,
            y_to: None,
            y_points: 101,
            tol: 1e-6,
            title: String::new(),
        }
    }
}

impl Config {
    /// Checks the `[map]` section (only maps need it: the defaults name lambda, which a
    /// Stribeck bifurcation config does not have).
    pub fn check_map(&self) -> Result<(), ConfigError> {
        self.check_tangent("`map`")?;
        let m = &self.map;
        for (key, name) in [("map.x", m.x), ("map.y", m.y)] {
            if name == Param::Lambda && self.model.friction != FrictionLaw::Coulomb {
                return Err(ConfigError::range(
                    key,
                    "\"lambda\"",
                    "fs, fk, l1 or l2 with friction = \"stribeck\"",
                ));
            }
        }
        if m.x.overlaps(m.y) {
            return Err(ConfigError::range(
                "map.y",
                format!("\"{}\"", m.y),
                &format!("a parameter other than map.x = \"{}\"", m.x),
            ));
        }
        check_grid("map", (m.x_points, m.y_points), 65536, MAX_MAP_CELLS)?;
        self.check_z()?;
        if !(m.risk.is_empty()
            || m.risk.len() == 2 && m.risk.iter().all(|s| s.is_finite() && *s > 0.0))
        {
            return Err(ConfigError::range(
                "map.risk",
                format!("{:?}", m.risk),
                "[] or [sigma_x, sigma_y], both finite and > 0 (in the axes' units)",
            ));
        }
        for (key, name, v) in [
            ("map.x_from", m.x, m.x_from),
            ("map.x_to", m.x, m.x_to),
            ("map.y_from", m.y, m.y_from),
            ("map.y_to", m.y, m.y_to),
        ] {
            self.check_value(key, name, v)?;
        }
        for (key, from, to) in [
            ("map.x_to", m.x_from, m.x_to),
            ("map.y_to", m.y_from, m.y_to),
        ] {
            if from == to {
                let from_key = key.replace("_to", "_from");
                return Err(ConfigError::range(
                    key,
                    to,
                    &format!("values other than {from_key} = {from} (a range of non-zero width)"),
                ));
            }
        }
        Ok(())
    }

    /// Refuses a value `v` of `name` (given at `key`: a map's range end, an uncertain
    /// parameter's draw) that this config would not accept as its own: outside the
    /// parameter's range, a clearance the initial state lies outside of or f32 cannot
    /// resolve, a magnitude the precision cannot hold.
    pub fn check_value(&self, key: &str, name: Param, v: f64) -> Result<(), ConfigError> {
        let mut p = self.params();
        name.set(&mut p, v);
        p.check()
            .map_err(|e| ConfigError::range(key, v, &format!("{} for `{name}`", e.range)))?;
        if name == Param::Clearance {
            self.check_clearance(key, v)?;
        }
        self.check_precision([(key, v)])
    }

    /// Parameter values of map cell (ix, iy): grid points at cell centres.
    ///
    /// Each half is counted from its own end (the middle cell of an odd count is the range's
    /// midpoint), so that an axis given the other way round (`from` and `to` swapped) has the
    /// same values bit for bit in the reverse order: a mirrored map integrates the very same
    /// parameters, and long runs that amplify an ulp (the recurrence search) agree.
    pub fn map_axis(from: f64, to: f64, n: u32) -> Vec<f64> {
        let d = to - from;
        (0..n)
            .map(|i| match (2 * i + 1).cmp(&n) {
                std::cmp::Ordering::Less => from + d * (i as f64 + 0.5) / n as f64,
                std::cmp::Ordering::Equal => (from + to) / 2.0,
                std::cmp::Ordering::Greater => to - d * ((n - 1 - i) as f64 + 0.5) / n as f64,
            })
            .collect()
    }
}

impl Config {
    /// The z axis of a volume (`map.z` set and checked), or None for a plane.
    pub fn z_axis(&self) -> Option<ZAxis> {
        let m = &self.map;
        Some(ZAxis {
            param: m.z?,
            from: m.z_from?,
            to: m.z_to?,
            points: m.z_points?,
        })
    }

    /// Slices of the map: `map.z_points` for a volume, 1 for a plane.
    pub fn z_count(&self) -> usize {
        self.z_axis().map_or(1, |z| z.points as usize)
    }

    /// Slice `k` of a volume as the plane `rattle map` computes: the z parameter set to its
    /// k-th value, no z axis (a plane's config is its own only slice).
    pub fn slice(&self, k: usize) -> Config {
        match self.z_axis() {
            Some(z) => self.plane_at(z.values()[k]),
            None => self.clone(),
        }
    }

    /// The plane of a volume at `z` (any value of its z parameter, not only a slice's): the z
    /// parameter set to it, no z axis.
    pub fn plane_at(&self, v: f64) -> Config {
        let mut c = self.clone();
        if let Some(z) = self.z_axis() {
            c.model.set(z.param, v);
        }
        c.map.z = None;
        c.map.z_from = None;
        c.map.z_to = None;
        c.map.z_points = None;
        c
    }

    /// Checks `map.z`, `map.z_from`, `map.z_to` and `map.z_points`: all four or none; a
    /// parameter other than x and y within its range, a range of non-zero width, at most
    /// [`MAX_Z_POINTS`] slices and [`MAX_MAP_CELLS`] cells in all.
    fn check_z(&self) -> Result<(), ConfigError> {
        let m = &self.map;
        let Some(z) = m.z else {
            let given = [
                ("map.z_from", m.z_from.is_some()),
                ("map.z_to", m.z_to.is_some()),
                ("map.z_points", m.z_points.is_some()),
            ];
            if let Some((key, _)) = given.iter().find(|g| g.1) {
                return Err(ConfigError::Conflict(format!(
                    "`{key}` applies to a volume only: set `map.z` (the third axis's parameter) \
                     or remove it"
                )));
            }
            return Ok(());
        };
        for (key, missing) in [
            ("map.z_from", m.z_from.is_none()),
            ("map.z_to", m.z_to.is_none()),
            ("map.z_points", m.z_points.is_none()),
        ] {
            if missing {
                return Err(ConfigError::Conflict(format!(
                    "`map.z` = \"{z}\" needs `{key}` too (a volume's z axis: map.z_from, \
                     map.z_to, map.z_points)"
                )));
            }
        }
        if z == Param::Lambda && self.model.friction != FrictionLaw::Coulomb {
            return Err(ConfigError::range(
                "map.z",
                "\"lambda\"",
                "fs, fk, l1 or l2 with friction = \"stribeck\"",
            ));
        }
        if z.overlaps(m.x) || z.overlaps(m.y) {
            return Err(ConfigError::range(
                "map.z",
                format!("\"{z}\""),
                &format!(
                    "a parameter other than map.x = \"{}\" and map.y = \"{}\"",
                    m.x, m.y
                ),
            ));
        }
        let (from, to, n) = (
            m.z_from.unwrap_or(0.0),
            m.z_to.unwrap_or(0.0),
            m.z_points.unwrap_or(0),
        );
        if !(1..=MAX_Z_POINTS).contains(&n) {
            return Err(ConfigError::range(
                "map.z_points",
                n,
                &format!("[1, {MAX_Z_POINTS}]"),
            ));
        }
        let cells = u64::from(m.x_points) * u64::from(m.y_points) * u64::from(n);
        if cells > MAX_MAP_CELLS {
            return Err(ConfigError::range(
                "map.x_points x map.y_points x map.z_points",
                format!("{} x {} x {n} = {cells} cells", m.x_points, m.y_points),
                &format!("at most {MAX_MAP_CELLS} cells"),
            ));
        }
        self.check_value("map.z_from", z, from)?;
        self.check_value("map.z_to", z, to)?;
        if from == to {
            return Err(ConfigError::range(
                "map.z_to",
                to,
                &format!("values other than map.z_from = {from} (a range of non-zero width)"),
            ));
        }
        Ok(())
    }

    /// The basin axes' ranges, defaults resolved: (x_from, x_to, y_from, y_to).
    pub fn basin_ranges(&self) -> (f64, f64, f64, f64) {
        let b = &self.basin;
        let r = self.model.clearance;
        let default = |c: StateCoord| match c {
            StateCoord::Z0 => (-r, r),
            _ => (-1.0, 1.0),
        };
        let (x0, x1) = default(b.x);
        let (y0, y1) = default(b.y);
        (
            b.x_from.unwrap_or(x0),
            b.x_to.unwrap_or(x1),
            b.y_from.unwrap_or(y0),
            b.y_to.unwrap_or(y1),
        )
    }

    /// Checks the `[basin]` section: two different coordinates, finite ranges of non-zero
    /// width (z0 within the clearance), a grid of at most [`MAX_BASIN_CELLS`] cells and a
    /// matching tolerance in (0, 0.1].
    pub fn check_basin(&self) -> Result<(), ConfigError> {
        self.check_tangent("`basin`")?;
        let b = &self.basin;
        if b.x == b.y {
            return Err(ConfigError::range(
                "basin.y",
                format!("\"{}\"", b.y.name()),
                &format!("a coordinate other than basin.x = \"{}\"", b.x.name()),
            ));
        }
        check_grid("basin", (b.x_points, b.y_points), 16384, MAX_BASIN_CELLS)?;
        let (x0, x1, y0, y1) = self.basin_ranges();
        let r = self.model.clearance;
        for (key, c, v) in [
            ("basin.x_from", b.x, x0),
            ("basin.x_to", b.x, x1),
            ("basin.y_from", b.y, y0),
            ("basin.y_to", b.y, y1),
        ] {
            let (ok, range) = match c {
                StateCoord::Z0 => (v.abs() <= r, format!("[-r, r] = [{}, {r}] for z0", -r)),
                _ => (v.abs() <= 1e3, format!("[-1000, 1000] for {}", c.name())),
            };
            if !(v.is_finite() && ok) {
                return Err(ConfigError::range(key, v, &range));
            }
        }
        for (key, a, z) in [("basin.x_to", x0, x1), ("basin.y_to", y0, y1)] {
            if a == z {
                return Err(ConfigError::range(
                    key,
                    z,
                    "a value other than the range's start (a range of non-zero width)",
                ));
            }
        }
        if !(b.tol.is_finite() && b.tol > 0.0 && b.tol <= 0.1) {
            return Err(ConfigError::range("basin.tol", b.tol, "(0, 0.1]"));
        }
        self.check_precision([
            ("basin.x_from", x0),
            ("basin.x_to", x1),
            ("basin.y_from", y0),
            ("basin.y_to", y1),
        ])
    }
}

/// Checks `SECTION.x_points` and `SECTION.y_points` (each in [1, max_points]) and their
/// product (at most `max_cells`).
fn check_grid(
    section: &str,
    (nx, ny): (u32, u32),
    max_points: u32,
    max_cells: u64,
) -> Result<(), ConfigError> {
    for (axis, n) in [("x", nx), ("y", ny)] {
        if !(1..=max_points).contains(&n) {
            return Err(ConfigError::range(
                &format!("{section}.{axis}_points"),
                n,
                &format!("[1, {max_points}]"),
            ));
        }
    }
    let cells = nx as u64 * ny as u64;
    if cells > max_cells {
        return Err(ConfigError::range(
            &format!("{section}.x_points x {section}.y_points"),
            format!("{nx} x {ny} = {cells} cells"),
            &format!("at most {max_cells} cells"),
        ));
    }
    Ok(())
}
