"""A YOLO detector exported to ONNX, run by onnxruntime (CPU by default, or any execution provider).

Implements docs/DESIGN.md "What real means here" (a team can drop in its own YOLOv5,
YOLOv8 or YOLO11 export) and the "YOLO to ONNX" detector of [Bouda2025]_: letterbox
preprocessing, the two output layouts, a confidence threshold, class-wise
non-maximum suppression, boxes mapped back to the original image, and class
probabilities over :data:`poi.core.names.CLASSES` ([Avevor2022]_ section 2.1.5).

Output layouts (C = number of classes the model declares in ``names``; the batch
dimension may be dynamic, one image is fed):

* ``yolov8`` (YOLOv8, YOLO11, YOLO26 raw head; Ultralytics ``format=onnx`` with
  ``nms=False`` and, for YOLO26 and YOLOv10, ``end2end=False``): (1, 4+C, N), rows
  cx, cy, w, h in input pixels then C class scores already passed through a
  sigmoid, no objectness; e.g. (1, 28, 2100) for C = 24 at 320x320. poibench
  runs class-wise NMS on it.
* ``end2end`` (boxes after NMS: Ultralytics ``nms=True`` exports of YOLOv8, YOLO11
  and YOLO26, and the NMS-free one-to-one head of YOLO26 and YOLOv10, exported
  with ``end2end=True``, their default): (1, K, 6), rows x1, y1, x2, y2 in input
  pixels, score, class index; e.g. (1, 300, 6) for max_det = 300. Rows scoring
  below ``conf`` (the zero padding included) are dropped; no NMS is run on them,
  as Ultralytics' ``predict`` runs none, except between boxes whose classes
  poibench merges (a ``class_map`` sending two model classes to one, or the
  placards and 'qr' with a label classifier).
* ``yolov5`` (the YOLOv5 repository's export): (1, N, 5+C), columns cx, cy, w,
  h, objectness, then C class scores; a class's score is obj * cls; e.g.
  (1, 6300, 29) for C = 24 at 320x320.

The layout is decided by the shape and the model's metadata (an Ultralytics >= 8
export writes ``task``, ``end2end``, ``imgsz``, ``names`` and, in ``args``, ``nms``),
never from a guess on one dimension: the shape must fit the layout, and where it
fits two the metadata decides; a shape that fits none is refused with one line
naming the layouts accepted and the export options that give them.

Boxes go through NMS as the network gives them and are clipped to the frame
afterwards, in Ultralytics' order (``non_max_suppression`` then ``scale_boxes``),
so a box cut by the frame edge competes with its full extent.

>>> img, r, (left, top) = letterbox(np.zeros((480, 640, 3), np.uint8), (320, 320))
>>> img.shape, r, left, top
((320, 320, 3), 0.5, 0, 40)
>>> img, r, (left, top) = letterbox(np.zeros((480, 640, 3), np.uint8), (320, 320), stride=32)
>>> img.shape, r, left, top
((256, 320, 3), 0.5, 0, 8)

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import ast
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from poi.core.names import (
    CLASS_INDEX,
    CLASS_TYPES,
    CLASSES,
    HAZMAT_LABELS,
    canonical_type,
    class_domain,
    class_to_identity,
)
from poi.core.types import Detection, Frame
from poi.detectors.base import (
    DetectorConfigError,
    canonical_class,
    choose_providers,
    make_detection,
    open_onnx_session,
    register,
)
from poi.detectors.hazmat_labels import LABEL_CLASSES, HazmatLabelClassifier
from poi.detectors.model_names import OnnxModelError, load_names_file, parse_names_metadata
from poi.detectors.qr import attach_qr_text

PAD_VALUE = 114  # Ultralytics' letterbox grey
DEFAULT_IMGSZ_PX = 640
# the largest input side taken: a declared 20000x20000 input ran out of memory, a metadata imgsz of
# 100000 made OpenCV allocate 22.5 GB for the letterbox (a 4096x4096 float32 input is 201 MB)
MAX_INPUT_PX = 4096
# the input element types taken: an image scaled to 0..1 (an int8 input was an onnxruntime traceback)
INPUT_TYPES = {"tensor(float)": np.float32, "tensor(float16)": np.float16}
DEFAULT_STRIDE_PX = 32  # YOLO's largest stride; Ultralytics writes it as metadata 'stride'
LAYOUTS = ("auto", "yolov5", "yolov8", "end2end")
LETTERBOXES = ("square", "rect")
HAZMAT_INDICES = np.array([CLASS_INDEX[c] for c in HAZMAT_LABELS], dtype=np.int64)  # (16,) into CLASSES
IS_HAZMAT = np.isin(np.arange(len(CLASSES)), HAZMAT_INDICES)  # (len(CLASSES),)
# What the label classifier decides between: the placards, and QR codes, which white placards
# with black symbols (poison, corrosive, inhalation hazard) resemble at a detector's input size.
LABELLED = IS_HAZMAT | (np.arange(len(CLASSES)) == CLASS_INDEX["qr"])  # (len(CLASSES),)


def letterbox(
    rgb: np.ndarray, size_hw: tuple[int, int], stride: int | None = None
) -> tuple[np.ndarray, float, tuple[int, int]]:
    """Resize keeping the aspect ratio and pad with grey 114 to ``size_hw``.

    Returns the (H_in, W_in, 3) image, the scale r and the (left, top) padding
    in pixels, so an input pixel x_in maps back to x = (x_in - left) / r.
    r = min(H_in / h, W_in / w); the resized image is round(w r) x round(h r)
    and the padding is split with the odd pixel at the bottom / right.
    With ``stride``, the minimal letterbox of Ultralytics' ``LetterBox(auto=True)``
    (``rect``, what its ``predict`` feeds a dynamic model): each padding is only
    (size - resized) mod stride, e.g. 640x480 into 320 gives 320x256.
    """
    h, w = rgb.shape[:2]
    H_in, W_in = size_hw
    r = min(H_in / h, W_in / w)
    w_new, h_new = int(round(w * r)), int(round(h * r))
    w_new, h_new = min(w_new, W_in), min(h_new, H_in)
    if stride is not None:
        H_in, W_in = h_new + (H_in - h_new) % stride, w_new + (W_in - w_new) % stride
    resized = cv2.resize(rgb, (w_new, h_new), interpolation=cv2.INTER_LINEAR) if (w_new, h_new) != (w, h) else rgb
    left, top = (W_in - w_new) // 2, (H_in - h_new) // 2
    out = np.full((H_in, W_in, 3), PAD_VALUE, dtype=np.uint8)  # (H_in, W_in, 3)
    out[top : top + h_new, left : left + w_new] = resized
    return out, r, (left, top)


def _flag(value: Any) -> bool:
    return str(value).strip().lower() in ("true", "1", "yes")


def export_flags(metadata: Mapping[str, str]) -> tuple[bool, bool]:
    """(end2end, nms) as an Ultralytics export recorded them: top-level ``end2end`` (and ``nms``),
    and ``nms`` / ``end2end`` in the ``args`` dict literal; absent or unreadable means False."""
    end2end, nms = _flag(metadata.get("end2end", "")), _flag(metadata.get("nms", ""))
    try:
        args = ast.literal_eval(metadata.get("args", "{}"))
    except (ValueError, SyntaxError):
        args = {}
    if isinstance(args, Mapping):
        end2end |= args.get("end2end") is True
        nms |= args.get("nms") is True
    return end2end, nms


def expected_layouts(C: int) -> str:
    """The accepted output layouts for C classes and the export options that give each."""
    return (
        f"(1, 4+C={4 + C}, N) raw YOLOv8/YOLO11/YOLO26 (Ultralytics format=onnx nms=False, and end2end=False "
        f"for YOLO26/YOLOv10), (1, K, 6) boxes after NMS (nms=True, or end2end=True for YOLO26/YOLOv10) "
        f"or (1, N, 5+C={5 + C}) YOLOv5 (the yolov5 repository's export.py)"
    )


def resolve_layout(shape: Sequence[Any], C: int, layout: str, metadata: Mapping[str, str]) -> str:
    """'yolov8', 'end2end' or 'yolov5' for an output of ``shape`` from a model declaring C classes.

    ``layout`` 'auto' takes the one layout the shape fits; where it fits two, the
    metadata decides: an Ultralytics >= 8 export (key ``task``) is never yolov5, and
    ``end2end`` or ``nms`` (:func:`export_flags`) pick end2end over a raw layout.
    An explicit layout must fit. Anything else raises :class:`OnnxModelError`.
    """
    dims = tuple(shape)
    batch_ok = len(dims) == 3 and (dims[0] in (1, None) or isinstance(dims[0], str))  # str: dynamic
    if not batch_ok:
        raise OnnxModelError(f"model output has shape {dims}; expected {expected_layouts(C)}")
    task = metadata.get("task")
    if task is not None and task != "detect":
        raise OnnxModelError(
            f"model task is {task!r} (output shape {dims}); poibench decodes detect models: export one "
            "trained with task=detect"
        )
    fits = {"yolov8": dims[1] == 4 + C, "end2end": dims[2] == 6, "yolov5": dims[2] == 5 + C}
    if layout == "auto":
        ultralytics = task is not None
        if ultralytics:
            fits["yolov5"] = False
        candidates = [k for k, ok in fits.items() if ok]
        if len(candidates) > 1 and "end2end" in candidates:
            end2end, nms = export_flags(metadata)
            if end2end or nms:
                candidates = ["end2end"]
            elif ultralytics:
                candidates = [k for k in candidates if k != "end2end"]
        if len(candidates) == 1:
            return candidates[0]
        if candidates:
            both = "both " if len(candidates) == 2 else "all of "
            raise OnnxModelError(
                f"model output shape {dims} fits {both}{' and '.join(candidates)} for C={C}; "
                f"set layout: {' or '.join(candidates)}"
            )
        if ultralytics:
            raise OnnxModelError(
                f"model output has shape {dims}; an Ultralytics detect model's output for C={C} class names "
                f"must be (1, {4 + C}, N) (raw, nms=False end2end=False) or (1, K, 6) (nms=True, or "
                "end2end=True); re-export with one of those"
            )
        raise OnnxModelError(
            f"model output has shape {dims}, which fits no layout for C={C} class names; "
            f"expected {expected_layouts(C)}"
        )
    if layout == "yolov8" and not fits["yolov8"]:
        raise OnnxModelError(
            f"model output has shape {dims}; a yolov8/yolo11 output for C={C} class names must be (1, {4 + C}, N)"
        )
    if layout == "end2end" and not fits["end2end"]:
        raise OnnxModelError(
            f"model output has shape {dims}; an end2end output (boxes after NMS) must be (1, K, 6): "
            "x1, y1, x2, y2, score, class"
        )
    if layout == "yolov5" and not fits["yolov5"]:
        raise OnnxModelError(
            f"model output has shape {dims}; a yolov5 output for C={C} class names must be (1, N, {5 + C})"
        )
    return layout


def decode_end2end(out: np.ndarray, C: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boxes (K, 4) x1, y1, x2, y2 in input pixels, scores (K,) and class indices (K,) from a
    (1, K, 6) output; a row whose class is not an integer in [0, C) gets class -1."""
    pred = out[0]  # (K, 6)
    c = pred[:, 5].astype(np.float64)  # (K,)
    valid = np.isfinite(c) & (c == np.round(c)) & (c >= 0) & (c < C)
    cls = np.where(valid, np.round(np.where(valid, c, 0)), -1).astype(np.int64)
    return pred[:, :4], pred[:, 4], cls


