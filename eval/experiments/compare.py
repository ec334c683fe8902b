"""``poibench suite compare RUN RUN [RUN ...]``: detectors or settings ranked on one suite.

Each RUN is the ``--out`` folder of a finished ``poibench suite run`` (the same holds for a
sweep's or a regress run's folder: each of its setting combinations is one entrant). From
each folder it reads what the run wrote (eval/experiments/sweep.py): ``sweep.yaml`` (the
detector, rules and settings), ``trials.csv`` (a row a trial) and ``funnel.csv`` (per type,
the points lost to each cause, summed over the trials).

The entrants must have run the same suite, version and rules, and each must have a finished
trial of every maze, with the same seed: anything else is refused with one line, since a
mean over other mazes is not comparable. Then:

- each entrant's mean score fraction over the mazes, with its 95% bootstrap percentile
  interval (:func:`eval.experiments.sweep.mean_interval`), and the entrants ranked by it;
- each entrant against the first by the paired difference, maze by maze: the mean of its
  fraction minus the first's on each maze, with the same interval of those differences. The
  mazes differ from one another far more than two detectors do on one maze; pairing takes
  that shared part out, so a difference whose interval excludes 0 is one the suite shows,
  where two overlapping intervals of means would say nothing;
- per type, the points each entrant lost (``funnel.csv``'s causes summed): where the ranking
  comes from.

:func:`compare_runs` gives the table ``compare.csv`` holds; :func:`format_compare` the text.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from eval.experiments.sweep import (
    BOOTSTRAP_SEED,
    SET_PREFIX,
    mean_interval,
    read_rows,
    setting_groups,
)
from poi.core.loader import safe_load_file

LOST_PREFIX = "lost."


class CompareError(ValueError):
    """Runs that cannot be compared (one line)."""


@dataclass(kw_only=True)
class Entrant:
    """One finished run (or one setting combination of a sweep) on the suite's mazes."""

    label: str
    folder: str
    detector: str
    rules: str
    suite: str
    suite_version: int
    settings: dict[str, str] = field(default_factory=dict)
    fractions: dict[str, float] = field(default_factory=dict)  # maze (scenario name) -> score fraction
    seeds: dict[str, int] = field(default_factory=dict)  # maze -> seed
    failed: dict[str, str] = field(default_factory=dict)  # maze -> the error of its trial
    lost: dict[str, float] | None = None  # type -> points lost; None without funnel.csv


def _read_funnel(folder: Path, settings: dict[str, str]) -> dict[str, float] | None:
    """Per type, the points lost to every cause (funnel.csv's rows for these settings)."""
    import pandas as pd

    from eval.scoring.funnel import CAUSES

    path = folder / "funnel.csv"
    if not path.is_file():
        return None
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except pd.errors.EmptyDataError:
        return {}
    if "type" not in df:
        return {}
    for k, v in settings.items():
        if SET_PREFIX + k in df:
            df = df[df[SET_PREFIX + k] == v]
    out: dict[str, float] = {}
    for _, row in df.iterrows():
        lost = sum(float(row[c]) for c in CAUSES if c in row and row[c] not in ("", "nan"))
        out[row["type"]] = out.get(row["type"], 0.0) + lost
    return out


def load_run(folder: str | Path) -> list[Entrant]:
    """The entrants of one run folder: one for a suite run, one a setting combination for a sweep."""
    p = Path(folder)
    where = f"{folder}: give the --out folder of a finished poibench suite run"
    if not p.is_dir():
        raise CompareError(f"{folder}: no such folder")
    meta_path, trials = p / "sweep.yaml", p / "trials.csv"
    if not trials.is_file() or not meta_path.is_file():
        missing = "trials.csv" if not trials.is_file() else "sweep.yaml"
        raise CompareError(f"{where} (it has no {missing})")
    meta = safe_load_file(meta_path, error=CompareError)
    ident = meta.get("sweep") if isinstance(meta, dict) else None
    if not isinstance(ident, dict):
        raise CompareError(f"{meta_path}: not a poibench run's sweep.yaml")
    keys = [str(k) for k, _ in ident.get("grid") or []]
    df = read_rows(trials)
    if not len(df):
        raise CompareError(f"{trials}: no finished trial")
    out = []
    for rec, g in setting_groups(df.astype({SET_PREFIX + k: str for k in keys}), keys):
        settings = {c[len(SET_PREFIX) :]: str(v) for c, v in rec.items()}
        suites = sorted({(str(s), int(v)) for s, v in zip(g["suite"], g["suite_version"], strict=True)})
        if len(suites) != 1:
            raise CompareError(f"{trials}: rows of more than one suite ({suites})")
        label = p.name or str(p)
        if settings:
            label += " " + " ".join(f"{k}={v}" for k, v in settings.items())
        e = Entrant(
            label=label,
            folder=str(folder),
            detector=str(ident.get("detector", "")),
            rules=str(ident.get("rules") or "each scenario's own"),
            suite=suites[0][0],
            suite_version=suites[0][1],
            settings=settings,
            lost=_read_funnel(p, settings),
        )
        for r in g.itertuples():
            e.seeds[str(r.scenario)] = int(r.seed)
            if r.error:
                e.failed[str(r.scenario)] = str(r.error)
            else:
                e.fractions[str(r.scenario)] = float(r.fraction)
        out.append(e)
    return out


