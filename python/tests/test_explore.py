"""`rattle explore` in a real browser (Debian's chromium, driven by selenium through
chromium-driver): the page's class layer is `rattle map`'s NPY, a clicked cell's panel is
`rattle point` at that cell, a dragged box recomputes that region, the exported command and
TOML reproduce the layer byte for byte; and the server refuses bad requests with the command
line's messages and stays up through a thousand rapid zooms. Without the browser these tests fail
(they are not skipped)."""

import json
import os
import re
import signal
import subprocess
import tempfile
from concurrent.futures import ThreadPoolExecutor
import time
import urllib.error
import urllib.request
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(os.environ.get("RATTLE_BIN", ROOT / "target" / "release" / "rattle"))
SHOTS = Path(os.environ.get("RATTLE_SHOTS", "/tmp"))
# The page's plotting area inside its canvas (src/serve/page.js, `M`).
LEFT, RIGHT, TOP, BOTTOM = 78, 16, 16, 52

CONFIG = """[model]
eta = 1.26
friction = "coulomb"
[method]
steps_per_period = 128
[run]
transient_periods = 200
sample_periods = 100
[map]
x = "R"
x_from = 0.5
x_to = 0.7
x_points = 24
y = "lambda"
y_from = 0.0
y_to = 0.1
y_points = 20
"""


def run(*args, cwd=None):
    r = subprocess.run([str(BIN), *args], capture_output=True, text=True, cwd=cwd, timeout=600)
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    assert BIN.exists(), f"build the command line first: {BIN}"
    d = tmp_path_factory.mktemp("explore")
    cfg = d / "map.toml"
    cfg.write_text(CONFIG)
    # The server's own scratch directory (random name, mode 0700) goes with it.
    scratch = lambda: set(Path(tempfile.gettempdir()).glob("rattle-explore-*"))
    before = scratch()
    p = subprocess.Popen([str(BIN), "explore", "--config", str(cfg), "--port", "0"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    m = re.search(r"http://127\.0\.0\.1:\d+/", line)
    assert m, f"no URL printed: {line!r}"
    yield {"url": m.group(0), "cfg": cfg, "dir": d, "proc": p}
    # Ctrl-C stops it as every command: the interrupt's exit code, nothing of its own left.
    p.send_signal(signal.SIGINT)
    assert p.wait(timeout=30) == 130
    assert scratch() <= before


@pytest.fixture(scope="module")
def browser():
    o = webdriver.ChromeOptions()
    for a in ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
              "--window-size=1300,900"]:
        o.add_argument(a)
    o.binary_location = "/usr/bin/chromium"
    d = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=o)
    yield d
    d.quit()


