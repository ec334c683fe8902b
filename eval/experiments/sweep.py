"""Many trials: the cross product of settings times a suite's scenarios, one row per trial.

``run_sweep(spec, out_dir)`` expands ``--set key=v1,v2`` items into a grid,
crosses it with the suite's scenarios and runs every trial (``eval.trial.run``,
no video) on a backend: a local process pool or Ray tasks. Each finished
trial is appended to ``trials.csv`` as one complete line, written whole and synced
before the next, so a killed sweep loses no finished row; ``--resume`` drops a
torn last line (a row cut short), then skips trials already recorded without
error (failed and torn ones are run again). A trial
that raises is recorded with its error and the sweep goes on. A run that ends rewrites
``trials.csv`` with each trial's last row in task order (:func:`write_in_task_order`), so
the same sweep gives the same file and aggregate whatever its workers and resumes.

With ``SweepSpec.shard`` (``--shard I/N``, :mod:`eval.experiments.shard`) only every N-th trial
of the task order runs, and ``sweep.yaml`` names the shard and every trial of the run, which
``poibench suite merge`` (:mod:`eval.experiments.merge`) joins the shards by.

With ``SweepSpec.cache`` (a folder) each scenario's perception is recorded once and
every trial replays it (:mod:`eval.trial.perception_cache`): the same rows, a fraction
of the CPU.

The aggregate (``aggregate.csv``) has, per setting combination, the number of
trials, the mean score fraction with its 95% interval (:func:`mean_interval`: a bootstrap
percentile interval over the scenarios, so it stays within [0, 1]), and the means of
false reports, misses, localisation errors and of the trials' CPU seconds (per simulated
second too: a trial's own, ``eval.trial.cost``; ``wall_s`` is the worker's wall time for
the trial); with one swept parameter a plot of the fraction against it, with two a
heatmap, each numeric axis in numeric order.
"""

from __future__ import annotations

import csv
import hashlib
import io
import itertools
import json
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from eval.experiments.shard import Shard
from eval.experiments.suites import Suite, load_suite
from eval.stats import bootstrap_means
from poi.core.loader import safe_load_file
from poi.core.poi_file import write_text_atomic

ROW_FIELDS_HEAD = ["trial", "suite", "suite_version", "scenario", "seed"]
ROW_FIELDS_TAIL = [
    "score",
    "max_score",
    "fraction",
    "false_reports",
    "misses",
    "loc_err_median_m",
    "loc_err_p90_m",
    "pose_err_median_m",
    "pose_err_p90_m",
    "frames",
    "wall_s",
    "cpu_s",
    "cpu_s_per_sim_s",
    "boxes_per_frame",
    "funnel_lost",
    "funnel_check",
    "error",
    "complete",
]
SET_PREFIX = "set."
FUNNEL_LINES = "funnel.jsonl"  # each trial's per-type funnel, a JSON line a trial (funnel.csv sums them)


class SweepError(ValueError):
    """A sweep cannot run as asked (one line)."""


def split_values(text: str) -> list[str]:
    """Comma-separated values, commas inside brackets or braces kept.

    >>> split_values("4,9,16")
    ['4', '9', '16']
    >>> split_values("[0, 1],[2, 3]")
    ['[0, 1]', '[2, 3]']
    """
    out, depth, cur = [], 0, ""
    for ch in text:
        if ch in "[{(":
            depth += 1
        elif ch in "]})":
            depth -= 1
        if ch == "," and depth == 0:
            out.append(cur.strip())
            cur = ""
        else:
            cur += ch
    out.append(cur.strip())
    if any(v == "" for v in out):
        raise SweepError(f"empty value in {text!r}")
    return out


def parse_grid(items: list[str]) -> list[tuple[str, list[str]]]:
    """``key=v1,v2`` items -> [(key, [v1, v2])], keys unique, in the given order."""
    return _parse_set(items, split_values, "key=value[,value...]")


def parse_settings(items: list[str]) -> list[tuple[str, list[str]]]:
    """``key=value`` items, one value each (commas kept: ``[0, 1]`` is one value) -> a grid of one
    combination, keys unique, in the given order (``suite run --set``, ``regress --set``)."""
    return _parse_set(items, lambda value: [value], "key=value")


def _parse_set(items: list[str], values_of, expected: str) -> list[tuple[str, list[str]]]:
    grid: list[tuple[str, list[str]]] = []
    for item in items:
        if "=" not in item:
            raise SweepError(f"--set {item!r}: expected {expected}")
        key, values = item.split("=", 1)
        key = key.strip()
        if any(k == key for k, _ in grid):
            raise SweepError(f"--set {key}: given twice")
        try:
            grid.append((key, values_of(values)))
        except SweepError as e:
            raise SweepError(f"--set {key}: {e}") from None
    return grid


