"""rattle from Python: the impact oscillator with dry friction, swept on the GPU or the CPU.

The commands of the command line as functions that return numpy arrays, computed by the same
library (no files unless `.save(prefix)` is called, which writes the command line's files):

    import rattle
    p = rattle.point("configs/fig2.toml", eta=1.5)        # p.cls == "period-1"
    m = rattle.map("configs/r_lambda.toml", **{"map.x_points": 64, "map.y_points": 64})
    m.layers["class"], m.x, m.y                           # numpy arrays
    b = rattle.bifurcation("configs/fig2.toml")           # b.values, b.y (section samples)
    s = rattle.sensitivity("configs/fig2.toml", uncertain=["R=0.6+-0.01"], samples=64)

A config is a TOML file's path, a `Config` (from a path or TOML text, with `.set(key, value)`),
or TOML text through `toml=`; keyword overrides use the keys of the command line's `--set`
(`eta=1.5`, `**{"method.backend": "cpu"}`). Bad input raises `ConfigError` (a `ValueError`)
naming the key and its allowed range, a run too large for memory `TooLargeError` (also a
`MemoryError`) before anything is allocated. The computation releases the interpreter lock;
Ctrl-C raises `KeyboardInterrupt` within a fraction of a second of the next progress report.
`progress=` takes a callable `(done, total)`, or `True` for a tqdm bar where tqdm is installed.
"""

from __future__ import annotations

import io
import json
import os
import warnings as _warnings
from typing import Any, Callable, Dict, Optional, Union

import numpy as np

from . import _rattle
from ._errors import ConfigError, RattleError, TooLargeError

__version__ = _rattle.__version__
__all__ = [
    "Config",
    "ConfigError",
    "TooLargeError",
    "RattleError",
    "point",
    "bifurcation",
    "map",
    "sensitivity",
    "basin",
    "bench",
    "validate",
    "Point",
    "Basin",
    "Map",
    "Bifurcation",
    "Sensitivity",
]

PathLike = Union[str, "os.PathLike[str]"]
Progress = Union[None, bool, Callable[[int, int], Any]]


def _toml_string(v: str) -> str:
    """A TOML basic string (the escapes TOML requires: quote, backslash, control characters)."""
    out = []
    for ch in v:
        o = ord(ch)
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif o < 0x20 or o == 0x7F:
            out.append(f"\\u{o:04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _value(v: Any, key: str = "") -> str:
    """A Python value as a TOML value, typed as a user expects: bool and numpy bools as
    booleans, ints and numpy integers as integers, floats and numpy floats as floats (nan, inf
    included), strings and paths as strings, lists, tuples and numpy arrays as arrays."""
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        n = int(v)
        if not -(2**63) <= n < 2**63:
            raise ConfigError(f"`{key}` = {n}: allowed integers of 64 bits")
        return str(n)
    if isinstance(v, (float, np.floating)):
        x = float(v)
        if x != x:
            return "nan"
        if x in (float("inf"), float("-inf")):
            return "inf" if x > 0 else "-inf"
        return repr(x)
    if isinstance(v, str):
        return _toml_string(v)
    if isinstance(v, os.PathLike):
        return _toml_string(os.fspath(v))
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x, key) for x in v) + "]"
    raise ConfigError(
        f"`{key}`: a {type(v).__name__} cannot be a config value "
        "(give a bool, int, float, str, or a list or numpy array of them)"
    )


def _set(key: str, value: Any) -> str:
    if not isinstance(key, str):
        raise ConfigError(f"config keys are strings, not {type(key).__name__}: {key!r}")
    return f"{key}={_value(value, key)}"


class Config:
    """A configuration: a TOML file or TOML text, and `--set` overrides applied in order.

    >>> c = rattle.Config("configs/fig2.toml").set("sweep.points", 200)
    >>> rattle.bifurcation(c)
    """

    def __init__(self, path: Optional[PathLike] = None, toml: Optional[str] = None):
        if path is not None and toml is not None:
            raise TypeError("give a path or TOML text, not both")
        self.path = os.fspath(path) if path is not None else None
        self.toml = toml
        self.sets: list = []

    def set(self, key: str, value: Any) -> "Config":
        """Overrides `key` (the command line's `--set` key, e.g. `map.x_points`, or a model key
        such as `eta`); returns the config."""
        self.sets.append(_set(key, value))
        return self

    def _with(self, overrides: Dict[str, Any]) -> "Config":
        c = Config(self.path, self.toml)
        c.sets = list(self.sets) + [_set(k, v) for k, v in overrides.items()]
        return c

    def __repr__(self) -> str:
        src = f"path={self.path!r}" if self.path is not None else "toml=..."
        return f"Config({src}, sets={self.sets!r})"


