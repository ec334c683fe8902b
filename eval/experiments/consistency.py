"""Covariance consistency: NEES of the pipeline's R, track Sigma and SLAM pose covariance.

A covariance P is consistent with the errors e it describes when the normalised estimation
error squared, NEES = e^T P^-1 e, is chi-square with d degrees of freedom (d = dim e)
([BarShalom2001]_ 5.4). Over N independent samples the sum is chi-square with N d degrees
of freedom, so the mean NEES lies in ``chi2.ppf([0.005, 0.995], N d) / N`` 99% of the time
(:func:`chi2_interval`); a mean above it says P is too small (over-confident), below it too
large.

:func:`run_consistency` runs scenarios through the simulator with their sensor noise on and
the pipeline behind the oracle detector (ground-truth boxes with the pipeline's own centre
noise model; no confusions, no false boxes, so detection mistakes do not confound), and
collects, with the simulator's truth:

* ``R cam <type>``: each observation's camera-frame position against the object's true
  position in the true camera frame, with Sigma_c + extent^2 I (the detection and depth
  model, [Avevor2022]_ 2.2.2; d = 3);
* ``R cam axis 1 (narrowest)``, ``2``, ``3 (widest)``: the same errors along each principal
  axis of their covariance, all types together (:func:`axis_nees`, d = 1). They sum to ``R cam``;
  a covariance too wide along one axis and too thin along another can have a right sum;
* ``R map <type>``: each observation as the tracker receives it (map frame, after the SLAM
  correction) against the object's true position, with its R (d = 3);
* ``track Sigma confirm`` / ``track Sigma end``: each confirmed track's mu and Sigma when it
  is confirmed and at the end of the run against the true position of the object most of its
  detections came from (d = 3);
* ``SLAM pose`` (every frame) and ``SLAM pose end`` (last frame of each run): the filter's
  (x, y, theta) against the true tracker pose, with the filter's pose covariance (d = 3);
  ``SLAM pose position`` (d = 2) and ``SLAM pose heading`` (d = 1) split the per-frame one
  (:func:`pose_part_nees`).

How N is counted. Observations in different frames have independent pixel and depth noise,
but an object's extent error and the pose error repeat from frame to frame, so per-frame
samples of one object (``R ...``) or one run (``SLAM pose``) are correlated, and N of them
hold fewer than N independent ones. Each such series (one object in one run, one run's
poses, in frame order) counts as n / tau samples, tau = 1 + 2 sum_k rho_k its integrated
autocorrelation time (:func:`effective_count`, [Geyer1992]_), and the interval is that of
N_eff independent samples (a chi-square of the same mean and variance). The
autocorrelation is taken about the mean of all the quantity's series, not each series' own,
so an error that lasts a whole run counts ([Gelman2013]_ 11.5). What the objects of one run
share (the registration offset, the mount's error, the pose a SLAM map rests on) lies in no
series, so N_eff is also at most what the scatter of the runs' sums allows
(:func:`run_scatter_count`, [LiangZeger1986]_, [Cameron2015]_; docs/CONSISTENCY.md "What a
run's samples share"). ``track Sigma`` (one sample per track) and ``SLAM pose end`` (one per
run) count each sample once, limited the same way.

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [BarShalom2001] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, "Estimation with Applications to
   Tracking and Navigation", Wiley, 2001.
.. [Geyer1992] C. J. Geyer, "Practical Markov chain Monte Carlo", Statistical Science 7(4),
   473-483, 1992.
.. [LiangZeger1986] K.-Y. Liang, S. L. Zeger, "Longitudinal data analysis using generalized
   linear models", Biometrika 73(1), 13-22, 1986.
.. [Cameron2015] A. C. Cameron, D. L. Miller, "A practitioner's guide to cluster-robust
   inference", Journal of Human Resources 50(2), 317-372, 2015.
.. [Gelman2013] A. Gelman, J. B. Carlin, H. S. Stern, D. B. Dunson, A. Vehtari, D. B. Rubin,
   "Bayesian Data Analysis", 3rd ed., CRC Press, 2013.
"""

