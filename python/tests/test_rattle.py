"""rattle from Python against the command line: the same configs give the same numbers, bad
input the same errors, and the calls behave as a Python user expects (no files unless asked,
the interpreter lock released, Ctrl-C, progress). Run from the repository root after `cargo
build --release` (the command line's binary is the reference) and `pip install ./python`."""

import csv
import json
import os
import subprocess
import sys
import threading
import time
import _thread
from pathlib import Path

import numpy as np
import pytest

import rattle

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(os.environ.get("RATTLE_BIN", ROOT / "target" / "release" / "rattle"))
FIG2 = str(ROOT / "configs" / "fig2.toml")
RL = str(ROOT / "configs" / "r_lambda.toml")
# A 32 x 32 map on the CPU in f64 (the same numbers on any machine), short runs.
SMALL = {
    "map.x_points": 32,
    "map.y_points": 32,
    "method.backend": "cpu",
    "method.precision": "f64",
    "run.transient_periods": 200,
    "run.sample_periods": 100,
}


def cli(*args, cwd=None):
    assert BIN.exists(), f"build the command line first: {BIN}"
    r = subprocess.run([str(BIN), *args], capture_output=True, text=True, cwd=cwd)
    return r


def sets(d):
    out = []
    for k, v in d.items():
        out += ["--set", f"{k}={v}"]
    return out


def test_point_prints_the_papers_period_1_and_matches_the_command_line():
    p = rattle.point(FIG2, eta=1.5)
    assert p.cls == "period-1"
    r = cli("point", "--config", FIG2, "--eta", "1.5", "--json")
    assert r.returncode == 0, r.stderr
    j = json.loads(r.stdout)
    assert j["class"] == p.cls and j["period"] == p.period == 1
    assert j["multipliers"] is not None and p.multipliers is not None
    assert abs(p.multipliers).max() < 1.0
    np.testing.assert_array_equal(np.asarray(j["samples"]), p.samples)
    assert p.to_dict()["class"] == "period-1" and "period-1" in p.caption


def test_map_layers_are_the_command_lines_files_byte_for_byte(tmp_path):
    m = rattle.map(RL, **SMALL)
    r = cli("map", "--config", RL, *sets(SMALL), "--out", str(tmp_path / "cli"))
    assert r.returncode == 0, r.stderr
    saved = m.save(tmp_path / "py")
    npys = sorted(p for p in os.listdir(tmp_path) if p.startswith("cli-") and p.endswith(".npy"))
    assert len(npys) >= 20 and len(npys) == len(m.layers), (npys, list(m.layers))
    for f in npys:
        name = f[len("cli-") : -len(".npy")]
        a = np.load(tmp_path / f)
        b = m.layers[name]
        assert a.dtype == b.dtype and a.shape == b.shape == (32, 32) + a.shape[2:], name
        np.testing.assert_array_equal(a, b, err_msg=name)
        # .save writes the command line's file, byte for byte.
        assert (tmp_path / f).read_bytes() == (tmp_path / f"py-{name}.npy").read_bytes(), name
    assert str(tmp_path / "py.json") in saved and str(tmp_path / "py.png") in saved
    cj = json.loads((tmp_path / "cli.json").read_text())
    assert cj["class_counts"] == m.class_counts
    assert m.x.shape == (32,) and m.y.shape == (32,) and m.x_param == "R"
    assert m.x[0] > 0.5 and m.x[-1] < 0.7 and np.all(np.diff(m.x) > 0)
    assert "32 x 32" in m.caption


