"""Object tracking: Mahalanobis gating, pairing, Kalman update, support ([Avevor2022]_ 2.4, [Bouda2025]_ 2.2.5).

Each track is a static object: position mu with covariance Sigma (map frame), a
distribution over :data:`poi.core.names.CLASSES`, and for QR codes the decoded strings
with their vote counts. Per frame (:meth:`Tracker.step`):

1. m^2 = (o - mu)^T (Sigma + R)^-1 (o - mu) for every observation/track pair of the
   same type ([Avevor2022]_ 2.4.3); a QR observation with a decoded text never pairs with a
   QR track that has a different text. Pairs need m^2 < gate (strict).
2. Pairing: the greedy loop of [Avevor2022]_ 2.4.3, or an optimal (Hungarian) assignment.
3. Paired tracks get the Kalman update with H = I ([Avevor2022]_ 2.4.4; covariance in Joseph's
   form, :func:`kalman_update`; with the errors that repeat over frames kept apart, see
   below), support + 1 and
   their class distribution fused; each such update's innovation, its covariance S and its
   d^2 (NIS) are in the step's result (:class:`Innovation`), to check the filter on a log
   that has no ground truth. An unpaired observation inside the gate of a
   track already taken this frame (or started by an earlier observation of this
   frame) is a duplicate detection of that object (two detectors, or two boxes on one
   object) and is dropped, unless both are QR boxes that do not meet (two codes side by side
   on one chart, closer than a gate); the other unpaired observations start tentative tracks.
4. Tracks in view but not paired lose ``miss_penalty`` support; a tentative track
   whose support falls below ``drop_support``, or not seen for ``t_max`` s ([Bouda2025]_
   2.2.5), is deleted. Confirmed tracks are never deleted.
5. A tentative track is confirmed once it has ``n_min`` detections and the largest
   standard deviation of its fresh part Sigma_w is at most ``settle_sigma_m``: what more
   views of the object can still shrink; the shared part (the pose's error, which a long
   run's drift grows) no view of the object removes, and a track waiting on it was never
   reported (rrl-hard's longest maze lost 22 of 106 points so; a QR or Landolt-C track also
   once it has text, a Landolt-C one once its rings read include
   ``landolt_required_rings``); confirmed tracks get report ids 0, 1, 2, ... in
   confirmation order.
6. One place, one object (``cross_type_radius_m``, **poibench**): a track is not confirmed,
   and a confirmed one is withdrawn (unconfirmed, its report id dropped) once another
   confirmed track does, while a track of another type whose mean lies within that radius
   wins the place's vote: each type's class mass over both tracks' detections, n_1 P_1(type) +
   n_2 P_2(type), P a track's fused class distribution and n its detections (on a tie, the
   older track wins). Step 1 pairs observations with tracks of their own type only, so a
   sign the detector now and then boxes as a doll grows a doll track on the sign; this is
   the class vote of [Avevor2022]_ 2.4.5 taken over the two tracks of one place instead of
   within one. A box of the wrong type is mostly an unsure one that gives the object's own
   type some of its mass (measured in docs/results/detectors.md), so an object boxed
   as another type more often than as its own can still win. The radius must
   stay under half the spacing of real neighbours of two types (at least 0.41 m in the
   shipped worlds). A track whose identity was read from pixels (:data:`READ_TYPES` with
   text: a Landolt-C target's rings, each with its gap, or a QR code's decoded text) settles
   its place without a vote: that structure shows on nothing else, while any other type there
   is the network's guess (the shipped detector boxes the black-and-white Landolt-C cards as
   corrosive placards and QR pages as poison ones: all 6 of its false reports in the ``rmrc``
   trial; on the ``rrl`` suite it boxes QR codes as extinguisher signs). A track of a type not
   read from pixels within the radius of one is not confirmed, has no vote there, and one
   confirmed before the reading is withdrawn. The vote is taken again each frame, as the
   class vote within a track is: a track confirmed while it won its place (often before the
   place's own object was seen enough) is withdrawn once a confirmed track of another type
   wins it, and may be confirmed again if it wins it back.
7. One code, one report (``same_text_radius_m``, **poibench**): a QR track is not confirmed,
   and a confirmed one is withdrawn, while a QR track confirmed before it with the same decoded
   text lies within that radius. A code's text is its identity (a second report of it is a
   false duplicate under every preset), and two tracks of one code arise when its observations
   are biased alike and their covariances small (a miscalibrated mount: ``rrl-hard``'s
   ``hard-02`` reported Chart B twice, 0.19 m apart and 0.27 m above the code, each outside
   the other's gate). Codes of other texts side by side, as on an RMRC chart, are unaffected.

Errors that repeat (``tracker.shared_errors``, on by default). The document fuses every
observation as if its error were fresh. Part of it is not: the pose error (the SLAM's, or
``Sigma_eps``), and which side of an object the depth hits, are nearly the same in
successive frames, so averaging n observations does not shrink them, and a track's
``Sigma`` came out over-confident (``poibench consistency``: README, "Covariance
consistency"). Each observation's R is split into a fresh part ``R_w`` and a shared part
``R_s = L_o L_o^T`` (:attr:`poi.core.types.Observation.R_shared`, ``L_o`` its symmetric
square root), modelled as one common error ``L_o z``, z ~ N(0, I) for all of a track's
observations (the "consider" idea of the Schmidt-Kalman filter in its simplest form: the
shared error is carried, not estimated). The track keeps ``Sigma_w`` and ``L``: the gain
``K`` weighs the fresh errors, ``Sigma_w`` gets Joseph's form with ``R_w``, and ``L`` goes
where the mean goes, ``L+ = (I - K) L + K L_o``; the track reports
``Sigma = Sigma_w + L L^T``, which never falls below the shared part
(:func:`shared_error_update`). The gate uses that ``Sigma`` plus the observation's whole R.

The shared error is not always one error: the pose error moves at each SLAM update, with its
covariance about the same. The fresh parts are thin (a few tenths of a millimetre along the
ray, where a sign's depth plane averages many pixels) and their thin axes turn from view to
view, so the gain ``Sigma_w (Sigma_w + R_w)^-1``, the best one while the shared error stays,
had entries near 2 off its diagonal and swung tracks along those axes on a shared error that
moved: a rrl-hard placard's track ended 0.5 m off with a NEES of 230. The gain's innovation
covariance therefore also holds what no fresh error explains: the change of the shared
factor, ``D = L_o - L``, and ``tracker.shared_change`` times the shared covariance
(docs/CONSISTENCY.md "A track's gain and a shared error that moves").

Gate allowance (``tracker.gate_allowance_m``, per type). A 3-D object seen from another side,
or boxed differently by the detector (a door cut by the image border, a heater by the
thermal camera's grille), lands elsewhere by more than R says of one view, and its track
would split. The association's m^2 therefore adds ``allowance^2 I`` to ``Sigma + R``
(:meth:`Tracker.distances`); R and Sigma, which the fusion, the confirmation and the report
use, stay what the models say, so ``poibench consistency`` can hold them to the truth.

>>> mu, Sigma = kalman_update(np.zeros(3), np.eye(3), np.array([2.0, 0.0, 0.0]), np.eye(3))
>>> mu.tolist(), np.diag(Sigma).tolist()
([1.0, 0.0, 0.0], [0.5, 0.5, 0.5])

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [BarShalom2001] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, "Estimation with Applications to
   Tracking and Navigation", Wiley, 2001.
.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import update as filterpy_update

from poi.config import TrackerConfig
from poi.core.assignment import optimal_assignment
from poi.core.geometry import iou_matrix
from poi.core.landolt import merge_orientation_votes, parse_orientation_text
from poi.core.names import CLASS_INDEX, CLASS_TYPES, CLASSES, HAZMAT_LABELS
from poi.core.types import Observation, TrackSnapshot
from poi.estimation.covariance import Calibration

N_CLASSES = len(CLASSES)
IDENTITY3 = np.eye(3)  # H: a track's position is observed directly
HAZMAT_SLICE = slice(0, len(HAZMAT_LABELS))  # hazmat labels come first in CLASSES
TEXT_TYPES = ("qr", "landolt-c")  # types whose text is read from pixels and voted on over frames
READ_TYPES = TEXT_TYPES  # a track of these with text settles its place against placard guesses (step 6)
# type -> (N_CLASSES,) bool: the classes of that type (a placard's 16 labels, one for each other type)
TYPE_CLASSES = {t: np.array([u == t for u in CLASS_TYPES]) for t in set(CLASS_TYPES)}


class TrackerError(ValueError):
    """Tracker settings or inputs that do not fit together."""


def kalman_update(
    mu: np.ndarray, Sigma: np.ndarray, o: np.ndarray, R: np.ndarray, K: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """One Kalman update with H = I ([Avevor2022]_ 2.4.4).

    mu+ = mu + K (o - mu), and the covariance in Joseph's form ([BarShalom2001]_ 5.2),
    Sigma+ = (I - K) Sigma (I - K)^T + K R K^T. Without ``K`` the gain is the optimal
    K = Sigma (Sigma + R)^-1 and the update is filterpy's ``update(mu, Sigma, o, R, H=I)``;
    for it Joseph's form equals the document's Sigma - K Sigma, but it is a sum of positive
    semidefinite terms, so it stays positive definite when R << Sigma (a track started from the
    prior diag(100, 100, 4) and a centimetre R), where Sigma - K Sigma is a difference of nearly
    equal numbers. Joseph's form holds for any gain, so a given ``K`` (filterpy takes none:
    :func:`shared_error_update` needs one) is applied by hand.
    """
    if K is None:
        updated = filterpy_update(mu, Sigma, o, R, H=IDENTITY3)  # (x, P): without return_all
        mu_new, Sigma_new = updated[0], updated[1]
    else:
        A = IDENTITY3 - K
        mu_new, Sigma_new = mu + K @ (o - mu), A @ Sigma @ A.T + K @ R @ K.T
    return mu_new, 0.5 * (Sigma_new + Sigma_new.T)


def symmetric_sqrt(S: np.ndarray) -> np.ndarray:
    """The symmetric square root L of a positive semidefinite S (L L^T = L^2 = S), by
    eigendecomposition; negative rounding in the eigenvalues is taken as 0.

    >>> symmetric_sqrt(np.diag([4.0, 9.0, 0.0])).diagonal().tolist()
    [2.0, 3.0, 0.0]
    """
    w, V = np.linalg.eigh(0.5 * (S + S.T))
    return (V * np.sqrt(np.clip(w, 0.0, None))) @ V.T


def innovation_covariance(
    Sigma_w: np.ndarray, L: np.ndarray, R_w: np.ndarray, L_o: np.ndarray, change: float = 0.0
) -> np.ndarray:
    """S, the covariance of the innovation o - mu that :func:`shared_error_update` weighs.

    S = Sigma_w + R_w + D D^T + c L_o L_o^T with D = L_o - L: the fresh errors of track and
    observation, the part of the shared error they do not have in common, and the share ``c``
    (``tracker.shared_change``) of it that may have moved. With no shared part (L = L_o = 0)
    it is the plain Kalman filter's Sigma + R ([BarShalom2001]_ 5.2).

    >>> Z = np.zeros((3, 3))
    >>> np.diag(innovation_covariance(np.eye(3), Z, 2 * np.eye(3), Z)).tolist()
    [3.0, 3.0, 3.0]
    """
    D = L_o - L
    return Sigma_w + R_w + D @ D.T + change * (L_o @ L_o.T)


def shared_error_update(
    mu: np.ndarray,
    Sigma_w: np.ndarray,
    L: np.ndarray,
    o: np.ndarray,
    R_w: np.ndarray,
    L_o: np.ndarray,
    change: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One update with the errors that repeat kept apart (module docstring).

    The gain weighs the fresh errors, ``K = Sigma_w (Sigma_w + R_w + D D^T + c L_o L_o^T)^-1``:
    ``D = L_o - L`` is how far the observation's shared factor is from the track's, and ``c``
    (``change``, ``tracker.shared_change``) the share of the shared covariance that may have
    moved since the track's earlier views; both parts of the innovation are what no fresh error
    explains. mu+ = mu + K (o - mu). Each part of the error then goes where K takes it: the
    fresh part in Joseph's form, ``Sigma_w+ = (I - K) Sigma_w (I - K)^T + K R_w K^T``, which
    holds for any gain ([BarShalom2001]_ 5.2), and the shared error's factor as the mean goes,
    ``L+ = (I - K) L + K L_o``. The track's covariance is ``Sigma_w+ + L+ L+^T``.

    With equal shared parts and ``change`` 0 it is the Kalman update of the fresh parts, and
    the shared covariance stays as it is, however many observations are fused:

    >>> L = np.eye(3)
    >>> mu, Sw, L = shared_error_update(np.zeros(3), np.eye(3), L, np.ones(3), np.eye(3), np.eye(3))
    >>> mu.tolist(), np.diag(Sw).tolist(), np.diag(L @ L.T).tolist()
    ([0.5, 0.5, 0.5], [0.5, 0.5, 0.5], [1.0, 1.0, 1.0])
    """
    S = innovation_covariance(Sigma_w, L, R_w, L_o, change)
    K = np.linalg.solve(S, Sigma_w).T  # Sigma_w S^-1, both symmetric
    mu_new, Sigma_w_new = kalman_update(mu, Sigma_w, o, R_w, K)
    return mu_new, Sigma_w_new, (IDENTITY3 - K) @ L + K @ L_o


