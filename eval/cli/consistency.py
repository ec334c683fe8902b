"""``poibench consistency [SCENARIO] [--suite NAME] [--frames N|all] [--runs M] [--seed S] [--fit-extents]``.

Monte Carlo NEES of the pipeline's covariances against the simulator's truth
(:mod:`eval.experiments.consistency`): prints the table (quantity, N, d, mean NEES, its chi-square 99%
interval, inside?) and writes ``consistency.json`` and ``consistency.png`` to ``--out``.
``--frames all`` runs each scenario to its end (what happens late in a run, such as the
T265's loop closures, is outside the first few hundred frames).
A SCENARIO (file or shipped name, default the built-in one) runs ``--runs`` times with seeds
S, S + 1, ...; ``--suite`` (repeatable) runs the first ``--runs`` scenarios of each suite with
their own seeds (or S, S + 1, ... when ``--seed`` is given: other mazes of the same kind; then
``--runs`` may exceed the suite's size, its scenarios taken again in turn with fresh seeds). ``--fit-extents``
also prints the 3-D types' centre offsets and extent spreads that would make their camera-frame
R consistent on these runs (:mod:`eval.experiments.extent_fit`), as ``--set`` settings.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

DEFAULT_FRAMES = 600
DEFAULT_RUNS = 2


def frame_count(text: str) -> int | None:
    """``--frames``: a whole number, or ``all`` (None: each run to its end)."""
    if text.strip().lower() == "all":
        return None
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of frames or 'all', got {text!r}") from None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "consistency",
        help="NEES of the pipeline's R, track Sigma and SLAM pose covariance against the truth",
        description="Run scenarios with their sensor noise on through the pipeline behind the oracle "
        "detector and compare the mean NEES (e^T P^-1 e) of each covariance with its chi-square 99% "
        "interval. Prints the table; writes consistency.json and consistency.png to --out.",
    )
    p.add_argument("scenario", nargs="?", help="scenario YAML file or shipped name (default: the built-in one)")
    p.add_argument(
        "--suite",
        action="append",
        help="run the first --runs scenarios of this suite (e.g. rrl-hard) instead; repeatable; with --seed, "
        "--runs may exceed the suite's size (its scenarios again, with fresh seeds)",
    )
    p.add_argument(
        "--frames",
        type=frame_count,
        default=DEFAULT_FRAMES,
        help=f"frames per run, or 'all': each run to its end (default {DEFAULT_FRAMES})",
    )
    p.add_argument("--runs", type=int, default=DEFAULT_RUNS, help=f"number of runs (default {DEFAULT_RUNS})")
    p.add_argument(
        "--seed",
        type=int,
        help="seed of the first run (default: the scenario's own; with --suite each scenario's own)",
    )
    p.add_argument(
        "--fit-extents",
        action="store_true",
        help="also fit the 3-D types' centre offset and extent spreads to these runs' errors",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a pipeline setting (slam.n_min=3) or a scenario setting (sensors.fps=15); repeatable",
    )
    p.add_argument("--out", default="consistency", help="output folder (default: ./consistency)")
    p.set_defaults(func=cmd_consistency)


def suite_runs(names: list[str], runs: int, seed: int | None, sim_sets: list[str]) -> list:
    """The scenarios ``--suite`` runs: the first ``runs`` of each suite, noise on, with their
    own seeds; with ``seed``, seeds seed, seed + 1, ... and, past a suite's size, its
    scenarios again in turn (new mazes of the same kind)."""
    from eval.experiments.consistency import ConsistencyError
    from eval.experiments.suites import load_suite
    from sim.scenario import apply_settings, with_noise

    scenarios = []
    for name in names:
        suite = load_suite(name)
        n = len(suite.scenarios)
        if runs > n and seed is None:
            raise ConsistencyError(
                f"--runs {runs}: suite {name!r} has {n} scenarios; give --seed to run more, "
                "its scenarios again with fresh seeds (new mazes of the same kind)"
            )
        picked = [
            with_noise(apply_settings(suite.build(suite.scenarios[i % n]), sim_sets), True) for i in range(runs)
        ]
        if seed is not None:
            picked = [apply_settings(sc, [f"seed={seed + i}"]) for i, sc in enumerate(picked)]
        scenarios += picked
    return scenarios


def cmd_consistency(args: argparse.Namespace) -> int:
    from eval.experiments.consistency import ConsistencyError, format_table, run_consistency, write_outputs
    from eval.trial.scenarios import resolve_scenario, split_settings
    from sim.scenario import apply_settings

    if args.frames is not None and args.frames < 1:
        raise ConsistencyError(f"--frames: expected a positive number of frames, got {args.frames}")
    if args.runs < 1:
        raise ConsistencyError(f"--runs: expected a positive number of runs, got {args.runs}")
    sim_sets, pipe_sets = split_settings(args.set)
    if args.suite is not None:
        if args.scenario is not None:
            raise ConsistencyError("give a SCENARIO or --suite, not both")
        scenarios = suite_runs(args.suite, args.runs, args.seed, sim_sets)
        title = "suite " + " + ".join(args.suite)
    else:
        base = resolve_scenario(args.scenario, None, args.set, "on")
        seed0 = base.seed if args.seed is None else args.seed
        scenarios = [apply_settings(base, [f"seed={seed0 + i}"]) for i in range(args.runs)]
        title = base.name
    t0, c0 = time.perf_counter(), time.process_time()
    result = run_consistency(
        scenarios,
        frames=args.frames,
        pipeline_sets=pipe_sets,
        progress=lambda s: print(f"consistency: running {s}", file=sys.stderr),
    )
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    sys.stdout.write(format_table(result.rows))
    extra = {}
    if args.fit_extents:
        from eval.experiments.extent_fit import fit_extents, fitted_settings, format_fits
        from poi.config import apply_overrides, load_config

        if not result.samples.extent:
            raise ConsistencyError("--fit-extents: no observation of a 3-D type in these runs")
        fits = fit_extents(result.samples.extent)
        sets = fitted_settings(fits, apply_overrides(load_config(), pipe_sets))
        sys.stdout.write("\n" + format_fits(fits) + "\n" + "\n".join(f"--set '{x}'" for x in sets) + "\n")
        extra["extent_fit"] = {"fits": [dataclasses.asdict(f) for f in fits], "settings": sets}
    meta = {
        "title": f"{title}, {len(scenarios)} run(s) x {'all' if args.frames is None else args.frames} frames",
        "scenario": title,
        "frames_per_run": "all" if args.frames is None else args.frames,
        "settings": args.set,
        **extra,
    }
    paths = write_outputs(result, Path(args.out), meta)
    print(
        f"{result.frames} frames in {wall:.0f} s wall, {cpu:.0f} s CPU; wrote {', '.join(str(p) for p in paths)}",
        file=sys.stderr,
    )
    return 0
