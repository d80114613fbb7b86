//! The checks of a configuration's values against what the model, the method and the
//! configured precision accept, each refusal naming the key and its allowed range.

use super::*;

impl Config {
    /// Checks everything a command uses: [`Config::check_base`] and the sweep.
    pub fn check(&self) -> Result<(), ConfigError> {
        self.check_base()?;
        self.check_sweep()
    }

    /// Checks what `cmd` reads: [`Config::check_base`] and the command's own section.
    pub fn check_command(&self, cmd: Command) -> Result<(), ConfigError> {
        use Command as C;
        self.check_base()?;
        match cmd {
            C::Point | C::Plot => Ok(()),
            C::Map => self.check_map(),
            C::Sweep => self.check_sweep(),
            C::Basin => self.check_basin(),
            C::Sensitivity => self.check_tangent("`sensitivity`"),
        }
    }

    /// Checks model, initial state, method and run (what every command uses).
    pub fn check_base(&self) -> Result<(), ConfigError> {
        let m = &self.model;
        if !(m.lambda.is_finite() && m.lambda >= 0.0) {
            return Err(ConfigError::range("model.lambda", m.lambda, "[0, inf)"));
        }
        // Levels that the friction law ignores are still checked: an impossible value is a
        // mistake whichever law reads it.
        m.given().check()?;
        self.params().check()?;
        for (i, v) in self.initial.y.iter().enumerate() {
            if !v.is_finite() {
                return Err(ConfigError::range(
                    &format!("initial.y[{i}]"),
                    v,
                    "finite values",
                ));
            }
        }
        let z0 = self.initial.y[2] - self.initial.y[0];
        if z0.abs() > m.clearance {
            return Err(ConfigError::range(
                "initial.y",
                format!("{:?} (|y3 - y1| = {})", self.initial.y, z0.abs()),
                &format!("|y3 - y1| <= r = {}", m.clearance),
            ));
        }
        let me = &self.method;
        if !(8..=1 << 20).contains(&me.steps_per_period) {
            return Err(ConfigError::range(
                "method.steps_per_period",
                me.steps_per_period,
                "[8, 1048576]",
            ));
        }
        if !(1..=1000).contains(&me.max_events) {
            return Err(ConfigError::range(
                "method.max_events",
                me.max_events,
                "[1, 1000]",
            ));
        }
        if !(me.zeno_speed.is_finite() && me.zeno_speed >= 0.0 && me.zeno_speed < 1.0) {
            return Err(ConfigError::range(
                "method.zeno_speed",
                me.zeno_speed,
                "[0, 1)",
            ));
        }
        let r = &self.run;
        if r.transient_periods > 10_000_000 {
            return Err(ConfigError::range(
                "run.transient_periods",
                r.transient_periods,
                "[0, 10000000]",
            ));
        }
        if !(2..=1_000_000).contains(&r.sample_periods) {
            return Err(ConfigError::range(
                "run.sample_periods",
                r.sample_periods,
                "[2, 1000000]",
            ));
        }
        if !(r.period_tol.is_finite() && r.period_tol > 0.0 && r.period_tol < 1.0) {
            return Err(ConfigError::range("run.period_tol", r.period_tol, "(0, 1)"));
        }
        if !(1..=1000).contains(&r.horizon) {
            return Err(ConfigError::range("run.horizon", r.horizon, "[1, 1000]"));
        }
        if r.look > 10_000_000 {
            return Err(ConfigError::range(
                "run.look",
                r.look,
                "[0, 10000000] (forcing periods)",
            ));
        }
        if let Some(o) = r.overlap
            && !(1..=super::MAX_OVERLAP).contains(&o)
        {
            return Err(ConfigError::range(
                "run.overlap",
                o,
                &format!("[1, {}]", super::MAX_OVERLAP),
            ));
        }
        if !(r.lyapunov_tol.is_finite() && r.lyapunov_tol > 0.0) {
            return Err(ConfigError::range(
                "run.lyapunov_tol",
                r.lyapunov_tol,
                "(0, inf)",
            ));
        }
        self.check_clearance("model.r", m.clearance)?;
        self.check_precision(
            m.values().into_iter().chain(
                [
                    "initial.y[0]",
                    "initial.y[1]",
                    "initial.y[2]",
                    "initial.y[3]",
                ]
                .into_iter()
                .zip(self.initial.y),
            ),
        )?;
        Ok(())
    }

    /// The smallest clearance the f32 integrator resolves: below it the guards of the stops
    /// compare positions whose rounding exceeds the clearance (measured at Fig. 2's eta = 1.5:
    /// the exponent drifts at r = 1e-11 and is NaN from r = 1e-12; f64 is unaffected).
    pub const F32_MIN_CLEARANCE: f64 = 1e-9;