def mahalanobis2(o: np.ndarray, mu: np.ndarray, Sigma: np.ndarray, R: np.ndarray) -> float:
    """m^2 = (o - mu)^T (Sigma + R)^-1 (o - mu) ([Avevor2022]_ 2.4.3).

    >>> mahalanobis2(np.array([3.0, 0, 0]), np.zeros(3), 0.5 * np.eye(3), 0.5 * np.eye(3))
    9.0
    """
    r = o - mu
    return float(r @ np.linalg.solve(Sigma + R, r))


def pair_greedy(distances: np.ndarray, threshold: float) -> list[tuple[int, int]]:
    """The pairing loop of [Avevor2022]_ 2.4.3: closest pair first while m^2 < threshold.

    ``distances`` is M x N (observations x tracks); it is not modified. Entries that
    may never pair can be ``inf``.

    >>> pair_greedy(np.array([[1.0, 2.0], [2.5, 50.0]]), 9.0)
    [(0, 0)]
    """
    M, N = distances.shape
    pairs: list[tuple[int, int]] = []
    if M == 0 or N == 0:
        return pairs
    D = np.array(distances, dtype=float)
    i, j = np.unravel_index(np.argmin(D), D.shape)
    while D[i, j] < threshold:
        pairs.append((int(i), int(j)))
        D[i, :] = threshold  # observation i is no longer available
        D[:, j] = threshold  # track j is no longer available
        i, j = np.unravel_index(np.argmin(D), D.shape)
    return pairs