def settled(b, timeout=300):
    """Waits for the page's map at the configured grid, no request pending."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        s = b.execute_script("return window.rattle && window.rattle.map && "
                             "[window.rattle.map.coarse, window.rattle.busy]")
        if s and not s[0] and not s[1]:
            return b.execute_script("return window.rattle.map")
        time.sleep(0.2)
    raise AssertionError("the map did not arrive: " + b.find_element("id", "status").text)


def post(url, body, timeout=120):
    data = body if isinstance(body, bytes) else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=timeout) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def get(url, timeout=60):
    try:
        with urllib.request.urlopen(url, timeout=timeout) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def pixel(b, m, fx, fy):
    """Canvas offset (from its centre, as ActionChains moves) of the plot fraction (fx, fy),
    fy from the bottom."""
    w, h = b.execute_script("const c = document.getElementById('map'); return [c.width, c.height]")
    aw, ah = w - LEFT - RIGHT, h - TOP - BOTTOM
    x = LEFT + fx * aw
    y = TOP + ah - fy * ah
    return int(round(x - w / 2)), int(round(y - h / 2))


def test_the_page_is_rattle_map_and_point_and_zooms_and_exports(server, browser):
    b, url, d = browser, server["url"], server["dir"]
    t0 = time.time()
    b.get(url)
    m = settled(b)
    print(f"page to full map: {time.time() - t0:.2f} s")
    # The class layer the page received is `rattle map`'s NPY for the same config.
    run("map", "--config", str(server["cfg"]), "--boundaries", "--out", str(d / "cli"))
    npy = np.load(d / "cli-class.npy")
    assert npy.shape == (m["ny"], m["nx"]) == (20, 24)
    assert np.array_equal(npy.reshape(-1), np.array(m["class"])), "class layer differs"
    # The boundaries over it are `rattle map --boundaries`'s.
    b.find_element("id", "bounds").click()
    t0 = time.time()
    while b.execute_script("return window.rattle.bounds") is None:
        assert time.time() - t0 < 300, b.find_element("id", "status").text
        time.sleep(0.2)
    got = b.execute_script("return window.rattle.bounds.points")
    want = json.loads((d / "cli-boundaries.json").read_text())["points"]
    key = lambda p: (p["type"], p["x"], p["y"], tuple(p["classes"]))
    assert len(got) > 10 and sorted(map(key, got)) == sorted(map(key, want))
    st, csv_bytes = get(url + "api/export/boundaries.csv")
    assert st == 200 and csv_bytes == (d / "cli-boundaries.csv").read_bytes()
    b.save_screenshot(str(SHOTS / "explore-map.png"))
    # The SVG export is the view as shown: every cell under a rectangle of its legend colour,
    # every boundary curve drawn.
    svg = ET.fromstring(b.execute_script("return window.rattle.svg()"))
    ns = "{http://www.w3.org/2000/svg}"
    cells = [r for r in svg.iter(ns + "rect") if r.get("class") == "cells"]
    covered = np.zeros((m["ny"], m["nx"]), dtype=int)
    for r in cells:
        iy, a, z = int(r.get("data-row")), int(r.get("data-from")), int(r.get("data-to"))
        covered[iy, a:z] += 1
        for ix in range(a, z):
            legend = m["legend"][m["shown"][iy * m["nx"] + ix]]
            assert r.get("fill") == "rgb({},{},{})".format(*legend["rgb"]), (iy, ix)
    assert (covered == 1).all()
    curves = b.execute_script("return window.rattle.bounds.curves")
    lines = list(svg.iter(ns + "polyline")) + list(svg.iter(ns + "circle"))
    assert len(lines) == len(curves)

    # A click on a cell: the panel is `rattle point` at that cell's parameters.
    canvas = b.find_element("id", "map")
    ix, iy = 5, 3
    off = pixel(b, m, (ix + 0.5) / m["nx"], (iy + 0.5) / m["ny"])
    ActionChains(b).move_to_element_with_offset(canvas, *off).click().perform()
    t0 = time.time()
    while b.execute_script("return window.rattle.point") is None:
        assert time.time() - t0 < 120, b.find_element("id", "panel").text
        time.sleep(0.1)
    print(f"click to panel: {time.time() - t0:.2f} s")
    p = b.execute_script("return window.rattle.point")
    v = m["view"]
    assert p["x"] == pytest.approx(v["x_from"] + (v["x_to"] - v["x_from"]) * (ix + 0.5) / m["nx"], abs=0)
    assert p["y"] == pytest.approx(v["y_from"] + (v["y_to"] - v["y_from"]) * (iy + 0.5) / m["ny"], abs=0)
    cli = json.loads(run("point", "--config", str(server["cfg"]), "--set", f"R={p['x']!r}",
                         "--set", f"lambda={p['y']!r}", "--json").stdout)
    assert (p["report"]["class"], p["report"]["period"]) == (cli["class"], cli["period"])
    assert b.find_element("id", "panel").get_attribute("data-cls") == cli["class"]
    assert b.find_element("id", "nearest").text.startswith("nearest boundary: ")
    time.sleep(1)  # the figure
    b.save_screenshot(str(SHOTS / "explore-point.png"))

    # A dragged box: the region recomputed at the full grid, the view in the URL.
    a, c = pixel(b, m, 0.25, 0.25), pixel(b, m, 0.75, 0.6)
    ActionChains(b).move_to_element_with_offset(canvas, *a).click_and_hold() \
        .move_to_element_with_offset(canvas, *c).release().perform()
    t0 = time.time()
    while b.execute_script("return window.rattle.map.view.x_from") == v["x_from"]:
        assert time.time() - t0 < 60
        time.sleep(0.1)
    z = settled(b)
    zv = z["view"]
    span = v["x_to"] - v["x_from"], v["y_to"] - v["y_from"]
    assert zv["x_from"] == pytest.approx(v["x_from"] + 0.25 * span[0], abs=span[0] / 100)
    assert zv["x_to"] == pytest.approx(v["x_from"] + 0.75 * span[0], abs=span[0] / 100)
    assert zv["y_from"] == pytest.approx(v["y_from"] + 0.25 * span[1], abs=span[1] / 100)
    assert zv["y_to"] == pytest.approx(v["y_from"] + 0.6 * span[1], abs=span[1] / 100)
    assert (z["nx"], z["ny"]) == (24, 20) and len(z["class"]) == 24 * 20
    assert f"x_from={zv['x_from']}" in b.current_url.replace("%2E", ".") or "x_from=" in b.current_url
    b.save_screenshot(str(SHOTS / "explore-zoom.png"))

    # The exports: the command line and the TOML reproduce the layer byte for byte.
    st, command = get(url + "api/export/command")
    assert st == 200
    # Shell commands carrying the served configuration (a here-document), then the map on it.
    script = command.decode()
    assert script.startswith("cat > view.toml <<'RATTLE_CONFIG'\n")
    assert script.endswith("\nrattle map --config view.toml --out view\n")
    script = script.replace("\nrattle map ", f"\n'{BIN}' map ").replace("--out view\n", "--out again\n")
    r = subprocess.run(["bash", "-c", script], cwd=d, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    again = np.load(d / "again-class.npy")
    assert np.array_equal(again.reshape(-1), np.array(z["class"]))
    st, toml = get(url + "api/export/toml")
    assert st == 200
    (d / "view.toml").write_bytes(toml)
    run("map", "--config", str(d / "view.toml"), "--out", str(d / "fromtoml"))
    assert (d / "fromtoml-class.npy").read_bytes() == (d / "again-class.npy").read_bytes()
    st, npy_bytes = get(url + "api/export/class.npy")
    assert st == 200 and npy_bytes == (d / "again-class.npy").read_bytes()
    st, png = get(url + "api/export/png")
    assert st == 200 and png[:8] == b"\x89PNG\r\n\x1a\n"

    # Back: the first view again, from the URL.
    b.back()
    t0 = time.time()
    while b.execute_script("return window.rattle.map.view.x_from") != v["x_from"]:
        assert time.time() - t0 < 60
        time.sleep(0.1)
    assert settled(b)["class"] == m["class"]


def test_a_layer_of_a_large_map_is_coloured(server, browser):
    """A scalar layer of a map of 512 x 512 cells (more than 125k) gets its colours and legend:
    its range was taken by spreading the values into Math.min, which overflows the stack there
    (round 7 M2: the exponent layer left the class picture under the exponent's name)."""
    b = browser
    b.get(server["url"])
    settled(b)
    got = b.execute_script(
        """
        const n = 512 * 512, v = new Array(n);
        for (let i = 0; i < n; i++) v[i] = ((i % 977) - 488) / 4880;
        const m = {nx: 512, ny: 512, layers: [["lyapunov", v]]};
        try {
          const c = colours(m, "lyapunov");
          return [c.out.length, c.out[0], c.out[488], null];
        } catch (e) {
          return [0, null, null, String(e)];
        }
        """)
    assert got[3] is None, got[3]
    assert got[0] == 512 * 512
    # -0.1 (the lowest) and 0 (the middle of the diverging scale) get different colours.
    assert got[1] != got[2]


def test_bad_requests_get_the_command_lines_message_and_the_server_stays_up(server):
    url = server["url"]
    # The command line's message for the same bad view.
    cli = subprocess.run([str(BIN), "map", "--config", str(server["cfg"]), "--set",
                          "map.x_from=1.5", "--out", str(server["dir"] / "bad")],
                         capture_output=True, text=True)
    assert cli.returncode == 2
    said = cli.stderr.strip().removeprefix("error: ")
    view = {"x_from": 1.5, "x_to": 0.7, "y_from": 0.0, "y_to": 0.1}
    st, j = post(url + "api/map", {"view": view})
    assert st == 400 and j["error"] == said, (j, said)
    assert not (server["dir"] / "bad.json").exists()
    # A body over the limit gets the JSON error shape too (round 7 L4: plain text).
    st, j = post(url + "api/map", b'{"view": "' + b"x" * (3 << 20) + b'"}')
    assert st == 413 and "2 MB" in j["error"], j
    # An unknown key inside the view too (round 7 L4: it was accepted).
    for body in [b"{", b"[]", b'{"view": 3}', json.dumps({"view": view, "extra": 1}).encode(),
                 json.dumps({"view": {**view, "x_points": 3}}).encode()]:
        st, j = post(url + "api/map", body)
        assert st == 400 and j["error"].startswith("malformed request"), (body, j)
    st, j = post(url + "api/point", {"view": {**view, "x_from": 0.5}, "x": -1.0, "y": 0.05})
    assert st == 400 and "`model.R` = -1" in j["error"] and "[0, 1]" in j["error"], j
    # Nothing from a request names a file.
    for name in ["..%2F..%2Fetc%2Fpasswd", "view.json", "nope.npy"]:
        st, _ = get(url + "api/export/" + name)
        assert st in (404, 409), name
    # A thousand rapid views from clients that go away: the last view computes, the server is up.
    good = {"x_from": 0.5, "x_to": 0.7, "y_from": 0.0, "y_to": 0.1}

    def zoom(k):
        v = {**good, "x_to": 0.7 - 1e-4 * (k % 50)}
        try:
            post(url + "api/map", {"view": v, "coarse": True}, timeout=0.05)
        except Exception:
            pass  # the client went away

    def rss():
        status = Path(f"/proc/{server['proc'].pid}/status").read_text()
        return int(re.search(r"VmRSS:\s+(\d+) kB", status).group(1)) / 1024

    post(url + "api/map", {"view": good, "coarse": True}, timeout=300)
    before = rss()
    with ThreadPoolExecutor(max_workers=64) as pool:
        list(pool.map(zoom, range(1000)))
    st, j = post(url + "api/map", {"view": good, "coarse": True}, timeout=300)
    assert st == 200 and j["coarse"] and len(j["class"]) == j["nx"] * j["ny"]
    assert server["proc"].poll() is None
    # Nothing of the thousand requests stays behind (measured: 113 MB before, 128 MB after).
    print(f"server memory {before:.0f} MB before, {rss():.0f} MB after")
    assert rss() < before + 64
    st, _ = get(url + "api/base")
    assert st == 200


def test_progress_names_its_phase_and_never_claims_100_percent_early(server, browser):
    # Round 8 L5 and L6: the full map's progress was labelled "coarse picture: N%" (the coarse
    # picture's watcher went on polling), and it read 100% while the long look and the
    # recurrence search still ran. Every status the page shows during a load is recorded.
    b = browser
    b.get(server["url"])
    settled(b)
    b.execute_script(
        "window.seen = [];"
        "new MutationObserver(() => window.seen.push(document.getElementById('status').textContent))"
        ".observe(document.getElementById('status'), {childList: true, characterData: true, subtree: true});"
        "history.pushState(null, '', '#x_from=0.51&x_to=0.69&y_from=0.004&y_to=0.096');"
        "window.dispatchEvent(new PopStateEvent('popstate'));"
    )
    t0 = time.time()
    while not any(s.startswith("done") for s in b.execute_script("return window.seen")):
        assert time.time() - t0 < 300, b.execute_script("return window.seen")
        time.sleep(0.2)
    seen = b.execute_script("return window.seen")
    full = next(i for i, s in enumerate(seen) if re.match(r"\d+ x \d+ map", s))
    assert not any(s.startswith("coarse picture:") for s in seen[full:]), seen
    assert not any("100%" in s for s in seen), seen
    # The map takes long enough here for the page to have shown its progress at least once.
    assert any(re.search(r"map: (\d+%|looking)", s) for s in seen), seen


VOLUME = CONFIG.replace("eta = 1.26\n", "") + """z = "eta"
z_from = 1.2
z_to = 1.5
z_points = 3
"""


def test_a_volumes_slider_shows_each_slice_as_rattle_map_at_that_z(tmp_path, browser):
    """A volume config: the page shows one plane with a slider over the slices; each slice shown
    is `rattle map` at that z (the plane's config with the z value set), a dragged box keeps the
    slice, the exported command reproduces the slice shown, and a slice shown before comes back
    from the maps kept (only its coarse picture computed again)."""
    from selenium.webdriver.common.keys import Keys
    b, d = browser, tmp_path
    cfg = d / "vol.toml"
    cfg.write_text(VOLUME)
    plane = d / "plane.toml"
    plane.write_text(CONFIG.replace("eta = 1.26\n", ""))
    p = subprocess.Popen([str(BIN), "explore", "--config", str(cfg), "--port", "0"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        m = re.search(r"http://127\.0\.0\.1:\d+/", p.stdout.readline())
        assert m
        url = m.group(0)
        st, base = get(url + "api/base")
        base = json.loads(base)
        zs = base["z"]["values"]
        assert st == 200 and base["z"]["param"] == "eta" and len(zs) == 3
        b.get(url)
        slider = b.find_element("id", "z")
        assert b.find_element("id", "zpick").is_displayed()

        def cli(z, out):
            run("map", "--config", str(plane), "--set", f"model.eta={z!r}", "--out", str(d / out))
            return np.load(d / f"{out}-class.npy").reshape(-1)

        shown, timings = [], []
        for k in range(3):
            if k > 0:
                # The keyboard moves the slider one slice, as a user's arrow key does.
                slider.send_keys(Keys.ARROW_RIGHT)
                t0 = time.time()
                while b.execute_script("return window.rattle.map.view.z") != zs[k]:
                    assert time.time() - t0 < 120, b.find_element("id", "status").text
                    time.sleep(0.1)
            m = settled(b)
            assert m["view"]["z"] == zs[k]
            assert f"eta = {zs[k]}" in b.find_element("id", "zval").text
            assert f"z={zs[k]}" in b.current_url
            assert np.array_equal(cli(zs[k], f"s{k}"), np.array(m["class"])), f"slice {k}"
            shown.append(m["class"])
            timings.append(m["timings"])
            b.save_screenshot(str(SHOTS / f"explore-slice{k}.png"))
        # The slices differ (the test compares more than one picture).
        assert shown[0] != shown[2]
        # The exported command computes the slice shown.
        st, command = get(url + "api/export/command")
        script = command.decode().replace("\nrattle map ", f"\n'{BIN}' map ")
        r = subprocess.run(["bash", "-c", script], cwd=d, capture_output=True, text=True,
                           timeout=600)
        assert r.returncode == 0, r.stderr
        assert np.array_equal(np.load(d / "view-class.npy").reshape(-1), np.array(shown[2]))
        # A dragged box keeps the slice.
        canvas = b.find_element("id", "map")
        a, c = pixel(b, m, 0.2, 0.2), pixel(b, m, 0.7, 0.7)
        ActionChains(b).move_to_element_with_offset(canvas, *a).click_and_hold() \
            .move_to_element_with_offset(canvas, *c).release().perform()
        t0 = time.time()
        while b.execute_script("return window.rattle.map.view.x_from") == m["view"]["x_from"]:
            assert time.time() - t0 < 60
            time.sleep(0.1)
        assert settled(b)["view"]["z"] == zs[2]
        # Back to the first slice's full view: from the maps kept.
        b.back()
        t0 = time.time()
        while b.execute_script("return window.rattle.map.view.x_from") != m["view"]["x_from"]:
            assert time.time() - t0 < 60
            time.sleep(0.1)
        slider.send_keys(Keys.HOME)
        t0 = time.time()
        back = settled(b)
        while back["view"]["z"] != zs[0]:
            assert time.time() - t0 < 60
            time.sleep(0.1)
            back = settled(b)
        print(f"a kept slice back in {time.time() - t0:.2f} s")
        assert back["class"] == shown[0] and not back["coarse"]
        # The kept map itself, not a new run: its timings are the first run's.
        assert back["timings"] == timings[0]
        # A z outside the volume: refused with the range.
        st, e = post(url + "api/map", {"view": {**base["view"], "z": 1.7}})
        assert st == 400 and "[1.2, 1.5]" in e["error"], e
    finally:
        p.send_signal(signal.SIGINT)
        p.wait(timeout=30)
