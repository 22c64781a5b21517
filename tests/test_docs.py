"""The documentation does what it says (issue 35).

- The shell blocks of README.md and docs/tutorial.md (```bash / ```sh fences) run:
  every ``gcs ...`` line in them, in order, in one scratch folder, with smaller
  settings where the text's would be slow (`SMALL`), each exits 0 and writes the
  files the block's ``<!-- writes: ... -->`` comment names. A ``<!-- file: NAME
  -->`` comment above a fenced snippet (the outposts GeoJSON, the area polygon)
  writes it as NAME first; ``make`` and ``source`` lines are not run; a block
  marked ``<!-- not run: REASON -->`` (SITL, a vehicle) is reported skipped with
  that reason, and any other command in an unmarked block fails the test. The
  README's commands and the tutorial's are the same job: a command line run once
  is not run again. "Your own DEM" is the built-in one, cropped to the tutorial's
  36.48-36.57 N, 84.29-84.17 W and written as a geographic GeoTIFF, ``dem.tif``.
- Every error message docs/troubleshooting.md lists is still the code's.
- The site builds with ``mkdocs build --strict`` (skipped where mkdocs is not
  installed: ``make docs`` installs it).
"""

import ast
import re
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
RUN_DOCS = ("README.md", "docs/tutorial.md")
GCS = Path(sys.executable).with_name("gcs")

#: the tutorial's DEM: the built-in terrain cropped to S, W, N, E (degrees)
DEM_AREA = (36.48, -84.29, 36.57, -84.17)
#: what the doc test adds to the text's commands, so the whole file takes well under
#: a minute and a half on 2 cores: a smaller crop around the base, a short search,
#: and no separation (a simulated flight at 100x falls off the proven schedule on a
#: busy machine and the separation guard, rightly, holds it: exit status 1)
SMALL_AREA = "36.505,-84.26,36.545,-84.205"
SMALL = {
    "plan": ["--area", SMALL_AREA, "--time-budget", "0.3", "--separation", "0"],
    "exposure": ["--area", SMALL_AREA],
    "bases": ["--area", SMALL_AREA],
}
SIM_SPEEDUP = "100"
#: commands in run blocks that are not run (installing, activating)
NOT_RUN = ("make", "source")

MARKER = re.compile(r"<!--\s*(file|writes|not run):\s*(.*?)\s*-->")


@dataclass
class Block:
    doc: str
    line: int
    lang: str
    text: str
    markers: dict = field(default_factory=dict)

    @property
    def id(self):
        return f"{Path(self.doc).name}:{self.line}"


def blocks(doc: str) -> list:
    """The fenced blocks of ``doc`` with the marker comments just above each."""
    out, markers, lines = [], {}, (ROOT / doc).read_text().splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        m = MARKER.fullmatch(line.strip())
        if m:
            markers[m.group(1)] = m.group(2)
        elif line.startswith("```"):
            lang, start, body = line[3:].strip(), i + 1, []
            i += 1
            while not lines[i].startswith("```"):
                body.append(lines[i])
                i += 1
            out.append(Block(doc, start, lang, "\n".join(body), markers))
            markers = {}
        elif line.strip():
            markers = {}      # a marker belongs to the block right below it
        i += 1
    return out


def commands(block: Block) -> list:
    """The block's command lines, continuations joined, comments dropped."""
    joined = re.sub(r"\\\n\s*", " ", block.text)
    out = []
    for line in joined.splitlines():
        line = re.sub(r"\s+#.*$", "", line).strip()
        if line and not line.startswith("#"):
            out.append(line)
    return out


SHELL = [b for doc in RUN_DOCS for b in blocks(doc) if b.lang in ("bash", "sh")]
for _b in SHELL:     # a block of make / source lines only: said so, like a marked one
    if "not run" not in _b.markers and all(c.split()[0] in NOT_RUN for c in commands(_b)):
        _b.markers["not run"] = "make / source lines are not run by the doc test"
RUN = [b for b in SHELL if "not run" not in b.markers]
SKIPPED = [b for b in SHELL if "not run" in b.markers]
FILES = [b for doc in RUN_DOCS for b in blocks(doc) if "file" in b.markers]