from __future__ import annotations

import json
import math
from collections import Counter, defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.stats import chi2, norm
from scipy.stats import t as student_t

from eval.experiments.extent_fit import ExtentSample
from eval.trial.episode import Observer, Tick
from poi.core.geometry import invert_transform, planar_pose, transform_points, wrap_angle

LEVEL = 0.99  # two-sided: chi2.ppf(0.005) and chi2.ppf(0.995)
# A detection is the truth object of its type whose box centre is nearest, within this
# fraction of the box's larger side (the oracle moves centres by ~1 px + 3% of the size).
MATCH_FRACTION = 0.5
POSE_DIM = 3
# R cam's principal axes, narrowest first (:func:`axis_nees`)
AXES = ("1 (narrowest)", "2", "3 (widest)")


class ConsistencyError(ValueError):
    """Settings of a consistency run that cannot be used (one line)."""


def nees(e: np.ndarray, P: np.ndarray) -> float:
    """e^T P^-1 e.

    >>> nees(np.array([1.0, 2.0]), np.diag([1.0, 4.0]))
    2.0
    """
    e = np.asarray(e, dtype=float)
    return float(e @ np.linalg.solve(np.asarray(P, dtype=float), e))


def axis_nees(e: np.ndarray, P: np.ndarray) -> np.ndarray:
    """e's NEES along each principal axis of P, narrowest first: (v_i^T e)^2 / lambda_i for P's
    eigenpairs (lambda_i, v_i). Each is chi-square with 1 degree of freedom when e ~ N(0, P), and
    they sum to :func:`nees`; a P of the right size but the wrong shape (too wide along one
    axis, too thin along another) has a right sum and wrong parts.

    >>> axis_nees(np.array([1.0, 2.0]), np.diag([4.0, 1.0])).tolist()
    [4.0, 0.25]
    """
    lam, V = np.linalg.eigh(np.asarray(P, dtype=float))
    return (V.T @ np.asarray(e, dtype=float)) ** 2 / lam


def pose_part_nees(e: np.ndarray, P: np.ndarray) -> dict[str, tuple[int, float]]:
    """The planar pose error ``e`` = (x, y, theta) split: its position against the position
    block of ``P`` (d = 2) and its heading against the heading variance (d = 1), each with the
    other part left free (the marginal). A pose covariance of the right size in sum can be too
    wide in heading and too thin in position; these rows tell them apart.

    >>> parts = pose_part_nees(np.array([0.1, 0.0, 0.02]), np.diag([0.01, 0.04, 1e-4]))
    >>> {k: (d, round(v, 3)) for k, (d, v) in parts.items()}
    {'position': (2, 1.0), 'heading': (1, 4.0)}
    """
    e, P = np.asarray(e, dtype=float), np.asarray(P, dtype=float)
    return {"position": (2, nees(e[:2], P[:2, :2])), "heading": (1, float(e[2] ** 2 / P[2, 2]))}


def chi2_interval(n: float, d: int, level: float = LEVEL) -> tuple[float, float]:
    """The two-sided ``level`` interval of the mean of n NEES samples of dimension d (n may be
    an effective count, :func:`effective_count`: a chi-square with n d degrees of freedom).

    >>> [round(v, 3) for v in chi2_interval(100, 3)]
    [2.407, 3.668]
    """
    if not n > 0 or d < 1:
        raise ConsistencyError(f"chi2_interval: expected n > 0 and d >= 1, got n={n}, d={d}")
    a = 0.5 * (1.0 - level)
    lo, hi = chi2.ppf([a, 1.0 - a], n * d)
    return float(lo) / n, float(hi) / n