def combinations(grid: list[tuple[str, list[str]]]) -> list[dict[str, str]]:
    """The cross product of the grid, first key slowest.

    >>> combinations([("a", ["1", "2"]), ("b", ["x", "y"])])
    [{'a': '1', 'b': 'x'}, {'a': '1', 'b': 'y'}, {'a': '2', 'b': 'x'}, {'a': '2', 'b': 'y'}]
    """
    keys = [k for k, _ in grid]
    return [dict(zip(keys, vals, strict=True)) for vals in itertools.product(*[v for _, v in grid])]


@dataclass(kw_only=True)
class TrialTask:
    """Everything a worker needs to run one trial (plain data, picklable)."""

    trial: str
    suite: str
    suite_version: int
    scenario_name: str
    scenario_yaml: str
    seed: int
    settings: dict[str, str]
    pipeline_sets: list[str]  # the pipeline part of ``settings``, as key=value items
    detector: str
    rules: str
    out_dir: str
    cache: str | None = None  # perception cache folder (eval.trial.perception_cache); None: every trial in full


@dataclass(kw_only=True)
class SweepSpec:
    suite: str
    grid: list[tuple[str, list[str]]] = field(default_factory=list)
    detector: str = "default"
    rules: str | None = None  # None: each scenario's own, else ex3 (eval.scoring.rules.trial_rules)
    workers: int = 1
    backend: str = "local"
    address: str | None = None
    resume: bool = False
    keep_trials: bool = True  # keep each trial's folder (pois.csv, score.json, map.png)
    cache: str | None = None  # perception cache folder; None: render and detect every trial
    shard: Shard | None = None  # run only this shard's trials (eval.experiments.shard); None: all

    def identity(self) -> dict:
        """What must match for --resume to continue a sweep."""
        return {
            "suite": self.suite,
            "grid": [[k, v] for k, v in self.grid],
            "detector": self.detector,
            "rules": self.rules,
        }


def trial_id(scenario: str, settings: dict[str, str]) -> str:
    """A short stable id of a (scenario, settings) pair."""
    text = json.dumps([scenario, sorted(settings.items())])
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def _set_error(e: Exception) -> str:
    """A setting's error as one ``--set`` line (its message once, whether or not it names --set)."""
    msg = str(e)
    return msg if msg.startswith("--set") else f"--set: {msg}"


def make_tasks(suite: Suite, spec: SweepSpec, out_dir: Path) -> list[TrialTask]:
    """Grid x scenarios, settings outer, scenarios inner; scenario settings applied to the scenario."""
    from eval.scoring.rules import RulesError, load_rules, trial_rules
    from eval.trial.pipeline_config import check_trial_settings
    from eval.trial.scenarios import split_settings
    from poi.config import ConfigError
    from poi.detectors import DetectorConfigError
    from sim.scenario import ScenarioError, apply_settings

    tasks = []
    scoring: dict[str, str] = {}  # rules name -> its scoring ("points", "map_error"), each loaded once
    for combo in combinations(spec.grid) or [{}]:
        items = [f"{k}={v}" for k, v in combo.items()]
        sim_sets, pipe_sets = split_settings(items)
        try:
            # a setting that cannot take effect in a trial is refused here, not recorded in every row
            check_trial_settings(pipe_sets, spec.detector)
        except (ConfigError, DetectorConfigError) as e:
            raise SweepError(_set_error(e)) from None
        for entry in suite.scenarios:
            sc = suite.build(entry)
            try:
                sc = apply_settings(sc, sim_sets) if sim_sets else sc
            except ScenarioError as e:
                raise SweepError(_set_error(e)) from None
            rules = trial_rules(spec.rules, sc.rules)
            if rules not in scoring:
                try:
                    scoring[rules] = load_rules(rules).scoring
                except RulesError as e:
                    raise SweepError(f"{entry.name}: rules {rules}: {e}") from None
            if scoring[rules] != "points":
                given = "--rules" if spec.rules else f"scenario {entry.name}'s own rules"
                raise SweepError(
                    f"{given} {rules}: sweeps, tune and regress aggregate points scores; "
                    f"{rules} scores a map error (run its trials with poibench run, or give --rules)"
                )
            tid = trial_id(entry.name, combo)
            tasks.append(
                TrialTask(
                    trial=tid,
                    suite=suite.name,
                    suite_version=suite.version,
                    scenario_name=entry.name,
                    scenario_yaml=sc.to_yaml(),
                    seed=sc.seed,
                    settings=combo,
                    pipeline_sets=pipe_sets,
                    detector=spec.detector,
                    rules=rules,
                    out_dir=str(out_dir / "trials" / tid),
                    cache=None if spec.cache is None else str(spec.cache),
                )
            )
    return tasks


