"""The oracle detector: boxes from the simulator's ground truth, with a seeded noise model.

For benchmarking the rest of the pipeline alone (issue: "Oracle detector"). It
lives with the simulator because it reads ground truth, which ``poi`` never
sees. Per visible object it

* skips the views the in-view test fails (:func:`poi.core.in_view.boxable_view`: a box under
  ``min_box_px``, or less than ``min_visible_fraction`` of the object visible, unless a type not
  read off its face shows ``min_large_pixels`` or more), and misses the rest with
  probability ``miss_rate``;
* moves the box centre by N(0, sigma^2) per axis with sigma_u = a + b w,
  sigma_v = a + b h (the form [Avevor2022]_ section 2.1.4 fits; a and b default to the
  pipeline's model of it, :mod:`poi.core.sensor_noise`) and jitters its size;
* reports another class with probability ``confusion_rate``, drawn from a row of
  a confusion matrix (default: another label of the same type for hazmats, any
  other class otherwise);
* adds Poisson(``false_positives_per_frame``) boxes of random classes.

Like a real detector it knows one class space, ``classes``: the 24 rescue classes
by default, the four arena classes for the TurtleBot goal arena
(:func:`oracle_for`). Objects of other classes are never detected, and confusions
and false positives stay within the space; ``class_probs`` spread 1 - p over its
other classes (0 elsewhere in :data:`poi.core.names.CLASSES`).

QR text is left empty by default so the pipeline's QR reader decodes it from the
pixels, as it would for a real detector (``qr_text: truth`` copies the truth). In a world
with Landolt-C targets the oracle knows their class too (:func:`target_confusion`); their
text is always left empty: the pipeline reads the rings from the pixels.

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from poi.core.in_view import IN_VIEW_FRACTION, IN_VIEW_LARGE_PX, IN_VIEW_MIN_PX, boxable_view
from poi.core.names import (
    ARENA_TYPES,
    CLASS_INDEX,
    CLASSES,
    HAZMAT_LABELS,
    RESCUE_CLASSES,
    TARGET_TYPES,
    class_to_identity,
    identity_to_class,
)
from poi.core.sensor_noise import CENTER_SIGMA_A_PX, CENTER_SIGMA_B, center_sigma_px
from poi.core.types import Detection, Frame
from sim.simulator import FrameTruth

ORACLE_STREAM = 2
# A pillar of the goal arena is 5 cm wide: 10 px at 3 m in a 640 px image. The [Bouda2025]
# team's YOLO 11n finds them at 160-240 px image height (section 2.1.2), where such a
# pillar is 3-5 px wide, so the arena's oracle keeps boxes down to 4 px on their short side.
ARENA_MIN_BOX_PX = 4.0


@dataclass(kw_only=True)
class OracleSettings:
    seed: int = 0
    miss_rate: float = 0.05
    min_box_px: float = IN_VIEW_MIN_PX
    min_visible_fraction: float = IN_VIEW_FRACTION
    min_large_pixels: int = IN_VIEW_LARGE_PX  # a large view of a type read off no face (boxable_view)
    center_sigma_a_px: float = CENTER_SIGMA_A_PX
    center_sigma_b: float = CENTER_SIGMA_B
    size_jitter: float = 0.05
    confusion_rate: float = 0.02
    false_positives_per_frame: float = 0.01
    confidence_range: tuple[float, float] = (0.55, 0.97)
    qr_text: str = "decode"  # or "truth"
    classes: tuple[str, ...] = RESCUE_CLASSES  # the detector's class space, names of poi.core.names.CLASSES
    # (K, K) over ``classes``, rows: detected | actual; default: default_confusion(classes)
    confusion: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        for name in ("miss_rate", "confusion_rate"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"oracle.{name}: expected a probability in [0, 1], got {v}")
        if self.qr_text not in ("decode", "truth"):
            raise ValueError(f"oracle.qr_text: expected 'decode' or 'truth', got {self.qr_text!r}")
        unknown = [c for c in self.classes if c not in CLASS_INDEX]
        if len(self.classes) < 2 or unknown or len(set(self.classes)) != len(self.classes):
            raise ValueError(
                "oracle.classes: expected at least two distinct names of poi.core.names.CLASSES, "
                f"got {self.classes!r}"
            )


def default_confusion(classes: tuple[str, ...] = RESCUE_CLASSES) -> np.ndarray:
    """Pr(reported class | actual class, misclassified) over ``classes``: hazmats among
    hazmats, the others uniform among the other non-hazmat classes.

    >>> default_confusion(("pillar-blue", "pillar-red", "ball")).tolist()[0]
    [0.0, 0.5, 0.5]
    """
    K = len(classes)
    hazmat = np.array([c in HAZMAT_LABELS for c in classes])
    M = np.zeros((K, K))
    for a in range(K):
        M[a] = hazmat == hazmat[a]
        M[a, a] = 0.0
        if M[a].sum() == 0:  # the only class of its kind: any other class
            M[a] = 1.0
            M[a, a] = 0.0
        M[a] /= M[a].sum()
    return M


def oracle_for(sim) -> OracleDetector:
    """The oracle detector for a simulation: seeded by its scenario, knowing the classes of
    its world (the rescue classes in a maze; the arena's, down to ``ARENA_MIN_BOX_PX``, in
    the TurtleBot goal arena)."""
    if sim.arena is not None:
        settings = OracleSettings(seed=sim.scenario.seed, classes=ARENA_TYPES, min_box_px=ARENA_MIN_BOX_PX)
    elif any(o.type in TARGET_TYPES for o in sim.objects):
        classes = RESCUE_CLASSES + TARGET_TYPES
        settings = OracleSettings(seed=sim.scenario.seed, classes=classes, confusion=target_confusion(classes))
    else:
        settings = OracleSettings(seed=sim.scenario.seed)
    return OracleDetector(settings)


def target_confusion(classes: tuple[str, ...]) -> np.ndarray:
    """:func:`default_confusion` over ``classes`` with the Landolt-C target kept apart: no other
    class is confused for it, and it is never confused (a ring target looks like nothing else).

    >>> target_confusion(("door", "valve", "landolt-c")).tolist()
    [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    """
    targets = [i for i, c in enumerate(classes) if c in TARGET_TYPES]
    rest = tuple(c for c in classes if c not in TARGET_TYPES)
    keep = [i for i, c in enumerate(classes) if c not in TARGET_TYPES]
    M = np.zeros((len(classes), len(classes)))
    M[np.ix_(keep, keep)] = default_confusion(rest)
    for i in targets:
        M[i, i] = 1.0
    return M


class OracleDetector:
    """Implements the ``poi`` detector protocol; call :meth:`set_truth` before each ``detect``."""

    name = "oracle"

    def __init__(self, settings: OracleSettings | None = None) -> None:
        self.settings = s = settings or OracleSettings()
        self.classes = s.classes
        K = len(self.classes)
        self.confusion = s.confusion if s.confusion is not None else default_confusion(self.classes)
        if np.shape(self.confusion) != (K, K):
            raise ValueError(f"oracle.confusion: expected a {K} x {K} matrix over oracle.classes")
        self._index = {c: i for i, c in enumerate(self.classes)}  # class name -> index in classes
        self._full = np.array([CLASS_INDEX[c] for c in self.classes])  # index in classes -> in CLASSES
        self._truth: FrameTruth | None = None
        self.last_timing_ms: dict[str, float] = {}

    def set_truth(self, truth: FrameTruth) -> None:
        self._truth = truth

    def _probs(self, cls: int, conf: float) -> np.ndarray:
        """Over CLASSES: ``conf`` on class ``cls`` (an index in ``classes``), 1 - conf spread
        evenly over the other classes of the space."""
        p = np.zeros(len(CLASSES))
        p[self._full] = (1.0 - conf) / (len(self.classes) - 1)
        p[self._full[cls]] = conf
        return p

    def detect(self, frame: Frame) -> list[Detection]:
        s = self.settings
        truth = self._truth
        if truth is None or truth.index != frame.index:
            raise RuntimeError(f"oracle detector: no ground truth for frame {frame.index}; call set_truth first")
        rng = np.random.default_rng([s.seed, ORACLE_STREAM, frame.index])
        W, H = frame.intrinsics.width, frame.intrinsics.height
        out: list[Detection] = []
        for v in truth.visible:
            x1, y1, x2, y2 = v.box_xyxy
            w, h = x2 - x1, y2 - y1
            draws = rng.random(3)
            noise = rng.standard_normal(4)
            if not boxable_view(
                v.type,
                visible_fraction=v.visible_fraction,
                pixels=v.pixels,
                min_side_px=min(w, h),
                min_visible_fraction=s.min_visible_fraction,
                min_large_pixels=s.min_large_pixels,
                min_box_px=s.min_box_px,
            ):
                continue
            if draws[0] < s.miss_rate:
                continue
            cx = 0.5 * (x1 + x2) + noise[0] * center_sigma_px(w, a_px=s.center_sigma_a_px, b=s.center_sigma_b)
            cy = 0.5 * (y1 + y2) + noise[1] * center_sigma_px(h, a_px=s.center_sigma_a_px, b=s.center_sigma_b)
            w2 = w * (1.0 + s.size_jitter * noise[2])
            h2 = h * (1.0 + s.size_jitter * noise[3])
            actual = self._index.get(identity_to_class(v.type, v.text))
            if actual is None:
                continue  # not a class this detector knows
            cls = actual
            if draws[1] < s.confusion_rate:
                cls = int(rng.choice(len(self.classes), p=self.confusion[actual]))
            conf = float(s.confidence_range[0] + draws[2] * (s.confidence_range[1] - s.confidence_range[0]))
            typ, text = class_to_identity(self.classes[cls])
            if typ == "qr":
                text = v.text if s.qr_text == "truth" and cls == actual else ""
            elif typ in TARGET_TYPES:
                text = ""  # read from the pixels by the pipeline
            box = (
                float(np.clip(cx - w2 / 2, 0, W)),
                float(np.clip(cy - h2 / 2, 0, H)),
                float(np.clip(cx + w2 / 2, 0, W)),
                float(np.clip(cy + h2 / 2, 0, H)),
            )
            out.append(
                Detection(
                    class_name=self.classes[cls],
                    type=typ,
                    text=text,
                    box_xyxy=box,
                    confidence=conf,
                    source="oracle",
                    class_probs=self._probs(cls, conf),
                )
            )
        for _ in range(int(rng.poisson(s.false_positives_per_frame))):
            cls = int(rng.integers(len(self.classes)))
            bw, bh = rng.uniform(20, 120, 2)
            cx, cy = rng.uniform(bw / 2, W - bw / 2), rng.uniform(bh / 2, H - bh / 2)
            conf = float(rng.uniform(*s.confidence_range))
            typ, text = class_to_identity(self.classes[cls])
            out.append(
                Detection(
                    class_name=self.classes[cls],
                    type=typ,
                    text=text,
                    box_xyxy=(cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2),
                    confidence=conf,
                    source="oracle",
                    class_probs=self._probs(cls, conf),
                )
            )
        return out