def test_fig2_samples_are_the_command_lines_csv(tmp_path):
    # The README's first command, as it runs (GPU where there is one: lavapipe in CI).
    b = rattle.bifurcation(FIG2)
    r = cli("bifurcation", "--config", FIG2, "--out", str(tmp_path / "f"))
    assert r.returncode == 0, r.stderr
    with open(tmp_path / "f.csv") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["eta", "sample", "y1", "y2", "y3", "y4"]
    rows = rows[1:]
    assert len(rows) == len(b.values) > 2000
    np.testing.assert_array_equal(np.array([float(x[0]) for x in rows]), b.values)
    np.testing.assert_array_equal(np.array([int(x[1]) for x in rows]), b.sample)
    np.testing.assert_array_equal(np.array([[float(v) for v in x[2:]] for x in rows]), b.y)
    cj = json.loads((tmp_path / "f.json").read_text())
    assert cj["class_counts"] == b.class_counts
    assert [p["class"] for p in cj["points"]] == b.point_classes
    assert cj["caption"] == b.caption


def test_sensitivity_probabilities_are_the_command_lines(tmp_path):
    o = {"method.backend": "cpu", "run.transient_periods": 100, "run.sample_periods": 64}
    unc = ["R=0.60+-0.02", "lambda=0.020+-0.005"]
    s = rattle.sensitivity(RL, uncertain=unc, samples=16, seed=3, **o)
    args = ["sensitivity", "--config", RL, *sets(o), "--samples", "16", "--seed", "3"]
    for u in unc:
        args += ["--uncertain", u]
    r = cli(*args, "--out", str(tmp_path / "s"))
    assert r.returncode == 0, r.stderr
    cj = json.loads((tmp_path / "s.json").read_text())
    got = {c["name"]: (c["p"], c["low"], c["high"]) for c in cj["classes"]}
    assert got == s.probabilities and sum(p for p, _, _ in got.values()) == pytest.approx(1)
    assert s.draws["values"].shape == (16 * 4, 2)
    assert s.nominal in ("chaotic",) or s.nominal.startswith("period-"), s.nominal
    assert cj["nominal"] == s.to_dict()["study"]["nominal"]


def test_basin_ids_are_the_command_lines_file(tmp_path):
    cfg = str(ROOT / "configs" / "basin.toml")
    o = {"basin.x_points": 24, "basin.y_points": 16, "method.backend": "cpu"}
    b = rattle.basin(cfg, **o)
    r = cli("basin", "--config", cfg, *sets(o), "--out", str(tmp_path / "b"))
    assert r.returncode == 0, r.stderr
    a = np.load(tmp_path / "b.npy")
    assert a.dtype == b.ids.dtype and a.shape == b.ids.shape == (16, 24)
    np.testing.assert_array_equal(a, b.ids)
    cj = json.loads((tmp_path / "b.json").read_text())
    assert [x["class"] for x in cj["attractors"]] == [x["class"] for x in b.attractors]
    assert b.ids.max() == len(b.attractors) >= 1
    assert len(b.x) == 24 and len(b.y) == 16


def test_bench_rows_and_validate_table():
    rows = rattle.bench(FIG2, points=200, periods=5, backends=["cpu"])
    got = {(r["backend"], r["schedule"], r["precision"]) for r in rows}
    assert ("cpu", "batched", "f32") in got and ("cpu", "bare", "f64") in got
    assert all(r["steps_per_s"] > 0 for r in rows)
    with pytest.raises(rattle.ConfigError, match="backends"):
        rattle.bench(FIG2, backends=["tpu"])
    table = rattle.validate(FIG2, state_points=8, **{"sweep.points": 40})
    assert "f64 GPU vs f64 CPU" in table and "classification over the sweep" in table


def test_bad_input_names_the_key_and_range_and_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(rattle.ConfigError) as e:
        rattle.map(RL, **{"map.x_points": 0})
    assert "map.x_points" in str(e.value) and "[1, 65536]" in str(e.value)
    assert isinstance(e.value, ValueError)
    r = cli("map", "--config", RL, "--set", "map.x_points=0", "--out", "m")
    assert r.returncode == 2 and "[1, 65536]" in r.stderr
    with pytest.raises(rattle.ConfigError, match="R"):
        rattle.point(FIG2, R=1.5)
    with pytest.raises(rattle.ConfigError, match="run.decide"):
        rattle.point(FIG2, **{"run.decide": "elsewhere"})
    with pytest.raises(rattle.ConfigError):
        rattle.point(toml="[model]\nno_such_key = 1\n")
    # Too large for the memory (here 64 MiB, RATTLE_MEMORY_LIMIT, so that no machine would
    # start it): refused before anything is allocated.
    monkeypatch.setenv("RATTLE_MEMORY_LIMIT", str(64 << 20))
    with pytest.raises(MemoryError) as e:
        rattle.map(RL, **{"map.x_points": 2048, "map.y_points": 2048})
    assert isinstance(e.value, rattle.ConfigError) and "map.x_points" in str(e.value)
    assert os.listdir(tmp_path) == []