def decode_output(out: np.ndarray, C: int, layout: str) -> tuple[np.ndarray, np.ndarray]:
    """Boxes (N, 4) cx, cy, w, h in input pixels and class scores (N, C) from a raw output."""
    if layout == "yolov8":
        pred = out[0].T  # (4+C, N) -> (N, 4+C)
        return pred[:, :4], pred[:, 4 : 4 + C]
    pred = out[0]  # (N, 5+C)
    obj = pred[:, 4:5]  # (N, 1)
    return pred[:, :4], obj * pred[:, 5 : 5 + C]  # score = obj * cls, (N, C)


def _as_size_hw(value: Any, where: str) -> tuple[int, int]:
    if isinstance(value, str):
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError) as exc:
            raise DetectorConfigError(f"{where}: expected an int or [h, w], got {value!r}") from exc
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        hw = (int(value), int(value))
    elif isinstance(value, Sequence) and len(value) == 2:
        hw = (int(value[0]), int(value[1]))
    else:
        raise DetectorConfigError(f"{where}: expected an int or [h, w], got {value!r}")
    if hw[0] <= 0 or hw[1] <= 0:
        raise DetectorConfigError(f"{where}: sizes must be positive, got {hw}")
    if max(hw) > MAX_INPUT_PX:
        raise DetectorConfigError(f"{where}: {hw[0]}x{hw[1]}; expected at most {MAX_INPUT_PX} px a side")
    return hw


