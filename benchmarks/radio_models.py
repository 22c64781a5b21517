"""Radio models (issue 59): our link model against Longley-Rice ITM, on planned routes.

Our model (`planner.link.in_contact`, `Radio()`): a vehicle hears the ground station
when it is within 5 km and 60 % of the first Fresnel zone (915 MHz) of the ray from
the antenna is clear of the terrain, or within 100 m (slant) whatever the ground.
The other: the Irregular Terrain Model (Longley-Rice, version 1.2.2) in its
point-to-point mode, as the `itmlogic` package (PyPI, 1.2) implements it, on the
terrain profile between the antenna and the vehicle, its median basic transmission
loss turned into a verdict by a link budget (`BUDGETS`).

On each case (the demo plan, `gcs/data/demo.toml`, and seeded synthetic terrains
planned the same way with one base and one outpost) every vehicle's airborne
trajectory is sampled every `STEP_S` seconds of the fleet clock; at each sample
both verdicts are computed. Printed per case: the seconds each model takes per
sample (ours warm, one numba thread; ITM with building its profile), what ITM
flags as outside its validity, the loss ITM gives by what our model sees of the
ray (clear, Fresnel zone grazed, line of sight blocked), and per link budget: the
agreement rate, the confusion matrix (ours in/out of contact vs ITM's), each
vehicle's share of airborne time out of contact and longest silence by each model,
the disagreements by cause, and a few of them in detail. A summary of all cases
ends the run.

ITM settings (`ITM`): 915 MHz, vertical polarisation, antenna heights above the
ground 2 m (the plan's mast) and the vehicle's own height above the ground there
(at least 0.5 m, ITM's lower limit), average ground (relative permittivity 15,
conductivity 0.005 S/m: ITM's and SPLAT!'s "average ground"), climate 5
(continental temperate) with its surface refractivity 301 N-units (Hufford,
Longley & Kissick 1982, NTIA Report 82-100), scaled to the profile's mean elevation
(as ITM's own point_to_point does), variability mode 12 (mobile, point-to-point),
the median: 50 % of time, 50 % confidence. The profile: the terrain's bilinear
surface (the one our model reads) every `PROFILE_M` metres on the straight line
between the two, Earth curvature left to ITM.

    pip install -e '.[radio-models]'   # itmlogic, for this benchmark only
    .venv/bin/python -m benchmarks.radio_models               # plans the demo itself
    .venv/bin/python -m benchmarks.radio_models --plan DIR    # a saved plan folder
                                                              # (plan.json, terrain.tif)
"""

import math
import sys
import time
from pathlib import Path

import numpy as np

from planner.link import Antenna, Radio, in_contact

#: fleet seconds between two samples of a trajectory
STEP_S = 2.0
#: metres between two points of an ITM terrain profile (at most: the demo's cells are
#: 84 m, the synthetic terrains' 30 m)
PROFILE_M = 30.0
#: horizontal metres below which ITM is not run (a profile of no length): free-space
#: loss over the slant distance instead
MIN_ITM_M = 10.0
#: ITM's distances: below 1 km it flags its answer out of range (kwx 4)
ITM_MIN_KM = 1.0
ITM = dict(fmhz=915.0, ipol=1, eps=15.0, sgm=0.005, klim=5, ens0=301.0, mdvar=12)
#: (name, TX dBm, TX antenna dBi, RX antenna dBi, RX sensitivity dBm, fade margin dB).
#: TX power: SiK radios 20 dBm (100 mW), 27 or 30 dBm (1 W: RFD900x, SiK 1 W), from
#: the Holybro SiK Telemetry Radio V3 specification; sensitivity -121 dBm at 2 kbps
#: air rate (same source, the Si443x transceiver's figure); at the SiK default air
#: rate of 64 kbps an estimate: -121 dBm + 10 log10(64 / 2) = -106 dBm (noise
#: bandwidth scales with the rate); antennas: stock half-wave dipoles, 2 dBi each;
#: fade margin 10 dB (cable and connector losses are taken inside it)
BUDGETS = (("SiK 100 mW, 64 kbps", 20.0, 2.0, 2.0, -106.0, 10.0),
           ("1 W, 64 kbps", 30.0, 2.0, 2.0, -106.0, 10.0),
           ("1 W, 2 kbps", 30.0, 2.0, 2.0, -121.0, 10.0))