def autocorrelation_time(x: np.ndarray, centre: float | None = None) -> float:
    """tau = 1 + 2 sum_{k>=1} rho_k of a series, the sum stopped before the first lag whose
    autocorrelation is <= 0 (the initial positive sequence of [Geyer1992]_ in its simplest
    form); 1 for a series of fewer than 2 values or with no spread about ``centre``.

    ``rho_k`` is the lag-k autocovariance about ``centre`` over the lag-0 one. The default
    centre is the series' own mean; :func:`effective_count` passes the mean of all the
    quantity's series, so that a series that sits above or below the others all along (an
    error that lasts the whole run) counts as correlated, as it is ([Gelman2013]_ 11.5).

    >>> autocorrelation_time(np.array([1.0, -1.0] * 50))  # anticorrelated: no inflation
    1.0
    >>> blocks = np.repeat(np.random.default_rng(0).standard_normal(200), 10)  # 10 equal values each
    >>> 8.0 < autocorrelation_time(blocks) < 14.0  # about 10
    True
    >>> x = np.array([3.0, 5.0] * 50)  # far above the centre all along: about one sample
    >>> round(x.size / autocorrelation_time(x, centre=0.0), 2)
    1.06
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    c = x - (x.mean() if centre is None else float(centre))
    if n < 2 or not np.any(c != 0.0):
        return 1.0
    acov = np.correlate(c, c, mode="full")[n - 1 :] / n  # lags 0 .. n-1, biased estimate
    rho = acov[1:] / acov[0]
    stop = int(np.argmax(rho <= 0.0)) if np.any(rho <= 0.0) else rho.size
    return 1.0 + 2.0 * float(rho[:stop].sum())


def effective_count(series: list[np.ndarray]) -> float:
    """The number of independent samples that correlated series of one quantity hold: the sum
    of n / tau over the series, each at least 1 and at most its own length, with tau
    (:func:`autocorrelation_time`) taken about the mean of all the series together.

    About each series' own mean, tau sees only the fluctuations within a run: an error that
    lasts a whole run (a drift, a map's pose, the route's view of an object) shifts the
    series' mean and is taken out with it, and the run means then scatter 2-6 times more than
    the interval allows (docs/CONSISTENCY.md "How N is counted, honestly"). About the common
    mean that shift is a correlation that lasts the run, as in the multi-chain effective
    sample size of [Gelman2013]_ 11.5, whose between-chain variance plays the same part.

    >>> effective_count([np.array([1.0, 2.0, 1.0, 2.0]), np.array([2.0, 1.0, 2.0, 1.0])])  # alike
    8.0
    >>> round(effective_count([np.full(50, 1.0) + np.tile([0, 0.1], 25), np.full(50, 5.0)]), 2)  # apart
    2.0
    """
    arrays = [np.asarray(x, dtype=float) for x in series]
    if not arrays:
        return 0.0
    centre = float(np.concatenate(arrays).mean())
    return float(sum(min(len(x), max(1.0, len(x) / autocorrelation_time(x, centre))) for x in arrays))


def run_scatter_count(values: np.ndarray, runs: np.ndarray, level: float = LEVEL) -> float:
    """The number of independent samples that the scatter of the runs' sums allows, for
    samples of one quantity from independent runs (``runs``: each sample's run) that may share
    errors within a run (the depth registration, the mount, the map a run's poses rest on).

    The variance of the mean is the runs' cluster-robust one ([LiangZeger1986]_),
    V = G / (G - 1) sum_r (S_r - n_r m)^2 / N^2 over G runs with n_r samples summing to S_r;
    N_eff = s^2 / V, s^2 the samples' variance, is the count of independent samples whose
    mean varies as much. V rests on G - 1 degrees of freedom, so N_eff is scaled by
    (z / t_{G-1})^2, the level's normal quantile over Student's t with G - 1 degrees of
    freedom ([Cameron2015]_ VI.C): the interval then holds the mean as often as it says even
    with few runs (docs/CONSISTENCY.md "What a run's samples share"). Infinite (no limit:
    :func:`effective_count` alone decides) for fewer than two runs, runs of one sample each
    (nothing within a run to share) or runs whose sums agree exactly.

    >>> x = np.array([1.0, 3.0, 1.0, 3.0, 5.0, 7.0, 5.0, 7.0]); r = np.array([0, 0, 0, 0, 1, 1, 1, 1])
    >>> round(run_scatter_count(x, r), 4)  # two runs apart: 1.43 samples, times (2.576 / 63.66)^2
    0.0023
    >>> run_scatter_count(x, np.zeros(8, int))
    inf
    """
    x = np.asarray(values, dtype=float)
    keys, idx = np.unique(np.asarray(runs), return_inverse=True)
    g = keys.size
    counts = np.bincount(idx, minlength=g)
    if g < 2 or counts.max() < 2:
        return math.inf
    m = float(x.mean())
    sums = np.bincount(idx, weights=x, minlength=g)
    V = g / (g - 1) * float(np.sum((sums - counts * m) ** 2)) / x.size**2
    if not V > 0.0:
        return math.inf
    q = 0.5 + 0.5 * level
    scale = (norm.ppf(q) / student_t.ppf(q, g - 1)) ** 2
    return float(x.var(ddof=1) / V * scale)


@dataclass(kw_only=True)
class Row:
    """One quantity's summary: N samples of dimension d (N_eff independent ones), their mean
    NEES and its interval."""

    quantity: str
    n: int
    n_eff: float
    d: int
    mean: float
    lo: float
    hi: float

    @property
    def inside(self) -> bool:
        return self.lo <= self.mean <= self.hi

    def to_dict(self) -> dict:
        return {
            "quantity": self.quantity,
            "n": self.n,
            "n_eff": round(self.n_eff, 1),
            "d": self.d,
            "mean_nees": round(self.mean, 4),
            "interval_99": [round(self.lo, 4), round(self.hi, 4)],
            "inside": self.inside,
        }


@dataclass(kw_only=True)
class Samples:
    """NEES samples by quantity (name -> d, values, and the series each value belongs to) and
    the per-frame pose NEES of each run."""

    runs: int = 0  # runs begun (collect_run), which names each run's series
    values: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))
    series: dict[str, list[object]] = field(default_factory=lambda: defaultdict(list))
    dims: dict[str, int] = field(default_factory=dict)
    pose_series: list[tuple[str, list[float]]] = field(default_factory=list)
    extent: list[ExtentSample] = field(default_factory=list)  # 3-D objects' camera-frame errors

    run_of: dict[str, list[int]] = field(default_factory=lambda: defaultdict(list))

    def add(self, quantity: str, d: int, value: float, series: object = None, run: int = 0) -> None:
        """One sample of run ``run``; ``series`` names the correlated series it continues, in
        time order (None: a sample correlated with the others of its run only through what the
        run shares)."""
        self.dims[quantity] = d
        self.values[quantity].append(float(value))
        self.series[quantity].append(object() if series is None else series)
        self.run_of[quantity].append(run)

    def rows(self) -> list[Row]:
        out = []
        for q in sorted(self.values, key=_order):
            v = np.asarray(self.values[q])
            groups: dict[object, list[float]] = defaultdict(list)
            for key, x in zip(self.series[q], v, strict=True):
                groups[key].append(x)
            n_eff = effective_count([np.asarray(g) for g in groups.values()])
            n_eff = min(n_eff, run_scatter_count(v, np.asarray(self.run_of[q])))
            lo, hi = chi2_interval(n_eff, self.dims[q])
            out.append(Row(quantity=q, n=v.size, n_eff=n_eff, d=self.dims[q], mean=float(v.mean()), lo=lo, hi=hi))
        return out


def _order(q: str) -> tuple[int, str]:
    heads = ("R cam", "R cam axis", "R map", "track Sigma confirm", "track Sigma end", "SLAM pose")
    return max((i for i, head in enumerate(heads) if q.startswith(head)), default=len(heads)), q


def match_detections(detections, visible) -> list[int | None]:
    """For each detection, the id of the visible truth object it boxes: same type, nearest box
    centre within MATCH_FRACTION of the box's larger side; None when there is none."""
    out: list[int | None] = []
    for det in detections:
        cu, cv = det.center_uv
        best, best_d = None, np.inf
        for v in visible:
            if v.type != det.type:
                continue
            x1, y1, x2, y2 = v.box_xyxy
            dist = float(np.hypot(0.5 * (x1 + x2) - cu, 0.5 * (y1 + y2) - cv))
            if dist < best_d and dist <= MATCH_FRACTION * max(x2 - x1, y2 - y1, 1.0):
                best, best_d = v.id, dist
        out.append(best)
    return out


def box_size_at_depth(obs, intr) -> tuple[float, float] | None:
    """An observation's box as metres at its depth z, (w z / fx, h z / fy); None when
    :func:`poi.estimation.localize.localize` called the box cut (``Observation.box_cut``: by the
    image border, or by a nearer surface): it holds part of the item only."""
    if any(obs.box_cut):
        return None
    w, h = obs.detection.size_wh
    z = float(obs.position_cam[2])
    return w * z / intr.fx, h * z / intr.fy


class NeesCollector(Observer):
    """The NEES samples of one run (module docstring), an observer of its episode
    (:mod:`eval.trial.episode`): per frame the observations against the truth of the objects
    they box and the SLAM pose against the true tracker pose; at the end (:meth:`finish`) each
    confirmed track's mu and Sigma, at confirmation and at the end."""

    def __init__(
        self, samples: Samples, run: int, truth_map: dict[int, np.ndarray], solid_types: set[str]
    ) -> None:
        self.samples = samples
        self.run = run
        self.truth_map = truth_map
        self.solid_types = solid_types
        self.votes: dict[int, Counter] = defaultdict(Counter)
        self.confirmed_at: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.pose_series: list[float] = []
        self.last_pose: float | None = None

    def on_frame(self, tick: Tick) -> None:
        res, truth = tick.res, tick.step.truth
        if res.skipped_reason:
            return
        self._observations(res, truth, tick.frame.intrinsics)
        det_ids = match_detections(res.detections, truth.visible)
        for det, oid in zip(res.detections, det_ids, strict=True):
            if det.track_id is not None and oid is not None:
                self.votes[det.track_id][oid] += 1
        for snap in res.newly_confirmed:
            self.confirmed_at[snap.track_id] = (snap.position_map.copy(), snap.covariance.copy())
        slam = tick.pipe.slam
        if slam is not None and slam.slam is not None:
            self._pose(slam.slam, truth)

    def _observations(self, res, truth, intrinsics) -> None:
        samples, run = self.samples, self.run
        ids = match_detections([o.detection for o in res.observations], truth.visible)
        T_cam_map = invert_transform(truth.T_map_camera)
        for obs, oid in zip(res.observations, ids, strict=True):
            if oid is None:
                continue
            t = obs.detection.type
            p_true = self.truth_map[oid]
            e_cam = obs.position_cam - transform_points(T_cam_map, p_true)
            Sigma_cam = obs.Sigma_c if obs.Sigma_extent_c is None else obs.Sigma_c + obs.Sigma_extent_c
            run_object = (run, oid)  # this run's series of this object
            if t in self.solid_types:
                ray = obs.position_cam / float(np.linalg.norm(obs.position_cam))
                samples.extent.append(
                    ExtentSample(
                        type=t,
                        object_key=run_object,
                        e_cam=e_cam,
                        Sigma_c=obs.Sigma_c,
                        ray=ray,
                        box_m=box_size_at_depth(obs, intrinsics),
                    )
                )
            samples.add(f"R cam {t}", 3, nees(e_cam, Sigma_cam), run_object, run)
            for axis, q in zip(AXES, axis_nees(e_cam, Sigma_cam), strict=True):
                samples.add(f"R cam axis {axis}", 1, q, run_object, run)
            samples.add(f"R map {t}", 3, nees(obs.position_map - p_true, obs.R), run_object, run)

    def _pose(self, s, truth) -> None:
        run = self.run
        e = s.pose - planar_pose(truth.T_map_tracker)
        e[2] = wrap_angle(e[2])
        self.last_pose = nees(e, s.pose_covariance)
        self.samples.add("SLAM pose", POSE_DIM, self.last_pose, run, run)
        for q, (d, value) in pose_part_nees(e, s.pose_covariance).items():
            self.samples.add(f"SLAM pose {q}", d, value, run, run)
        self.pose_series.append(self.last_pose)

    def _object_of(self, track_id: int) -> int | None:
        """The object most of a track's detections came from."""
        votes = self.votes[track_id]
        return votes.most_common(1)[0][0] if votes else None

    def finish(self, confirmed, name: str) -> None:
        """The tracks' samples, from the run's ``confirmed`` tracks at the end; ``name`` labels
        the run's pose series."""
        samples, run = self.samples, self.run
        for tid, (mu, Sigma) in sorted(self.confirmed_at.items()):
            oid = self._object_of(tid)
            if oid is not None:
                samples.add("track Sigma confirm", 3, nees(mu - self.truth_map[oid], Sigma), run=run)
        for snap in confirmed:
            oid = self._object_of(snap.track_id)
            if oid is not None:
                samples.add(
                    "track Sigma end", 3, nees(snap.position_map - self.truth_map[oid], snap.covariance), run=run
                )
        if self.last_pose is not None:
            samples.add("SLAM pose end", POSE_DIM, self.last_pose, run=run)
            samples.pose_series.append((name, self.pose_series))


def clean_oracle(sc, sim):
    """The oracle a consistency run uses: ground-truth boxes with the pipeline's own centre
    noise, no confusions, no false boxes (the arena's classes in the goal arena)."""
    from sim.oracle import ARENA_MIN_BOX_PX, OracleDetector, OracleSettings

    oracle_kw = {"seed": sc.seed, "confusion_rate": 0.0, "false_positives_per_frame": 0.0}
    if sim.arena is not None:
        from poi.core.names import ARENA_TYPES

        oracle_kw.update(classes=ARENA_TYPES, min_box_px=ARENA_MIN_BOX_PX)
    return OracleDetector(OracleSettings(**oracle_kw))


def collect_run(sc, samples: Samples, *, frames: int | None, pipeline_sets: list[str] = ()) -> int:
    """Simulate ``sc`` (its noise as it is set) for up to ``frames`` frames through the pipeline
    behind a clean oracle (:func:`clean_oracle`) and add its NEES samples to ``samples``
    (:class:`NeesCollector`); returns the frames run. The pipeline is configured as a trial's
    (:func:`eval.trial.pipeline_config.trial_pipeline_config`), without the thermal detector (the
    oracle boxes heat sources)."""
    from eval.trial.episode import run_episode
    from eval.trial.pipeline_config import trial_pipeline_config
    from eval.trial.sources import SimulationSource
    from poi.pipeline import Pipeline

    run = samples.runs
    samples.runs += 1
    source = SimulationSource(sc, frames)
    try:
        sets = ["thermal.enabled=false", *pipeline_sets]
        cfg = trial_pipeline_config("oracle", sets, sensor_sets=source.sensor_settings())
        lc = cfg.localize
        solid_types = {t for t, row in lc.types.items() if row.shape in ("body", "leaf")}
        source.oracle = clean_oracle(sc, source.sim)
        pipe = Pipeline(cfg, [source.oracle])
        truth_map = {o.id: np.asarray(o.position_map, dtype=float) for o in source.sim.truth_objects()}
        collector = NeesCollector(samples, run, truth_map, solid_types)
        run_episode(source, pipe, [collector], desc="consistency")
        collector.finish(pipe.confirmed(), f"{sc.name} (seed {sc.seed})")
        return source.n_frames
    finally:
        source.close()


@dataclass(kw_only=True)
class ConsistencyResult:
    rows: list[Row]
    runs: list[str]
    frames: int
    samples: Samples


def run_consistency(
    scenarios: list,
    *,
    frames: int | None,
    pipeline_sets: list[str] = (),
    progress: Callable[[str], None] | None = None,
) -> ConsistencyResult:
    """NEES over the runs of ``scenarios`` (each a :class:`sim.scenario.Scenario`, noise on)."""
    if not scenarios:
        raise ConsistencyError("consistency: no scenario to run")
    samples = Samples()
    total = 0
    names = []
    for sc in scenarios:
        if not sc.sensors.noise:
            raise ConsistencyError(f"consistency: scenario {sc.name}: sensor noise is off; NEES needs it on")
        if progress is not None:
            progress(f"{sc.name} (seed {sc.seed})")
        total += collect_run(sc, samples, frames=frames, pipeline_sets=list(pipeline_sets))
        names.append(f"{sc.name}:{sc.seed}")
    return ConsistencyResult(rows=samples.rows(), runs=names, frames=total, samples=samples)


def format_table(rows: list[Row]) -> str:
    """The table ``poibench consistency`` prints."""
    head = f"{'quantity':<32} {'N':>6} {'N_eff':>6} {'d':>2} {'mean NEES':>10}  {'99% interval':<17} inside"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r.quantity:<32} {r.n:>6} {r.n_eff:>6.1f} {r.d:>2} {r.mean:>10.3f}  [{r.lo:6.3f}, {r.hi:6.3f}]  "
            f"{'yes' if r.inside else 'NO'}"
        )
    return "\n".join(lines) + "\n"


