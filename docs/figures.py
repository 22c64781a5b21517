"""Draw the pictures the README and the documentation show, from the code (`make figures`).

Runs `gcs demo` (the built-in terrain and outposts, 4 UAVs, k = 1, vehicle 2
shot down) into a scratch folder and keeps, made smaller (palette PNGs):

- ``docs/img/overview.png``: the plan's ``overview.png``;
- ``docs/img/view3d.png``: the plan's ``view3d.png``;
- ``docs/img/flight.png``: the flight's ``flight.png``;
- ``docs/img/livemap.png``: a headless Chromium's screenshot of ``gcs fly --map``
  flying the demo's plan on the simulator, once the lost vehicle and the
  re-planned routes are on the page (only where Chromium, chromedriver and
  selenium are installed: `make browser`, ``.[test]``; otherwise the picture
  already there is kept, and this says so);
- ``docs/img/coverage_methods.png``: ``benchmarks/coverage_methods.png`` as the
  last ``python -m benchmarks coverage`` drew it (copied, not run again: the
  benchmark takes many minutes).

    python docs/figures.py [--keep DIR]
"""

import argparse
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from PIL import Image

from gcs.sim import free_base_port

DOCS = Path(__file__).resolve().parent
IMG = DOCS / "img"
GCS = Path(sys.executable).with_name("gcs")
WIDTH = 1400            # the widest a picture is kept
COLOURS = 256           # palette size (octree keeps the few pure colours of routes and posts)


def shrink(src: Path, dst: Path, width: int = WIDTH) -> None:
    """``src`` at most ``width`` pixels wide, as a palette PNG (a fraction of the size)."""
    im = Image.open(src).convert("RGB")
    if im.width > width:
        im = im.resize((width, round(im.height * width / im.width)), Image.LANCZOS)
    im = im.quantize(colors=COLOURS, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_suffix(".tmp.png")
    im.save(tmp, optimize=True)
    tmp.replace(dst)
    print(f"  {dst.relative_to(DOCS.parent)}  {dst.stat().st_size // 1024} KB")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def livemap(plan_dir: Path, work: Path) -> Path | None:
    """A screenshot of ``gcs fly --map`` over the demo's plan, vehicle 2 lost; None
    (with the reason printed) where no headless browser can be driven."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver_bin = shutil.which("chromedriver")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        webdriver = None
    if not (chromium and driver_bin and webdriver):
        print("  live map: no Chromium / chromedriver / selenium here (make browser; "
              "pip install -e '.[test]'): docs/img/livemap.png left as it was")
        return None
    port = _free_port()
    flight = subprocess.Popen(
        [str(GCS), "fly", str(plan_dir), "--sim", "4", "--speedup", "20", "--kill", "2@item30",
         "--map", f"127.0.0.1:{port}", "--sim-base-port", str(free_base_port(count=4)),
         "-o", str(work / "flight-map")],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                 "--disable-background-networking", "--disable-dev-shm-usage",
                 "--window-size=1400,800", f"--user-data-dir={work / 'chromium'}"):
        options.add_argument(flag)
    browser = webdriver.Chrome(service=Service(executable_path=driver_bin), options=options)
    shot = work / "livemap.png"
    try:
        deadline = time.monotonic() + 30
        while True:   # the server starts before the first connection; give it a moment
            try:
                browser.get(f"http://127.0.0.1:{port}/")
                break
            except Exception:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:
            ready = browser.execute_script(
                "return window.gcsMap && window.gcsMap.replans() >= 1 && "
                "Object.values(window.gcsMap.vehicles()).some(v => v.lost)")
            if ready:
                time.sleep(8)     # the survivors a little way along their new routes
                break
            time.sleep(0.5)
        else:
            print("  live map: no re-plan shown within 4 minutes; left as it was")
            return None
        browser.save_screenshot(str(shot))
    finally:
        browser.quit()
        flight.terminate()
        flight.wait(timeout=30)
    return shot


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", metavar="DIR", help="run in DIR and keep it (default: "
                        "a temporary folder)")
    args = parser.parse_args()
    work = Path(args.keep or tempfile.mkdtemp(prefix="gcs-figures-"))
    try:
        print(f"gcs demo -o {work / 'demo'} ...")
        demo = subprocess.run([str(GCS), "demo", "-o", str(work / "demo"),
                               "--base-port", str(free_base_port(count=4))],
                              capture_output=True, text=True, check=False)
        if demo.returncode != 0:
            print(demo.stdout[-4000:] + demo.stderr[-4000:])
            print(f"gcs demo failed (exit status {demo.returncode}): no picture changed")
            return 1
        shrink(work / "demo" / "plan" / "overview.png", IMG / "overview.png")
        shrink(work / "demo" / "plan" / "view3d.png", IMG / "view3d.png")
        shrink(work / "demo" / "flight" / "flight.png", IMG / "flight.png")
        shrink(DOCS.parent / "benchmarks" / "coverage_methods.png", IMG / "coverage_methods.png")
        shot = livemap(work / "demo" / "plan", work)
        if shot:
            shrink(shot, IMG / "livemap.png")
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