#: synthetic cases: (family, seed); terrains of SIDE x SIDE cells of 30 m
SYNTHETIC = (("hills", 3), ("ridges", 7), ("peaks", 5))
SIDE = 160
DEMO_TOML = Path(__file__).resolve().parent.parent / "gcs" / "data" / "demo.toml"
#: examples printed per kind of disagreement
EXAMPLES = 3
DB = 8.685890  # 20 / ln 10, as ITM writes it


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    itm = _itmlogic()
    import numba
    numba.set_num_threads(1)  # a shared machine; and ours per sample as ITM's: one core
    plan_dir = argv[argv.index("--plan") + 1] if "--plan" in argv else None
    _check_itm(itm)
    _print_settings()
    results = []
    for name, make in _cases(plan_dir):
        t = time.perf_counter()
        terrain, plan = make()
        print(f"\n== {name}: {terrain.shape[0]} x {terrain.shape[1]} cells of "
              f"{terrain.cell_size:.0f} m (planned in {time.perf_counter() - t:.0f} s) ==",
              flush=True)
        results.append((name, _case(itm, terrain, plan)))
    _summary(results)
    return results


# --- itmlogic -------------------------------------------------------------------------
def _itmlogic():
    """itmlogic's three entry points of the point-to-point mode, or exit saying how to
    install it."""
    try:
        from itmlogic.misc.qerfi import qerfi
        from itmlogic.preparatory_subroutines.qlrpfl import qlrpfl
        from itmlogic.preparatory_subroutines.qlrps import qlrps
        from itmlogic.statistics.avar import avar
    except ImportError:
        sys.exit("radio_models needs itmlogic, which the planner does not: "
                 "pip install -e '.[radio-models]'")
    return dict(qerfi=qerfi, qlrpfl=qlrpfl, qlrps=qlrps, avar=avar)


def itm_loss(itm, elev, spacing_m, hg, fmhz, ipol, eps, sgm, klim, ens0, mdvar,
             zsys=None, zr=0.0, zc=0.0):
    """ITM point-to-point: (basic transmission loss dB, free-space loss dB, prop) for
    the terrain profile ``elev`` (m AMSL, ``spacing_m`` apart, first point under the
    transmitter) and antenna heights ``hg`` (m above the ground at each end). ``zr``,
    ``zc``: standard normal deviates of time reliability and confidence (0: median).
    ``zsys``: elevation the refractivity is scaled to (None: the profile's mean)."""
    elev = [float(e) for e in elev]
    zsys = float(np.mean(elev)) if zsys is None else zsys
    wn, gme, ens, zgnd = itm["qlrps"](fmhz, zsys, ens0, ipol, eps, sgm)
    prop = {"fmhz": fmhz, "hg": [float(hg[0]), float(hg[1])], "ipol": ipol, "eps": eps,
            "sgm": sgm, "klim": klim, "ens0": ens0, "pfl": [len(elev) - 1, spacing_m] + elev,
            "kwx": 0, "wn": wn, "gme": gme, "ens": ens, "zgnd": zgnd, "gma": 157e-9,
            "lvar": 5, "klimx": 0, "mdvarx": mdvar}
    prop = itm["qlrpfl"](prop)
    free = DB * math.log(2.0 * wn * prop["dist"])
    extra, prop = itm["avar"](zr, 0.0, zc, prop)
    return free + extra, free, prop


