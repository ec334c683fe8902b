"""``poibench tune``: search pipeline thresholds for the best mean score on a suite (Optuna).

Each Optuna trial runs the whole suite with its drawn settings (on the local
or the Ray backend, ``--workers`` scenarios at once) and scores the mean score
fraction over the suite's scenarios. The sampler is Optuna's TPE seeded with
``--seed``, so the same command draws the same settings. Every suite trial is
a row of ``trials.csv`` as in a sweep; the study is ``study.csv``, the best
settings ``best.yaml`` (the ``--set`` items and the whole pipeline config they
give), plots ``history.png`` (score by trial, best so far) and, with two or
more parameters, ``importance.png``.

With ``cache`` (a folder) each scenario is rendered and detected once for the whole study
and every trial replays it (:mod:`eval.trial.perception_cache`).

A parameter is ``key=float:LOW:HIGH``, ``key=int:LOW:HIGH``, ``key=log:LOW:HIGH``
(float on a log scale) or ``key=choice:A,B,C``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import yaml

from eval.experiments.suites import load_suite
from eval.experiments.sweep import (
    RowWriter,
    SweepError,
    SweepSpec,
    local_pool,
    make_tasks,
    read_rows,
    row_fields,
    run_local,
    run_ray,
)


@dataclass(kw_only=True)
class Param:
    key: str
    kind: str  # float, int, log, choice
    low: float = 0.0
    high: float = 0.0
    choices: tuple[str, ...] = ()


def parse_param(item: str) -> Param:
    """``key=kind:...`` -> Param.

    >>> parse_param("tracker.gate=float:1:25")
    Param(key='tracker.gate', kind='float', low=1.0, high=25.0, choices=())
    >>> parse_param("tracker.assignment=choice:greedy,hungarian").choices
    ('greedy', 'hungarian')
    """
    if "=" not in item or ":" not in item:
        raise SweepError(
            f"--param {item!r}: expected key=float:LOW:HIGH, int:LOW:HIGH, log:LOW:HIGH or choice:A,B"
        )
    key, spec = item.split("=", 1)
    kind, rest = spec.split(":", 1)
    if kind == "choice":
        choices = tuple(v.strip() for v in rest.split(",") if v.strip())
        if len(choices) < 2:
            raise SweepError(f"--param {key}: a choice needs at least two values")
        return Param(key=key.strip(), kind=kind, choices=choices)
    if kind not in ("float", "int", "log"):
        raise SweepError(f"--param {key}: unknown kind {kind!r}; expected float, int, log or choice")
    try:
        low, high = (float(v) for v in rest.split(":"))
    except ValueError:
        raise SweepError(f"--param {key}: expected {kind}:LOW:HIGH with numbers") from None
    if not low < high or (kind == "log" and low <= 0):
        raise SweepError(f"--param {key}: need LOW < HIGH (and LOW > 0 for log), got {low}, {high}")
    if kind == "int" and not (low.is_integer() and high.is_integer()):
        raise SweepError(f"--param {key}: int:LOW:HIGH needs whole numbers, got {rest}")
    return Param(key=key.strip(), kind=kind, low=low, high=high)


def _bounds(p: Param) -> list[str]:
    """The values of ``p`` that stand for all it can draw: each choice, or the range's two ends."""
    if p.kind == "choice":
        return list(p.choices)
    if p.kind == "int":
        return [str(int(p.low)), str(int(p.high))]
    return [repr(p.low), repr(p.high)]


def check_params(params: list[Param], suite, detector: str, rules: str | None) -> None:
    """Refuse, before any study trial, a parameter given twice or one whose key, range end or
    choice a trial would refuse (:func:`eval.experiments.sweep.make_tasks` on each end and
    choice: an unknown key, a value out of the setting's range, a setting that cannot take
    effect): otherwise Optuna finds out only when it draws such a value, trials later."""
    seen: set[str] = set()
    for p in params:
        if p.key in seen:
            raise SweepError(f"--param {p.key}: given twice")
        seen.add(p.key)
        for v in _bounds(p):
            try:
                make_tasks(
                    suite, SweepSpec(suite=suite.name, grid=[(p.key, [v])], detector=detector, rules=rules), Path()
                )
            except SweepError as e:
                what = "choice" if p.kind == "choice" else "range end"
                raise SweepError(
                    f"--param {p.key}: {what} {v} is refused ({str(e).removeprefix('--set: ')})"
                ) from None