def run_task(task: TrialTask) -> dict:
    """Run one trial and return its row; any exception becomes the row's error."""
    import sim.gl  # noqa: F401  (a fresh worker process chooses its GL backend first)

    t0 = time.perf_counter()
    row: dict = {
        "trial": task.trial,
        "suite": task.suite,
        "suite_version": task.suite_version,
        "scenario": task.scenario_name,
        "seed": task.seed,
        **{SET_PREFIX + k: v for k, v in task.settings.items()},
    }
    try:
        from eval.scoring.rules import load_rules
        from eval.trial.perception_cache import PerceptionCache
        from eval.trial.run import run_trial
        from sim.scenario import parse_scenario

        sc = parse_scenario(task.scenario_yaml, f"<{task.scenario_name}>")
        res = run_trial(
            sc,
            task.out_dir,
            pipeline_sets=task.pipeline_sets,
            detector=task.detector,
            rules=load_rules(task.rules),
            rules_name=task.rules,
            video=False,
            progress=False,
            record_live=False,
            perception_cache=PerceptionCache(task.cache) if task.cache else None,
        )
        errs = [o.distance_m for o in res.score.objects if o.found_by is not None and o.distance_m is not None]
        row.update(
            score=res.score.total,
            max_score=res.score.max_total,
            fraction=round(res.score.total / res.score.max_total, 6) if res.score.max_total else float("nan"),
            false_reports=res.score.false_reports,
            misses=res.score.misses,
            loc_err_median_m=round(float(np.median(errs)), 4) if errs else float("nan"),
            loc_err_p90_m=round(float(np.percentile(errs, 90)), 4) if errs else float("nan"),
            pose_err_median_m=res.pose_error.get("median_m", float("nan")),
            pose_err_p90_m=res.pose_error.get("p90_m", float("nan")),
            frames=res.n_frames,
            cpu_s=round(res.cost.cpu_s, 2),
            cpu_s_per_sim_s=round(res.cost.cpu_s_per_sim_s, 4),
            error="",
        )
        f = res.funnel
        if f is not None:  # the trial's funnel (eval.scoring.funnel), summed per type by funnel_table
            act = f.activity
            row.update(
                boxes_per_frame=round(act.boxes / act.frames, 3) if act.frames else float("nan"),
                funnel_lost=round(f.lost, 3),
                funnel_check="ok" if f.check_ok else "MISMATCH",
                funnel_per_type=f.per_type(),  # to funnel.jsonl, not trials.csv (run_sweep)
            )
    except Exception as e:  # a failing trial is a row, never the end of the sweep
        first = str(e).splitlines()[0] if str(e) else ""
        row.update(error=f"{type(e).__name__}: {first}"[:300])
    row["wall_s"] = round(time.perf_counter() - t0, 2)
    row["complete"] = 1
    return row


# ----------------------------------------------------------------------- rows on disk


def row_fields(grid_keys: list[str]) -> list[str]:
    return ROW_FIELDS_HEAD + [SET_PREFIX + k for k in grid_keys] + ROW_FIELDS_TAIL


def drop_torn_tail(path: Path) -> int:
    """Cut a trials file back to its last complete line; returns the bytes dropped (0: none).

    Every row is written as one whole line ending in a newline, so bytes after the
    last newline are a row a kill (or a disk that filled) cut short: it is dropped,
    its trial counts as not run, and the next append starts on a fresh line instead
    of being glued onto the fragment.
    """
    if not path.exists():
        return 0
    with open(path, "rb+") as f:
        size = f.seek(0, os.SEEK_END)
        if size == 0:
            return 0
        pos = size
        while pos > 0:
            step = min(65536, pos)
            f.seek(pos - step)
            chunk = f.read(step)
            nl = chunk.rfind(b"\n")
            if nl >= 0:
                keep = pos - step + nl + 1
                break
            pos -= step
        else:
            keep = 0
        if keep < size:
            f.truncate(keep)
            f.flush()
            os.fsync(f.fileno())
        return size - keep


def csv_line(fields: list[str], row: dict) -> str:
    """One row of a trials file as the text written: ``fields`` in order, csv's quoting and
    line end (the appending writer and the rewrite in task order share it, so a run's file and a
    merged one are the same bytes)."""
    buf = io.StringIO()
    csv.DictWriter(buf, fieldnames=fields, extrasaction="raise").writerow(row)
    return buf.getvalue()


