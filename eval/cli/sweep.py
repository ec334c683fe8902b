"""``poibench suite``, ``poibench sweep`` and ``poibench regress``: many trials at once."""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from eval.cli.args import RULES_HELP, positive_int, shard


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--workers", type=positive_int, default=1, help="trials at once (default 1)")
    p.add_argument("--backend", choices=["local", "ray"], default="local", help="process pool or Ray tasks")
    p.add_argument("--address", help="Ray cluster address (default: start a local Ray instance)")
    p.add_argument(
        "--detector",
        default="default",
        help="default, oracle, FILE.onnx, python:MODULE:CLASS or a poibench.detectors entry point name",
    )
    p.add_argument("--rules", help=f"{RULES_HELP} (default: each scenario's own rules, else ex3)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--cache",
        metavar="DIR",
        help="perception cache: each scenario is rendered and detected once, every trial replays it "
        "(default: $XDG_CACHE_HOME/poibench/perception or ~/.cache/poibench/perception)",
    )
    p.add_argument("--no-cache", action="store_true", help="render and detect every trial")


def _shard_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--shard",
        type=shard,
        metavar="I/N",
        help="run only shard I of N (0-based: the trials k with k %% N == I), into a folder of its own; "
        "join the N folders with poibench suite merge (a Slurm array or a Kubernetes indexed job, "
        "docs/guides/suites.md)",
    )


def check_shard(args) -> None:
    """A shard needs a folder of its own to merge; refuse ``--shard`` without ``--out``."""
    from eval.experiments.sweep import SweepError

    if args.shard is not None and not args.out:
        raise SweepError(f"--shard {args.shard}: needs --out, the shard's folder that poibench suite merge joins")


def cache_dir(args) -> str | None:
    """The perception cache folder ``--cache`` and ``--no-cache`` choose (None: no cache),
    checked before any trial: a folder this process can make and write in, and a valid
    ``$POIBENCH_CACHE_MAX_GB`` (a trial that cannot use the cache runs without it, so either
    mistake would otherwise go unsaid)."""
    from eval.cli.output import check_output_folder
    from eval.experiments.sweep import SweepError
    from eval.trial.perception_cache import default_cache_dir, max_cache_bytes

    if args.no_cache and args.cache:
        raise SweepError("--cache and --no-cache: choose one")
    if args.no_cache:
        return None
    folder = Path(args.cache) if args.cache else default_cache_dir()
    check_output_folder(folder, "--cache" if args.cache else "the perception cache")
    max_cache_bytes()
    return str(folder)


