"""``poibench suite merge``: the folders of a run's shards joined into the folder one run writes.

Each shard (``--shard I/N``, :mod:`eval.experiments.shard`) wrote ``sweep.yaml`` with the run's
identity and every trial id of the whole run in task order, and ``trials.csv`` with its own
trials. The merge checks that the shards are of one run (the same suite, version, settings,
detector and rules, the same N and trial ids), that each of ``0 .. N-1`` is given once and that
each shard finished (a row for every one of its trials), and refuses anything else with one
line. It then writes, through the writers a run uses:

* ``trials.csv``: one row a trial, in the run's task order, each row the shard's last one for
  that trial (a shard resumed after a failure holds the failed row and the rerun's) and its
  values exactly as the shard wrote them (:class:`eval.experiments.sweep.RowWriter`); it is the
  ``trials.csv`` of a single run of one worker, byte for byte, apart from what a run measures
  of itself (``wall_s``, ``cpu_s``, ``cpu_s_per_sim_s``);
* ``funnel.jsonl`` in the same order, each trial's folder under ``trials/``;
* ``sweep.yaml`` as a single run writes it (no ``shard``), then ``aggregate.csv``,
  ``funnel.csv`` and the plot from the merged rows by the code a run ends with
  (:func:`eval.experiments.sweep.write_summaries`).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import yaml

from eval.experiments.sweep import (
    FUNNEL_LINES,
    RowWriter,
    SweepError,
    append_funnel,
    last_rows,
    read_funnels,
    write_summaries,
)
from poi.core.loader import safe_load_file


class MergeError(SweepError):
    """Shards that do not make one run (one line naming the folder and what differs)."""


@dataclass(kw_only=True)
class ShardRun:
    """What one shard's folder holds."""

    folder: Path
    doc: dict  # its sweep.yaml
    index: int
    count: int
    trial_ids: list[str]  # every trial of the whole run, in task order
    header: list[str]  # trials.csv's columns
    rows: dict[str, dict[str, str]]  # trial id -> its last complete row, values as written

    def own_ids(self) -> list[str]:
        """This shard's trials, in task order."""
        return [t for k, t in enumerate(self.trial_ids) if k % self.count == self.index]


def load_shard(folder: str | Path) -> ShardRun:
    """A shard's folder, read and checked on its own (:class:`MergeError`)."""
    p = Path(folder)
    meta, trials = p / "sweep.yaml", p / "trials.csv"
    if not meta.is_file():
        raise MergeError(f"{p}: not a shard's folder (no sweep.yaml); give the --out of a run with --shard I/N")
    doc = safe_load_file(meta, error=MergeError)
    shard = doc.get("shard") if isinstance(doc, dict) else None
    if not isinstance(shard, dict):
        raise MergeError(f"{meta}: not a shard (no 'shard'); only runs with --shard I/N are merged")
    try:
        index, count, ids = int(shard["index"]), int(shard["count"]), [str(t) for t in shard["trial_ids"]]
    except (KeyError, TypeError, ValueError):
        raise MergeError(f"{meta}: 'shard' needs index, count and trial_ids") from None
    if not trials.is_file():
        raise MergeError(f"{p}: shard {index}/{count} did not finish (no trials.csv); rerun it with --resume")
    header, rows = last_rows(trials)
    run = ShardRun(folder=p, doc=doc, index=index, count=count, trial_ids=ids, header=header, rows=rows)
    own = run.own_ids()
    stray = [t for t in rows if t not in set(own)]
    if stray:
        raise MergeError(f"{trials}: trial {stray[0]} is not one of shard {index}/{count}'s")
    missing = [t for t in own if t not in rows]
    if missing:
        raise MergeError(
            f"{p}: shard {index}/{count} did not finish ({len(own) - len(missing)} of {len(own)} trials "
            "recorded); rerun it with --resume"
        )
    return run


def _same_run(shards: list[ShardRun]) -> None:
    """Refuse shards of different runs, N, or a shard missing or given twice (one line)."""
    first = shards[0]
    for s in shards[1:]:
        for what, a, b in (
            ("sweep (suite, --set, detector, rules)", first.doc.get("sweep"), s.doc.get("sweep")),
            ("suite_version", first.doc.get("suite_version"), s.doc.get("suite_version")),
            ("shard count N", first.count, s.count),
            ("trial ids", first.trial_ids, s.trial_ids),
            ("trials.csv columns", first.header, s.header),
        ):
            if a != b:
                raise MergeError(f"{s.folder} and {first.folder}: not shards of one run (their {what} differ)")
    seen: dict[int, Path] = {}
    for s in shards:
        if s.index in seen:
            raise MergeError(f"shard {s.index}/{s.count} given twice: {seen[s.index]} and {s.folder}")
        seen[s.index] = s.folder
    missing = [i for i in range(first.count) if i not in seen]
    if missing:
        raise MergeError(
            f"shard {missing[0]}/{first.count} missing ({len(seen)} of {first.count} shards given); "
            "merge needs every shard"
        )


def merge_shards(folders: list[str | Path], out_dir: str | Path) -> tuple[object, object]:
    """Join shard folders into ``out_dir`` (the module docstring); returns (rows, aggregate)."""
    if not folders:
        raise MergeError("give the shards' folders")
    out = Path(out_dir)
    if out.exists() and any(p.name != ".poibench.lock" for p in out.iterdir()):
        raise MergeError(f"--out {out}: not empty; the merged run needs a folder of its own")
    shards = [load_shard(f) for f in folders]
    _same_run(shards)
    by_trial = {t: s for s in shards for t in s.own_ids()}
    first = shards[0]
    out.mkdir(parents=True, exist_ok=True)
    writer = RowWriter(out / "trials.csv", first.header)
    funnels = {s.index: read_funnels(s.folder / FUNNEL_LINES) for s in shards}
    try:
        for tid in first.trial_ids:
            s = by_trial[tid]
            writer.write(s.rows[tid])
            if tid in funnels[s.index]:
                append_funnel(out / FUNNEL_LINES, tid, funnels[s.index][tid])
            src = s.folder / "trials" / tid
            if src.is_dir():
                shutil.copytree(src, out / "trials" / tid)
    finally:
        writer.close()
    doc = {k: v for k, v in first.doc.items() if k != "shard"}
    (out / "sweep.yaml").write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    keys = [str(k) for k, _ in (doc.get("sweep") or {}).get("grid") or []]
    return write_summaries(out, keys)