def _config(config: Union[None, PathLike, Config], toml: Optional[str], overrides) -> Config:
    if isinstance(config, Config):
        if toml is not None:
            raise TypeError("give a Config or TOML text, not both")
        return config._with(overrides)
    return Config(config, toml)._with(overrides)


def _progress(progress: Progress, what: str):
    """The callable the extension calls with (done, total), and what closes it."""
    if progress is None or progress is False:
        return None, lambda: None
    if progress is not True and not callable(progress):
        raise TypeError(
            f"progress must be a callable (done, total), True or None, not {type(progress).__name__}"
        )
    if progress is True:
        try:
            from tqdm.auto import tqdm  # type: ignore
        except ImportError:
            return None, lambda: None
        bar = tqdm(total=1, desc=what)

        def update(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        return update, bar.close
    return progress, lambda: None


def _warn(ws) -> None:
    for w in ws:
        _warnings.warn(w, RuntimeWarning, stacklevel=4)


def _points(pts: list, with_z: bool) -> dict:
    """Boundary points (JSON objects) as arrays by key."""
    out = {
        "x": np.asarray([p["x"] for p in pts], dtype=float),
        "y": np.asarray([p["y"] for p in pts], dtype=float),
        "type": np.asarray([p["type"] for p in pts], dtype=str),
        "class_a": np.asarray([p["classes"][0] for p in pts], dtype=str),
        "class_b": np.asarray([p["classes"][1] for p in pts], dtype=str),
        "before": np.asarray([p["change"][0] for p in pts], dtype=str),
        "after": np.asarray([p["change"][1] for p in pts], dtype=str),
        "uncertainty": np.asarray([p["uncertainty"] for p in pts], dtype=float),
        "located": np.asarray([p["located"] for p in pts], dtype=bool),
        "period": np.asarray([p["period"] for p in pts], dtype=int),
        "reason": np.asarray([p.get("reason", "") for p in pts], dtype=str),
        "evidence": np.asarray([p.get("evidence", "") for p in pts], dtype=str),
    }
    if with_z:
        # A volume's: each point with its slice's z, or the z of its change between slices.
        out["z"] = np.asarray([p["z"] for p in pts], dtype=float)
    return out


def _npy(b: bytes) -> np.ndarray:
    return np.load(io.BytesIO(b), allow_pickle=False)


class Point:
    """One parameter point: its class, period, exponents, multipliers and samples.

    `cls` is the class name (`period-1`, `chaotic`, ...); `samples` the stroboscopic section
    states (n x 4); `to_dict()` the command line's `rattle point --json` report."""

    def __init__(self, report: dict):
        self._report = report
        self.cls: str = report["class"]
        self.period: Optional[int] = report["period"]
        self.lyapunov: float = report["lyapunov"]
        self.lyapunov_se: float = report["lyapunov_se"]
        # The run's own exponent over its last window (`lyapunov` is a confirmed cycle's).
        self.run_lyapunov: float = report["run_lyapunov"][0]
        self.rule: str = report["rule"]
        self.samples = np.asarray(report["samples"], dtype=float).reshape(-1, 4)
        self.impact_speeds = np.asarray(report["impact_speeds"], dtype=float)
        m = report.get("multipliers")
        self.multipliers = (
            None if m is None else np.array([complex(re, im) for re, im in m], dtype=complex)
        )
        spectrum = report.get("lyapunov_spectrum")
        self.lyapunov_spectrum = None if spectrum is None else np.asarray(spectrum, dtype=float)

    @property
    def caption(self) -> str:
        r = self._report
        p = r["params"]
        return (
            f"{self.cls} at eta = {p['eta']}, R = {p['restitution']}: largest Lyapunov exponent "
            f"{self.lyapunov:.4g} +- {self.lyapunov_se:.2g} per unit time, "
            f"{r['impacts_per_period']:.3g} impacts per period ({r['backend']}, {r['precision']})"
        )

    def to_dict(self) -> dict:
        return json.loads(json.dumps(self._report))

    def __repr__(self) -> str:
        return f"<rattle.Point {self.cls}, exponent {self.lyapunov:.4g}>"


class Map:
    """A map over two parameters: every layer of the command line's NPY files as an array of
    shape (ny, nx) (or (ny, nx, 2)), rows along `y`, columns along `x`. A volume (`map.z`
    set) has a first axis along `z`: shape (nz, ny, nx), slice k the map at z[k]."""

    def __init__(self, data):
        self._data = data
        self._json = json.loads(data.report())
        self.layers: Dict[str, np.ndarray] = {k: _npy(v) for k, v in data.layers().items()}
        self.x = np.asarray(self._json["x"]["values"], dtype=float)
        self.y = np.asarray(self._json["y"]["values"], dtype=float)
        self.x_param: str = self._json["x"]["param"]
        self.y_param: str = self._json["y"]["param"]
        z = self._json.get("z")
        self.z: Optional[np.ndarray] = None if z is None else np.asarray(z["values"], dtype=float)
        self.z_param: Optional[str] = None if z is None else z["param"]
        self.class_counts: Dict[str, int] = self._json["class_counts"]
        self.timings: Dict[str, float] = self._json["report"]["timings"]

    @property
    def caption(self) -> str:
        return self._json["caption"]

    @property
    def classes(self) -> np.ndarray:
        """The class codes (the `class` layer; n > 0: period n)."""
        return self.layers["class"]

    def __getattr__(self, name: str) -> np.ndarray:
        layers = self.__dict__.get("layers", {})
        if name in layers:
            return layers[name]
        raise AttributeError(name)

    def boundaries(self) -> dict:
        """The typed boundaries between the classes (`rattle map --boundaries`, docs/maps.md):
        `points` as arrays (`x`, `y`, `type`, `class_a`, `class_b`, `before`, `after`: the class
        just before and just after the change, `uncertainty`, `located`, `period`, `reason`: why
        an `undetermined` point is not typed, `evidence`: what typed a located end; a volume's
        with `z`),
        `curves` as a list of dicts with `type`, `classes` (a volume's with `z`) and `points` (an array of
        shape (k, 2) in parameter values), and the counts (`edges`, `trials`,
        `continuations`, `claims`, `continuation_s`, `coexistence_s`, `seconds`). A volume's
        also has `across` (the changes on the edges between its slices: its `points` as
        arrays with `z`, and its counts) and `surfaces` (`sheets`: type, changing class,
        period, vertices, triangles, extent; `codim2`: where sheets of two types meet)."""
        j = json.loads(self._data.boundaries())
        j["points"] = _points(j["points"], self.z_param is not None)
        for c in j["curves"]:
            c["points"] = np.asarray(c["points"], dtype=float).reshape(-1, 2)
        if "across" in j:
            # A volume's edges between slices: each point with the z of its change.
            j["across"]["points"] = _points(j["across"]["points"], True)
        return j

    def to_dict(self) -> dict:
        d = dict(self._json)
        d["layers"] = {k: v.tolist() for k, v in self.layers.items()}
        return d

    def save(self, prefix: PathLike) -> list:
        """Writes the command line's files (PREFIX.png, PREFIX-*.npy, PREFIX.json, ...)."""
        return [str(p) for p in self._data.save(os.fspath(prefix))]

    def to_xarray(self):
        """An `xarray.Dataset` of every layer of one value per cell on the (y, x) axes, or a
        volume's on the (z, y, x) axes, each coordinate with its values, its parameter's
        label (`long_name`) and units ("1": the model's parameters are dimensionless)
        (needs xarray)."""
        import xarray as xr  # type: ignore

        axes = [("y", self.y_param, self.y), ("x", self.x_param, self.x)]
        if self.z_param is not None:
            axes.insert(0, ("z", self.z_param, self.z))
        coords = {
            p: (p, v, {"long_name": self._json[a]["label"], "units": "1", "axis": a.upper()})
            for a, p, v in axes
        }
        dims = tuple(p for _, p, _ in axes)
        return xr.Dataset(
            {k: (dims, v) for k, v in self.layers.items() if v.ndim == len(dims)},
            coords=coords,
            attrs={"caption": self.caption},
        )

    def __repr__(self) -> str:
        if self.z_param is not None:
            return (
                f"<rattle.Map volume {len(self.z)} x {len(self.y)} x {len(self.x)} over "
                f"{self.z_param}, {self.y_param}, {self.x_param}>"
            )
        return f"<rattle.Map {len(self.y)} x {len(self.x)} over {self.x_param}, {self.y_param}>"


class Bifurcation:
    """A bifurcation diagram: the section samples as the CSV holds them (`values`, `sample`,
    `y` with y1..y4 in its columns, `direction` for continuation), the points' classes and the
    located bifurcation points."""

    def __init__(self, data):
        self._data = data
        self._json = json.loads(data.report())
        d, v, k, y = data.samples()
        self.direction = np.asarray(d, dtype=str)
        self.values: np.ndarray = v
        self.sample: np.ndarray = k
        self.y: np.ndarray = y
        self.param: str = self._json["config"]["sweep"]["param"]
        points = self._json.get("points") or []
        self.point_values = np.asarray([p["value"] for p in points], dtype=float)
        self.point_classes = [p["class"] for p in points]
        self.bifurcations = self._json["bifurcations"]
        self.class_counts: Dict[str, int] = self._json["class_counts"]

    @property
    def caption(self) -> str:
        return self._json["caption"]

    def to_dict(self) -> dict:
        return json.loads(json.dumps(self._json))

    def save(self, prefix: PathLike) -> list:
        """Writes the command line's files (PREFIX.csv, PREFIX.png, PREFIX.json)."""
        return [str(p) for p in self._data.save(os.fspath(prefix))]

    def to_xarray(self):
        """An `xarray.Dataset` of the samples, one row per sample (needs xarray)."""
        import xarray as xr  # type: ignore

        return xr.Dataset(
            {f"y{i + 1}": ("row", self.y[:, i]) for i in range(4)},
            coords={self.param: ("row", self.values), "sample": ("row", self.sample)},
            attrs={"caption": self.caption},
        )

    def __repr__(self) -> str:
        return f"<rattle.Bifurcation over {self.param}, {len(self.values)} samples>"


class Sensitivity:
    """A sensitivity study: class probabilities with their 95% intervals, distances to the
    nearest class change, Sobol indices, and the draws."""

    def __init__(self, data):
        self._data = data
        self._json = json.loads(data.report())
        s = self._json["study"]
        self.nominal: str = self._json["nominal"]
        self.probabilities: Dict[str, tuple] = {
            c["name"]: (c["p"], c["low"], c["high"]) for c in s["classes"]
        }
        self.sobol = s["sobol"]
        self.distances = s["distances"]
        sets, rows, values, classes, lyap = data.draws()
        self.draws = {
            "set": np.asarray(sets, dtype=str),
            "row": np.asarray(rows, dtype=np.int64),
            "values": np.asarray(values, dtype=float),
            "class": np.asarray(classes, dtype=str),
            "lyapunov": np.asarray(lyap, dtype=float),
        }

    @property
    def caption(self) -> str:
        return self._json["caption"]

    def to_dict(self) -> dict:
        return json.loads(json.dumps(self._json))

    def save(self, prefix: PathLike) -> list:
        """Writes the command line's files (PREFIX.json, PREFIX.csv, the figures)."""
        return [str(p) for p in self._data.save(os.fspath(prefix))]

    def __repr__(self) -> str:
        return f"<rattle.Sensitivity nominal {self.nominal}>"


class Basin:
    """Basins of attraction at one parameter point: `ids` (ny, nx) gives each initial state's
    attractor (1, 2, ... by size; -1 where the run failed) on the axes `x`, `y` (state
    coordinates `x_coord`, `y_coord`); `attractors` describes each (class, period, section
    points, multipliers)."""

    def __init__(self, data):
        self._data = data
        self._json = json.loads(data.report())
        self.ids = _npy(data.ids())
        g = self._json["grid"]
        self.x = np.asarray(g["x_values"], dtype=float)
        self.y = np.asarray(g["y_values"], dtype=float)
        self.x_coord: str = str(g["x"])
        self.y_coord: str = str(g["y"])
        self.attractors = self._json["attractors"]

    @property
    def caption(self) -> str:
        return self._json["caption"]

    def to_dict(self) -> dict:
        d = dict(self._json)
        d["ids"] = self.ids.tolist()
        return d

    def save(self, prefix: PathLike) -> list:
        """Writes the command line's files (PREFIX.png, PREFIX.npy, PREFIX.json)."""
        return [str(p) for p in self._data.save(os.fspath(prefix))]

    def __repr__(self) -> str:
        return f"<rattle.Basin {len(self.y)} x {len(self.x)}, {len(self.attractors)} attractors>"


def _call(fn, what, config, toml, progress, overrides, **extra):
    """Runs the extension's `fn` on the config; its warnings go to `warnings`."""
    c = _config(config, toml, overrides)
    cb, close = _progress(progress, what)
    try:
        out = fn(c.path, c.toml, c.sets, progress=cb, **extra)
    finally:
        close()
    if isinstance(out, tuple):  # point: (report, warnings)
        out, ws = out
    else:
        ws = out.warnings
    _warn(ws)
    return out


def point(
    config: Union[None, PathLike, Config] = None,
    *,
    toml: Optional[str] = None,
    progress: Progress = None,
    **overrides: Any,
) -> Point:
    """Integrates one parameter point and classifies its motion (`rattle point`)."""
    return Point(json.loads(_call(_rattle.point, "point", config, toml, progress, overrides)))


def map(
    config: Union[None, PathLike, Config] = None,
    *,
    toml: Optional[str] = None,
    progress: Progress = None,
    **overrides: Any,
) -> Map:
    """A map of classes, exponents and multipliers over two parameters (`rattle map`)."""
    return Map(_call(_rattle.map, "map", config, toml, progress, overrides))


def bifurcation(
    config: Union[None, PathLike, Config] = None,
    *,
    toml: Optional[str] = None,
    progress: Progress = None,
    **overrides: Any,
) -> Bifurcation:
    """Sweeps one parameter: the bifurcation diagram (`rattle bifurcation`)."""
    return Bifurcation(_call(_rattle.bifurcation, "bifurcation", config, toml, progress, overrides))


def sensitivity(
    config: Union[None, PathLike, Config] = None,
    *,
    toml: Optional[str] = None,
    uncertain: Optional[list] = None,
    samples: Optional[int] = None,
    seed: Optional[int] = None,
    progress: Progress = None,
    **overrides: Any,
) -> Sensitivity:
    """Class probabilities, distances and Sobol indices under parameter uncertainty
    (`rattle sensitivity`); `uncertain` as the command line's `--uncertain` strings."""
    return Sensitivity(
        _call(
            _rattle.sensitivity,
            "sensitivity",
            config,
            toml,
            progress,
            overrides,
            uncertain=uncertain,
            samples=samples,
            seed=seed,
        )
    )


def basin(
    config: Union[None, PathLike, Config] = None,
    *,
    toml: Optional[str] = None,
    progress: Progress = None,
    **overrides: Any,
) -> Basin:
    """Basins of attraction over a grid of initial states (`rattle basin`)."""
    return Basin(_call(_rattle.basin, "basin", config, toml, progress, overrides))


def bench(
    config: Union[None, PathLike, Config] = None,
    *,
    toml: Optional[str] = None,
    points: int = 2000,
    periods: int = 100,
    backends: Optional[list] = None,
    **overrides: Any,
) -> list:
    """RK4 steps per second of every backend (`"gpu"`, `"cpu"`) and precision
    (`rattle bench`): one dict per row (`backend`, `precision`, `steps_per_s`, `timings`, ...;
    `{"error": ...}` for a row that could not be measured)."""
    c = _config(config, toml, overrides)
    rows, ws = _rattle.bench(c.path, c.toml, c.sets, points, periods, backends)
    _warn(ws)
    return json.loads(rows)


def validate(
    config: Union[None, PathLike, Config] = None,
    *,
    toml: Optional[str] = None,
    state_points: int = 64,
    **overrides: Any,
) -> str:
    """The same points on GPU and CPU (`rattle validate`): the agreement table, as text.
    Needs a GPU adapter (`RattleError` without one)."""
    c = _config(config, toml, overrides)
    table, ws = _rattle.validate(c.path, c.toml, c.sets, state_points)
    _warn(ws)
    return table