def register(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("suite", help="list or run the benchmark suites")
    ssub = s.add_subparsers(dest="suite_cmd", required=True)
    ls = ssub.add_parser("list", help="the shipped suites")
    ls.set_defaults(func=cmd_suite_list)
    r = ssub.add_parser("run", help="run a suite and print its table")
    r.add_argument("name", help="shipped suite name or suite file")
    r.add_argument(
        "--out",
        help="folder for trials.csv, funnel.csv, points.png and each trial's files (default: a temporary one)",
    )
    r.add_argument("--resume", action="store_true", help="continue a killed run in --out")
    r.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a pipeline or scenario setting for every trial, e.g. detector.label_model=L.onnx; repeatable",
    )
    _common(r)
    _shard_option(r)
    r.set_defaults(func=cmd_suite_run)
    m = ssub.add_parser(
        "merge",
        help="join the folders of a run's shards (--shard I/N) into the folder one run writes",
        description="Join the --out folders of every shard of one suite run, sweep or regress run "
        "(--shard I/N) into the folder a single run writes: trials.csv row for row in the run's order, "
        "then aggregate.csv, funnel.csv and the plot from the merged rows. Refuses shards of different "
        "runs or N, a shard missing or given twice, and a shard that did not finish.",
    )
    m.add_argument("shards", nargs="+", metavar="SHARD_DIR", help="a shard's --out folder (every one of 0..N-1)")
    m.add_argument("--out", required=True, help="the merged run's folder (new or empty)")
    m.set_defaults(func=cmd_suite_merge, locks_out=True)
    c = ssub.add_parser(
        "compare",
        help="rank finished suite runs (detectors or settings) on the same mazes, with intervals",
        description="Rank the --out folders of finished suite runs of one suite: mean score fraction "
        "with its 95% bootstrap interval over the mazes, the paired difference to the first, and the "
        "points each lost per type; writes compare.csv.",
    )
    c.add_argument(
        "runs",
        nargs="+",
        metavar="RUN",
        help="a finished suite run's --out folder: two or more, or one sweep's folder of two setting "
        "combinations or more",
    )
    c.add_argument("--out", default="compare.csv", help="the table as CSV (default compare.csv)")
    c.set_defaults(func=cmd_suite_compare, out_is_file=True)

    w = sub.add_parser("sweep", help="settings grid x suite scenarios, one row per trial")
    w.add_argument("--suite", required=True, help="shipped suite name or suite file")
    w.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2", help="values to sweep (repeatable)")
    w.add_argument("--out", required=True, help="folder for trials.csv, aggregate.csv and plots")
    w.add_argument("--resume", action="store_true", help="skip trials already finished in --out")
    _common(w)
    _shard_option(w)
    w.set_defaults(func=cmd_sweep)

    g = sub.add_parser("regress", help="run a suite and fail when the score drops below a baseline")
    g.add_argument("--suite", default="smoke", help="suite to run (default smoke)")
    g.add_argument("--baseline", required=True, help="baseline JSON file (written with --update)")
    g.add_argument(
        "--tolerance", type=float, default=0.02, help="allowed drop of the mean score fraction (default 0.02)"
    )
    g.add_argument("--update", action="store_true", help="write the baseline from this run")
    g.add_argument("--junit", help="write JUnit XML here")
    g.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="pipeline or scenario setting")
    g.add_argument("--out", help="folder for the trials (default: a temporary one)")
    g.add_argument(
        "--merged",
        metavar="DIR",
        help="judge this finished run (the poibench suite merge of its shards) against the baseline "
        "instead of running the suite",
    )
    _common(g)
    _shard_option(g)
    g.set_defaults(func=cmd_regress)

    t = sub.add_parser("tune", help="search pipeline thresholds for the best mean score on a suite (Optuna)")
    t.add_argument("--suite", default="smoke", help="suite to score on (default smoke)")
    t.add_argument(
        "--param",
        action="append",
        default=[],
        required=True,
        metavar="KEY=KIND:...",
        help="float:LOW:HIGH, int:LOW:HIGH, log:LOW:HIGH or choice:A,B",
    )
    t.add_argument(
        "--trials", type=positive_int, default=20, help="Optuna trials, each a whole suite run (default 20)"
    )
    t.add_argument("--seed", type=int, default=0, help="sampler seed (default 0)")
    t.add_argument("--out", required=True, help="folder for study.csv, best.yaml, trials.csv and plots")
    _common(t)
    t.set_defaults(func=cmd_tune)


def check_backend(args) -> None:
    """Refuse ``--address`` without ``--backend ray``: only Ray connects to a cluster."""
    from eval.experiments.sweep import SweepError

    if args.address is not None and args.backend != "ray":
        raise SweepError(f"--address {args.address}: a Ray cluster's address; it needs --backend ray")


def _spec(args, suite: str, grid):
    from eval.cli.run import check_detector
    from eval.experiments.sweep import SweepSpec

    check_detector(args.detector)
    check_backend(args)
    return SweepSpec(
        suite=suite,
        grid=grid,
        detector=args.detector,
        rules=args.rules,
        workers=args.workers,
        backend=args.backend,
        address=args.address,
        resume=getattr(args, "resume", False),
        cache=cache_dir(args),
        shard=getattr(args, "shard", None),
    )


