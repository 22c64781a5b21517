"""The `gcs` command line: a thin layer, one module per command.

Each command module defines ``HELP`` (one line), ``add_arguments(parser)`` and
``run(args) -> int``. Bad input raises `common.errors.InputError`, which is
printed as one line with exit status 2.
"""

import argparse
import difflib
import importlib
import re
import sys
import warnings

from common.errors import ClusterError, InputError
from gcs import __version__

COMMANDS = ("exposure", "bases", "plan", "export", "upload", "download", "fly", "failsafes", "sim",
            "demo")


def _available_commands():
    for name in COMMANDS:
        try:
            yield name, importlib.import_module(f"gcs.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"gcs.cli.{name}":
                raise


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows a flag's default unless it is None (a scenario file's value or one the
    help text names itself)."""

    def _get_help_string(self, action):
        if action.default is None or "(default:" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


class _OneLineErrors(argparse.ArgumentParser):
    """A command line error is one line, ``gcs plan: error: ...``, and exit status 2,
    as every other bad input: not argparse's usage block above it (``--help``
    shows that)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


class _Parser(_OneLineErrors):
    """argparse without abbreviations (a flight tool does not guess which option was
    meant: ``--uav`` is not ``--uavs``), and an unknown option reported by its own
    command's parser, with the options it could have meant."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, allow_abbrev=False, **kwargs)
        self.commands = {}

    def error(self, message):
        if message.endswith("required: COMMAND"):  # a bare `gcs`
            message += " (gcs --help lists them)"
        super().error(message)

    def parse_args(self, args=None, namespace=None):
        parsed, extra = self.parse_known_args(args, namespace)
        if extra:
            command = self.commands.get(getattr(parsed, "command", None), self)
            command.error(_unrecognized(command, extra))
        return parsed


def _unrecognized(parser, extra) -> str:
    """'unrecognized arguments: ...', with "did you mean" for a misspelt option."""
    text = f"unrecognized arguments: {' '.join(extra)}"
    flags = [s for a in parser._actions for s in a.option_strings if s.startswith("--")]
    for word in extra:
        if word.startswith("--"):
            close = difflib.get_close_matches(word.split("=")[0], flags, n=1, cutoff=0.6)
            if close:
                return f"{text} (did you mean {' or '.join(close)}?)"
    return text


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="gcs",
        description="Plan hidden, reduced-time coverage missions for UAV fleets and fly them "
                    "on PX4 / ArduPilot vehicles.",
    )
    parser.add_argument("--version", action="version", version=f"gcs {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True,
                                parser_class=_OneLineErrors)
    for name, module in _available_commands():
        cmd = sub.add_parser(name, help=module.HELP, description=module.HELP,
                             formatter_class=_HelpFormatter, allow_abbrev=False)
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
        cmd._negative_number_matcher = NEGATIVE_VALUE
        parser.commands[name] = cmd
    return parser


#: what argparse takes for a negative number rather than an option: also lists such
#: as "-35.36,149.16,584", so southern and western coordinates work as typed
#: (argparse's own matcher knows only plain numbers; it is a private attribute,
#: present from Python 3.2 to 3.13)
NEGATIVE_VALUE = re.compile(r"^-\.?\d[\d.,eE+-]*$")


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warning(args.command)
        return _run(args)


def _one_line_warning(command):
    """Warnings reach the user as one line in their words, not a Python warning with
    its source line (which also breaks the progress bars)."""
    from gcs.progress import console

    def show(message, category, filename, lineno, file=None, line=None):
        console.print(f"gcs {command}: warning: {message}", markup=False, highlight=False)
    return show


def _run(args) -> int:
    try:
        return int(args._run(args) or 0)
    except InputError as exc:
        print(f"gcs {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except ClusterError as exc:
        print(f"gcs {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"gcs {args.command}: interrupted", file=sys.stderr)
        return 130