def _check_itm(itm):
    """Our use of itmlogic against its own published test (Crystal Palace to Mursley,
    41.5 MHz, 77.8 km: 128.597 dB at 1 % and 139.741 dB at 99 % reliability, 50 %
    confidence, tests/test_p2p.py of the itmlogic repository)."""
    profile = [96, 84, 65, 46, 46, 46, 61, 41, 33, 27, 23, 19, 15, 15, 15, 15, 15, 15, 15,
               15, 15, 15, 15, 15, 17, 19, 21, 23, 25, 27, 29, 35, 46, 41, 35, 30, 33, 35,
               37, 40, 35, 30, 51, 62, 76, 46, 46, 46, 46, 46, 46, 50, 56, 67, 106, 83, 95,
               112, 137, 137, 76, 103, 122, 122, 83, 71, 61, 64, 67, 71, 74, 77, 79, 86, 91,
               83, 76, 68, 63, 76, 107, 107, 107, 119, 127, 133, 135, 137, 142, 148, 152,
               152, 107, 137, 104, 91, 99, 120, 152, 152, 137, 168, 168, 122, 137, 137, 170,
               183, 183, 187, 194, 201, 192, 152, 152, 166, 177, 198, 156, 127, 116, 107,
               104, 101, 98, 95, 103, 91, 97, 102, 107, 107, 107, 103, 98, 94, 91, 105, 122,
               122, 122, 122, 122, 137, 137, 137, 137, 137, 137, 137, 137, 140, 144, 147,
               150, 152, 159]
    got = [itm_loss(itm, profile, 77.8e3 / (len(profile) - 1), (143.9, 8.5), 41.5, 0, 15.0,
                    0.005, 5, 314.0, 11, zsys=0.0, zr=z)[0]
           for z in itm["qerfi"]([0.01, 0.99])]
    ok = abs(got[0] - 128.5969) < 1e-3 and abs(got[1] - 139.7413) < 1e-3
    print(f"itmlogic's own point-to-point test: {got[0]:.3f} dB and {got[1]:.3f} dB "
          f"(expected 128.597 and 139.741): {'reproduced' if ok else 'NOT REPRODUCED'}")
    if not ok:
        sys.exit("itmlogic is not driven as its own test drives it")


def _print_settings():
    print(f"ITM: {ITM['fmhz']:g} MHz, vertical polarisation, eps {ITM['eps']:g}, "
          f"sigma {ITM['sgm']:g} S/m, climate 5 (continental temperate), Ns "
          f"{ITM['ens0']:g} N-units, mode {ITM['mdvar']} (mobile, point-to-point), "
          f"median (50 % time, 50 % confidence); profile every <= {PROFILE_M:g} m")
    print(f"ours: Radio() = {Radio()}; samples every {STEP_S:g} s of airborne time")
    print("link budgets (max path loss = TX + antennas - sensitivity - fade margin):")
    for name, tx, gt, gr, sens, fade in BUDGETS:
        top = _max_loss((name, tx, gt, gr, sens, fade))
        free_km = 10 ** ((top - 20 * math.log10(ITM["fmhz"]) - 32.45) / 20)
        print(f"  {name:<20} TX {tx:g} dBm, {gt:g} + {gr:g} dBi, RX {sens:g} dBm, "
              f"margin {fade:g} dB -> {top:.0f} dB (free space would reach "
              f"{free_km:.0f} km)")


def _max_loss(budget) -> float:
    _, tx, gt, gr, sens, fade = budget
    return tx + gt + gr - sens - fade