def class_wise_nms(xyxy: np.ndarray, score: np.ndarray, group: np.ndarray, iou: float) -> np.ndarray:
    """Indices of the (M, 4) boxes OpenCV's class-wise NMS keeps, best first.

    ``cv2.dnn.NMSBoxesBatched`` separates the classes by shifting each class's boxes
    by class x (largest coordinate + 1), which only keeps them apart when no
    coordinate is negative: boxes crossing the top or left edge are translated first
    (IoU does not change under a translation). A box is dropped when its IoU with a
    kept better one exceeds ``iou``, as in Ultralytics' ``non_max_suppression``.
    """
    if len(xyxy) == 0:
        return np.zeros(0, dtype=np.int64)
    xywh = np.column_stack([xyxy[:, :2], xyxy[:, 2:] - xyxy[:, :2]]).astype(np.float64)  # (M, 4)
    lowest = float(xyxy[:, :2].min())
    if lowest < 0.0:
        xywh[:, :2] -= lowest
    kept = cv2.dnn.NMSBoxesBatched(
        xywh.tolist(),
        score.astype(np.float64).tolist(),
        group.astype(np.int32).tolist(),
        -1.0,  # scores are already filtered (>= conf); OpenCV's own test is strict (>)
        float(iou),
    )
    return np.asarray(kept, dtype=np.int64).reshape(-1)


def _as_stride(value: str | None, path: Path) -> int:
    """The model's largest stride from its metadata ``stride``, else 32."""
    if value is None:
        return DEFAULT_STRIDE_PX
    try:
        stride = int(ast.literal_eval(str(value)))
    except (ValueError, SyntaxError, TypeError) as exc:
        raise OnnxModelError(f"{path}: metadata stride must be an integer, got {value!r}") from exc
    if stride < 1:
        raise OnnxModelError(f"{path}: metadata stride must be >= 1, got {stride}")
    return stride