def pair_hungarian(distances: np.ndarray, threshold: float) -> list[tuple[int, int]]:
    """Optimal assignment (least total m^2 among the most pairs) keeping pairs with m^2 < threshold.

    :func:`poi.core.assignment.optimal_assignment` with the ``"sum"`` big M, the rule
    this tracker has always used (it decides which of equally good pairings is taken).

    >>> pair_hungarian(np.array([[1.0, 2.0], [2.5, 50.0]]), 9.0)
    [(0, 1), (1, 0)]
    """
    distances = np.asarray(distances, dtype=float)
    return optimal_assignment(distances, distances < threshold, rule="sum")


def observation_probs(obs: Observation, fusion: str, confusion: np.ndarray | None) -> np.ndarray:
    """The class distribution one detection contributes ([Avevor2022]_ 2.1.5).

    ``confusion``: p(actual B | detected A) = p for B = A and (1 - p) C[A, B] otherwise,
    with A the detected class and p its confidence. ``mean``: the detector's own
    distribution when it gives one, else p on A and (1 - p) spread evenly on the rest.
    """
    det = obs.detection
    A = CLASS_INDEX.get(det.class_name)
    if A is None:
        raise TrackerError(f"detection class {det.class_name!r} is not in poi.core.names.CLASSES")
    p = float(np.clip(det.confidence, 0.0, 1.0))
    if fusion == "confusion":
        if confusion is None:
            raise TrackerError("tracker.fusion=confusion needs a calibration file with a confusion matrix")
        q = (1.0 - p) * confusion[A]
        q[A] = p
        return q
    if det.class_probs is not None:
        q = np.asarray(det.class_probs, dtype=float)
        if q.shape != (N_CLASSES,) or not np.all(np.isfinite(q)) or q.sum() <= 0:
            raise TrackerError(f"detection class_probs: expected {N_CLASSES} finite values with a positive sum")
        return q / q.sum()
    q = np.full(N_CLASSES, (1.0 - p) / (N_CLASSES - 1))
    q[A] = p
    return q