class RowWriter:
    """Appends complete rows to a CSV file: each row is one ``os.write`` of a whole line on
    an append-only descriptor, fsynced before returning, so a kill leaves whole rows only
    (a torn last line, from a crash of the machine, is dropped when the file is opened again)."""

    def __init__(self, path: Path, fields: list[str]) -> None:
        self.path = path
        self.fields = fields
        self.dropped_bytes = drop_torn_tail(path)
        new = not path.exists() or path.stat().st_size == 0
        if not new:
            with open(path, encoding="utf-8", newline="") as f:
                header = next(csv.reader(f), [])
            if header != fields:
                there = [h for h in header if h not in fields] or ["(none)"]
                here = [f for f in fields if f not in header] or ["(none)"]
                raise SweepError(
                    f"{path}: holds the rows of another run (its columns {', '.join(there)}, this run's "
                    f"{', '.join(here)}; other settings, parameters or poibench version); choose another --out"
                )
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        if new:
            self._append(dict(zip(fields, fields, strict=True)))

    def _append(self, row: dict) -> None:
        data = csv_line(self.fields, row).encode("utf-8")
        while data:
            n = os.write(self._fd, data)
            data = data[n:]
        os.fsync(self._fd)

    def write(self, row: dict) -> None:
        self._append({k: row.get(k, "") for k in self.fields})

    def close(self) -> None:
        os.close(self._fd)


def read_rows(path: Path):
    """The complete rows of a trials file as a DataFrame (a line cut by a kill is dropped);
    for a trial recorded more than once, the last row."""
    import pandas as pd

    if not path.exists():
        return pd.DataFrame()
    df = pd.read_csv(
        path, dtype={"trial": str, "error": str}, keep_default_na=False, na_values=["nan", ""], on_bad_lines="skip"
    )
    if "complete" not in df:
        return pd.DataFrame()
    df = df[df["complete"] == 1]
    df = df.assign(error=df["error"].fillna("").astype(str))
    return df.drop_duplicates("trial", keep="last").reset_index(drop=True)


# --------------------------------------------------------------------------- backends


PARENT_POLL_S = 1.0  # how often a pool worker checks that its sweep is still running


def exit_with_parent(parent_pid: int, poll_s: float = PARENT_POLL_S) -> None:
    """A pool worker's initializer: a daemon thread ends the worker once ``parent_pid`` is no
    longer its parent. A sweep killed by SIGTERM or SIGKILL (``kill``, a batch system's
    cancel) gets no chance to stop its pool, whose workers would run their trials on; the
    rows are the parent's to write, so those trials run again on ``--resume`` anyway."""
    import threading

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        os._exit(1)

    threading.Thread(target=watch, name="poibench-parent-watch", daemon=True).start()