# --- cases ----------------------------------------------------------------------------
def _cases(plan_dir):
    """[(name, () -> (terrain, plan))]: the demo, then the synthetic terrains."""
    def demo():
        if plan_dir:
            from planner.plan import TERRAIN_FILE, Plan
            from planner.terrain import read_terrain
            return read_terrain(Path(plan_dir) / TERRAIN_FILE), Plan.load(plan_dir)
        from planner.pipeline import plan_mission
        from planner.scenario import make_scenario, read_scenario
        scenario = make_scenario(read_scenario(DEMO_TOML), {}, source=str(DEMO_TOML))
        ctx, outcome = plan_mission(scenario, scheduler=None)
        return ctx.terrain, outcome.plan

    def synthetic(family, seed):
        def make():
            from benchmarks.cases import synthetic_case
            from planner.pipeline import plan_mission
            scenario, terrain, outposts = synthetic_case(family, seed, SIDE)
            ctx, outcome = plan_mission(scenario, terrain=terrain, outposts=outposts,
                                        scheduler=None)
            return ctx.terrain, outcome.plan
        return make

    name = f"demo plan ({plan_dir})" if plan_dir else "demo plan (gcs/data/demo.toml)"
    return [(name, demo)] + [(f"synthetic {f} seed {s} (base near a corner, outpost at the "
                              f"centre)", synthetic(f, s)) for f, s in SYNTHETIC]


# --- one case -------------------------------------------------------------------------
def _samples(terrain, plan):
    """(vehicle ids [n], times [n], flight index [n], xyz [n, 3]) of every airborne
    sample of every vehicle."""
    ids, times, flight_of, xyz = [], [], [], []
    for v in plan.vehicles:
        rows = np.asarray(v.trajectory, float)
        if not len(rows):
            continue
        x, y = terrain.from_lonlat(rows[:, 1], rows[:, 2])
        flights = [(s["takeoff_s"], s["landing_s"]) for s in v.sorties] or \
            [(v.takeoff_s, v.mission_time_s)]
        for k, (a, b) in enumerate(flights):
            t = np.arange(a, b, STEP_S)
            ids.append(np.full(len(t), v.id))
            times.append(t)
            flight_of.append(np.full(len(t), k))
            xyz.append(np.stack([np.interp(t, rows[:, 0], x), np.interp(t, rows[:, 0], y),
                                 np.interp(t, rows[:, 0], rows[:, 3])], axis=1))
    return (np.concatenate(ids), np.concatenate(times), np.concatenate(flight_of),
            np.concatenate(xyz))


def _antennas(plan):
    link = plan.metrics.get("link") or {}
    return [Antenna(float(a[0]), float(a[1]), float(a[2])) for a in link.get("antennas", [])]


def _profile(terrain, ax, ay, px, py):
    """(elevations, spacing m, horizontal distance m) on the line antenna -> point."""
    dist = math.hypot(px - ax, py - ay)
    n = max(2, int(math.ceil(dist / PROFILE_M)))
    s = np.linspace(0.0, 1.0, n + 1)
    elev = terrain.ground(ax + s * (px - ax), ay + s * (py - ay))
    return elev, dist / n, dist


def _fresnel_clearance(elev, spacing, z0, z1, wavelength, curv):
    """Least (ray - ground - Earth bulge) / first-Fresnel-zone radius over the profile's
    inner points: what our model compares with 0.6 (< 0: the line of sight is cut)."""
    n = len(elev) - 1
    d = n * spacing
    t = np.arange(1, n) / n
    if not len(t) or d <= 0:
        return math.inf
    from planner.exposure.los import EARTH_RADIUS_M
    gap = z0 + (z1 - z0) * t - elev[1:-1] - curv * d * d * t * (1 - t) / (2 * EARTH_RADIUS_M)
    radius = np.sqrt(wavelength * d * t * (1 - t))
    return float(np.min(gap / radius))