def test_the_command_lines_warnings_come_through_pythons_warnings():
    o = dict(SMALL, **{"map.x_points": 4, "map.y_points": 4, "map.y": "l1", "map.y_to": 2})
    with pytest.warns(RuntimeWarning, match="l1 has no effect") as w:
        rattle.map(RL, **o)
    assert w[0].filename == __file__


def test_a_config_object_and_toml_text_give_the_same_point():
    c = rattle.Config(FIG2).set("eta", 1.5)
    a = rattle.point(c)
    b = rattle.point(toml=Path(FIG2).read_text(), eta=1.5)
    assert a.cls == b.cls == "period-1"
    np.testing.assert_array_equal(a.samples, b.samples)


def test_no_files_unless_asked(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rattle.map(RL, **SMALL)
    rattle.bifurcation(FIG2, **{"sweep.points": 16, "method.backend": "cpu"})
    assert os.listdir(tmp_path) == []


def test_the_interpreter_lock_is_released_and_progress_reported():
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.01)

    seen = []
    t = threading.Thread(target=count)
    t.start()
    t0 = time.perf_counter()
    try:
        o = dict(SMALL, **{"map.x_points": 48, "map.y_points": 48})
        rattle.map(RL, progress=lambda done, total: seen.append((done, total)), **o)
    finally:
        stop.set()
        t.join()
    wall = time.perf_counter() - t0
    during = [x for x in ticks if x - t0 < wall]
    # The other thread ran all along (about every 10 ms, not once at the end).
    assert wall > 0.3 and len(during) > 0.5 * wall / 0.01, (wall, len(during))
    # In cells: the total counted first is the map's, and grows only with the work the run
    # finds it needs (the adaptive horizon, the long look); done never goes back nor past it.
    assert seen and seen[0][1] == 48 * 48
    assert [t for _, t in seen] == sorted(t for _, t in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)
    assert all(d <= t for d, t in seen)


def test_ctrl_c_raises_keyboard_interrupt_within_a_block_and_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    o = dict(SMALL, **{"map.x_points": 256, "map.y_points": 256})
    timer = threading.Timer(0.5, _thread.interrupt_main)
    t0 = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        rattle.map(RL, **o)
    took = time.perf_counter() - t0
    timer.cancel()
    # A 256 x 256 map takes a minute here; it stopped at the next report after the interrupt.
    assert took < 10, took
    assert os.listdir(tmp_path) == []
    # The package still works afterwards.
    assert rattle.point(FIG2, eta=1.5).cls == "period-1"


def test_a_progress_callback_that_raises_ends_the_run_with_its_error(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)

    class Stop(Exception):
        pass

    def progress(done, total):
        raise Stop(done)

    o = dict(SMALL, **{"map.x_points": 256, "map.y_points": 256})
    t0 = time.perf_counter()
    with pytest.raises(Stop):
        rattle.map(RL, progress=progress, **o)
    assert time.perf_counter() - t0 < 10
    assert os.listdir(tmp_path) == []


def test_to_xarray_where_xarray_is_installed():
    xr = pytest.importorskip("xarray")
    m = rattle.map(RL, **dict(SMALL, **{"map.x_points": 8, "map.y_points": 6}))
    ds = m.to_xarray()
    assert isinstance(ds, xr.Dataset) and ds["class"].shape == (6, 8)
    np.testing.assert_array_equal(ds["R"].values, m.x)