def local_pool(workers: int):
    """A pool of ``workers`` spawned processes (no GL state is forked), or None for one worker;
    each worker ends when the sweep's process does (:func:`exit_with_parent`).

    ``tune`` keeps one for the whole study: a replayed trial costs a second or two of CPU,
    a fresh worker's imports about as much again."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    if workers <= 1:
        return None
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=mp.get_context("spawn"),
        initializer=exit_with_parent,
        initargs=(os.getpid(),),
    )


def run_local(tasks: list[TrialTask], workers: int, pool=None) -> Iterator[dict]:
    """Rows as trials finish, in ``pool`` or a pool of ``workers`` processes of its own."""
    from concurrent.futures import as_completed

    if pool is None and workers <= 1:
        for t in tasks:
            yield run_task(t)
        return
    own = pool is None
    if own:
        pool = local_pool(workers)
    try:
        futures = [pool.submit(run_task, t) for t in tasks]
        try:
            for f in as_completed(futures):
                yield f.result()
        finally:
            for f in futures:
                f.cancel()
    finally:
        if own:
            pool.shutdown()


def run_ray(tasks: list[TrialTask], workers: int, address: str | None) -> Iterator[dict]:
    """Rows as Ray tasks finish; a local Ray instance with ``workers`` CPUs unless ``address``."""
    try:
        import ray
    except ImportError:
        raise SweepError("--backend ray needs the 'ray' extra: pip install -e '.[ray]'") from None
    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            ray.init(num_cpus=max(workers, 1), include_dashboard=False, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(run_task)
        pending = [remote.remote(t) for t in tasks]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                yield ray.get(ref)
    finally:
        if started:
            ray.shutdown()


# ------------------------------------------------------------------------------ sweep


def _check_out(out: Path, spec: SweepSpec) -> None:
    meta = out / "sweep.yaml"
    # hidden files (a command's lock on its --out) do not make a folder another run's
    if not meta.exists() and out.is_dir() and any(not p.name.startswith(".") for p in out.iterdir()):
        what = "a trial (poibench run)" if (out / "config.yaml").exists() else "other files"
        raise SweepError(f"{out} holds {what}, not a suite run or sweep; choose an empty or new --out")
    if meta.exists():
        old = safe_load_file(meta, error=SweepError)
        if not spec.resume:
            raise SweepError(
                f"{out} already holds a suite run or sweep; choose another --out (suite run and sweep: "
                "or add --resume to continue it)"
            )
        if not isinstance(old, dict) or old.get("sweep") != spec.identity():
            raise SweepError(
                f"{meta}: that sweep had other settings; --resume needs the same suite, --set and rules"
            )
        old_shard = old.get("shard") or {}
        was = f"{old_shard.get('index')}/{old_shard.get('count')}" if old_shard else "none"
        now = str(spec.shard) if spec.shard else "none"
        if was != now:
            raise SweepError(f"{meta}: that run was --shard {was}; --resume needs the same --shard, not {now}")


def sweep_doc(spec: SweepSpec, suite: Suite, tasks: list[TrialTask]) -> dict:
    """``sweep.yaml``: what the run was (``identity``), its suite's version and its trial count; a
    shard's adds ``shard``: its index, the count and every trial id of the whole run in task order,
    which ``poibench suite merge`` checks the shards against and orders their rows by."""
    doc: dict = {
        "poibench_sweep": 1,
        "sweep": spec.identity(),
        "suite_version": suite.version,
        "trials": len(tasks),
    }
    if spec.shard is not None:
        doc["shard"] = {**spec.shard.to_dict(), "trial_ids": [t.trial for t in tasks]}
    return doc


def run_sweep(
    spec: SweepSpec, out_dir: str | Path, progress: Callable[[int, int], None] | None = None
) -> tuple[object, object]:
    """Run (or resume) a sweep; returns (rows, aggregate) DataFrames, also written to out_dir."""
    if spec.workers < 1:
        raise SweepError(f"--workers must be at least 1, got {spec.workers}")
    out = Path(out_dir)
    suite = load_suite(spec.suite)
    all_tasks = make_tasks(suite, spec, out)  # refuses settings and rules that cannot take effect, first
    _check_out(out, spec)
    out.mkdir(parents=True, exist_ok=True)
    (out / "sweep.yaml").write_text(
        yaml.safe_dump(sweep_doc(spec, suite, all_tasks), sort_keys=False), encoding="utf-8"
    )
    tasks = spec.shard.select(all_tasks) if spec.shard is not None else all_tasks
    path = out / "trials.csv"
    dropped = drop_torn_tail(path)
    if dropped:
        print(f"{path}: dropped a torn last line ({dropped} bytes); its trial runs again", file=sys.stderr)
    done_rows = read_rows(path)
    finished = set(done_rows.loc[done_rows["error"] == "", "trial"]) if len(done_rows) else set()
    todo = [t for t in tasks if t.trial not in finished]
    if progress:
        progress(len(tasks) - len(todo), len(tasks))
    writer = RowWriter(path, row_fields([k for k, _ in spec.grid]))
    try:
        rows: Iterable[dict]
        if spec.backend == "local":
            rows = run_local(todo, spec.workers)
        elif spec.backend == "ray":
            rows = run_ray(todo, spec.workers, spec.address)
        else:
            raise SweepError(f"--backend: expected local or ray, got {spec.backend!r}")
        for row in rows:
            per_type = row.pop("funnel_per_type", None)
            if per_type is not None:
                append_funnel(out / FUNNEL_LINES, row["trial"], per_type)
            writer.write(row)
            if progress:
                progress(1, len(tasks))
    finally:
        writer.close()
    write_in_task_order(path, [t.trial for t in tasks])
    return write_summaries(out, [k for k, _ in spec.grid])


def last_rows(path: Path) -> tuple[list[str], dict[str, dict[str, str]]]:
    """(columns, trial -> its last complete row) of a trials file, every value the text written."""
    with open(path, encoding="utf-8", newline="") as f:
        reader = csv.reader(f)
        header = next(reader, [])
        rows: dict[str, dict[str, str]] = {}
        for cells in reader:
            if len(cells) != len(header):
                continue  # a line a kill cut short (read_rows skips it too)
            row = dict(zip(header, cells, strict=True))
            if row.get("complete") == "1":
                rows.pop(row["trial"], None)  # a trial run again goes where its last row is
                rows[row["trial"]] = row
    return header, rows


def write_in_task_order(path: Path, trial_ids: list[str]) -> None:
    """Rewrite a finished run's ``trials.csv`` with one row a trial (its last), in task order,
    the values as written: workers finish in an order of their own, and a resumed run appends
    its reruns, so the file a run leaves, and the aggregate's bootstrap, which draws mazes by
    row, are the same whatever the workers and the interruptions. Trials without a row (a run
    stopped early) are left out; the file is replaced atomically."""
    header, rows = last_rows(path)
    if not header:
        return
    lines = [csv_line(header, dict(zip(header, header, strict=True)))]
    lines += [csv_line(header, rows[tid]) for tid in trial_ids if tid in rows]
    write_text_atomic(path, "".join(lines))


def write_summaries(out: Path, keys: list[str]) -> tuple[object, object]:
    """The rows of ``out/trials.csv`` and what is computed from them, written beside it:
    ``aggregate.csv``, ``funnel.csv`` and the plot; returns (rows, aggregate) DataFrames. A run and
    ``poibench suite merge`` both end here, so a merged folder's summaries are a single run's."""
    df = read_rows(out / "trials.csv")
    agg = aggregate(df, keys)
    agg.to_csv(out / "aggregate.csv", index=False)
    funnels = read_funnels(out / FUNNEL_LINES)
    funnel_table(df, keys, out, funnels).to_csv(out / "funnel.csv", index=False)
    plot_sweep(out, agg, keys)
    plot_points(out, df, keys, funnels)
    return df, agg


def append_funnel(path: Path, trial: str, per_type: dict) -> None:
    """Append one trial's per-type funnel to ``funnel.jsonl`` as one whole line, fsynced (as
    :class:`RowWriter` does; a torn last line is skipped when read)."""
    line = json.dumps({"trial": trial, "per_type": per_type}, sort_keys=True, separators=(",", ":")) + "\n"
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, line.encode("utf-8"))
        os.fsync(fd)
    finally:
        os.close(fd)


def read_funnels(path: Path) -> dict[str, dict]:
    """Trial -> per-type funnel from ``funnel.jsonl`` (the last line of a trial run twice wins;
    a line a kill cut short is skipped)."""
    out: dict[str, dict] = {}
    if not path.exists():
        return out
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(rec, dict) and isinstance(rec.get("per_type"), dict):
            out[str(rec.get("trial"))] = rec["per_type"]
    return out


def summed_funnel(rows, out: Path, funnels: dict[str, dict] | None = None) -> dict[str, dict[str, float]]:
    """The per-type funnel (eval.scoring.funnel.Funnel.per_type) summed over ``rows``' trials;
    ``funnels``: the run's :func:`read_funnels`, where the caller has read them already."""
    from eval.scoring.funnel import sum_per_type

    funnels = read_funnels(Path(out) / FUNNEL_LINES) if funnels is None else funnels
    trials = list(rows["trial"]) if "trial" in rows else []
    return sum_per_type([funnels[t] for t in trials if t in funnels])