@register("onnx")
@dataclass(kw_only=True)
class OnnxYoloDetector:
    """YOLOv5 / YOLOv8 / YOLO11 / YOLO26 / YOLOv10 ONNX export on onnxruntime.

    Settings: ``model`` path; ``conf`` minimum score; ``type_conf`` object type -> the minimum
    score of that type's boxes in place of ``conf`` (a type the model cannot report is refused;
    a placard's score is the named one, s q_label, as for ``conf``); ``nms_iou`` IoU above which
    the lower-scored of two same-class boxes is dropped; ``max_det`` detections
    kept per frame; ``imgsz`` input size used when the model's input dims are
    dynamic (int or [h, w]; default the metadata's ``imgsz``, else 640);
    ``names`` a names file overriding the metadata; ``class_map`` model name ->
    name in CLASSES (or None to ignore that class); ``layout`` 'auto', 'yolov5',
    'yolov8' or 'end2end' (module docstring); ``letterbox`` 'square' (pad to the
    full input size) or 'rect' (Ultralytics' minimal letterbox, padding each side
    only to a multiple of the model's stride; dynamic models only);
    ``providers`` onnxruntime execution providers in order of preference, those
    this onnxruntime lacks skipped and named in ``notes`` (one line), the CPU
    always last; ``threads`` onnxruntime intra-op threads (1: a second one,
    its spinning off, costs about 17% more CPU for the same boxes; 2.5x with it on); ``read_qr`` decode
    the text of every 'qr' detection here (:func:`poi.detectors.qr.attach_qr_text`;
    off by default because poi.pipeline does it after all detectors);
    ``label_model`` a hazmat label classifier (:mod:`poi.detectors.hazmat_labels`)
    that names every placard the model finds from its full-resolution crop: the
    model's 16 hazmat classes and 'qr' then compete as one in NMS, a placard's
    confidence is s q_label (s the model's score, q the classifier's), and a
    'qr' box the classifier sees as a placard becomes one
    (:meth:`_name_placards`). A model class 'hazmat' (or 'placard') finds placards
    without naming them (``poibench train --placards one``); it needs ``label_model``.
    ``last_timing_ms`` holds the last frame's preprocess / inference /
    postprocess / labels / qr times in milliseconds; ``highest_score`` the best class score of
    any box of its classes in any frame so far, below ``conf`` or not.
    """

    model: str | Path
    conf: float = 0.25
    nms_iou: float = 0.45
    max_det: int = 300
    imgsz: int | Sequence[int] | None = None
    names: str | Path | None = None
    class_map: Mapping[str, str | None] | None = None
    layout: str = "auto"
    letterbox: str = "square"
    providers: Sequence[str] | None = None
    threads: int = 1  # a second intra-op thread: +17% CPU (spinning off), same boxes (issue 18)
    read_qr: bool = False
    label_model: str | Path | None = None
    type_conf: Mapping[str, float] | None = None
    name: str = field(default="onnx", init=False)
    notes: list[str] = field(default_factory=list, init=False)
    last_timing_ms: dict[str, float] = field(default_factory=dict, init=False)
    highest_score: float = field(default=0.0, init=False)  # the best class score of any box so far, kept or not
    model_names: list[str] = field(default_factory=list, init=False)
    input_hw: tuple[int, int] = field(default=(0, 0), init=False)
    _session: Any = field(default=None, init=False, repr=False)
    _input_name: str = field(default="", init=False, repr=False)
    _input_dtype: Any = field(default=np.float32, init=False, repr=False)
    _layout: str = field(default="", init=False, repr=False)
    _stride: int | None = field(default=None, init=False, repr=False)  # set for letterbox 'rect'
    _merged: np.ndarray = field(default=None, init=False, repr=False)  # type: ignore[assignment]
    _class_to_ours: np.ndarray = field(default=None, init=False, repr=False)  # type: ignore[assignment]
    _domain: np.ndarray = field(default=None, init=False, repr=False)  # type: ignore[assignment]
    _labeler: HazmatLabelClassifier | None = field(default=None, init=False, repr=False)
    # (len(CLASSES),) each class's minimum score: conf, or type_conf of its type
    _thresholds: np.ndarray = field(default=None, init=False, repr=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        self._check_settings()
        path = Path(self.model)
        choice = choose_providers(self.providers, DetectorConfigError)
        session = open_onnx_session(path, self.threads, OnnxModelError, providers=choice.providers)
        self._session = session
        if choice.note:
            self.notes.append(f"detector: {choice.note}")
        elif session.get_providers()[0] != choice.providers[0]:  # available, but it failed to load
            self.notes.append(
                f"detector: {choice.providers[0]} could not be started; running on {session.get_providers()[0]}"
            )
        metadata = dict(session.get_modelmeta().custom_metadata_map)
        self.model_names = self._read_names(path, metadata)
        try:
            self._class_to_ours = self._map_classes(self.model_names)
        except OnnxModelError as e:
            raise OnnxModelError(f"{path}: {e}") from None
        # (len(CLASSES),) the classes of the model's domain(s), where no-information mass goes
        self._domain = np.zeros(len(CLASSES), dtype=bool)
        for m in self._class_to_ours[self._class_to_ours >= 0]:
            self._domain[[CLASS_INDEX[c] for c in class_domain(CLASSES[int(m)])]] = True
        self._merged = self._merged_groups()
        self.input_hw = self._read_input(session, path, metadata)
        outputs = session.get_outputs()
        try:
            self._layout = resolve_layout(outputs[0].shape, len(self.model_names), self.layout, metadata)
        except OnnxModelError as e:
            raise OnnxModelError(f"{path}: {e}") from None
        if self.label_model is not None:
            if not np.any(IS_HAZMAT[self._class_to_ours[self._class_to_ours >= 0]]):
                raise DetectorConfigError(
                    f"detector 'onnx': label_model names hazmat placards, but {path.name} reports none"
                )
            self._labeler = HazmatLabelClassifier(model=self.label_model, threads=self.threads)
        self._thresholds = self._class_thresholds()

    def _check_settings(self) -> None:
        if not 0.0 <= float(self.conf) <= 1.0:
            raise DetectorConfigError(f"detector 'onnx': conf must be in [0, 1], got {self.conf}")
        if not 0.0 <= float(self.nms_iou) <= 1.0:
            raise DetectorConfigError(f"detector 'onnx': nms_iou must be in [0, 1], got {self.nms_iou}")
        if int(self.max_det) < 1:
            raise DetectorConfigError(f"detector 'onnx': max_det must be >= 1, got {self.max_det}")
        if int(self.threads) < 1:
            raise DetectorConfigError(f"detector 'onnx': threads must be >= 1, got {self.threads}")
        if self.layout not in LAYOUTS:
            raise DetectorConfigError(f"detector 'onnx': layout must be one of {LAYOUTS}, got {self.layout!r}")
        if self.letterbox not in LETTERBOXES:
            raise DetectorConfigError(
                f"detector 'onnx': letterbox must be one of {LETTERBOXES}, got {self.letterbox!r}"
            )

    def _class_thresholds(self) -> np.ndarray:
        """(len(CLASSES),) float64: each class's minimum score, ``type_conf`` of its type where
        given, else ``conf``; a type_conf of a type the model cannot report is refused."""
        thresholds = np.full(len(CLASSES), float(self.conf))
        type_conf = dict(self.type_conf or {})
        unknown = sorted(set(type_conf) - self.known_types)
        if unknown:
            raise DetectorConfigError(
                f"detector 'onnx': type_conf names {', '.join(map(repr, unknown))}, which "
                f"{Path(self.model).name} cannot report (its types: {', '.join(sorted(self.known_types))})"
            )
        for t, c in type_conf.items():
            if not 0.0 <= float(c) <= 1.0:
                raise DetectorConfigError(f"detector 'onnx': type_conf.{t} must be in [0, 1], got {c}")
            thresholds[[k for k, ct in enumerate(CLASS_TYPES) if ct == t]] = float(c)
        return thresholds

    @property
    def known_types(self) -> frozenset[str]:
        """The object types (poi.core.names.TYPES) this model can report."""
        identities = (class_to_identity(CLASSES[int(m)]) for m in self._class_to_ours if m >= 0)
        return frozenset(identity[0] for identity in identities if identity is not None)

    def _read_names(self, path: Path, metadata: Mapping[str, str]) -> list[str]:
        if self.names is not None:
            return load_names_file(self.names)
        if "names" not in metadata:
            raise OnnxModelError(
                f"{path}: no 'names' in the model metadata; give a names file (one class name a line, "
                "or YAML): --set detector.options.names=FILE"
            )
        return parse_names_metadata(metadata["names"])

    def _map_classes(self, model_names: list[str]) -> np.ndarray:
        """Index in CLASSES for each model class, -1 for a class mapped to None (ignored)."""
        class_map = dict(self.class_map or {})
        stray = sorted(set(class_map) - set(model_names))
        if stray:
            raise OnnxModelError(f"class_map names {stray} are not model classes {model_names}")
        ours = np.full(len(model_names), -1, dtype=np.int64)
        unknown = []
        for j, model_name in enumerate(model_names):
            target = class_map.get(model_name, model_name)
            if target is None:
                continue
            if canonical_type(str(target)) == "hazmat":
                # a placard the model finds but does not name (class 'hazmat' or 'placard'):
                # it stands in the placards' group and the label classifier names it
                if self.label_model is None:
                    raise DetectorConfigError(
                        f"detector 'onnx': model class {model_name!r} finds placards without naming their "
                        "label; give the label classifier that names them (the setting detector.label_model)"
                    )
                ours[j] = HAZMAT_INDICES[0]
                continue
            name = canonical_class(str(target))
            if name is None:
                unknown.append(model_name if model_name not in class_map else f"{model_name}->{target}")
                continue
            ours[j] = CLASS_INDEX[name]
        if unknown:
            raise OnnxModelError(
                f"model class names {unknown} are not known types or hazmat labels; "
                "map them with class_map (name -> one of poi.core.names.CLASSES, or null to ignore)"
            )
        return ours

    def _groups(self, ours: np.ndarray) -> np.ndarray:
        """The NMS group (an index into CLASSES) of each class in ``ours``: the class itself, or
        with a label classifier, one group for the 16 placards and 'qr'."""
        group = ours.copy()
        if self._labeler is not None:
            group[LABELLED[ours]] = HAZMAT_INDICES[0]
        return group

    def _merged_groups(self) -> np.ndarray:
        """(len(CLASSES),) True for an NMS group that more than one model class falls into (by
        ``class_map`` or the label classifier), where an end2end model's boxes still need NMS."""
        kept = self._class_to_ours[self._class_to_ours >= 0]
        labelled = np.any(LABELLED[kept]) and self.label_model is not None
        group = kept.copy()
        if labelled:
            group[LABELLED[kept]] = HAZMAT_INDICES[0]
        return np.bincount(group, minlength=len(CLASSES)) > 1

    def _read_input(self, session: Any, path: Path, metadata: Mapping[str, str]) -> tuple[int, int]:
        inputs = session.get_inputs()
        if len(inputs) != 1:
            raise OnnxModelError(f"{path}: expected one input image, found {len(inputs)} inputs")
        inp = inputs[0]
        self._input_name = inp.name
        if inp.type not in INPUT_TYPES:
            raise OnnxModelError(
                f"{path}: input is {inp.type}; expected an image as tensor(float) or tensor(float16), 0..1"
            )
        self._input_dtype = INPUT_TYPES[inp.type]
        shape = list(inp.shape)
        if len(shape) != 4 or (isinstance(shape[1], int) and shape[1] != 3):
            raise OnnxModelError(f"{path}: input has shape {shape}; expected (1, 3, H, W)")
        H, W = shape[2], shape[3]
        static = isinstance(H, int) and isinstance(W, int) and H > 0 and W > 0
        if static and max(H, W) > MAX_INPUT_PX:
            raise OnnxModelError(
                f"{path}: input has shape {shape}; expected (1, 3, H, W) with H and W at most {MAX_INPUT_PX}"
            )
        if self.letterbox == "rect":
            if static:
                raise DetectorConfigError(
                    f"detector 'onnx': letterbox 'rect' needs a model with a dynamic input size; {path.name} "
                    f"has a fixed {H}x{W} input (export with dynamic=True, or use letterbox 'square')"
                )
            self._stride = _as_stride(metadata.get("stride"), path)
            hw = self._dynamic_size(path, metadata)
            if hw[0] % self._stride or hw[1] % self._stride:
                raise DetectorConfigError(
                    f"detector 'onnx': letterbox 'rect' needs imgsz a multiple of the model's stride "
                    f"{self._stride}, got {hw[0]}x{hw[1]}"
                )
            return hw
        if static:
            if self.imgsz is not None and _as_size_hw(self.imgsz, "imgsz") != (H, W):
                raise DetectorConfigError(
                    f"detector 'onnx': imgsz {self.imgsz} differs from the model's fixed input {H}x{W}"
                )
            return (H, W)
        return self._dynamic_size(path, metadata)

    def _dynamic_size(self, path: Path, metadata: Mapping[str, str]) -> tuple[int, int]:
        """The letterbox size for a dynamic model: ``imgsz``, else the metadata's, else 640."""
        if self.imgsz is not None:
            return _as_size_hw(self.imgsz, "detector 'onnx': imgsz")
        if "imgsz" in metadata:
            return _as_size_hw(metadata["imgsz"], f"{path}: metadata imgsz")
        return (DEFAULT_IMGSZ_PX, DEFAULT_IMGSZ_PX)

    @property
    def output_layout(self) -> str:
        """'yolov5' or 'yolov8', as decided when the model was loaded."""
        return self._layout

    def detect(self, frame: Frame) -> list[Detection]:
        """Detections in ``frame.rgb`` with boxes in its pixels, best first."""
        rgb = frame.rgb
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"frame {frame.index}: rgb must be uint8 (H, W, 3), got {rgb.dtype} {rgb.shape}")
        h, w = rgb.shape[:2]

        t0 = time.perf_counter()
        img, r, (left, top) = letterbox(rgb, self.input_hw, self._stride)  # (H_in, W_in, 3)
        x = img.transpose(2, 0, 1)[None].astype(self._input_dtype) / 255.0  # (1, 3, H_in, W_in)
        x = np.ascontiguousarray(x, dtype=self._input_dtype)
        t1 = time.perf_counter()
        out = self._session.run(None, {self._input_name: x})[0]
        t2 = time.perf_counter()
        self.last_timing_ms = {"labels": 0.0}
        dets = self._postprocess(np.asarray(out, dtype=np.float32), r, left, top, rgb)
        t3 = time.perf_counter()
        if self.read_qr:
            dets = attach_qr_text(rgb, dets)
        t4 = time.perf_counter()
        labels_ms = self.last_timing_ms["labels"]
        self.last_timing_ms = {
            "preprocess": (t1 - t0) * 1e3,
            "inference": (t2 - t1) * 1e3,
            "postprocess": (t3 - t2) * 1e3 - labels_ms,
            "labels": labels_ms,
            "qr": (t4 - t3) * 1e3,
        }
        return dets

    def _postprocess(self, out: np.ndarray, r: float, left: int, top: int, rgb: np.ndarray) -> list[Detection]:
        h, w = rgb.shape[:2]
        C = len(self.model_names)
        resolve_layout(out.shape, C, self._layout, {})  # the run's shape must match the declared one
        if self._layout == "end2end":
            box_in, top_score, cls = decode_end2end(out, C)  # (N, 4) xyxy, (N,), (N,)
            finite = np.all(np.isfinite(box_in), axis=1) & np.isfinite(top_score) & (cls >= 0)
            cls = np.where(finite, cls, 0)
            scores = np.zeros((len(cls), C), dtype=np.float32)  # (N, C): the graph gives the top class only
            scores[np.arange(len(cls)), cls] = np.where(finite, top_score, 0.0)
        else:
            box_in, scores = decode_output(out, C, self._layout)  # (N, 4) cxcywh, (N, C)
            finite = np.all(np.isfinite(box_in), axis=1) & np.all(np.isfinite(scores), axis=1)
            cls = np.argmax(np.where(np.isfinite(scores), scores, -np.inf), axis=1)  # (N,)
            top_score = scores[np.arange(len(cls)), cls]  # (N,)
        ours = self._class_to_ours[cls]  # (N,), -1 for ignored classes
        candidate = finite & (ours >= 0)
        if np.any(candidate):  # the best score of the run, kept or not: a silent detector says how near it came
            self.highest_score = max(self.highest_score, float(np.max(top_score[candidate])))
        # the lowest threshold first; each class's own after NMS and naming (greedy NMS keeps a
        # box whatever the lower-scored boxes are, so this is a run at each class's threshold)
        keep = candidate & (top_score >= float(self._thresholds.min()))  # a float32 test, as conf's
        if not np.any(keep):
            return []
        box_in, scores, cls, top_score, ours = (
            box_in[keep],
            scores[keep],
            cls[keep],
            top_score[keep],
            ours[keep],
        )
        # Input pixels -> original-image xyxy: x = (x_in - left) / r, not clipped yet.
        if self._layout == "end2end":
            x1, y1 = (box_in[:, 0] - left) / r, (box_in[:, 1] - top) / r
            x2, y2 = (box_in[:, 2] - left) / r, (box_in[:, 3] - top) / r
        else:
            x1 = (box_in[:, 0] - 0.5 * box_in[:, 2] - left) / r
            y1 = (box_in[:, 1] - 0.5 * box_in[:, 3] - top) / r
            x2 = (box_in[:, 0] + 0.5 * box_in[:, 2] - left) / r
            y2 = (box_in[:, 1] + 0.5 * box_in[:, 3] - top) / r
        xyxy = np.stack([x1, y1, x2, y2], axis=1)  # (M, 4)
        # Class-wise NMS (classes in CLASSES, so two model names for one class compete; with a
        # label classifier the 16 hazmat labels and qr are one class, named after NMS) on the
        # boxes as the network gave them, then clipping, as Ultralytics' predict does.
        group = self._groups(ours)
        pool = np.flatnonzero((x2 > x1) & (y2 > y1))  # a box without area suppresses nothing
        if self._layout == "end2end":  # NMS was done in the graph, but for classes merged here
            passed, pool = pool[~self._merged[group[pool]]], pool[self._merged[group[pool]]]
        else:
            passed = pool[:0]
        order = np.concatenate(
            [passed, pool[class_wise_nms(xyxy[pool], top_score[pool], group[pool], self.nms_iou)]]
        )
        # The max_det best boxes after NMS, then clipping (Ultralytics' order: capping after dropping
        # the boxes clipped to nothing would let in-frame boxes past the cap that Ultralytics cuts).
        order = order[np.argsort(-top_score[order], kind="stable")][: int(self.max_det)]
        xyxy = np.stack(
            [np.clip(x1, 0, w), np.clip(y1, 0, h), np.clip(x2, 0, w), np.clip(y2, 0, h)], axis=1
        )  # (M, 4)
        order = order[(xyxy[order, 2] > xyxy[order, 0]) & (xyxy[order, 3] > xyxy[order, 1])]
        if order.size == 0:
            return []
        classes, conf = ours[order], top_score[order].astype(np.float64)  # (K,), (K,)
        probs = self._class_probs(scores[order], classes)  # (K, len(CLASSES))
        if self._labeler is not None:
            t0 = time.perf_counter()
            classes, conf, probs = self._name_placards(self._labeler, rgb, xyxy[order], classes, conf, probs)
            self.last_timing_ms["labels"] = (time.perf_counter() - t0) * 1e3
            named = np.flatnonzero(conf >= self._thresholds[classes])
            named = named[np.argsort(-conf[named], kind="stable")]
            order, classes, conf, probs = order[named], classes[named], conf[named], probs[named]
        elif self.type_conf:  # float32, as the score test above
            named = np.flatnonzero(top_score[order] >= self._thresholds[classes].astype(np.float32))
            order, classes, conf, probs = order[named], classes[named], conf[named], probs[named]
        n = int(self.max_det)
        return [
            make_detection(
                CLASSES[int(classes[row])],
                tuple(xyxy[i]),
                float(conf[row]),
                source="onnx",
                class_probs=probs[row],
            )
            for row, i in enumerate(order[:n])
        ]

    def _name_placards(
        self,
        labeler: HazmatLabelClassifier,
        rgb: np.ndarray,
        boxes: np.ndarray,
        classes: np.ndarray,
        conf: np.ndarray,
        probs: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Relabel the placards among K detections with the label classifier ``labeler``.

        For a placard with the model's score s and classifier output q (16 labels,
        then background): label j* = argmax_j q_j, confidence s q_j*, Pr(label j) =
        s q_j, and the rest, 1 - s (1 - q_background), spread over the other classes
        as the model's scores had it (uniformly over its domain when they were all
        zero). A 'qr' box is treated so when q_j* > q_background (the classifier's
        background includes QR codes); otherwise it stays as the model had it.
        """
        cand = np.flatnonzero(LABELLED[classes])  # (M,)
        if cand.size == 0:
            return classes, conf, probs
        q = labeler.classify(rgb, boxes[cand])  # (M, 17)
        n_lab = len(LABEL_CLASSES) - 1
        best = np.argmax(q[:, :n_lab], axis=1)  # (M,)
        placard = IS_HAZMAT[classes[cand]] | (q[np.arange(cand.size), best] > q[:, n_lab])  # (M,)
        hz, q, best = cand[placard], q[placard], best[placard]  # (H,), (H, 17), (H,)
        if hz.size == 0:
            return classes, conf, probs
        s = conf[hz]  # (H,)
        classes, conf, probs = classes.copy(), conf.copy(), probs.copy()
        classes[hz] = HAZMAT_INDICES[best]
        conf[hz] = s * q[np.arange(hz.size), best]
        others = self._domain & ~IS_HAZMAT  # (len(CLASSES),)
        rest = probs[hz] * others  # (H, len(CLASSES)), the non-placard mass as the model spread it
        target = 1.0 - s * (1.0 - q[:, n_lab])  # (H,)
        total = rest.sum(axis=1)
        uniform = others / max(int(others.sum()), 1)
        rest = np.where(
            (total > 0)[:, None],
            rest * (target / np.where(total > 0, total, 1.0))[:, None],
            uniform * target[:, None],
        )
        rest[:, HAZMAT_INDICES] = s[:, None] * q[:, :n_lab]
        probs[hz] = rest
        return classes, conf, probs

    def _class_probs(self, model_scores: np.ndarray, top: np.ndarray) -> np.ndarray:
        """Class probabilities over CLASSES for K detections ([Avevor2022]_ section 2.1.5).

        ``model_scores`` (K, C) are mapped onto CLASSES (the max over model names of
        one class); the top class keeps its score p, the rest 1 - p goes to the
        others in proportion to their scores, or, when those are all zero, uniformly
        over the other classes of the model's domain (:func:`poi.core.names.class_domain`:
        the 24 rescue classes for a rescue model, the arena's four for an arena model,
        all of CLASSES for a model of both). With scores on other classes, row k
        equals ``spread_class_probs(mapped[k], top[k])``.
        """
        K, n = len(top), len(CLASSES)
        S = np.zeros((K, n), dtype=np.float64)  # (K, len(CLASSES))
        for j, m in enumerate(self._class_to_ours):
            if m >= 0:
                S[:, m] = np.maximum(S[:, m], np.clip(model_scores[:, j], 0.0, 1.0))
        rows = np.arange(K)
        p = S[rows, top]  # (K,)
        rest = S.sum(axis=1) - p  # (K,)
        safe = np.where(rest > 0.0, rest, 1.0)
        m_dom = max(int(self._domain.sum()) - 1, 1)
        probs = np.where(
            (rest > 0.0)[:, None], S * ((1.0 - p) / safe)[:, None], self._domain * ((1.0 - p) / m_dom)[:, None]
        )  # (K, len(CLASSES))
        probs[rows, top] = p
        return probs