VOLUME = dict(
    SMALL,
    **{
        "map.x_points": 6,
        "map.y_points": 5,
        "map.z": "eta",
        "map.z_from": 1.2,
        "map.z_to": 1.8,
        "map.z_points": 3,
    },
)


def test_a_volume_is_the_command_lines_z_y_x_arrays(tmp_path):
    m = rattle.map(RL, **VOLUME)
    r = cli("map", "--config", RL, *sets(VOLUME), "--out", str(tmp_path / "cli"))
    assert r.returncode == 0, r.stderr
    assert m.z_param == "eta" and m.z.shape == (3,) and np.all(np.diff(m.z) > 0)
    cj = json.loads((tmp_path / "cli.json").read_text())
    np.testing.assert_array_equal(np.asarray(cj["axes"]["z_values"]), m.z)
    for name, v in m.layers.items():
        a = np.load(tmp_path / f"cli-{name}.npy")
        assert a.shape == v.shape == (3, 5, 6) + a.shape[3:], name
        np.testing.assert_array_equal(a, v, err_msg=name)
    assert cj["class_counts"] == m.class_counts
    # Slice 1 is the plane at its eta, from Python too.
    plane = {k: v for k, v in VOLUME.items() if not k.startswith("map.z")}
    p = rattle.map(RL, eta=float(m.z[1]), **plane)
    for name, v in p.layers.items():
        np.testing.assert_array_equal(m.layers[name][1], v, err_msg=name)
    assert "volume 3 x 5 x 6" in repr(m)


def test_a_volumes_boundaries_between_slices_are_the_command_lines(tmp_path):
    m = rattle.map(RL, **VOLUME)
    b = m.boundaries()
    r = cli("map", "--config", RL, *sets(VOLUME), "--boundaries", "--out", str(tmp_path / "cli"))
    assert r.returncode == 0, r.stderr
    j = json.loads((tmp_path / "cli-boundaries.json").read_text())
    a = j["across"]["points"]
    assert len(a) > 0 and b["across"]["edges"] == j["across"]["edges"]
    np.testing.assert_array_equal(b["across"]["points"]["z"], [p["z"] for p in a])
    np.testing.assert_array_equal(b["across"]["points"]["x"], [p["x"] for p in a])
    assert list(b["across"]["points"]["type"]) == [p["type"] for p in a]
    assert b["surfaces"] == j["surfaces"]


def test_a_volume_is_refused_as_the_command_line_refuses_it():
    bad = dict(VOLUME, **{"map.z": "R"})
    with pytest.raises(rattle.ConfigError, match="map.z"):
        rattle.map(RL, **bad)
    r = cli("map", "--config", RL, *sets(bad), "--out", "/nonexistent/x")
    assert r.returncode == 2 and "map.z" in r.stderr


def test_a_volume_to_xarray_has_z_y_x_with_units():
    xr = pytest.importorskip("xarray")
    m = rattle.map(RL, **VOLUME)
    ds = m.to_xarray()
    assert ds["class"].dims == ("eta", "lambda", "R") and ds["class"].shape == (3, 5, 6)
    np.testing.assert_array_equal(ds["eta"].values, m.z)
    assert ds["eta"].attrs["units"] == "1" and "forcing" in ds["eta"].attrs["long_name"]
    assert ds["R"].attrs["axis"] == "X"


# Reliability round 5: the package's edges, each against what the command line does.


def test_validate_checks_state_points_before_anything_is_allocated():
    # H1: 10**9 state points aborted the interpreter (8 GB allocated); 0 ran.
    for n in (0, -3, 10**9, 2**70):
        with pytest.raises(rattle.ConfigError, match="state_points"):
            rattle.validate(FIG2, state_points=n)
    r = cli("validate", "--config", FIG2, "--state-points", "1000000000")
    assert r.returncode == 2 and "--state-points" in r.stderr and "1 to 100000" in r.stderr