@dataclass(kw_only=True)
class Track:
    """One tracked object ([Avevor2022]_ 2.4.1: position mu, covariance Sigma, probabilities p).
    Sigma is kept as its fresh part ``Sigma_w`` and the shared error's factor ``L_shared``
    (module docstring)."""

    track_id: int
    type: str
    mu: np.ndarray
    Sigma_w: np.ndarray
    L_shared: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    probs: np.ndarray
    n_prob: int = 1
    text_votes: dict[str, int] = field(default_factory=dict)
    support: float = 1.0
    n_detections: int = 1
    first_seen_s: float = 0.0
    last_seen_s: float = 0.0
    confirmed: bool = False
    report_id: int | None = None

    # named as [Avevor2022] writes it, like mu and Sigma_w (pyproject ignores N803/N806 alike)
    @property
    def Sigma(self) -> np.ndarray:  # noqa: N802
        """The track's covariance, Sigma_w + L L^T."""
        return self.Sigma_w + self.L_shared @ self.L_shared.T

    @property
    def text(self) -> str:
        """QR: the most voted decoded string (ties: the first seen); hazmat: the argmax label;
        Landolt-C: per ring, the direction read most often (poi.core.landolt.merge_orientation_votes)."""
        if self.type == "hazmat":
            return HAZMAT_LABELS[int(np.argmax(self.probs[HAZMAT_SLICE]))]
        if self.type == "qr" and self.text_votes:
            best = max(self.text_votes.values())
            return next(t for t, n in self.text_votes.items() if n == best)
        if self.type == "landolt-c" and self.text_votes:
            return merge_orientation_votes(self.text_votes)
        return ""

    @property
    def max_std_m(self) -> float:
        """sqrt of the largest eigenvalue of Sigma."""
        return float(np.sqrt(max(np.linalg.eigvalsh(self.Sigma)[-1], 0.0)))

    @property
    def max_fresh_std_m(self) -> float:
        """sqrt of the largest eigenvalue of the fresh part Sigma_w (what more views shrink)."""
        return float(np.sqrt(max(np.linalg.eigvalsh(self.Sigma_w)[-1], 0.0)))

    def snapshot(self) -> TrackSnapshot:
        return TrackSnapshot(
            track_id=self.track_id,
            report_id=self.report_id,
            type=self.type,
            text=self.text,
            position_map=self.mu.copy(),
            covariance=self.Sigma.copy(),
            first_seen_s=self.first_seen_s,
            support=self.support,
            n_detections=self.n_detections,
            confirmed=self.confirmed,
            class_probs=self.probs.copy(),
            extra={"last_seen_s": self.last_seen_s, "text_votes": dict(self.text_votes)},
        )


