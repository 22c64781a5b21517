"""`gcs failsafes --restore FLIGHT_DIR`: put back the failsafe parameters that
`gcs fly --set-failsafes` changed, as its flight.json recorded them (each vehicle
by its system id), and read each back."""

import json
import sys
from pathlib import Path

from common.errors import InputError
from gcs.cli.options import add_connection_arguments, open_link

HELP = "restore the failsafe parameters gcs fly --set-failsafes changed (from flight.json)"


def add_arguments(parser) -> None:
    parser.add_argument("--restore", required=True, metavar="FLIGHT_DIR",
                        help="the output folder of the flight that set them (its flight.json "
                             "keeps each vehicle's previous values)")
    add_connection_arguments(parser)


def changes_of(flight_dir) -> dict:
    """sysid -> [change] that flight.json says --set-failsafes made; InputError for a
    folder without a readable flight.json."""
    from gcs.flight import FLIGHT_FILE

    path = Path(flight_dir) / FLIGHT_FILE
    try:
        document = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError("--restore", f"{path}: no such file (give the folder gcs fly "
                                      "wrote with -o)") from None
    except (OSError, ValueError) as exc:
        raise InputError("--restore", f"{path}: not a flight report ({exc})") from None
    failsafes = document.get("failsafes") if isinstance(document, dict) else None
    if not isinstance(failsafes, dict):
        raise InputError("--restore", f"{path}: records no failsafes (a flight of an older "
                                      "gcs, or one that never reached its vehicles)")
    return {int(sysid): f["set"] for sysid, f in failsafes.items() if f.get("set")}


def run(args) -> int:
    from gcs.flight.failsafes import restore

    changes = changes_of(args.restore)
    if not changes:
        print(f"{args.restore}: --set-failsafes changed nothing: nothing to restore")
        return 0
    link = open_link(args, set(changes))
    failed = 0
    try:
        for sysid, made in sorted(changes.items()):
            vehicle = link.vehicles.get(sysid)
            if vehicle is None:
                print(f"gcs failsafes: error: vehicle {sysid} did not answer: not restored",
                      file=sys.stderr)
                failed += 1
                continue
            wrong = restore(vehicle, made)
            said = ", ".join(f"{c['parameter']} = {c['previous']:g}" for c in made)
            if wrong:
                print(f"gcs failsafes: error: vehicle {sysid}: {', '.join(wrong)} did not "
                      "read back as restored", file=sys.stderr)
                failed += 1
            else:
                print(f"vehicle {sysid}: restored {said}")
    finally:
        link.close()
    return 1 if failed else 0