def setting_groups(df, keys: list[str]) -> Iterator[tuple[dict, object]]:
    """(the setting columns' values, the rows) of each setting combination of a sweep's rows,
    in the order they first appear; one group of every row when nothing was swept."""
    cols = [SET_PREFIX + k for k in keys]
    groups = df.groupby(cols, sort=False, dropna=False) if cols else [((), df)]
    for key, g in groups:
        yield dict(zip(cols, key if isinstance(key, tuple) else (key,), strict=True)), g


def drawn_trials(df, funnels: dict[str, dict]):
    """The rows of ``df`` that ``points.png`` draws: trials that finished with a funnel line."""
    return df[(df["error"] == "") & df["trial"].isin(list(funnels))] if len(df) else df


def points_bars(df, keys: list[str], out: Path, funnels: dict[str, dict]):
    """(bars, the per-type funnel summed over them) of ``points.png``
    (:mod:`eval.experiments.points_plot`): a bar a trial (its scenario's name) when the run holds
    one setting combination (a suite run, with ``--set`` or without), else a bar a combination
    (``key=value, ...``), its trials summed. Only trials that finished with a funnel line count;
    ``funnels`` is the run's :func:`read_funnels`."""
    from eval.experiments.points_plot import PointsBar
    from eval.scoring.funnel import lost_by_cause, sum_per_type

    ok = drawn_trials(df, funnels)
    groups = list(setting_groups(ok, keys)) if len(ok) else []
    if len(groups) == 1:
        rows = groups[0][1]
        parts = [(str(rows["scenario"].iloc[i]), rows.iloc[[i]]) for i in range(len(rows))]
    else:
        parts = [(", ".join(f"{k}={rec[SET_PREFIX + k]}" for k in keys), g) for rec, g in groups]
    bars: list[PointsBar] = []
    tables = []
    for label, rows in parts:
        per_type = summed_funnel(rows, out, funnels)
        tables.append(per_type)
        score = float(rows["score"].astype(float).sum())
        bars.append(
            PointsBar(
                label=label,
                score=score,
                max_score=float(rows["max_score"].astype(float).sum()),
                lost=lost_by_cause(per_type),
            )
        )
    return bars, sum_per_type(tables)