def small(argv: list) -> list:
    """The text's command with the doc test's smaller settings."""
    from gcs.sim import free_base_port

    command = argv[1]
    argv = argv + SMALL.get(command, [])
    if command == "fly" and "--sim" in argv:
        n = int(argv[argv.index("--sim") + 1])
        if "--speedup" in argv:
            argv[argv.index("--speedup") + 1] = SIM_SPEEDUP
        # not the SITL ports the text's users have: the suite runs beside other flights
        argv += ["--sim-base-port", str(free_base_port(count=n))]
    return argv


def write_dem(path: Path) -> None:
    """The built-in DEM (3 arc-seconds, geographic) cropped to `DEM_AREA`, as a GeoTIFF."""
    import rasterio
    from matplotlib import cbook
    from rasterio.transform import Affine

    from planner.terrain.dem import SAMPLE_NAME

    with cbook.get_sample_data(SAMPLE_NAME) as dem:
        h = dem["elevation"].astype(np.float32)
        west, north = float(dem["xmin"]), float(max(dem["ymin"], dem["ymax"]))
        dx, dy = float(dem["dx"]), float(dem["dy"])
    s, w, n, e = DEM_AREA
    c0, c1 = int((w - west) / dx), int(np.ceil((e - west) / dx))
    r0, r1 = int((north - n) / dy), int(np.ceil((north - s) / dy))
    sub = h[r0:r1, c0:c1]
    transform = Affine(dx, 0.0, west + c0 * dx, 0.0, -dy, north - r0 * dy)
    with rasterio.open(path, "w", driver="GTiff", width=sub.shape[1], height=sub.shape[0],
                       count=1, dtype="float32", crs="EPSG:4326", transform=transform) as ds:
        ds.write(sub, 1)


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """Every run block's commands, in order, in one folder: {block id: [results]}."""
    work = tmp_path_factory.mktemp("docs")
    write_dem(work / "dem.tif")
    snippets = {}
    for b in FILES:
        name = b.markers["file"]
        assert snippets.setdefault(name, b.text) == b.text, \
            f"{b.id}: {name} differs from the snippet of the same name elsewhere"
        (work / name).write_text(b.text + "\n")
    done, results = {}, {}
    for b in RUN:
        results[b.id] = []
        for line in commands(b):
            argv = shlex.split(line)
            if argv[0] in NOT_RUN:
                continue
            assert argv[0] == "gcs", \
                f"{b.id}: {line!r} is not a gcs command: mark the block <!-- not run: why -->"
            key = tuple(argv)
            if key in done:
                results[b.id].append(done[key])
                continue
            argv = small(argv)
            t0 = time.monotonic()
            p = subprocess.run([str(GCS)] + argv[1:], cwd=work, capture_output=True,
                               text=True, timeout=180, check=False)
            r = {"line": line, "rc": p.returncode, "s": round(time.monotonic() - t0, 1),
                 "out": (p.stdout + p.stderr)[-3000:]}
            done[key] = r
            results[b.id].append(r)
        results[b.id + ":writes"] = [f for f in b.markers.get("writes", "").split()
                                     if not (work / f).is_file()
                                     or (work / f).stat().st_size == 0]
    return results


def test_the_docs_have_run_blocks():
    docs = {b.doc for b in RUN}
    assert docs == set(RUN_DOCS), f"no command blocks found in {set(RUN_DOCS) - docs}"
    assert any("gcs plan" in b.text for b in RUN if b.doc == "README.md")
    assert {b.markers["file"] for b in FILES} >= {"outposts.geojson"}


@pytest.mark.parametrize("block", RUN, ids=[b.id for b in RUN])
def test_block_runs(ran, block):
    for r in ran[block.id]:
        assert r["rc"] == 0, f"{r['line']}: exit status {r['rc']}\n{r['out']}"
    assert not ran[block.id + ":writes"], f"not written: {ran[block.id + ':writes']}"


@pytest.mark.parametrize("block", SKIPPED, ids=[b.id for b in SKIPPED])
def test_block_not_run(block):
    assert all(line.split()[0] in ("gcs", "arducopter", "px4") + NOT_RUN
               for line in commands(block))
    pytest.skip(f"{block.id}: {block.markers['not run']}")


def test_outposts_snippet_has_only_known_keys():
    import json

    from planner.exposure.outposts import KNOWN_PROPERTIES

    for b in FILES:
        if b.markers["file"] == "outposts.geojson":
            for f in json.loads(b.text)["features"]:
                assert set(f["properties"]) <= KNOWN_PROPERTIES