def _run(spec, out: Path, quiet: bool):
    from eval.experiments.sweep import run_sweep
    from eval.progress import progress_bar

    bar = progress_bar(desc="trials", unit="trial", quiet=quiet)

    def progress(n: int, total: int) -> None:
        bar.total = total
        bar.update(n)

    try:
        return run_sweep(spec, out, progress)
    finally:
        bar.close()


def print_funnel(ok, per_type: dict) -> None:
    """The funnel summed over a run's trials (``per_type``, eval.experiments.sweep.summed_funnel)
    and its check: each trial's lost points add up to its max minus score (eval.scoring.funnel)."""
    from eval.scoring.funnel import format_funnel

    if "funnel_lost" not in ok or not len(ok):
        return
    lost = float(ok["funnel_lost"].astype(float).sum())
    max_minus = float((ok["max_score"].astype(float) - ok["score"].astype(float)).sum())
    print("\n" + format_funnel(per_type, lost, max_minus))
    bad = int((ok["funnel_check"] != "ok").sum())
    print(f"funnel check: lost = max - score in {len(ok) - bad} of {len(ok)} trials")


def cmd_suite_list(args) -> int:
    from eval.experiments.suites import load_suite, shipped_suites

    print(f"{'suite':10s} {'version':7s}  {'scenarios':9s}  what it holds")
    for name in shipped_suites():
        s = load_suite(name)
        print(f"{s.name:10s} {'v' + str(s.version):7s}  {len(s.scenarios):9d}  {s.description}")
    print("poibench suite run NAME runs one; each is eval/experiments/suites/NAME.yaml")
    return 0


# suite run's table: a format a column, decimals by unit (eval.experiments.table.format_table)
SUITE_RUN_FORMATS = {
    "scenario": "s",
    "seed": "d",
    "score": "g",
    "max_score": "g",
    "fraction": ".3f",
    "false_reports": "d",
    "misses": "d",
    "loc_err_median_m": ".3f",
    "pose_err_median_m": ".3f",
    "boxes_per_frame": ".2f",
    "wall_s": ".1f",
    "cpu_s_per_sim_s": ".3f",
    "error": "s",
}


def mean_line(ok, n_trials: int) -> str:
    """The mean score fraction of a run's finished trials with its 95% interval over the mazes
    (eval.experiments.sweep.mean_interval)."""
    import numpy as np

    from eval.experiments.sweep import BOOTSTRAP_SEED, mean_interval
    from eval.experiments.table import interval_text

    f = ok["fraction"].astype(float).to_numpy()
    if not len(f):
        return f"mean score fraction -: no trial of {n_trials} finished"
    lo, hi = mean_interval(f, rng=np.random.default_rng(BOOTSTRAP_SEED))
    interval = interval_text(lo, hi)
    how = "no interval from one maze" if interval == "-" else f"95% interval {interval}, bootstrap over the mazes"
    return f"mean score fraction {f.mean():.3f} ({how}) over {len(f)} of {n_trials} trials"


def print_suite_table(title: str, df, out: Path) -> None:
    """A suite run's table of trials, its mean with the interval and its funnel (``suite run``
    and ``suite merge`` print the same)."""
    from eval.experiments.sweep import summed_funnel
    from eval.experiments.table import format_table

    print(title)
    print(format_table(df, SUITE_RUN_FORMATS))
    ok = df[df["error"] == ""] if len(df) else df
    print(mean_line(ok, len(df)))
    print_funnel(ok, summed_funnel(ok, out))


def shard_note(args, out: Path, n_rows: int) -> str:
    """The line a shard ends with: what it ran and how its folder is joined to the others'."""
    from eval.text import counted

    return (
        f"shard {args.shard}: {counted(n_rows, 'trial')} in {out}; when all {args.shard.count} shards have "
        f"finished, join their folders with poibench suite merge DIR... --out MERGED"
    )