def plot_points(out: Path, df, keys: list[str], funnels: dict[str, dict] | None = None) -> bool:
    """``points.png`` in ``out`` (:mod:`eval.experiments.points_plot`); False (none written)
    when no trial finished with its funnel. The title says how many trials were left out."""
    from eval.experiments.points_plot import POINTS_PNG, write_points_png
    from eval.text import counted

    funnels = read_funnels(Path(out) / FUNNEL_LINES) if funnels is None else funnels
    bars, per_type = points_bars(df, keys, out, funnels)
    drawn = len(drawn_trials(df, funnels))
    failed = int((df["error"] != "").sum()) if len(df) else 0
    suite = str(df["suite"].iloc[0]) if len(df) and "suite" in df else ""
    score, top = sum(b.score for b in bars), sum(b.max_score for b in bars)
    left_out = [
        counted(failed, "failed trial") if failed else "",
        counted(len(df) - failed - drawn, "trial") + " without a funnel" if len(df) - failed - drawn else "",
    ]
    note = "; ".join(x for x in left_out if x)
    title = f"{suite}: {score:g} of {top:g} points, {top - score:g} lost" + (f" ({note} left out)" if note else "")
    return write_points_png(Path(out) / POINTS_PNG, bars, per_type, title)


def funnel_table(df, keys: list[str], out_dir: Path, funnels: dict[str, dict] | None = None):
    """``funnel.csv`` of a sweep: per setting combination and type, the objects, how many
    passed each stage and the points lost to each cause, summed over its trials."""
    import pandas as pd

    from eval.scoring.funnel import CAUSES, STAGES

    if not len(df):
        return pd.DataFrame()
    out = []
    for rec, g in setting_groups(df, keys):
        for t, row in sorted(summed_funnel(g[g["error"] == ""], out_dir, funnels).items()):
            out.append(
                {
                    **rec,
                    "type": t,
                    "objects": row.get("objects", 0),
                    **{s: row.get(s, 0) for s in STAGES},
                    **{c: row.get(c, 0) for c in CAUSES},
                }
            )
    return pd.DataFrame(out)


BOOTSTRAP_RESAMPLES = 10_000
# The resampling's own seed: every interval draws from a fresh generator of it, so the same
# values give the same interval whatever else a command computes.
BOOTSTRAP_SEED = 0


