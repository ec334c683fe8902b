"""The ``poibench`` command: one entry point for the simulator, the pipeline and the scorer.

Every user mistake (a malformed maze, scenario, rules or POI file, an unknown
setting, a model that does not fit) ends as one line on stderr,
``poibench <command>: error: <what and where>``, and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# Imported for its side effect: choose a headless GL backend before mujoco loads.
import sim.gl  # noqa: F401


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="poibench",
        description="Benchmark for the RoboCupRescue 'recognize objects' task: "
        "simulate a maze, run a perception pipeline, score its POI file.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for mod in _command_modules():
        mod.register(sub)
    return parser


def _command_modules() -> list:
    import importlib

    mods = []
    for name in (
        "eval.cli.sim",
        "eval.cli.run",
        "eval.cli.score",
        "eval.cli.replay",
        "eval.cli.datasets",
        "eval.cli.training",
        "eval.cli.photos",
        "eval.cli.evaluation",
        "eval.cli.quantize",
        "eval.cli.sweep",
        "eval.cli.consistency",
    ):
        try:
            mods.append(importlib.import_module(name))
        except ModuleNotFoundError as e:
            if e.name != name:
                raise
    return mods


def main(argv: list[str] | None = None) -> int:
    try:
        parser = build_parser()  # imports every command module (about 2 s): a Ctrl-C here is one line too
    except KeyboardInterrupt:
        print("poibench: interrupted", file=sys.stderr)
        return 130
    args = parser.parse_args(argv)
    try:
        _check_out(args)
        with _hold_out(args):
            return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print(f"{_command_name(args)}: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError, RuntimeError) as e:
        if not _is_user_error(e):
            raise
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        print(f"{_command_name(args)}: error: {msg}", file=sys.stderr)
        return 2


def _command_name(args: argparse.Namespace) -> str:
    """The command as typed, with its subcommand: ``poibench suite merge``, ``poibench run``."""
    sub = getattr(args, "suite_cmd", None) or getattr(args, "scenario_cmd", None)
    return f"poibench {args.command}" + (f" {sub}" if sub else "")


def _check_out(args: argparse.Namespace) -> None:
    """Refuse an unwritable ``--out`` before the command's start-up (a file for the commands
    that set ``out_is_file``, a folder for the others)."""
    from eval.cli.output import check_output_file, check_output_folder

    out = getattr(args, "out", None)
    if out is not None:
        (check_output_file if getattr(args, "out_is_file", False) else check_output_folder)(out)
        _refuse_out_over_an_input(args, out)


def _refuse_out_over_an_input(args: argparse.Namespace, out: str) -> None:
    """Refuse an ``--out`` that is one of the command's own input files (``--model``,
    ``--label-model``, ``--data``, ``--baseline``) or lies in a folder it reads (a compared
    run): writing it would destroy the input."""
    from eval.cli.output import OutputPathError

    target = Path(out).resolve()
    for option in ("model", "label_model", "data", "baseline", "runs", "images"):
        values = getattr(args, option, None)
        for value in values if isinstance(values, list) else [values]:
            if not isinstance(value, str) or not value or not Path(value).exists():
                continue
            given = Path(value).resolve()
            inside_a_run = option == "runs" and target.parent == given and target.exists()  # its trials.csv...
            if target == given or inside_a_run:
                flag = "--" + option.replace("_", "-") if option != "runs" else "a compared run"
                raise OutputPathError(f"--out {out}: it is (or is in) {flag} {value}; give another name")


def _hold_out(args: argparse.Namespace):
    """The lock on ``--out`` for the commands that set ``locks_out`` (those that write a trial's
    files: a second run into the same folder is refused while the first runs)."""
    import contextlib

    from eval.cli.output import hold_output_folder

    if getattr(args, "locks_out", False) and getattr(args, "out", None) is not None:
        return hold_output_folder(args.out)
    return contextlib.nullcontext()


def _is_user_error(e: BaseException) -> bool:
    """Our own error types (each a ValueError subclass with a one-line message) and file errors."""
    if isinstance(e, OSError):
        return True
    mod = type(e).__module__ or ""
    return mod.split(".")[0] in ("sim", "poi", "eval", "maze_assets")


if __name__ == "__main__":
    sys.exit(main())