def _suggest(trial, p: Param) -> str:
    if p.kind == "float":
        return repr(trial.suggest_float(p.key, p.low, p.high))
    if p.kind == "log":
        return repr(trial.suggest_float(p.key, p.low, p.high, log=True))
    if p.kind == "int":
        return str(trial.suggest_int(p.key, int(p.low), int(p.high)))
    return str(trial.suggest_categorical(p.key, list(p.choices)))


def run_tune(
    suite_name: str,
    params: list[Param],
    n_trials: int,
    out_dir: str | Path,
    *,
    seed: int = 0,
    detector: str = "default",
    rules: str = "ex3",
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
    progress: Callable[[int], None] | None = None,
    cache: str | None = None,
) -> dict:
    try:
        import optuna
    except ImportError:
        raise SweepError("poibench tune needs the 'tune' extra: pip install -e '.[tune]'") from None
    if n_trials < 1:
        raise SweepError(f"--trials must be at least 1, got {n_trials}")
    if workers < 1:
        raise SweepError(f"--workers must be at least 1, got {workers}")
    suite = load_suite(suite_name)
    check_params(params, suite, detector, rules)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    keys = [p.key for p in params]
    writer = RowWriter(out / "trials.csv", row_fields(keys))
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="maximize", sampler=optuna.samplers.TPESampler(seed=seed))

    def objective(trial) -> float:
        settings = {p.key: _suggest(trial, p) for p in params}
        spec = SweepSpec(
            suite=suite_name,
            grid=[(k, [v]) for k, v in settings.items()],
            detector=detector,
            rules=rules,
            workers=workers,
            backend=backend,
            address=address,
            cache=cache,
        )
        tasks = make_tasks(suite, spec, out / f"study_{trial.number:04d}")
        rows = list(run_ray(tasks, workers, address) if backend == "ray" else run_local(tasks, workers, pool))
        for r in rows:
            writer.write(r)
        ok = [float(r["fraction"]) for r in rows if not r["error"]]
        if progress:
            progress(1)
        # a setting that breaks trials scores as if those trials scored nothing
        return sum(ok) / len(rows) if rows else 0.0

    pool = local_pool(workers) if backend == "local" else None  # one pool for the whole study
    try:
        study.optimize(objective, n_trials=n_trials)
    finally:
        writer.close()
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    table = study.trials_dataframe(attrs=("number", "value", "params", "duration"))
    table.to_csv(out / "study.csv", index=False)
    best = study.best_trial
    sets = [f"{p.key}={_format(best.params[p.key])}" for p in params]
    from poi.config import apply_overrides, config_to_dict, load_config

    doc = {
        "poibench_tune": 1,
        "suite": suite.name,
        "suite_version": suite.version,
        "trials": n_trials,
        "best_trial": best.number,
        "best_mean_fraction": round(float(best.value), 6),
        "settings": sets,
        "pipeline": config_to_dict(apply_overrides(load_config(), [s for s in sets if not _is_scenario(s)])),
    }
    (out / "best.yaml").write_text(
        "# the best settings found; use them with poibench run --set ...\n" + yaml.safe_dump(doc, sort_keys=False),
        encoding="utf-8",
    )
    _plots(out, study, len(params))
    rows = read_rows(out / "trials.csv")
    return {"best": doc, "rows": len(rows)}


def _is_scenario(item: str) -> bool:
    from eval.trial.scenarios import split_settings

    return bool(split_settings([item])[0])


def _format(v) -> str:
    if isinstance(v, float):
        return repr(round(v, 6))
    return str(v)


def _plots(out: Path, study, n_params: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    values = [t.value if t.value is not None else math.nan for t in study.trials]
    best = [max(values[: i + 1]) for i in range(len(values))]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(range(len(values)), values, "o", label="trial")
    ax.plot(range(len(values)), best, "-", label="best so far")
    ax.set_xlabel("Optuna trial")
    ax.set_ylabel("mean score fraction over the suite")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "history.png", dpi=100)
    plt.close(fig)
    if n_params >= 2 and len(study.trials) >= 4:
        import optuna

        try:
            imp = optuna.importance.get_param_importances(study)
        except (RuntimeError, ValueError):
            return
        fig, ax = plt.subplots(figsize=(6, 0.5 * len(imp) + 1.5))
        ax.barh(list(imp)[::-1], list(imp.values())[::-1])
        ax.set_xlabel("importance (fANOVA)")
        fig.tight_layout()
        fig.savefig(out / "importance.png", dpi=100)
        plt.close(fig)