    /// Refuses a clearance `v` (at key `key`) that f32 cannot resolve, or that the initial
    /// state lies outside of (a sweep or a map over r starts every value from `initial.y`).
    pub(crate) fn check_clearance(&self, key: &str, v: f64) -> Result<(), ConfigError> {
        let z0 = (self.initial.y[2] - self.initial.y[0]).abs();
        if z0 > v {
            return Err(ConfigError::range(
                "initial.y",
                format!("{:?} (|y3 - y1| = {z0})", self.initial.y),
                &format!("|y3 - y1| <= r for every r swept, and {key} = {v}"),
            ));
        }
        if self.method.precision == Precision::F32 && v < Self::F32_MIN_CLEARANCE {
            return Err(ConfigError::range(
                key,
                v,
                "r >= 1e-9 with method.precision = \"f32\" (below it the stops' guards lose the \
                 clearance to the rounding of the positions; use \"f64\")",
            ));
        }
        Ok(())
    }

    /// Refuses values the configured precision cannot represent (f32: nonzero magnitudes
    /// outside [1.2e-38, 3.4e38] would become 0 or infinite).
    pub(crate) fn check_precision<'a>(
        &self,
        values: impl IntoIterator<Item = (&'a str, f64)>,
    ) -> Result<(), ConfigError> {
        if self.method.precision == Precision::F64 {
            return Ok(());
        }
        for (key, v) in values {
            let a = v.abs();
            if a != 0.0 && !(f32::MIN_POSITIVE as f64..=f32::MAX as f64).contains(&a) {
                return Err(ConfigError::range(
                    key,
                    v,
                    "0 or magnitudes in [1.2e-38, 3.4e38] with method.precision = \"f32\" \
                     (use \"f64\")",
                ));
            }
        }
        Ok(())
    }

    /// Checks the `[sweep]` section (bifurcation diagrams and the commands that sweep eta).
    pub fn check_sweep(&self) -> Result<(), ConfigError> {
        self.check_tangent("sweeps (`bifurcation`, `accuracy`, `validate`, `bench`)")?;
        let m = &self.model;
        let r = &self.run;
        let s = &self.sweep;
        if s.points > 1 && s.from == s.to {
            return Err(ConfigError::range(
                "sweep.to",
                s.to,
                "a value other than sweep.from (a range of non-zero width)",
            ));
        }
        self.check_precision([("sweep.from", s.from), ("sweep.to", s.to)])?;
        if s.param == Param::Clearance {
            self.check_clearance("sweep.from", s.from)?;
            self.check_clearance("sweep.to", s.to)?;
        }
        if s.param == Param::Lambda && m.friction != FrictionLaw::Coulomb {
            return Err(ConfigError::range(
                "sweep.param",
                "\"lambda\"",
                "fs, fk, l1 or l2 with friction = \"stribeck\"",
            ));
        }
        if !PLOT_VARS.contains(&s.plot.as_str()) {
            return Err(ConfigError::range(
                "sweep.plot",
                format!("\"{}\"", s.plot),
                &format!("one of {PLOT_VARS:?}"),
            ));
        }
        if !(1..=10_000_000).contains(&s.points) {
            return Err(ConfigError::range(
                "sweep.points",
                s.points,
                "[1, 10000000]",
            ));
        }
        for (key, v) in [("sweep.from", s.from), ("sweep.to", s.to)] {
            if !v.is_finite() {
                return Err(ConfigError::range(key, v, "finite values"));
            }
        }
        // Every swept value must be a valid model point.
        for v in [s.from, s.to] {
            let mut p = self.params();
            s.param.set(&mut p, v);
            p.check().map_err(|e| {
                ConfigError::range(
                    if v == s.from {
                        "sweep.from"
                    } else {
                        "sweep.to"
                    },
                    v,
                    &format!("{} for `{}`", e.range, s.param),
                )
            })?;
        }
        let bytes = s.points as u64 * r.sample_periods as u64 * 32;
        if bytes > MAX_SAMPLE_BYTES {
            return Err(ConfigError::range(
                "sweep.points x run.sample_periods",
                format!(
                    "{} x {} ({} MiB of samples)",
                    s.points,
                    r.sample_periods,
                    bytes >> 20
                ),
                &format!("at most {} MiB of samples", MAX_SAMPLE_BYTES >> 20),
            ));
        }
        Ok(())
    }
}

/// What a command reads of its configuration.
#[derive(Clone, Copy, Debug)]
pub enum Command {
    /// `point`: the model, the method and the run.
    Point,
    /// `point --plot`: as `point`, integrated in CPU f64 whatever the config names.
    Plot,
    /// `map` (and the other config of `--compare`): with `[map]`, its axes varied.
    Map,
    /// The commands that sweep (`bifurcation`, `accuracy`, `validate`, `bench`): with `[sweep]`.
    Sweep,
    /// `basin`: with `[basin]`.
    Basin,
    /// `sensitivity`: its uncertain parameters varied (`Request::sensitivity`).
    Sensitivity,
}

impl Command {
    /// Whether the command runs the adaptive driver's streams (`run.overlap`).
    pub(crate) fn streams(self) -> bool {
        matches!(self, Command::Map | Command::Sensitivity)
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            Command::Point | Command::Plot => "point",
            Command::Map => "map",
            Command::Sweep => "a sweep",
            Command::Basin => "basin",
            Command::Sensitivity => "sensitivity",
        }
    }
}
