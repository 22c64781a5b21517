"""`gcs fly --map` (issue 23) in a real headless browser: Debian's Chromium, driven
by Selenium through chromedriver, opens the page while a simulated flight runs
and sees the vehicles move, the base layer drawn from the plan (no request leaves
this machine), the outposts named, snapshots and losses. Skipped, with the
reason, where Chromium or its driver is absent (`.ci/run` installs them).

The server's documents are checked without a browser too."""

import json
import os
import shutil
import socket
import threading
import time
import urllib.request
from pathlib import Path

import pytest
from flown import problems_beside_guard

from gcs.cli import main
from gcs.livemap import parse_address
from gcs.sim import free_base_port

pytestmark = pytest.mark.timeout(300)

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
#: the flags the page is tested with: nothing but the page itself talks to the network
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu",
                  "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--no-first-run", "--disable-dev-shm-usage",
                  "--window-size=1400,900")
SCREENSHOT = os.environ.get("GCS_LIVEMAP_SCREENSHOT")   # where to keep the screenshot


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _post(url, body, timeout=2.0) -> int:
    """The HTTP status of a POST of JSON ``body``."""
    request = urllib.request.Request(url, data=body, method="POST",
                                     headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=timeout) as r:
            return r.status
    except urllib.error.HTTPError as exc:
        return exc.code


def _get(url, timeout=2.0):
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.status, r.headers.get("Content-Type"), r.read()


def _wait(predicate, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for {what}")


class Flying:
    """`gcs fly --sim 3 --map` in a thread; ``result`` is its exit status."""

    def __init__(self, plan_dir, out, port, speedup="25", kill="2@item12"):
        self.port, self.result = port, None
        argv = ["fly", str(plan_dir), "--sim", "3", "--speedup", speedup, "--lost-after", "2",
                "--sim-base-port", str(free_base_port(10, 3)), "--map", f"127.0.0.1:{port}",
                "-o", str(out)] + (["--kill", kill] if kill else [])
        self.thread = threading.Thread(target=lambda: setattr(self, "result", main(argv)),
                                       daemon=True)
        self.thread.start()
        self.url = f"http://127.0.0.1:{port}/"
        _wait(self._up, 60, "the live map to serve")

    def _up(self):
        try:
            return _get(self.url + "plan.json")[0] == 200
        except OSError:
            return False

    def join(self, timeout=200):
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "gcs fly did not end"
        return self.result


def test_parse_address():
    assert parse_address(None) == ("127.0.0.1", 8750)
    assert parse_address("") == ("127.0.0.1", 8750)
    assert parse_address("9000") == ("127.0.0.1", 9000)
    assert parse_address("0.0.0.0:8080") == ("0.0.0.0", 8080)
    with pytest.raises(ValueError, match="expected HOST:PORT"):
        parse_address("here:there")


def test_documents_without_a_browser(plan_dir, tmp_path):
    port = _free_port()
    fly = Flying(plan_dir, tmp_path / "flight", port, speedup="100", kill=None)
    status, kind, body = _get(fly.url + "plan.json")
    plan = json.loads(body)
    assert [o["name"] for o in plan["outposts"]] == ["hill"]
    assert plan["outposts"][0]["range_m"] == 2500.0
    (south, west), (north, east) = plan["base"]["bounds"]
    assert south < north and west < east
    assert len(plan["routes"]) == 3 and all(r["points"] for r in plan["routes"])
    assert {r["colour"] for r in plan["routes"]} == {"#1f77b4", "#ff7f0e", "#9467bd"}
    status, kind, png = _get(fly.url + "base.png")
    assert kind == "image/png" and png[:8] == b"\x89PNG\r\n\x1a\n"
    assert _get(fly.url)[2].startswith(b"<!DOCTYPE html>")
    assert b"Leaflet 1.9.4" in _get(fly.url + "leaflet/leaflet.js")[2]
    for bad in ("../__init__.py", "%2e%2e/__init__.py", ".hidden", "nope.js"):
        with pytest.raises(urllib.error.HTTPError):
            _get(fly.url + bad)
    # the operator's word on a battery: a vehicle of the flight, from this machine
    assert _post(fly.url + "swap", b'{"sysid": 2}') == 204
    assert [_post(fly.url + path, body) for path, body in
            (("swap", b'{"sysid": 99}'), ("swap", b"2"), ("swap", b"{}"),
             ("other", b'{"sysid": 2}'))] == [404, 400, 400, 404]
    states = []
    while fly.thread.is_alive():
        try:
            states.append(json.loads(_get(fly.url + "state.json")[2]))
        except OSError:
            break
        time.sleep(0.3)
    code = fly.join()
    report = json.loads((tmp_path / "flight" / "flight.json").read_text())
    assert problems_beside_guard(report) == [] and code == (0 if report["outcome"]["ok"] else 1)
    said = [e for e in report["events"] if e["event"].startswith("battery swap confirmed")]
    assert [(e["sysid"], e["event"]) for e in said] == \
        [(2, "battery swap confirmed by the operator (live map)")]
    assert not any(v["swap"] for s in states for v in s["vehicles"])    # one battery each
    moving = [s for s in states if any(v["position"] for v in s["vehicles"])]
    assert moving, "no state with positions"
    last = moving[-1]["vehicles"]
    assert {v["sysid"] for v in last} == {1, 2, 3}
    assert all(v["alt_amsl"] is not None for v in last)
    # the server stops with gcs fly
    with pytest.raises(OSError):
        _get(fly.url + "plan.json", timeout=1.0)


def test_map_port_in_use_is_bad_input(plan_dir, tmp_path, capsys):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        code = main(["fly", str(plan_dir), "--sim", "3", "--map", f"127.0.0.1:{port}",
                     "-o", str(tmp_path / "f")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1].startswith(f"gcs fly: error: --map: cannot serve on "
                                            f"127.0.0.1:{port}")


@pytest.fixture
def browser():
    if not CHROMIUM or not CHROMEDRIVER:
        pytest.skip("Chromium and chromedriver are not installed "
                    "(apt-get install chromium chromium-driver; .ci/run does)")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        pytest.skip("selenium is not installed (pip install -e '.[test]')")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    profile = Path(os.environ.get("TMPDIR", "/tmp")) / \
        f"gcs-chromium-{os.getpid()}-{time.time_ns()}"
    for flag in CHROMIUM_FLAGS + (f"--user-data-dir={profile}",):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"performance": "ALL", "browser": "ALL"})
    driver = webdriver.Chrome(service=Service(executable_path=CHROMEDRIVER), options=options)
    driver.set_page_load_timeout(60)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def _requested(driver) -> list:
    """Every URL the page asked for (Chrome's performance log)."""
    urls = []
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        if message.get("method") == "Network.requestWillBeSent":
            urls.append(message["params"]["request"]["url"])
    return urls