def cmd_suite_run(args) -> int:
    from eval.experiments.suites import load_suite
    from eval.experiments.sweep import parse_settings

    check_shard(args)
    suite = load_suite(args.name)
    settings = parse_settings(args.set)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        df, _ = _run(_spec(args, args.name, settings), out, args.quiet)
        print_suite_table(f"suite {suite.name} v{suite.version}: {suite.description}", df, out)
        if args.shard is not None:
            print(shard_note(args, out, len(df)))
        elif args.out:
            drawn = " points.png (each maze's lost points by cause)," if (out / "points.png").exists() else ""
            print(
                f"trials.csv, funnel.csv,{drawn} and each trial's files in {out}; "
                f"rank runs with poibench suite compare {out} OTHER"
            )
    return 0 if (df["error"] == "").all() else 1


def cmd_suite_merge(args) -> int:
    from eval.experiments.merge import merge_shards
    from eval.text import counted

    out = Path(args.out)
    df, agg = merge_shards(args.shards, out)
    suites = (
        sorted({f"{s} v{v}" for s, v in zip(df["suite"], df["suite_version"], strict=True)}) if len(df) else []
    )
    grid = [c for c in df.columns if c.startswith("set.")]
    if grid:
        print(agg.to_string(index=False))
    else:
        print_suite_table(f"suite {', '.join(suites) or '-'}: {len(args.shards)} shards merged", df, out)
    n = f"{counted(len(df), 'trial')} of {len(args.shards)} shards"
    drawn = ", points.png" if (out / "points.png").exists() else ""
    print(f"{n}: trials.csv, aggregate.csv, funnel.csv{drawn} in {out}")
    return 0 if (df["error"] == "").all() else 1


def cmd_suite_compare(args) -> int:
    from eval.experiments.compare import compare_runs, format_compare

    table = compare_runs(args.runs)
    print(format_compare(table))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(out, index=False)
    print(f"the table: {out}")
    return 0


def cmd_sweep(args) -> int:
    from eval.experiments.sweep import parse_grid
    from eval.text import counted

    grid = parse_grid(args.set)
    out = Path(args.out)
    df, agg = _run(_spec(args, args.suite, grid), out, args.quiet)
    print(agg.to_string(index=False))
    failed = int((df["error"] != "").sum())
    print(
        f"{counted(len(df), 'trial')} ({failed} failed): trials.csv, aggregate.csv, funnel.csv and plots in {out}"
    )
    if args.shard is not None:
        print(shard_note(args, out, len(df)))
    return 0 if failed == 0 else 1  # as suite run: a failed trial fails the command


def merged_rows(folder: Path, spec):
    """The rows of a finished run's folder (a merged one) made with ``spec``'s suite, settings,
    detector and rules; :class:`RegressError` (one line) for a folder of another run or none."""
    from eval.experiments.regress import RegressError
    from eval.experiments.sweep import read_rows
    from poi.core.loader import safe_load_file

    meta = folder / "sweep.yaml"
    if not meta.is_file() or not (folder / "trials.csv").is_file():
        raise RegressError(f"--merged {folder}: not a finished run's folder (no sweep.yaml or trials.csv)")
    doc = safe_load_file(meta, error=RegressError)
    if not isinstance(doc, dict) or "shard" in doc:
        raise RegressError(
            f"--merged {folder}: a shard, not a merged run; join every shard with poibench suite merge"
        )
    if doc.get("sweep") != spec.identity():
        raise RegressError(
            f"{meta}: that run had another suite, --set, detector or rules than this regress ({doc.get('sweep')})"
        )
    df = read_rows(folder / "trials.csv")
    if len(df) != doc.get("trials"):
        raise RegressError(
            f"--merged {folder}: {len(df)} of {doc.get('trials')} trials recorded; it did not finish"
        )
    return df