@dataclass(frozen=True, kw_only=True)
class Innovation:
    """What one paired (observation, track) update saw, before it: the filter's check that needs
    no ground truth (filterpy's ``y``, ``S`` and ``mahalanobis``).

    ``nu = o - mu`` (map frame, m), ``S`` its covariance (:func:`innovation_covariance`, m^2) and
    ``d2 = nu^T S^-1 nu``, the normalised innovation squared (NIS). When R and Sigma hold the
    errors, d2 is chi-square with 3 degrees of freedom: its mean over many updates is 3
    ([BarShalom2001]_ 5.4). The gate's m^2 (:meth:`Tracker.distances`) differs: it adds the
    gate allowance, and counts a shared error in both Sigma and R.
    """

    obs_index: int
    track_id: int
    nu: np.ndarray  # (3,)
    S: np.ndarray  # (3, 3)
    d2: float


@dataclass(kw_only=True)
class StepResult:
    newly_confirmed: list[TrackSnapshot]
    pairs: list[tuple[int, int]]  # (observation index, track id)
    innovations: list[Innovation] = field(default_factory=list)  # one a pair, in the order of pairs
    new_tracks: list[tuple[int, int]] = field(default_factory=list)  # (observation index, track id)
    duplicates: list[tuple[int, int]] = field(default_factory=list)  # (obs index, track id)
    dropped: list[int] = field(default_factory=list)  # track ids deleted this step
    withdrawn: list[int] = field(default_factory=list)  # confirmed track ids unconfirmed this step (steps 6, 7)