def test_a_json_rattle_did_not_write_deletes_nothing(tmp_path):
    # H2: a user's PREFIX.json with a `files` list made a new set delete those files.
    (tmp_path / "data.json").write_text('{"files": ["data.csv", "data-raw.csv"]}')
    for n in ("data.csv", "data-raw.csv"):
        (tmp_path / n).write_text("the user's own\n")
    m = rattle.map(RL, **dict(SMALL, **{"map.x_points": 4, "map.y_points": 4}))
    m.save(tmp_path / "data")
    assert (tmp_path / "data.csv").read_text() == "the user's own\n"
    assert (tmp_path / "data-raw.csv").read_text() == "the user's own\n"
    # A file of rattle's own set, changed by hand since, is not its any more.
    (tmp_path / "data-class.npy").write_bytes(b"edited")
    rattle.bifurcation(FIG2, **{"sweep.points": 20, "method.backend": "cpu"}).save(tmp_path / "data")
    assert (tmp_path / "data-class.npy").read_bytes() == b"edited"
    assert not (tmp_path / "data-lyapunov.npy").exists()  # still rattle's: removed


def test_overrides_are_checked_as_the_command_line_checks_them():
    # M1: values for a parameter the command varies, and a key given twice, were dropped.
    cases = [
        (lambda: rattle.map(RL, R=0.55, **SMALL), ["R=0.55", "map.x"]),
        (lambda: rattle.bifurcation(FIG2, eta=1.3), ["eta=1.3", "sweep.param"]),
        (
            lambda: rattle.sensitivity(
                FIG2, **{"lambda": 0.05}, uncertain=["lambda=0.02+-0.005"]
            ),
            ["lambda=0.05", "uncertain"],
        ),
        (lambda: rattle.point(rattle.Config(FIG2).set("eta", 1.3), eta=1.4), ["both set"]),
    ]
    for call, words in cases:
        with pytest.raises(rattle.ConfigError) as e:
            call()
        assert all(w in str(e.value) for w in words), str(e.value)
    r = cli("bifurcation", "--config", FIG2, "--eta", "1.3", "--out", "/nonexistent/x")
    assert r.returncode == 2 and "sweep.param" in r.stderr


def test_each_command_checks_only_the_sections_it_reads():
    # M2: `point` refused run.tangent = "spectrum" and long samples with sweep messages.
    cpu = {"method.backend": "cpu", "run.transient_periods": 10}
    p = rattle.point(FIG2, **dict(cpu, **{"run.tangent": "spectrum", "run.sample_periods": 20}))
    assert p.lyapunov_spectrum is not None and len(p.lyapunov_spectrum) == 4
    r = cli("point", "--config", FIG2, *sets({"run.tangent": '"spectrum"', "run.sample_periods": 70000}), "--set", "run.transient_periods=0", "--backend", "cpu", "--json")
    assert r.returncode == 0, r.stderr
    p = rattle.point(FIG2, **dict(cpu, **{"run.sample_periods": 70000, "run.transient_periods": 0}))
    assert p.samples.shape[0] > 0


def test_the_risk_layer_is_among_the_layers(tmp_path):
    # M4: `.save()` wrote PREFIX-risk.npy, `.layers` had no `risk`.
    m = rattle.map(RL, **dict(SMALL, **{"map.risk": [0.02, 0.005]}))
    assert m.layers["risk"].shape == (32, 32)
    m.save(tmp_path / "m")
    np.testing.assert_array_equal(np.load(tmp_path / "m-risk.npy"), m.layers["risk"])
    assert set(m.layers) == {p.name[2:-4] for p in tmp_path.glob("m-*.npy")}


