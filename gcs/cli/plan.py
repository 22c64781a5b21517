"""`gcs plan`: DEM and outposts in, hidden reduced-time coverage routes and mission files out."""

from common.fileio import check_output_dir
from gcs.cli.options import add_scenario_arguments, scenario_from_args

HELP = "plan hidden coverage routes for a UAV fleet and write the mission files"


def add_arguments(parser) -> None:
    add_scenario_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="DIR",
                        help="output directory (created; files in it are replaced atomically)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="dask scheduler (tcp://HOST:8786) to run the heavy stages on "
                             "(default: this machine; a local dask cluster on large areas)")


def run(args) -> int:
    scenario = scenario_from_args(args)   # option errors before any heavy import
    check_output_dir(args.output)
    from gcs.cli.views import plan_summary
    from gcs.plan_folder import write_plan_folder
    from gcs.progress import console, note_first_compile, stage_progress
    from planner.pipeline import plan_mission

    note_first_compile()
    with stage_progress() as progress:
        ctx, outcome = plan_mission(scenario, progress, scheduler=args.scheduler or "auto",
                                    log=lambda text: console.print(text, markup=False))
        _refuse_little(outcome.plan, scenario.min_area_pct)
        progress("write", 0.0)
        written = write_plan_folder(args.output, ctx, outcome)
        progress("write", 1.0)
    console.print(plan_summary(outcome.plan))
    for path, what in written:
        console.print(f"  {path}  [dim]{what}[/dim]")
    return 0


def _refuse_little(plan, min_pct) -> None:
    """InputError, before anything is written, when the plan plans less of the area
    of operations than ``min_pct`` (--min-area) asks for."""
    from common.errors import InputError
    from gcs.cli.views import planned_pct, why_unplanned

    pct = planned_pct(plan)
    if min_pct is None or pct is None or pct >= min_pct:
        return
    raise InputError("--min-area", f"the plan plans {pct:.1f} % of the area of operations, "
                                   f"less than {min_pct:g} %: {why_unplanned(plan)}")