def test_vehicles_move_on_the_page(plan_dir, tmp_path, browser):
    port = _free_port()
    fly = Flying(plan_dir, tmp_path / "flight", port)
    browser.get(fly.url)
    _wait(lambda: browser.execute_script("return window.gcsMap && window.gcsMap.updates()"),
          30, "the page's first update")
    # the base layer is the plan's picture, loaded; outposts named beside them
    loaded = browser.execute_script(
        "const i = document.querySelector('img.base-layer'); return i && i.complete && "
        "i.naturalWidth")
    assert loaded and loaded > 100
    assert "hill (2.5 km range)" in browser.find_element("css selector", ".outpost-label").text

    def where():
        return browser.execute_script("return window.gcsMap.vehicles()")

    def pixels():
        out = {}
        for sysid in ("1", "2", "3"):
            found = browser.find_elements("css selector", f".vehicle-{sysid}")
            if found:
                r = found[0].rect
                out[sysid] = (r["x"], r["y"])
        return out

    first = _wait(lambda: (lambda v: v if all(v.get(s, {}).get("latlng") for s in "123")
                           else None)(where()), 60, "all three vehicles on the map")
    px0 = pixels()
    # vehicles move on the page: their markers change place, on the map and on screen
    moved = _wait(lambda: (lambda v: v if sum(v[s]["latlng"] != first[s]["latlng"]
                                              for s in "123") >= 2 else None)(where()),
                  60, "vehicles to move")
    px1 = pixels()
    assert sum(px0.get(s) != px1.get(s) for s in "123") >= 2, (px0, px1)
    assert all(moved[s]["track"] >= 2 for s in "123")
    # snapshots appear, the lost vehicle is marked, the re-plan is drawn
    _wait(lambda: sum(v["snapshots"] for v in where().values()) >= 3, 90, "snapshots")
    _wait(lambda: where()["2"]["lost"], 90, "vehicle 2 marked lost")
    _wait(lambda: browser.execute_script("return window.gcsMap.replans()") >= 1, 90,
          "the re-planned routes")
    rows = browser.find_elements("css selector", "#vehicles tbody tr")
    assert len(rows) == 3 and "lost" in rows[1].get_attribute("class")
    headers = [" ".join(h.text.split())
               for h in browser.find_elements("css selector", "#vehicles th")]
    assert "alt AMSL" in headers and "alt above home" in headers
    if SCREENSHOT:
        Path(SCREENSHOT).parent.mkdir(parents=True, exist_ok=True)
        browser.save_screenshot(SCREENSHOT)
    # nothing but this machine was asked for anything (no tiles, no fonts, no CDN)
    # (the browser's own chrome:// pages are not the network)
    requested = [u for u in _requested(browser) if u.startswith(("http:", "https:", "ws:",
                                                                 "wss:"))]
    assert any(u.endswith("/base.png") for u in requested)
    assert all(u.startswith(fly.url) for u in requested), \
        [u for u in requested if not u.startswith(fly.url)]
    assert fly.join() == 1                       # a vehicle was lost: exit status 1