def test_python_values_become_the_toml_types_a_user_expects():
    # M8: values went through str(): '2024' became an integer, numpy bools strings.
    c = rattle.Config(FIG2)
    c.set("map.title", "2024").set("run.early_stop", np.bool_(True))
    c.set("eta", np.float32(1.5)).set("run.sample_periods", np.int64(10))
    c.set("initial.y", np.array([0.0, 0.0, 0.0, 0.0]))
    c.set("method.backend", "cpu").set("run.transient_periods", 10)
    assert rattle.point(c).cls
    with pytest.raises(rattle.ConfigError, match="map.title") as e:
        rattle.point(FIG2, **{"map.title": 5})
    assert "string" in str(e.value)
    with pytest.raises(rattle.ConfigError, match="run.sample_periods"):
        rattle.point(FIG2, **{"run.sample_periods": 2**70})
    with pytest.raises(rattle.ConfigError, match="map.title"):
        rattle.point(FIG2, **{"map.title": object()})
    # A string with quotes, backslashes and a newline stays that string.
    odd = 'a "b" \\ c\nd\x7f'
    m = rattle.map(RL, **dict(SMALL, **{"map.x_points": 2, "map.y_points": 2, "map.title": odd}))
    assert m.to_dict()["config"]["map"]["title"] == odd


def test_errors_keep_their_cause(tmp_path):
    # L1: "cannot read config /tmp" without the reason.
    with pytest.raises(rattle.ConfigError, match="not a regular file"):
        rattle.point(str(tmp_path))
    with pytest.raises(rattle.ConfigError, match="No such file"):
        rattle.point(str(tmp_path / "missing.toml"))


def test_progress_is_checked_up_front():
    # L6: progress=5 raised TypeError only once a long map had started.
    with pytest.raises(TypeError, match="progress"):
        rattle.map(RL, progress=5, **SMALL)


def test_notes_come_as_warnings():
    # L7: "model.l1 is ignored" under Coulomb friction was dropped.
    with pytest.warns(RuntimeWarning, match="model.l1 is ignored"):
        rattle.point(FIG2, l1=0.1, **{"method.backend": "cpu", "run.sample_periods": 10})
    with pytest.warns(RuntimeWarning, match="run.overlap is ignored by point"):
        rattle.point(FIG2, **{"run.overlap": 2, "method.backend": "cpu", "run.sample_periods": 10})


def test_the_memory_refusal_counts_one_start(monkeypatch):
    # L13: "with 0 start(s)" where the command line says 1.
    monkeypatch.setenv("RATTLE_MEMORY_LIMIT", str(64 << 20))
    with pytest.raises(rattle.TooLargeError) as e:
        rattle.map(RL, **{"map.x_points": 2048, "map.y_points": 2048})
    assert "with 1 start(s)" in str(e.value)


def test_integer_options_out_of_range_are_config_errors():
    # L14: OverflowError instead of ConfigError.
    u = ["R=0.6+-0.01"]
    for kw, name in [
        (dict(samples=-1), "samples"),
        (dict(seed=-1), "seed"),
        (dict(seed=2**40), "seed"),
        (dict(samples="many"), "samples"),
    ]:
        with pytest.raises(rattle.ConfigError, match=name):
            rattle.sensitivity(FIG2, uncertain=u, **kw)
    for kw, name in [(dict(points=-1), "points"), (dict(periods=2**70), "periods")]:
        with pytest.raises(rattle.ConfigError, match=name):
            rattle.bench(FIG2, backends=["cpu"], **kw)