def cmd_regress(args) -> int:
    from eval.experiments.regress import (
        RegressError,
        baseline_doc,
        check_baseline_run,
        compare,
        load_baseline,
        write_junit,
    )
    from eval.experiments.suites import load_suite
    from eval.experiments.sweep import parse_settings, summed_funnel

    suite = load_suite(args.suite)
    base_path = Path(args.baseline)
    check_shard(args)
    grid = parse_settings(args.set)
    if args.shard is not None and (args.update or args.junit or args.merged):
        flag = "--update" if args.update else ("--junit" if args.junit else "--merged")
        raise RegressError(
            f"--shard {args.shard} with {flag}: a verdict or baseline needs every scenario; run the shards, "
            "join them with poibench suite merge, then poibench regress --merged DIR"
        )
    if args.shard is not None:  # the shard's trials only; the baseline is read when the merged run is judged
        df, _ = _run(_spec(args, args.suite, grid), Path(args.out), args.quiet)
        print(shard_note(args, Path(args.out), len(df)))
        return 0 if (df["error"] == "").all() else 1
    if args.merged:  # nothing runs: the settings of how trials run cannot take effect
        flags = {
            "--workers": args.workers != 1,
            "--backend ray": args.backend == "ray",
            "--address": args.address,
            "--cache": args.cache,
            "--out": args.out,
        }
        running = [flag for flag, given in flags.items() if given]
        if running:
            raise RegressError(
                f"{', '.join(running)} with --merged {args.merged}: it judges a finished run, none runs"
            )
    baseline = None if args.update else load_baseline(base_path)
    change = (
        None if baseline is None else check_baseline_run(baseline, base_path, args.detector, args.rules, args.set)
    )
    if args.junit:
        from eval.cli.output import check_output_file

        check_output_file(args.junit, "--junit")
    if args.merged:
        df, out = merged_rows(Path(args.merged), _spec(args, args.suite, grid)), Path(args.merged)
        funnel = summed_funnel(df[df["error"] == ""], out)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(args.out) if args.out else Path(tmp)
            df, _ = _run(_spec(args, args.suite, grid), out, args.quiet)
            funnel = summed_funnel(df[df["error"] == ""], out)
    if args.update:
        if (df["error"] != "").any():
            bad = df[df["error"] != ""].iloc[0]
            print(
                f"poibench regress: error: trial {bad.scenario} failed ({bad.error}); baseline not written",
                file=sys.stderr,
            )
            return 2
        doc = baseline_doc(df, suite, args.detector, args.rules, list(args.set))
        base_path.parent.mkdir(parents=True, exist_ok=True)
        base_path.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
        print(f"baseline written: {base_path} (mean score fraction {doc['mean_fraction']:.4f})")
        if args.junit:
            write_junit(Path(args.junit), df, None, args.tolerance, suite.name)
        return 0
    verdict = compare(df, baseline, args.tolerance, suite)
    print("\n".join(verdict.lines if change is None else [change, *verdict.lines]))
    print_funnel(df[df["error"] == ""], funnel)
    if args.junit:
        write_junit(Path(args.junit), df, baseline, args.tolerance, suite.name)
    return 0 if verdict.passed else 1


def cmd_tune(args) -> int:
    from eval.cli.run import check_detector
    from eval.experiments.tune import parse_param, run_tune
    from eval.progress import progress_bar

    params = [parse_param(p) for p in args.param]
    check_detector(args.detector)
    check_backend(args)
    with progress_bar(total=args.trials, desc="tune", unit="study trial", quiet=args.quiet) as bar:
        res = run_tune(
            args.suite,
            params,
            args.trials,
            args.out,
            seed=args.seed,
            detector=args.detector,
            rules=args.rules,
            workers=args.workers,
            backend=args.backend,
            address=args.address,
            progress=bar.update,
            cache=cache_dir(args),
        )
    best = res["best"]
    print(f"best mean score fraction {best['best_mean_fraction']:.4f} (trial {best['best_trial']}) with:")
    print("  " + " ".join(f"--set {s}" for s in best["settings"]))
    print(f"study.csv, best.yaml, trials.csv and plots in {args.out}")
    return 0
