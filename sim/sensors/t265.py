"""T265 pose: 200 Hz samples with 6-DoF drift, jitter, latency, relocalisation and dropouts.

docs/FACTS.md "T265 tracking camera" gives the sources ([IntelT265]: 200 Hz pose;
[T265Issues]: drift of about 1% of distance, jumps, dropouts; [Hesch2014]: a
visual-inertial tracker cannot observe its global position and yaw, while gravity
keeps roll and pitch observable). The error model is **poibench**'s.

The tracker samples its pose every 1 / ``rate_hz`` seconds, at multiples of that period
(its own clock, not the frames'). At sample i, with ds_i
the distance travelled since the last sample and m_i >= 1 the drift multiplier of
the scene there (:mod:`sim.sensors.tracking_conditions`; 1 where light and texture
are good), the effective distance is dse_i = m_i ds_i and, with p_true the true
position and dp_i = p_true(i) - p_true(i - 1)::

    p_est(i) = p0 + sum_j<=i (1 + scale_error) Rz(psi_j-1) dp_j + e_xy(i) + e_z(i) + J(i) + w_p
    R_est(i) = Rz(psi_i) Rx(r_i) Ry(q_i) R_true(i) exp(w_r)

* e_xy: a random walk in x and y, e_xy(i) = e_xy(i-1) + drift_fraction dse_i u_i, u_i a
  horizontal unit vector whose direction wanders by N(0, 0.2^2 ds_i) rad;
* e_z = b_z s_eff(i), with b_z ~ N(0, z_drift_fraction^2) drawn once (s_eff = sum dse);
* psi_i = +-yaw_drift_deg_per_m s_eff(i) (sign drawn once): heading error, which also
  turns every later step (so it grows into position error as it does on the device);
* r_i, q_i (roll, pitch): Gauss-Markov in distance, x_i = a x_i-1 + sqrt(1 - a^2) sigma n_i
  with a = exp(-dse_i / tilt_correlation_m): bounded at tilt_sigma_deg, not drifting;
* J: false relocalisations (``jumps``: Poisson at rate_per_min m_i, N(0, sigma^2) in x, y)
  and loop closures (``relocalise``): back within radius_m of a place it passed min_gap_m
  or more of travel ago, facing within max_heading_deg of the same way, the tracker
  recognises it with probability ``probability`` / m_i at each keyframe (one every
  ``keyframe_m`` of travel), and its position and yaw errors jump back toward those of
  the earlier visit by ``strength`` (1: all the error gained since);
* w_p, w_r: white jitter per sample (``jitter_m``, ``jitter_deg``).

Frame k at time t_k gets the estimate of time t_k - latency_s, interpolated between
the two samples around it (positions linearly, rotations by slerp): a stale pose, as a
pipeline that reads the latest pose at a frame's arrival gets. With ``latency_extrapolate``
the same two samples are extrapolated to t_k (constant velocity, as librealsense's pose
prediction does). Dropouts (Poisson, 3-7 s) deliver no pose, confidence "low"; frames
within 2 s after a false jump have confidence "medium". A frame whose pose is the first to
include a jump (a loop closure or a false one) since the last frame with a pose is flagged
``relocalised``: the real device tells the host of each relocalisation (librealsense's
RS2_NOTIFICATION_CATEGORY_POSE_RELOCALIZATION, [IntelNotifications]). With noise off the pose is the
truth at t_k.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from poi.core.loader import number
from sim.sensors.base import PoseFunction, PoseTrack, TrackerMotion
from sim.sensors.tracking_conditions import T265ConditionsSpec


@dataclass(kw_only=True)
class JumpSpec:
    """False relocalisations: Poisson jumps of N(0, sigma_m^2) in x and y, at ``rate_per_min``
    in good conditions (times the T265's drift multiplier where the scene is dim or bare)."""

    rate_per_min: float = number(0.0, lo=0.0)
    sigma_m: float = number(0.2, lo=0.0)


@dataclass(kw_only=True)
class DropoutSpec:
    rate_per_min: float = number(0.0, lo=0.0)
    duration_s: tuple[float, float] = number((3.0, 7.0), lo=0.0)

    def __post_init__(self) -> None:
        if self.duration_s[0] > self.duration_s[1]:
            raise ValueError(f"duration_s: expected (shortest, longest), got {list(self.duration_s)}")


@dataclass(kw_only=True)
class RelocaliseSpec:
    """Loop closure: back at a place it mapped ``min_gap_m`` or more of travel ago (within
    ``radius_m``, heading within ``max_heading_deg``), the T265 recognises it with probability
    ``probability`` / multiplier per keyframe (one every ``keyframe_m``), and its pose jumps back
    toward the truth: ``strength`` of the error gained since that visit is removed.
    **poibench**'s model of librealsense's relocalisation with pose jumping on ([T265Issues])."""

    enabled: bool = True
    radius_m: float = number(0.5, lo=0.0, lo_open=True)
    min_gap_m: float = number(5.0, lo=0.0)
    max_heading_deg: float = number(60.0, lo=0.0, hi=180.0)
    probability: float = number(0.3, lo=0.0, hi=1.0)
    strength: float = number(1.0, lo=0.0, hi=1.0)
    keyframe_m: float = number(0.5, lo=0.0, lo_open=True)


@dataclass(kw_only=True)
class T265Spec:
    """The T265 pose model (sim/sensors/t265.py; docs/FACTS.md "T265 tracking camera").

    Per-axis drift, in distance travelled (times the conditions' multiplier): ``drift_fraction``
    (x and y: a random walk whose size grows by this fraction of the distance, its direction
    wandering), ``z_drift_fraction`` (z: a rate drawn once, N(0, this^2) metres per metre),
    ``yaw_drift_deg_per_m`` (yaw: a bias of this size, its sign drawn once), ``tilt_sigma_deg``
    and ``tilt_correlation_m`` (roll and pitch: bounded, a Gauss-Markov error of this standard
    deviation and correlation length; gravity keeps them observable). Poses come at
    ``rate_hz`` with white ``jitter_m`` / ``jitter_deg`` per sample; frame k gets the pose of
    time t_k - ``latency_s`` (SE(3)-interpolated between samples), or that pose extrapolated
    to t_k at the last samples' velocity with ``latency_extrapolate``.
    """

    enabled: bool = True
    drift_fraction: float = number(0.007, lo=0.0)
    z_drift_fraction: float = number(0.002, lo=0.0)
    yaw_drift_deg_per_m: float = number(0.08, lo=0.0)
    tilt_sigma_deg: float = number(0.3, lo=0.0)
    tilt_correlation_m: float = number(5.0, lo=0.0, lo_open=True)
    scale_error: float = number(0.0, lo=-1.0, lo_open=True)  # -0.2 means distances reported 20% short
    rate_hz: float = number(200.0, lo=1.0, hi=1000.0)
    latency_s: float = number(0.01, lo=0.0, hi=1.0)
    latency_extrapolate: bool = False
    jitter_m: float = number(0.0005, lo=0.0)
    jitter_deg: float = number(0.02, lo=0.0)
    conditions: T265ConditionsSpec = field(default_factory=T265ConditionsSpec)
    relocalise: RelocaliseSpec = field(default_factory=RelocaliseSpec)
    jumps: JumpSpec = field(default_factory=JumpSpec)
    dropouts: DropoutSpec = field(default_factory=DropoutSpec)


DRIFT_DIRECTION_WANDER_RAD_PER_SQRT_M = 0.2  # direction decorrelates over about 50 m
JUMP_CONFIDENCE_S = 2.0


@dataclass(kw_only=True)
class TrackingConditions:
    """The drift multiplier (>= 1; 1 in good light and texture) at times ``t_s``."""

    t_s: np.ndarray
    multiplier: np.ndarray


def interpolate_se3(Ta: np.ndarray, Tb: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Poses a fraction ``f`` of the way from ``Ta`` to ``Tb`` (each (n, 4, 4)): positions
    linearly, rotations along the geodesic, Ra exp(f log(Ra^T Rb)) (slerp). f outside [0, 1]
    extrapolates at the same velocity.

    >>> from poi.core.geometry import make_transform, rot_z
    >>> T = interpolate_se3(make_transform(np.eye(3), [0, 0, 0])[None],
    ...                     make_transform(rot_z(0.4), [2, 0, 0])[None], np.array([0.25]))
    >>> np.round(T[0, :3, 3], 6).tolist(), round(float(np.arctan2(T[0, 1, 0], T[0, 0, 0])), 6)
    ([0.5, 0.0, 0.0], 0.1)
    """
    f = np.asarray(f, dtype=float)
    Ra, Rb = Ta[:, :3, :3], Tb[:, :3, :3]
    rel = Rotation.from_matrix(np.einsum("nji,njk->nik", Ra, Rb)).as_rotvec()
    out = np.zeros(Ta.shape)
    out[:, :3, :3] = Ra @ Rotation.from_rotvec(rel * f[:, None]).as_matrix()
    out[:, :3, 3] = Ta[:, :3, 3] + f[:, None] * (Tb[:, :3, 3] - Ta[:, :3, 3])
    out[:, 3, 3] = 1.0
    return out


def pose_interpolator(t_s: np.ndarray, T: np.ndarray | list[np.ndarray]) -> PoseFunction:
    """A :data:`PoseFunction` through known poses at increasing times ``t_s`` (SE(3)
    interpolation between them, held at the ends)."""
    t_known = np.asarray(t_s, dtype=float)
    T_known = np.asarray(T, dtype=float)

    def poses(t: np.ndarray) -> np.ndarray:
        t = np.clip(np.asarray(t, dtype=float), t_known[0], t_known[-1])
        a = np.clip(np.searchsorted(t_known, t, side="right") - 1, 0, max(len(t_known) - 2, 0))
        b = np.minimum(a + 1, len(t_known) - 1)
        span = t_known[b] - t_known[a]
        f = np.divide(t - t_known[a], span, out=np.zeros_like(t), where=span > 0)
        return interpolate_se3(T_known[a], T_known[b], f)

    return poses


def _gauss_markov(dse: np.ndarray, n: np.ndarray, sigma: float, length_m: float) -> np.ndarray:
    """x_i = a_i x_i-1 + sqrt(1 - a_i^2) sigma n_i, a_i = exp(-dse_i / length_m), x_0 = 0."""
    a = np.exp(-dse / length_m)
    b = np.sqrt(1.0 - a * a) * sigma
    x = np.zeros(len(dse))
    acc = 0.0
    for i in range(1, len(dse)):
        acc = a[i] * acc + b[i] * n[i]
        x[i] = acc
    return x


def _estimate(
    Tg: np.ndarray,
    p_est: np.ndarray,
    psi: np.ndarray,
    roll: np.ndarray,
    pitch: np.ndarray,
    jitter_r: np.ndarray,
    idx: np.ndarray,
) -> np.ndarray:
    """The reported poses of samples ``idx``: R = Rz(psi) Rx(roll) Ry(pitch) R_true exp(jitter)."""
    R_err = Rotation.from_euler("ZXY", np.stack([psi[idx], roll[idx], pitch[idx]], axis=1)).as_matrix()
    T = np.zeros((len(idx), 4, 4))
    T[:, :3, :3] = R_err @ Tg[idx, :3, :3] @ Rotation.from_rotvec(jitter_r[idx]).as_matrix()
    T[:, :3, 3] = p_est[idx]
    T[:, 3, 3] = 1.0
    return T


def simulate_t265(
    truth: PoseFunction,
    t_s: np.ndarray,
    spec: T265Spec,
    rng: np.random.Generator,
    noise: bool,
    conditions: TrackingConditions | None = None,
) -> PoseTrack:
    """The T265's reported poses at frame times ``t_s``, from the true tracker poses
    ``truth(t)`` at any times, and the drift multiplier along the way (None: 1)."""
    t_s = np.asarray(t_s, dtype=float)
    n = len(t_s)
    if not spec.enabled:
        return PoseTrack(
            poses=[None] * n, confidence=["failed"] * n, error_m=np.full(n, np.nan), relocalised=[False] * n
        )
    T_frames = truth(t_s)
    if not noise:
        return PoseTrack(
            poses=[T.copy() for T in T_frames],
            confidence=["high"] * n,
            error_m=np.zeros(n),
            relocalised=[False] * n,
        )

    dt = 1.0 / spec.rate_hz
    t0 = (np.floor((t_s[0] - spec.latency_s) / dt) - 1.0) * dt  # samples at multiples of dt: own clock
    N = int(np.ceil((t_s[-1] - t0) / dt)) + 2
    grid = t0 + dt * np.arange(N)
    Tg = truth(grid)
    p_true = Tg[:, :3, 3]
    dp = np.diff(p_true, axis=0, prepend=p_true[:1])
    ds = np.linalg.norm(dp, axis=1)
    s = np.cumsum(ds)
    mult = np.ones(N) if conditions is None else np.interp(grid, conditions.t_s, conditions.multiplier)
    dse = ds * mult
    s_eff = np.cumsum(dse)

    # draws in a fixed order, each vectorised, so the stream does not depend on branches
    wander = rng.standard_normal(N) * DRIFT_DIRECTION_WANDER_RAD_PER_SQRT_M * np.sqrt(ds)
    theta = rng.uniform(0.0, 2.0 * np.pi) + np.cumsum(wander)
    yaw_sign = 1.0 if rng.random() < 0.5 else -1.0
    z_rate = rng.standard_normal() * spec.z_drift_fraction
    tilt_n = rng.standard_normal((2, N))
    jitter_p = rng.standard_normal((N, 3)) * spec.jitter_m
    jitter_r = rng.standard_normal((N, 3)) * np.deg2rad(spec.jitter_deg)
    duration_min = max(float(grid[-1] - grid[0]), 1e-9) / 60.0
    m_max = float(mult.max())
    n_cand = rng.poisson(spec.jumps.rate_per_min * m_max * duration_min)
    cand_t = np.sort(rng.uniform(grid[0], grid[-1], n_cand))
    cand_keep = rng.uniform(0.0, m_max, n_cand) < np.interp(cand_t, grid, mult)
    cand_xy = rng.standard_normal((n_cand, 2)) * spec.jumps.sigma_m
    n_drop = rng.poisson(spec.dropouts.rate_per_min * max(float(t_s[-1] - t_s[0]), 1e-9) / 60.0)
    drop_t = rng.uniform(t_s[0], t_s[-1], n_drop)
    drop_len = rng.uniform(*spec.dropouts.duration_s, size=n_drop)
    rel = spec.relocalise
    kf = np.unique(np.searchsorted(s, np.arange(0.0, s[-1], rel.keyframe_m)))
    kf_u = rng.random(len(kf))

    u = np.stack([np.cos(theta), np.sin(theta), np.zeros(N)], axis=1)
    offset = np.cumsum(spec.drift_fraction * dse[:, None] * u, axis=0)  # e_xy
    offset[:, 2] += z_rate * s_eff
    jump_t = cand_t[cand_keep]
    for tj, dxy in zip(jump_t, cand_xy[cand_keep], strict=True):
        offset[grid >= tj, :2] += dxy
    psi = yaw_sign * np.deg2rad(spec.yaw_drift_deg_per_m) * s_eff
    step = (1.0 + spec.scale_error) * dp

    def increments(lo: int) -> np.ndarray:  # steps lo.. turned by the yaw error before them
        psi_prev = psi[lo - 1 : N - 1] if lo > 0 else np.r_[0.0, psi[:-1]]
        c, sn = np.cos(psi_prev), np.sin(psi_prev)
        st = step[lo:]
        return np.stack([c * st[:, 0] - sn * st[:, 1], sn * st[:, 0] + c * st[:, 1], st[:, 2]], axis=1)

    inc = increments(0)
    cum = np.cumsum(inc, axis=0)
    p_est = p_true[0] + cum + offset
    reloc_t: list[float] = []
    jump_samples = list(np.searchsorted(grid, jump_t, side="left"))  # first sample each jump moves
    if rel.enabled and len(kf) > 1 and rel.probability > 0:
        yaw_true = np.arctan2(Tg[:, 1, 0], Tg[:, 0, 0])
        max_dyaw = np.deg2rad(rel.max_heading_deg)
        for a, ia in enumerate(kf):
            if kf_u[a] >= rel.probability / mult[ia]:
                continue
            ib = kf[:a][s[kf[:a]] <= s[ia] - rel.min_gap_m]  # earlier keyframes, far enough back
            if len(ib) == 0:
                continue
            d = np.linalg.norm(p_true[ib] - p_true[ia], axis=1)
            dyaw = np.abs((yaw_true[ib] - yaw_true[ia] + np.pi) % (2.0 * np.pi) - np.pi)
            ok = (d <= rel.radius_m) & (dyaw <= max_dyaw)
            if not ok.any():
                continue
            ib = int(ib[ok][np.argmin(d[ok])])
            err_now, err_then = p_est[ia] - p_true[ia], p_est[ib] - p_true[ib]
            offset[ia:] -= rel.strength * (err_now - err_then)
            psi[ia:] -= rel.strength * (psi[ia] - psi[ib])
            # the steps after ia turn by the corrected yaw error; those before keep theirs
            inc[ia + 1 :] = increments(ia + 1)
            cum[ia + 1 :] = cum[ia] + np.cumsum(inc[ia + 1 :], axis=0)
            p_est[ia:] = p_true[0] + cum[ia:] + offset[ia:]
            reloc_t.append(float(grid[ia]))
            jump_samples.append(int(ia))
    p_est = p_est + jitter_p

    tilt = np.deg2rad(spec.tilt_sigma_deg)
    roll = _gauss_markov(dse, tilt_n[0], tilt, spec.tilt_correlation_m)
    pitch = _gauss_markov(dse, tilt_n[1], tilt, spec.tilt_correlation_m)

    # frame k: the estimate of t_k - latency, from the two samples around that time
    tau = t_s - spec.latency_s
    ia = np.clip(np.floor((tau - grid[0]) / dt).astype(int), 0, N - 2)
    f = ((t_s if spec.latency_extrapolate else tau) - grid[ia]) / dt
    T_out = interpolate_se3(
        _estimate(Tg, p_est, psi, roll, pitch, jitter_r, ia),
        _estimate(Tg, p_est, psi, roll, pitch, jitter_r, ia + 1),
        f,
    )

    dropped = np.zeros(n, dtype=bool)
    for d0, dl in zip(drop_t, drop_len, strict=True):
        dropped |= (d0 <= t_s) & (t_s < d0 + dl)
    since = t_s[:, None] - jump_t[None, :]
    recent_jump = np.any((since >= 0.0) & (since < JUMP_CONFIDENCE_S), axis=1)
    err = np.linalg.norm(T_out[:, :3, 3] - T_frames[:, :3, 3], axis=1)
    err[dropped] = np.nan
    poses = [None if dropped[k] else T_out[k] for k in range(n)]
    conf = ["low" if dropped[k] else "medium" if recent_jump[k] else "high" for k in range(n)]
    return PoseTrack(
        poses=poses,
        confidence=conf,
        error_m=err,
        relocalisations_s=np.array(reloc_t),
        relocalised=relocalised_frames(np.asarray(jump_samples, dtype=int), ia + 1, dropped),
    )


def relocalised_frames(jump_samples: np.ndarray, last_sample: np.ndarray, dropped: np.ndarray) -> list[bool]:
    """Per frame: whether its pose is the first since the last delivered one to include a jump.
    ``jump_samples``: the first sample index each jump moves; ``last_sample``: the latest
    sample index each frame's pose is made from; ``dropped``: frames without a pose.

    >>> relocalised_frames(np.array([5]), np.array([2, 4, 5, 7]), np.zeros(4, bool))
    [False, False, True, False]
    >>> relocalised_frames(np.array([5]), np.array([2, 4, 5, 7]), np.array([False, False, True, False]))
    [False, False, False, True]
    """
    seen = np.searchsorted(np.sort(jump_samples), last_sample, side="right")  # jumps in each pose
    out: list[bool] = []
    before = None  # jumps in the last delivered pose
    for count, gone in zip(seen, dropped, strict=True):
        out.append(bool(not gone and before is not None and count > before))
        if not gone:
            before = int(count)
    return out


@dataclass(kw_only=True)
class T265:
    """The T265 as a trial's pose sensor (:class:`sim.sensors.base.PoseSensor`): its drift
    scaled along the route by ``conditions`` (the light and texture where it is)."""

    spec: T265Spec
    noise: bool
    conditions: TrackingConditions | None = None

    def track(self, motion: TrackerMotion, rng: np.random.Generator) -> PoseTrack:
        return simulate_t265(motion.poses_at, motion.times_s, self.spec, rng, self.noise, self.conditions)