def _knife_edges(elev, spacing, z0, z1, wavelength, curv, depth=2):
    """Excess loss (dB) of the Deygout construction over at most three knife edges
    (the main edge, then one on each side of it; ITU-R P.526's J(nu)) on the
    profile with its Earth bulge: a textbook reference for what ITM says of
    obstructed rays, not a verdict of its own."""
    from planner.exposure.los import EARTH_RADIUS_M
    n = len(elev) - 1
    if spacing <= 0:
        return 0.0
    x = np.arange(n + 1) * spacing
    h = np.asarray(elev, float) + curv * x * (x[-1] - x) / (2 * EARTH_RADIUS_M)
    h[0], h[-1] = z0, z1

    def loss(i0, i1, level):
        if i1 - i0 < 2 or level == 0:
            return 0.0
        idx = np.arange(i0 + 1, i1)
        a, b = x[idx] - x[i0], x[i1] - x[idx]
        over = h[idx] - (h[i0] + (h[i1] - h[i0]) * a / (a + b))
        nu = over * np.sqrt(2 * (a + b) / (wavelength * a * b))
        k = int(np.argmax(nu))
        if nu[k] <= -0.78:
            return 0.0
        v = nu[k] - 0.1
        j = int(idx[k])
        return (6.9 + 20 * math.log10(math.sqrt(v * v + 1) + v) + loss(i0, j, level - 1)
                + loss(j, i1, level - 1))
    return loss(0, n, depth)


def _case(itm, terrain, plan):
    from planner.exposure.los import DEFAULT_CURVATURE_COEFF
    radio = Radio()
    antennas = _antennas(plan)
    ids, times, flight_of, xyz = _samples(terrain, plan)
    n = len(times)
    in_contact(terrain, antennas, radio, xyz[:2])  # compiled / loaded
    t = time.perf_counter()
    ours = in_contact(terrain, antennas, radio, xyz)
    ours_s = time.perf_counter() - t

    eyes = [(*terrain.from_lonlat(a.lon, a.lat), a.mast_m) for a in antennas]
    loss = np.full(n, np.inf)        # best antenna's ITM median loss
    free = np.full(n, np.nan)        # its free-space loss
    dist = np.full(n, np.nan)        # its horizontal distance
    clear = np.full(n, np.nan)       # its Fresnel clearance (our measure)
    agl = np.full(n, np.nan)
    beyond = np.zeros(n, bool)       # ITM: the terrain's horizons cut the path
    kwx = np.zeros(n, int)
    unrun = np.zeros(n, bool)        # too close for ITM (free space used)
    knife = np.zeros(n)              # Deygout knife-edge excess loss, for reference
    itm_s = 0.0  # profiles and ITM only, not the reference figures beside them
    for i, (px, py, pz) in enumerate(xyz):
        for ax, ay, mast in eyes:
            t = time.perf_counter()
            elev, spacing, d = _profile(terrain, ax, ay, px, py)
            if not np.isfinite(elev).all():
                continue
            z0, ground = elev[0] + mast, elev[-1]
            hg = max(pz - ground, 0.5)
            if d < MIN_ITM_M:
                slant = max(math.hypot(d, pz - z0), 1.0)
                value = fs = DB * math.log(2 * ITM["fmhz"] / 47.7 * slant)
                prop, flag = None, 0
            else:
                value, fs, prop = itm_loss(itm, elev, spacing, (mast, hg), **ITM)
                flag = prop["kwx"]
            itm_s += time.perf_counter() - t
            if value < loss[i]:
                loss[i], free[i], dist[i], agl[i], kwx[i] = value, fs, d, pz - ground, flag
                unrun[i] = prop is None
                beyond[i] = prop is not None and prop["dl"][0] + prop["dl"][1] < prop["dist"]
                clear[i] = _fresnel_clearance(elev, spacing, z0, max(pz, ground + 0.5),
                                              radio.wavelength_m, DEFAULT_CURVATURE_COEFF)
                knife[i] = _knife_edges(elev, spacing, z0, max(pz, ground + 0.5),
                                        radio.wavelength_m, DEFAULT_CURVATURE_COEFF)

    print(f"antennas {[(a.lat, a.lon, a.mast_m) for a in antennas]}; {n} samples of "
          f"{len(set(ids))} vehicles; antenna to vehicle {np.nanmin(dist) / 1e3:.2f}-"
          f"{np.nanmax(dist) / 1e3:.2f} km (median {np.nanmedian(dist) / 1e3:.2f}), "
          f"vehicle {max(np.nanmin(agl), 0):.0f}-{np.nanmax(agl):.0f} m above the ground")
    print(f"time per sample: ours {ours_s / n * 1e6:.1f} us (numba, 1 thread, warm), ITM "
          f"{itm_s / n * 1e3:.2f} ms (itmlogic, pure Python, with building its profile): "
          f"{itm_s / max(ours_s, 1e-9):.0f}x")
    link = plan.metrics.get("link") or {}
    if link:
        print(f"check: our share out of contact here {1 - ours.mean():.4f}, the plan's "
              f"metrics.link (1 s steps) {link['share']:.4f}")
    flags = {k: int(np.count_nonzero(kwx == k)) for k in range(5)}
    print(f"ITM's own flags: kwx 0 (fine) {flags[0]}, 1 (nearly out of range) {flags[1]}, "
          f"3 (a combination out of range) {flags[3]}, 4 (out of range) {flags[4]}; "
          f"{np.count_nonzero(dist < ITM_MIN_KM * 1e3)} samples within {ITM_MIN_KM:g} km "
          f"(ITM's lower limit), {np.count_nonzero(unrun)} within {MIN_ITM_M:g} m "
          f"(free space)")
    kind = _kinds(clear, dist, radio)
    excess = loss - free
    print("loss over free space by what our model sees of the ray: ITM median [10th, "
          "90th percentile], knife edges (Deygout, 3 edges) median, dB; ITM's total loss, "
          "share of samples it puts beyond the terrain's horizons, share it flags "
          "kwx >= 3 (\"results probably invalid\"):")
    for name in KINDS:
        k = kind == name
        if k.any():
            q = np.percentile(excess[k], [50, 10, 90])
            print(f"  {name:<34} {np.count_nonzero(k):5d}: ITM {q[0]:5.1f} [{q[1]:5.1f}, "
                  f"{q[2]:5.1f}], edges {np.median(knife[k]):5.1f}; total "
                  f"{np.median(loss[k]):5.1f} dB; beyond {np.mean(beyond[k]):4.0%}; "
                  f"kwx>=3 {np.mean(kwx[k] >= 3):4.0%}")
    rows = []
    for budget in BUDGETS:
        heard = loss <= _max_loss(budget)
        rows.append(_compare(budget, ids, times, flight_of, ours, heard, kind, dict(
            dist=dist, agl=agl, clear=clear, loss=loss, free=free, beyond=beyond,
            knife=knife, kwx=kwx, edges_heard=free + knife <= _max_loss(budget))))
    return dict(n=n, rows=rows, ours_us=ours_s / n * 1e6, itm_ms=itm_s / n * 1e3)