def mean_interval(
    values, *, rng: np.random.Generator, level: float = 0.95, resamples: int = BOOTSTRAP_RESAMPLES
) -> tuple[float, float]:
    """The bootstrap percentile interval of the mean of ``values``, one value a maze (B. Efron
    and R. Tibshirani, "An Introduction to the Bootstrap", 1993, section 13.3).

    Draw the mazes with replacement ``resamples`` times, take each draw's mean, and return the
    (1 - level) / 2 and (1 + level) / 2 quantiles of those means. Each end is a mean of some of
    the values, so the interval lies within [min(values), max(values)]: a score fraction's
    within [0, 1], a paired difference of two fractions within [-1, 1] (a Student t interval,
    used before, gave [-1.06, 2.54] for two mazes). The maze is the unit resampled because a
    fraction is a ratio of points, not a count of independent successes (which Wilson's
    interval assumes). With few mazes it is narrower than its level says (with two it is at
    most [min, max]); (nan, nan) for fewer than two values.

    >>> mean_interval([0.0, 1.0], rng=np.random.default_rng(BOOTSTRAP_SEED))
    (0.0, 1.0)
    >>> mean_interval([0.4, 0.4, 0.4], rng=np.random.default_rng(BOOTSTRAP_SEED))
    (0.4, 0.4)
    """
    x = np.asarray(values, dtype=float).ravel()  # (n,)
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level}")
    if x.size < 2:
        return float("nan"), float("nan")
    means = bootstrap_means(x, rng, resamples)  # (resamples,): the mazes drawn with replacement
    lo, hi = np.quantile(means, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    # a mean of equal values can differ from them in the last bit: keep the ends within the values
    return float(np.clip(lo, x.min(), x.max())), float(np.clip(hi, x.min(), x.max()))


def aggregate(df, keys: list[str]):
    """Per setting combination: trials, failures, mean fraction and its 95% interval
    (:func:`mean_interval`), means."""
    import pandas as pd

    if not len(df):
        return pd.DataFrame()
    out = []
    for rec, g in setting_groups(df, keys):
        ok = g[g["error"] == ""]
        f = ok["fraction"].astype(float).to_numpy()
        n = len(f)
        mean = float(np.mean(f)) if n else float("nan")
        lo, hi = mean_interval(f, rng=np.random.default_rng(BOOTSTRAP_SEED))

        def mean_of(col: str, digits: int, ok=ok) -> float:
            # the mean of the trials that have a value (a trial that located nothing has no
            # location error); NaN, without numpy's empty-slice warning, when none has
            v = ok[col].astype(float).to_numpy()
            v = v[~np.isnan(v)]
            return round(float(v.mean()), digits) if v.size else float("nan")

        rec.update(
            trials=len(g),
            failed=int((g["error"] != "").sum()),
            fraction_mean=round(mean, 4),
            fraction_ci95_low=round(lo, 4),
            fraction_ci95_high=round(hi, 4),
            score_mean=mean_of("score", 3),
            false_reports_mean=mean_of("false_reports", 3),
            misses_mean=mean_of("misses", 3),
            loc_err_median_m=mean_of("loc_err_median_m", 4),
            pose_err_median_m=mean_of("pose_err_median_m", 4),
            wall_s_mean=round(float(g["wall_s"].astype(float).mean()), 2),
            cpu_s_mean=mean_of("cpu_s", 2),
            cpu_s_per_sim_s_mean=mean_of("cpu_s_per_sim_s", 4),
            boxes_per_frame_mean=mean_of("boxes_per_frame", 3) if "boxes_per_frame" in ok else float("nan"),
        )
        out.append(rec)
    return pd.DataFrame(out)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def axis_order(values: Iterable) -> list[str]:
    """A swept setting's values as an axis shows them: numbers in numeric order, anything
    else in the order first given (``--set``'s), each once.

    >>> axis_order(["16", "4", "9", "4"]), axis_order(["slam", "t265"]), axis_order(["1e-3", "0.01"])
    (['4', '9', '16'], ['slam', 't265'], ['1e-3', '0.01'])
    """
    seen = list(dict.fromkeys(str(v) for v in values))
    return sorted(seen, key=float) if all(_is_number(v) for v in seen) else seen


def sweep_figure(agg, keys: list[str]):
    """(file name, matplotlib Figure) of a sweep's aggregate: ``score.png`` for one swept
    parameter (the fraction with its 95% interval), ``heatmap.png`` for two, each axis in
    :func:`axis_order`; None for none or more than two."""
    if not len(agg) or not keys or len(keys) > 2:
        return None
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    cols = [SET_PREFIX + k for k in keys]
    a = agg.assign(**{c: agg[c].astype(str) for c in cols})
    if len(keys) == 1:
        a = a.set_index(cols[0]).loc[axis_order(a[cols[0]])]
        x = a.index.tolist()
        y = a["fraction_mean"].to_numpy(float)
        lo = y - a["fraction_ci95_low"].to_numpy(float)
        hi = a["fraction_ci95_high"].to_numpy(float) - y
        numeric = all(_is_number(v) for v in x)
        fig = Figure(figsize=(6, 4))
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        # a line joins numeric settings only; categories (t265, slam) stand apart
        fmt = "o-" if numeric else "o"
        ax.errorbar(range(len(x)), y, yerr=[np.nan_to_num(lo), np.nan_to_num(hi)], fmt=fmt, capsize=4)
        ax.set_xticks(range(len(x)), x)
        ax.set_xlabel(keys[0])
        ax.set_ylabel("score / max (mean, 95% bootstrap interval)")
        ax.grid(alpha=0.3)
        fig.tight_layout()
        return "score.png", fig
    table = a.pivot(index=cols[0], columns=cols[1], values="fraction_mean")
    table = table.reindex(index=axis_order(a[cols[0]]), columns=axis_order(a[cols[1]]))  # (rows, cols)
    fig = Figure(figsize=(1.2 * table.shape[1] + 3, 0.8 * table.shape[0] + 2.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    # origin "lower": the first row at the bottom, so a numeric y axis grows upwards
    im = ax.imshow(table.to_numpy(float), cmap="viridis", vmin=0, vmax=1, origin="lower")
    for i in range(table.shape[0]):
        for j in range(table.shape[1]):
            ax.text(j, i, f"{table.iat[i, j]:.2f}", ha="center", va="center", color="w", fontsize=9)
    ax.set_xticks(range(table.shape[1]), table.columns)
    ax.set_yticks(range(table.shape[0]), table.index)
    ax.set_xlabel(keys[1])
    ax.set_ylabel(keys[0])
    fig.colorbar(im, ax=ax, label="score / max (mean)")
    fig.tight_layout()
    return "heatmap.png", fig


def plot_sweep(out: Path, agg, keys: list[str]) -> None:
    """score.png (one parameter) or heatmap.png (two) in ``out`` (:func:`sweep_figure`)."""
    made = sweep_figure(agg, keys)
    if made is not None:
        name, fig = made
        fig.savefig(Path(out) / name, dpi=100)