def write_outputs(result: ConsistencyResult, out: Path, meta: dict) -> list[Path]:
    """consistency.json (the table and the settings) and consistency.png (the plot)."""
    out.mkdir(parents=True, exist_ok=True)
    doc = {
        "poibench_consistency": 1,
        **meta,
        "runs": result.runs,
        "frames": result.frames,
        "rows": [r.to_dict() for r in result.rows],
    }
    js = out / "consistency.json"
    js.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    png = out / "consistency.png"
    plot(result, png, title=str(meta.get("title", "")))
    return [js, png]


def plot(result: ConsistencyResult, path: Path, title: str = "") -> None:
    """Left: each quantity's mean NEES / d with its 99% interval / d (log scale). Right: the
    SLAM pose NEES of each run over its frames against the one-sample chi2(3) 99% band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result.rows
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(13, max(4.0, 0.3 * len(rows) + 1.5)))
    y = np.arange(len(rows))[::-1]
    for yi, r in zip(y, rows, strict=True):
        ax.plot([r.lo / r.d, r.hi / r.d], [yi, yi], color="0.6", lw=6, solid_capstyle="butt")
        ax.plot(r.mean / r.d, yi, "o", color="tab:green" if r.inside else "tab:red")
    ax.axvline(1.0, color="0.3", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_yticks(y, [f"{r.quantity} (N={r.n}, N_eff={r.n_eff:.0f})" for r in rows], fontsize=8)
    ax.set_xlabel("mean NEES / d (grey: 99% interval)")
    ax.set_title(title or "NEES against its chi-square interval")
    lo, hi = chi2.ppf([0.005, 0.995], POSE_DIM)
    for name, series in result.samples.pose_series:
        bx.plot(np.arange(len(series)), np.maximum(series, 1e-3), lw=0.8, label=name)
    bx.axhspan(lo, hi, color="0.85", label="chi2(3) 99% of single samples")
    bx.set_yscale("log")
    bx.set_xlabel("frame")
    bx.set_ylabel("SLAM pose NEES")
    bx.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