def test_a_raising_callback_with_streams_prints_no_panic():
    # L3: with run.overlap >= 2 an interrupt printed "a stream's thread panicked" on stderr.
    code = (
        "import rattle\n"
        "class Stop(Exception): pass\n"
        "def cb(d, t): raise Stop()\n"
        "o = {'map.x_points': 128, 'map.y_points': 128, 'method.backend': 'cpu',\n"
        "     'run.overlap': 2, 'run.transient_periods': 200, 'run.sample_periods': 100}\n"
        "try:\n"
        f"    rattle.map({RL!r}, progress=cb, **o)\n"
        "except Stop:\n"
        "    print('stopped')\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "stopped" in r.stdout, r.stderr
    assert "panicked" not in r.stderr, r.stderr


def test_boundaries_are_the_command_lines(tmp_path):
    # Map.boundaries() locates what `rattle map --boundaries` writes: the same points, the same
    # curves, as arrays; Fig. 2's period doubling crosses lambda = 0.02 at 1.37059.
    fig2 = Path(FIG2).read_text().split("[sweep]")[0]
    cfg = tmp_path / "line.toml"
    cfg.write_text(
        fig2
        + '\n[map]\nx = "eta"\nx_from = 1.30\nx_to = 1.80\nx_points = 64\n'
        + 'y = "lambda"\ny_from = 0.0185\ny_to = 0.0215\ny_points = 4\n'
    )
    m = rattle.map(str(cfg), **{"method.backend": "cpu", "method.precision": "f64"})
    b = m.boundaries()
    r = cli("map", "--config", str(cfg), "--backend", "cpu", "--precision", "f64",
            "--boundaries", "--out", str(tmp_path / "l"))
    assert r.returncode == 0, r.stderr
    j = json.loads((tmp_path / "l-boundaries.json").read_text())
    np.testing.assert_array_equal(b["points"]["x"], [p["x"] for p in j["points"]])
    np.testing.assert_array_equal(b["points"]["type"], [p["type"] for p in j["points"]])
    np.testing.assert_array_equal(
        b["points"]["reason"], [p.get("reason", "") for p in j["points"]])
    assert len(b["curves"]) == len(j["curves"])
    for c, d in zip(b["curves"], j["curves"]):
        assert c["type"] == d["type"] and c["classes"] == d["classes"]
        np.testing.assert_array_equal(c["points"], np.asarray(d["points"]))
    pd = (b["points"]["type"] == "period_doubling") & b["points"]["located"]
    x, y = b["points"]["x"][pd], b["points"]["y"][pd]
    lo, hi = np.argmax(np.where(y < 0.02, y, -1)), np.argmin(np.where(y > 0.02, y, 1))
    eta = x[lo] + (0.02 - y[lo]) / (y[hi] - y[lo]) * (x[hi] - x[lo])
    assert abs(eta - 1.37059) < 1e-4, eta


# Named judged cells of the 128 x 128 R x lambda grid (tests/data/r_lambda_judged_*.csv, judged
# by an integrator that shares no code with rattle; tests/harness.rs runs them through the
# command line's library paths): (ix, iy, the judge's class).
JUDGED = [(27, 20, "period-5"), (59, 4, "chaotic"), (121, 83, "period-2")]
RL128 = str(ROOT / "tests" / "data" / "r_lambda_128.toml")


def test_named_judged_cells_get_the_judges_class_from_point_and_map():
    # The same point gets the same class from Python's point and from a 3 x 3 map centred on
    # it on the 128 x 128 grid's spacing (the centre cell decided as on the whole map: its four
    # neighbours are the grid's), and it is the judge's. The grid's axes are cell-centred.
    f64 = {"method.backend": "cpu", "method.precision": "f64"}
    step_r, step_l = (0.7 - 0.5) / 128, (0.1 - 0.0) / 128
    for ix, iy, judge in JUDGED:
        r, lam = 0.5 + (0.7 - 0.5) * (ix + 0.5) / 128, 0.0 + (0.1 - 0.0) * (iy + 0.5) / 128
        p = rattle.point(RL128, R=r, **{"lambda": lam}, **f64)
        m = rattle.map(
            RL128,
            **{
                "map.x_from": r - 1.5 * step_r,
                "map.x_to": r + 1.5 * step_r,
                "map.x_points": 3,
                "map.y_from": lam - 1.5 * step_l,
                "map.y_to": lam + 1.5 * step_l,
                "map.y_points": 3,
            },
            **f64,
        )
        code = -4 if judge == "chaotic" else int(judge.split("-")[1])
        assert p.cls == judge, (ix, iy, p.cls, judge)
        assert m.classes[1, 1] == code, (ix, iy, m.classes[1, 1], judge)


def test_ctrl_c_stops_a_long_look_and_the_boundaries_at_once():
    # M4: a chaotic point's long look (here up to 10^7 periods on the CPU) reported only at the
    # end of each look stage, so Ctrl-C took 4-11 s; L6: Map.boundaries() ran without looking
    # at Ctrl-C at all (1.4-3.1 s). Both now stop within an integrator period of the interrupt.
    def interrupted_within(f, after):
        timer = threading.Timer(after, _thread.interrupt_main)
        timer.start()
        t0 = time.perf_counter()
        try:
            with pytest.raises(KeyboardInterrupt):
                f()
        finally:
            timer.cancel()
        return time.perf_counter() - t0 - after

    late = interrupted_within(
        lambda: rattle.point(FIG2, eta=1.72, **{"run.look": 10**7, "method.backend": "cpu"}),
        1.0,
    )
    assert late < 0.5, late
    m = rattle.map(RL, **dict(SMALL, **{"map.x_points": 48, "map.y_points": 48}))
    t0 = time.perf_counter()
    m.boundaries()
    whole = time.perf_counter() - t0
    assert whole > 1.0, f"the boundaries took {whole:.2f} s: too short for the test to bite"
    late = interrupted_within(m.boundaries, 0.3)
    assert late < 0.5, late
    # The package still works afterwards, and the boundaries are whole again.
    assert rattle.point(FIG2, eta=1.5).cls == "period-1"
    assert len(m.boundaries()["points"]["x"]) > 0


def test_an_interrupt_stops_its_own_computation_only():
    # Round 7 M6: the interrupt was one flag for the whole library: a progress callback that
    # raised in one thread, or Ctrl-C in the main thread, made another thread's rattle.map raise
    # KeyboardInterrupt (and each start cleared the flag for all). Each computation now has its
    # own: the other thread's map completes, equal to the same map run alone.
    o = dict(SMALL, **{"map.x_points": 48, "map.y_points": 48})
    alone = rattle.map(RL, **o)
    got = {}

    def other():
        try:
            got["map"] = rattle.map(RL, **o)
        except BaseException as e:  # noqa: BLE001 - the test reports what it was
            got["error"] = e

    class Stop(Exception):
        pass

    def raising(done, total):
        raise Stop(done)

    t = threading.Thread(target=other)
    t.start()
    time.sleep(0.3)
    # A callback that raises in this thread, then Ctrl-C here, while the other map runs.
    with pytest.raises(Stop):
        rattle.map(RL, progress=raising, **o)
    timer = threading.Timer(0.3, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            rattle.map(RL, **dict(o, **{"map.x_points": 256, "map.y_points": 256}))
    finally:
        timer.cancel()
    still = t.is_alive()
    t.join()
    assert "error" not in got, got
    assert still, "the other map ended before both interrupts: too short for the test to bite"
    np.testing.assert_array_equal(got["map"].classes, alone.classes)


def test_a_cycle_longer_than_128_periods_is_named_from_python():
    # Issue 66: the period-558 cycle of tests/long_cycles.rs (judged there by the independent
    # reference: |mu| 0.3051) was `unresolved`; Python names it as the command line does, with
    # the cycle's own exponent (ln|mu| over its period) and the run's beside it.
    o = {"model.R": 0.8, "model.lambda": 0.02, "model.eta": 1.2441471571906355}
    p = rattle.point(FIG2, **o, **{"method.backend": "cpu"})
    assert p.cls == "period-558" and p.period == 558
    mu = abs(p.multipliers[0])
    assert abs(mu - 0.3051) < 2e-3, mu
    own = np.log(mu) * 1.2441471571906355 / (2 * np.pi * 558)
    assert abs(p.lyapunov - own) < 1e-9 and p.lyapunov_se == 0.0
    assert np.isfinite(p.run_lyapunov)
    r = cli("point", "--config", FIG2, "--json", "--backend", "cpu",
            *[a for k, v in o.items() for a in ("--set", f"{k}={v}")])
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["class"] == "period-558"