def check_comparable(entrants: list[Entrant]) -> list[str]:
    """The mazes every entrant finished, in the first one's order; :class:`CompareError` (one
    line) when the runs are of different suites, versions or rules, or over different mazes."""
    if len(entrants) < 2:
        raise CompareError("give two runs or more (or a sweep's folder with two setting combinations or more)")
    a = entrants[0]
    for b in entrants[1:]:
        if (b.suite, b.suite_version) != (a.suite, a.suite_version):
            raise CompareError(
                f"{a.folder} is a run of suite {a.suite} v{a.suite_version}, {b.folder} of "
                f"{b.suite} v{b.suite_version}: compare runs of one suite"
            )
        if b.rules != a.rules:
            raise CompareError(
                f"{a.folder} was scored by rules {a.rules}, {b.folder} by {b.rules}: compare runs under one rules"
            )
    mazes = list(dict.fromkeys(m for e in entrants for m in e.seeds))
    for e in entrants:
        for m in mazes:
            if m in e.failed:
                raise CompareError(
                    f"{e.label}: maze {m} failed ({e.failed[m]}); rerun it with poibench suite run --resume "
                    "so every run has every maze"
                )
            if m not in e.fractions:
                raise CompareError(
                    f"{e.label} has no trial of maze {m}: not the same mazes as "
                    f"{next(x.label for x in entrants if m in x.fractions)}"
                )
            if e.seeds[m] != a.seeds[m]:
                raise CompareError(
                    f"{a.label} and {e.label} ran maze {m} with seeds {a.seeds[m]} and {e.seeds[m]}: "
                    "not the same mazes"
                )
    return mazes


def compare_runs(folders: list[str | Path]):
    """The comparison of finished runs (module docstring) as a DataFrame, one row an
    entrant, best first: rank, run, detector, settings, mazes, the mean fraction and its 95%
    interval, the paired difference to the first and its interval, points lost in all and per
    type (``lost.TYPE``)."""
    import pandas as pd

    seen: set[Path] = set()
    for f in folders:
        if Path(f).resolve() in seen:
            raise CompareError(f"{f}: given twice; compare different runs")
        seen.add(Path(f).resolve())
    entrants = [e for f in folders for e in load_run(f)]
    labels = [e.label for e in entrants]
    if len(set(labels)) < len(labels):  # two folders of one name: tell them apart by their paths
        for e in entrants:
            e.label = e.folder + e.label[len(Path(e.folder).name) :]
    mazes = check_comparable(entrants)
    F = np.array([[e.fractions[m] for m in mazes] for e in entrants])  # (entrants, mazes)
    means = F.mean(axis=1)  # (entrants,)
    order = sorted(range(len(entrants)), key=lambda i: (-means[i], entrants[i].label))
    best = order[0]
    types = sorted({t for e in entrants for t in (e.lost or {})})
    rows = []
    for rank, i in enumerate(order, start=1):
        e = entrants[i]
        lo, hi = mean_interval(F[i], rng=np.random.default_rng(BOOTSTRAP_SEED))
        d = F[i] - F[best]  # (mazes,) the paired differences to the first
        if i == best:
            d_mean, d_lo, d_hi = float("nan"), float("nan"), float("nan")
        else:
            d_mean = float(d.mean())
            d_lo, d_hi = mean_interval(d, rng=np.random.default_rng(BOOTSTRAP_SEED))
        lost = e.lost
        rows.append(
            {
                "rank": rank,
                "run": e.label,
                "folder": e.folder,
                "detector": e.detector,
                "settings": " ".join(f"{k}={v}" for k, v in e.settings.items()),
                "suite": e.suite,
                "suite_version": e.suite_version,
                "rules": e.rules,
                "mazes": len(mazes),
                "fraction_mean": round(float(means[i]), 4),
                "fraction_ci95_low": round(lo, 4),
                "fraction_ci95_high": round(hi, 4),
                "diff_to_first": round(d_mean, 4),
                "diff_ci95_low": round(d_lo, 4),
                "diff_ci95_high": round(d_hi, 4),
                "lost": float("nan") if lost is None else round(sum(lost.values()), 3),
                **{LOST_PREFIX + t: float("nan") if lost is None else round(lost.get(t, 0.0), 3) for t in types},
            }
        )
    return pd.DataFrame(rows)


def format_compare(table) -> str:
    """The ranking and the per-type points lost of :func:`compare_runs`' table, as printed."""
    from eval.experiments.table import format_table, interval_text

    first = table.iloc[0]
    lines = [
        f"suite {first['suite']} v{first['suite_version']}, rules {first['rules']}, {first['mazes']} mazes: "
        "runs ranked by mean score fraction",
        "95% intervals: bootstrap over the mazes; vs first: the paired difference to the first, maze by maze",
    ]
    shown = table.assign(
        interval=[interval_text(r.fraction_ci95_low, r.fraction_ci95_high) for r in table.itertuples()],
        diff_interval=[interval_text(r.diff_ci95_low, r.diff_ci95_high) for r in table.itertuples()],
    )
    lines.append(
        format_table(
            shown,
            {
                "rank": "d",
                "run": "s",
                "detector": "s",
                "settings": "s",
                "fraction_mean": ".3f",
                "interval": "s",
                "diff_to_first": "+.3f",
                "diff_interval": "s",
                "lost": "g",
            },
            {
                "fraction_mean": "mean",
                "interval": "95% interval",
                "diff_to_first": "vs first",
                "diff_interval": "95% interval",
                "lost": "points lost",
            },
        )
    )
    types = [c for c in table.columns if c.startswith(LOST_PREFIX)]
    if types:
        lost = table.set_index("run")[types].T  # (types, runs)
        lost.index = [t[len(LOST_PREFIX) :] for t in lost.index]
        lost = lost.reset_index(names="type")
        lines.append("")
        lines.append("points lost per type, summed over the mazes (funnel.csv)")
        lines.append(format_table(lost, {"type": "s", **{r: "g" for r in table["run"]}}))
    missing = table.loc[table["lost"].isna(), "run"].tolist()
    if missing:
        lines.append(f"no funnel.csv in {', '.join(missing)}: points lost per type unknown")
    return "\n".join(lines)
