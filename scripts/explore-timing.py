#!/usr/bin/env python3
"""Times `rattle explore` as a user meets it, in headless chromium (docs/explore.md):

1. the default map's page (configs/r_lambda.toml, 512 x 512): seconds from loading the page to
   its coarse first picture;
2. a 128 x 128 map of the same config: a dragged box recomputed at the full grid, against the
   wall of `rattle map` on the exported command line of that view (same grid and settings);
3. Fig. 2's settings (configs/fig2.toml, 500 + 200 periods at N = 256) on a 16 x 16 map: a
   clicked cell's panel, from the click to the panel.

Usage (from the repository root, after `cargo build --release`):
    python3 scripts/explore-timing.py [BIN]
"""

import re
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "target" / "release" / "rattle"
LEFT, RIGHT, TOP, BOTTOM = 78, 16, 16, 52


def start(*args):
    p = subprocess.Popen([str(BIN), "explore", "--port", "0", *args], stdout=subprocess.PIPE,
                         stderr=subprocess.DEVNULL, text=True)
    url = re.search(r"http://\S+/", p.stdout.readline()).group(0)
    return p, url


def browser():
    o = webdriver.ChromeOptions()
    for a in ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
              "--window-size=1300,900"]:
        o.add_argument(a)
    o.binary_location = "/usr/bin/chromium"
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=o)


def wait(b, js, timeout=1800):
    t0 = time.time()
    while not b.execute_script(js):
        if time.time() - t0 > timeout:
            raise SystemExit("timed out: " + js)
        time.sleep(0.05)
    return time.time() - t0


SETTLED = ("return window.rattle && window.rattle.map && !window.rattle.map.coarse && "
           "!window.rattle.busy")


def offset(b, fx, fy):
    w, h = b.execute_script("const c = document.getElementById('map'); return [c.width, c.height]")
    aw, ah = w - LEFT - RIGHT, h - TOP - BOTTOM
    return int(LEFT + fx * aw - w / 2), int(TOP + ah - fy * ah - h / 2)


def main():
    b = browser()
    try:
        # 1. The default map's coarse first picture.
        p, url = start("--config", str(ROOT / "configs" / "r_lambda.toml"))
        t0 = time.time()
        b.get(url)
        wait(b, "return window.rattle && window.rattle.map")
        print(f"default map (512 x 512): coarse picture {time.time() - t0:.2f} s after the page "
              "was asked for")
        p.terminate()
        p.wait()

        # 2. A 128 x 128 zoom against `rattle map` on its exported command line.
        sets = ["--set", "map.x_points=128", "--set", "map.y_points=128"]
        p, url = start("--config", str(ROOT / "configs" / "r_lambda.toml"), *sets)
        b.get(url)
        wait(b, SETTLED)
        canvas = b.find_element("id", "map")
        before = b.execute_script("return window.rattle.loads")
        t0 = time.time()
        ActionChains(b).move_to_element_with_offset(canvas, *offset(b, 0.3, 0.2)) \
            .click_and_hold().move_to_element_with_offset(canvas, *offset(b, 0.7, 0.6)) \
            .release().perform()
        wait(b, f"return window.rattle.loads > {before}")
        wait(b, SETTLED)
        zoom = time.time() - t0
        command = urllib.request.urlopen(url + "api/export/command").read().decode().split()
        with tempfile.TemporaryDirectory() as d:
            t1 = time.time()
            subprocess.run([str(BIN), *command[1:-1], f"{d}/view"], check=True,
                           capture_output=True)
            cli = time.time() - t1
        print(f"128 x 128 zoom: {zoom:.2f} s in the page, `rattle map` {cli:.2f} s "
              f"({zoom / cli:.2f} x)")
        p.terminate()
        p.wait()

        # 3. A click at Fig. 2's settings.
        p, url = start("--config", str(ROOT / "configs" / "fig2.toml"), "--set",
                       "map.x_points=16", "--set", "map.y_points=16")
        b.get(url)
        wait(b, SETTLED)
        canvas = b.find_element("id", "map")
        for fx in [0.53, 0.21, 0.84]:
            b.execute_script("window.rattle.point = null")
            t0 = time.time()
            ActionChains(b).move_to_element_with_offset(canvas, *offset(b, fx, 0.5)).click() \
                .perform()
            wait(b, "return window.rattle.point")
            pt = b.execute_script("return window.rattle.point")
            print(f"fig2 click at {pt['x_param']} = {pt['x']:.5f}: {pt['report']['class']}, "
                  f"panel in {time.time() - t0:.2f} s")
        p.terminate()
        p.wait()
    finally:
        b.quit()


main()