KINDS = ("within 100 m horizontally", "Fresnel clear (>= 0.6), <= 5 km",
         "Fresnel clear (>= 0.6), > 5 km", "grazing (LOS, < 0.6 clear)",
         "LOS blocked (diffraction)")


def _kinds(clear, dist, radio):
    kind = np.where(clear < 0, KINDS[4], np.where(clear < radio.fresnel, KINDS[3],
                    np.where(dist > radio.range_m, KINDS[2], KINDS[1])))
    kind[dist < radio.near_m] = KINDS[0]  # horizontal; our rule is slant (close enough)
    return kind


def _runs(flags, ids, flight_of):
    """Per vehicle: (share of samples flagged, longest run of flagged samples in s)."""
    out = {}
    for v in np.unique(ids):
        share = float(np.mean(flags[ids == v]))
        longest = 0
        for f in np.unique(flight_of[ids == v]):
            x = flags[(ids == v) & (flight_of == f)].astype(np.int8)
            edges = np.flatnonzero(np.diff(np.r_[0, x, 0]))
            if len(edges):
                longest = max(longest, int(np.max(edges[1::2] - edges[::2])))
        out[int(v)] = (share, longest * STEP_S)
    return out


def _compare(budget, ids, times, flight_of, ours, heard, kind, info):
    name = budget[0]
    agree = float(np.mean(ours == heard))
    both_in = np.count_nonzero(ours & heard)
    ours_only = np.count_nonzero(ours & ~heard)
    itm_only = np.count_nonzero(~ours & heard)
    both_out = np.count_nonzero(~ours & ~heard)
    print(f"\n-- budget {name}: max loss {_max_loss(budget):.0f} dB; agreement {agree:.1%}")
    print(f"   confusion (samples)      ITM in   ITM out\n"
          f"   ours in contact        {both_in:7d}   {ours_only:7d}\n"
          f"   ours out of contact    {itm_only:7d}   {both_out:7d}")
    a, b = _runs(~ours, ids, flight_of), _runs(~heard, ids, flight_of)
    print("   vehicle   out of contact: ours    ITM   longest silence: ours     ITM")
    for v in a:
        print(f"   {v:7d}   {a[v][0]:21.1%} {b[v][0]:6.1%} {a[v][1]:20.0f} s "
              f"{b[v][1]:6.0f} s")
    fleet_ours, fleet_itm = float(np.mean(~ours)), float(np.mean(~heard))
    print(f"   fleet     {fleet_ours:21.1%} {fleet_itm:6.1%} "
          f"{max(x[1] for x in a.values()):20.0f} s {max(x[1] for x in b.values()):6.0f} s")
    edges = info["edges_heard"]
    print(f"   for reference, free space + knife edges: out of contact "
          f"{np.mean(~edges):.1%}, agrees with ours {np.mean(edges == ours):.1%}, with "
          f"ITM {np.mean(edges == heard):.1%}")
    print("   disagreements by what our model sees of the ray "
          "(ours out / ITM in | ours in / ITM out):")
    for k in KINDS:
        m = kind == k
        x, y = np.count_nonzero(m & ~ours & heard), np.count_nonzero(m & ours & ~heard)
        if x or y:
            print(f"     {k:<34} {x:5d} | {y:5d}")
    for label, mask in (("ours out, ITM in", ~ours & heard), ("ours in, ITM out", ours & ~heard)):
        for k in KINDS:
            pick = np.flatnonzero(mask & (kind == k))
            if not len(pick):
                continue
            pick = pick[np.linspace(0, len(pick) - 1, min(EXAMPLES, len(pick))).astype(int)]
            print(f"   e.g. {label}, {k}:")
            for i in pick:
                print(f"     vehicle {ids[i]} t {times[i]:6.0f} s: {info['dist'][i]:5.0f} m "
                      f"away, {info['agl'][i]:4.0f} m AGL, Fresnel clearance "
                      f"{info['clear'][i]:+6.2f}, ITM {info['loss'][i]:5.1f} dB "
                      f"(free space {info['free'][i]:5.1f}, "
                      f"{info['loss'][i] - info['free'][i]:+5.1f}; edges "
                      f"{info['knife'][i]:+5.1f}; kwx {info['kwx'][i]})"
                      f"{', beyond horizons' if info['beyond'][i] else ''}")
    return dict(budget=name, agree=agree, ours_out=fleet_ours, itm_out=fleet_itm,
                longest_ours=max(x[1] for x in a.values()),
                longest_itm=max(x[1] for x in b.values()))


def _summary(results):
    print("\n== summary: share of airborne samples out of contact, agreement, longest "
          "silence ==")
    print(f"{'case':<52} {'budget':<20} {'ours':>6} {'ITM':>6} {'agree':>6} "
          f"{'longest ours':>12} {'ITM':>6}")
    for name, r in results:
        for row in r["rows"]:
            print(f"{name[:52]:<52} {row['budget']:<20} {row['ours_out']:6.1%} "
                  f"{row['itm_out']:6.1%} {row['agree']:6.1%} {row['longest_ours']:10.0f} s "
                  f"{row['longest_itm']:4.0f} s")
    print("time per sample: " + "; ".join(
        f"{name.split(' (')[0]}: ours {r['ours_us']:.1f} us, ITM {r['itm_ms']:.2f} ms"
        for name, r in results))


if __name__ == "__main__":
    main()