class Tracker:
    """Tracks static objects from map-frame observations; see the module docstring."""

    def __init__(self, cfg: TrackerConfig, calibration: Calibration | None = None) -> None:
        self.cfg = cfg
        self.confusion = calibration.confusion if calibration is not None else None
        if cfg.fusion == "confusion" and self.confusion is None:
            raise TrackerError("tracker.fusion=confusion needs a calibration file with a confusion matrix")
        self.tracks: dict[int, Track] = {}
        self._next_id = 0
        self._next_report_id = 0

    def gate_for(self, type_: str) -> float:
        return self.cfg.gates.get(type_, self.cfg.gate)

    def _allowance(self, type_: str) -> np.ndarray:
        """``tracker.gate_allowance_m`` of ``type_`` squared times I (module docstring)."""
        return self.cfg.gate_allowance_m.get(type_, 0.0) ** 2 * IDENTITY3

    def _compatible(self, obs: Observation, tr: Track) -> bool:
        det = obs.detection
        if det.type != tr.type:
            return False
        # two different decoded QR texts never pair; an empty text pairs with any
        return not (det.type == "qr" and det.text and tr.text and det.text != tr.text)

    def distances(self, observations: list[Observation], tracks: list[Track]) -> np.ndarray:
        """M x N matrix of m^2; inf where the pair is not allowed (type, QR text, per-type gate)."""
        D = np.full((len(observations), len(tracks)), np.inf)
        # each track's Sigma and allowance^2 I once per frame, not once per pair
        sigmas = [tr.Sigma for tr in tracks]
        allowances = [self._allowance(tr.type) for tr in tracks]
        for i, o in enumerate(observations):
            for j, tr in enumerate(tracks):
                if self._compatible(o, tr):
                    m2 = mahalanobis2(o.position_map, tr.mu, sigmas[j], o.R + allowances[j])
                    if m2 < self.gate_for(tr.type):
                        D[i, j] = m2
        return D

    def _split(self, obs: Observation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The observation's position, fresh covariance R_w and shared factor L_o (zero when
        ``tracker.shared_errors`` is off or the observation has no shared part)."""
        o, R = np.asarray(obs.position_map, float), np.asarray(obs.R, float)
        if not self.cfg.shared_errors or obs.R_shared is None:
            return o, R, np.zeros((3, 3))
        R_s = np.asarray(obs.R_shared, float)
        return o, R - R_s, symmetric_sqrt(R_s)

    def _new_track(self, obs: Observation, t: float) -> Track:
        c = self.cfg
        o, R_w, L_o = self._split(obs)
        if c.init == "prior":
            mu, Sigma_w, L = shared_error_update(
                np.array(c.mu0), np.diag(c.Sigma0_diag), np.zeros((3, 3)), o, R_w, L_o, c.shared_change
            )
        else:
            # the Kalman update from an uninformative prior: mu = o, Sigma = R
            mu, Sigma_w, L = o.copy(), R_w.copy(), L_o.copy()
        det = obs.detection
        tr = Track(
            track_id=self._next_id,
            type=det.type,
            mu=mu,
            Sigma_w=Sigma_w,
            L_shared=L,
            probs=observation_probs(obs, c.fusion, self.confusion),
            first_seen_s=t,
            last_seen_s=t,
        )
        if det.type in TEXT_TYPES and det.text:
            tr.text_votes[det.text] = 1
        self._next_id += 1
        self.tracks[tr.track_id] = tr
        return tr

    def _update(self, tr: Track, obs: Observation, t: float, obs_index: int) -> Innovation:
        """Fuse ``obs`` (observation ``obs_index`` of the frame) into ``tr``; the innovation it had."""
        o, R_w, L_o = self._split(obs)
        # nu = o - mu, S = Sigma_w + R_w + D D^T + c L_o L_o^T, d^2 = nu^T S^-1 nu (before the update)
        nu = o - tr.mu
        S = innovation_covariance(tr.Sigma_w, tr.L_shared, R_w, L_o, self.cfg.shared_change)
        innovation = Innovation(
            obs_index=obs_index, track_id=tr.track_id, nu=nu, S=S, d2=float(nu @ np.linalg.solve(S, nu))
        )
        tr.mu, tr.Sigma_w, tr.L_shared = shared_error_update(
            tr.mu, tr.Sigma_w, tr.L_shared, o, R_w, L_o, self.cfg.shared_change
        )
        # mean of the distributions ([Avevor2022] 2.4.5): running mean over paired detections
        q = observation_probs(obs, self.cfg.fusion, self.confusion)
        tr.probs = (tr.n_prob * tr.probs + q) / (tr.n_prob + 1)
        tr.n_prob += 1
        det = obs.detection
        if tr.type in TEXT_TYPES and det.text:
            tr.text_votes[det.text] = tr.text_votes.get(det.text, 0) + 1
        tr.support += 1.0
        tr.n_detections += 1
        tr.last_seen_s = t
        return innovation

    def _ready(self, tr: Track, read: np.ndarray, rivals: dict[int, list[Track]]) -> bool:
        if tr.n_detections < self.cfg.n_min or tr.max_fresh_std_m > self.cfg.settle_sigma_m:
            return False
        if self._outvoted(tr, read, rivals) or self._read_before(tr):
            return False
        if tr.type == "landolt-c" and not self._landolt_rings_read(tr):
            return False
        return not (tr.type in TEXT_TYPES and self.cfg.qr_requires_text and not tr.text)

    def _outvoted(
        self, tr: Track, read: np.ndarray, rivals: dict[int, list[Track]], *, by_confirmed: bool = False
    ) -> bool:
        """Whether a track of another type within ``cross_type_radius_m`` of ``tr`` (its
        ``rivals``, :meth:`_rivals`; a confirmed one, with ``by_confirmed``) wins the place's vote
        (:meth:`_votes`), or ``tr`` is a guess at a read target's place (:meth:`_on_read_target`
        with ``read`` of :meth:`_read_places`; module docstring, step 6)."""
        if self.cfg.cross_type_radius_m <= 0:
            return False
        if self._on_read_target(tr, read):
            return True
        return any(
            (other.confirmed or not by_confirmed)
            and not self._on_read_target(other, read)  # a guess on a read target has no vote
            and self._votes(other, tr) > self._votes(tr, other)
            for other in rivals.get(tr.track_id, ())
        )

    @staticmethod
    def _beside(o: Observation, observations: list[Observation], k: int | None) -> bool:
        """Whether QR observation ``o`` and observation ``k`` of the same frame (the one that took
        a track) are boxes that do not meet: two codes side by side, not one code boxed twice."""
        if k is None or o.detection.type != "qr":
            return False
        boxes = np.array([o.detection.box_xyxy, observations[k].detection.box_xyxy], dtype=float)
        return float(iou_matrix(boxes[:1], boxes[1:])[0, 0]) == 0.0

    def _read_before(self, tr: Track) -> bool:
        """Whether a QR track confirmed before ``tr`` has ``tr``'s text and lies within
        ``same_text_radius_m`` of it (module docstring, step 7)."""
        radius = self.cfg.same_text_radius_m
        if radius <= 0 or tr.type != "qr" or not tr.text:
            return False
        mine = tr.report_id if tr.confirmed else None  # confirmed ones are numbered in order
        return any(
            other.confirmed
            and other.report_id is not None
            and other is not tr
            and other.type == "qr"
            and other.text == tr.text
            and (mine is None or other.report_id < mine)
            and float(np.linalg.norm(other.mu - tr.mu)) < radius
            for other in self.tracks.values()
        )

    def _rivals(self) -> dict[int, list[Track]]:
        """Each track's rivals for its place: the tracks of another type whose means lie within
        ``cross_type_radius_m`` of its own (module docstring, step 6), from one distance matrix
        over the tracks; none while the radius is 0."""
        radius = self.cfg.cross_type_radius_m
        tracks = list(self.tracks.values())
        if radius <= 0 or len(tracks) < 2:
            return {}
        mus = np.array([t.mu for t in tracks], dtype=float)
        types = np.array([t.type for t in tracks])
        near = np.linalg.norm(mus[:, None, :] - mus[None, :, :], axis=2) < radius
        near &= types[:, None] != types[None, :]
        return {
            tracks[i].track_id: [tracks[j] for j in np.flatnonzero(row)] for i, row in enumerate(near) if row.any()
        }

    def _read_places(self) -> np.ndarray:
        """(K, 3) means of the tracks of :data:`READ_TYPES` with text: the places read from
        pixels (module docstring, step 6); none while ``cross_type_radius_m`` is 0."""
        if self.cfg.cross_type_radius_m <= 0:
            return np.zeros((0, 3))
        mus = [t.mu for t in self.tracks.values() if t.type in READ_TYPES and t.text]
        return np.array(mus, dtype=float).reshape(-1, 3)

    def _on_read_target(self, tr: Track, read: np.ndarray) -> bool:
        """Whether ``tr``, of a type not read from pixels (not in :data:`READ_TYPES`), lies within
        ``cross_type_radius_m`` of a place in ``read`` (:meth:`_read_places`)."""
        return (
            tr.type not in READ_TYPES
            and len(read) > 0
            and bool((np.linalg.norm(read - tr.mu, axis=1) < self.cfg.cross_type_radius_m).any())
        )

    @staticmethod
    def _votes(a: Track, b: Track) -> tuple[float, int]:
        """Track ``a``'s vote at the place it shares with ``b``, with the tie-break (the older
        wins): the class mass of a's type over both tracks' detections, n_a P_a(type a) +
        n_b P_b(type a), each P the track's fused class distribution ([Avevor2022]_ 2.4.5's
        mean, taken over the place's two tracks) and n its count."""
        mine = TYPE_CLASSES[a.type]
        return float(a.n_prob * a.probs[mine].sum() + b.n_prob * b.probs[mine].sum()), -a.track_id

    def _landolt_rings_read(self, tr: Track) -> bool:
        """Whether a Landolt-C track's rings read so far include ``landolt_required_rings``."""
        rings = parse_orientation_text(tr.text) if tr.text else {}
        return all(k in rings for k in self.cfg.landolt_required_rings)

    def step(
        self,
        observations: list[Observation],
        timestamp_s: float,
        in_view_not_detected: set[int] | frozenset[int] = frozenset(),
    ) -> StepResult:
        """Process one frame's observations.

        ``in_view_not_detected``: ids of tracks the camera could see this frame. Those
        that got no observation here lose ``miss_penalty`` support (a track id paired in
        this step is exempt, so passing every in-view id is correct).
        """
        tracks = list(self.tracks.values())
        D = self.distances(observations, tracks)
        # every allowed entry is already below its own gate: pair while finite
        idx_pairs = pair_hungarian(D, np.inf) if self.cfg.assignment == "hungarian" else pair_greedy(D, np.inf)
        pairs = [(i, tracks[j].track_id) for i, j in idx_pairs]
        paired_obs = {i for i, _ in pairs}
        paired_tracks = {tid for _, tid in pairs}
        innovations = [self._update(self.tracks[tid], observations[i], timestamp_s, i) for i, tid in pairs]

        dropped: list[int] = []
        for tid in sorted(set(in_view_not_detected) - paired_tracks):
            tr = self.tracks.get(tid)
            if tr is None:
                continue
            tr.support -= self.cfg.miss_penalty
            if not tr.confirmed and tr.support < self.cfg.drop_support:
                del self.tracks[tid]
                dropped.append(tid)
        for tid, tr in list(self.tracks.items()):
            if not tr.confirmed and timestamp_s - tr.last_seen_s > self.cfg.t_max:
                del self.tracks[tid]
                dropped.append(tid)

        new_tracks: list[tuple[int, int]] = []
        duplicates: list[tuple[int, int]] = []
        taker = {tid: i for i, tid in pairs}  # the observation that took each track this frame
        for i, o in enumerate(observations):
            if i in paired_obs:
                continue
            live = [tr for tr in self.tracks.values() if not self._beside(o, observations, taker.get(tr.track_id))]
            d = self.distances([o], live)[0] if live else np.zeros(0)
            if d.size and np.isfinite(d).any():
                duplicates.append((i, live[int(np.argmin(d))].track_id))
            else:
                new_tracks.append((i, self._new_track(o, timestamp_s).track_id))
                taker[new_tracks[-1][1]] = i

        # no confirmation below changes a track's text or mean
        read, rivals = self._read_places(), self._rivals()
        newly: list[TrackSnapshot] = []
        for tr in self.tracks.values():
            if not tr.confirmed and self._ready(tr, read, rivals):
                tr.confirmed = True
                tr.report_id = self._next_report_id
                self._next_report_id += 1
                newly.append(tr.snapshot())
        # the place's vote taken again: a confirmed track at a read target's place, or that a
        # confirmed one of another type now outvotes, is withdrawn, as is a QR track whose text
        # one confirmed before it near by now reads (the losers found first, so that the order
        # does not matter; one just confirmed is outvoted by no track)
        losers = [
            tr
            for tr in self.tracks.values()
            if tr.confirmed and (self._outvoted(tr, read, rivals, by_confirmed=True) or self._read_before(tr))
        ]
        withdrawn: list[int] = []
        for tr in losers:
            tr.confirmed, tr.report_id = False, None
            withdrawn.append(tr.track_id)
        return StepResult(
            newly_confirmed=newly,
            pairs=pairs,
            innovations=innovations,
            new_tracks=new_tracks,
            duplicates=duplicates,
            dropped=dropped,
            withdrawn=withdrawn,
        )

    def snapshots(self, confirmed_only: bool = False) -> list[TrackSnapshot]:
        """All tracks (or the confirmed ones, by report id) as snapshots."""
        trs = [t for t in self.tracks.values() if t.confirmed or not confirmed_only]
        if confirmed_only:
            trs.sort(key=lambda t: -1 if t.report_id is None else t.report_id)  # a confirmed one has one
        return [t.snapshot() for t in trs]