# --- the troubleshooting page's messages are the code's ------------------------------------

#: texts in the listed messages that come from Python, the OS or dask, not from us
FOREIGN = ("Address already in use", "Timed out trying to connect to", "Expecting value:",
           "line", "column", "char")
#: a word that is data (a file, a number, a position, a URL, a quoted name)
DATA = re.compile(r".*(\d|\.(tif|geojson|plan|waypoints|json|toml)\b|^'|'$|^-|^\[|\.\.\.).*")


def _code_strings() -> str:
    pieces = []
    for package in ("planner", "gcs", "missions", "autopilots", "common"):
        for path in (ROOT / package).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Constant) and isinstance(node.value, str):
                    pieces.append(" ".join(node.value.split()))
    return "\n".join(pieces)


def listed_messages() -> list:
    text = " ".join((ROOT / "docs" / "troubleshooting.md").read_text().split())
    return re.findall(r"`(gcs [a-z]+: error: [^`]+)`", text)


def phrases(message: str, code: str) -> tuple:
    """(longest phrase found, words not found): the message's words (its data and the
    source it names left out) in runs of two or more found in one of the code's strings."""
    body = message.split(": error: ", 1)[1]
    body = re.sub(r"^[^ ]+: ", "", body)          # the file or option the message names
    for foreign in FOREIGN:
        body = body.replace(foreign, " ")
    words = body.split()
    missing, longest, i = [], 0, 0
    while i < len(words):
        j = i + 1
        while j < len(words) and " ".join(words[i:j + 1]) in code:
            j += 1
        beside_data = any(0 <= k < len(words) and DATA.match(words[k]) for k in (i - 1, i + 1))
        if j - i == 1 and not DATA.match(words[i]) and not (beside_data and words[i] in code):
            missing.append(words[i])
        longest = max(longest, j - i)
        i = j
    return longest, missing, [w for w in words if not DATA.match(w)]


def test_troubleshooting_messages_are_the_codes():
    code = _code_strings()
    messages = listed_messages()
    assert len(messages) >= 25
    bad = {}
    for m in messages:
        longest, missing, words = phrases(m, code)
        # words between placeholders are not found as phrases; a reworded message is not
        # found at all
        if longest < min(3, len(words) - 1) or len(missing) > max(2, len(words) // 2):
            bad[m] = missing
    assert not bad, "messages on docs/troubleshooting.md that the code no longer has:\n" + \
        "\n".join(f"{m}\n  not found: {w}" for m, w in bad.items())


# --- the site ---------------------------------------------------------------------------------

def test_site_builds_strictly(tmp_path):
    try:
        import mkdocs  # noqa: F401
        import mkdocstrings  # noqa: F401
    except ImportError:
        pytest.skip("mkdocs / mkdocstrings not installed (`make docs` installs '.[docs]')")
    p = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q",
                        "-d", str(tmp_path / "site")], cwd=ROOT, capture_output=True,
                       text=True, timeout=300, check=False, env={"NO_MKDOCS_2_WARNING": "1",
                                                   "PATH": str(GCS.parent) + ":/usr/bin:/bin"})
    assert p.returncode == 0, p.stdout + p.stderr
    assert (tmp_path / "site" / "index.html").is_file()
    assert (tmp_path / "site" / "api" / "pipeline" / "index.html").is_file()


def test_planning_lists_every_scenario_key_in_its_section():
    """docs/planning.md's scenario files paragraph names each key of `SECTIONS` in its
    section, and examples/reference.toml has each (set or commented out)."""
    from planner.scenario import SECTIONS

    text = (ROOT / "docs/planning.md").read_text()
    para = " ".join(text[text.index("Sections: `[terrain]`"):].split("\n\n")[0].split())
    reference = (ROOT / "examples/reference.toml").read_text()
    aliases = {("outposts", "outposts"): "file", ("method", "method"): "method",
               ("outposts", "no_outposts"): None}
    for section, keys in SECTIONS.items():
        part = para[para.index(f"`[{section}]`") + 1:].split("`[")[0]   # to the next section
        for key in keys:
            name = aliases.get((section, key), key)
            if name is None:
                continue
            assert f"`{name}`" in part, (section, name)
            assert re.search(rf"^#? ?{name} =", reference, re.M), name
