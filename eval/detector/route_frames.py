"""Training frames from the robot's own tours: ``poibench route-frames``.

``poibench dataset`` aims a randomised camera at each object; a trial's camera
is the robot's, driving its tour and stepping its pan-tilt head, and the
shipped detector's false reports in trials come from what that camera sees and
the aimed views rarely show: objects cut by the image border, seen edge-on
along a corridor or half-hidden behind a door frame, with the head's slew blur.
This renders every ``every``-th frame of the default tour through freshly
generated RRL mazes (the trial's own camera, sensor models and lighting presets)
and labels them with the simulator's truth boxes, as ``poibench dataset``
labels its views (:func:`eval.detector.dataset.yolo_labels`: at least
``min_visible_fraction`` visible and ``min_box_px`` wide; Landolt-C targets
unlabelled; the objects that show less, and QR chart pages, in ``ignore/``).
Frames with nothing labelled stay in: they are the background the detector
must keep quiet on.

Mazes are generated from seeds drawn from ``SeedSequence([seed, j, 9])`` (31
bits: far from the suites' own seeds, 201-210, 301-...), 4-5 cells a side, a
lighting preset each, then the spec's ``settings`` (``--set``: a suite's own, such
as ``rrl-hard``'s dim light and dense objects).

With ``mine`` (a detector and its label model; ``default`` the shipped pair), the
frames are chosen by that detector's mistakes (:mod:`eval.detector.mining`, hard-example
mining): a frame stays when the detector at the operating confidence misses a labelled
object, boxes one as another type or boxes nothing there; of the frames it gets right,
one in ``keep_easy``. The manifest's ``mistakes`` column names them and the summary
counts them by kind: what the detector gets wrong on tours, before any training.

Layout: ``images/train/*.jpg``, ``labels/train/*.txt``, ``ignore/train/*.txt``, ``data.yaml``,
``manifest.csv``; all frames are training frames (validate on ``poibench dataset``'s val split or on trials).
A rerun skips finished mazes.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import yaml

from eval.detector.dataset import (
    LIGHTING,
    DatasetError,
    DatasetSpec,
    fitting_simulation,
    gather_manifest,
    label_boxes,
    object_class,
    write_data_yaml,
    write_labelled_image,
    write_rows,
    yolo_rows,
)
from poi.core.loader import safe_load_file
from poi.core.names import RESCUE_CLASSES
from poi.models import DEFAULT_LABEL_MODEL, DEFAULT_MODEL, SHIPPED

ROUTE_FRAMES_KEY = "route_frames"  # the key of dataset.yaml that holds a route-frames folder's spec


@dataclass(kw_only=True)
class RouteFramesSpec:
    mazes: int
    seed: int = 0
    every: int = 10  # one frame in this many (10 Hz frames: one a second)
    jpeg_quality: int = 95
    settings: tuple[str, ...] = ()  # scenario --set items every maze takes after its lighting
    # (detector ONNX, label model ONNX) whose mistakes choose, or "default": the shipped pair, kept
    # by that name (and its files' hashes) so that the folder's dataset.yaml does not depend on
    # where poibench is installed
    mine: tuple[str, str] | str | None = None
    keep_easy: int = 4  # with mine: one in this many of the frames the detector gets right stays

    def __post_init__(self) -> None:
        if self.mazes < 1:
            raise DatasetError(f"--mazes must be at least 1, got {self.mazes}")
        if self.every < 1:
            raise DatasetError(f"--every must be at least 1, got {self.every}")
        if self.keep_easy < 1:
            raise DatasetError(f"--keep-easy must be at least 1, got {self.keep_easy}")
        self.settings = tuple(self.settings)
        refused = {
            "seed": "each maze takes its own seed, drawn from --seed; give --seed",
            "name": "each maze is named by its index",
            "rules": "route-frames scores nothing",
        }
        for item in self.settings:
            key = item.split("=", 1)[0].strip()
            if key in refused:
                raise DatasetError(f"--set {item}: {refused[key]}")
        if self.mine is not None and self.mine != SHIPPED:
            if isinstance(self.mine, str):
                raise DatasetError(
                    f"--mine: expected '{SHIPPED}' or a detector and its label model, got {self.mine!r}"
                )
            self.mine = (str(self.mine[0]), str(self.mine[1]))
            for flag, f in zip(("--mine", "--mine-labels"), self.mine, strict=True):
                if not Path(f).is_file():
                    raise DatasetError(f"{flag} {f}: no such file")

    def mine_files(self) -> tuple[str, str] | None:
        """The mining pair's two ONNX files (the shipped pair's for ``mine`` "default")."""
        if self.mine == SHIPPED:
            return str(DEFAULT_MODEL), str(DEFAULT_LABEL_MODEL)
        return self.mine

    def to_dict(self) -> dict:
        """The spec as dataset.yaml keeps it; the keys of mining and settings only when used, so
        folders made before them resume. A mining spec also keeps the SHA-256 of its two model
        files (``mine_sha256``): a path such as the shipped detector's holds other weights once
        a new model ships, and a folder grown with them would mix two detectors' mistakes."""
        from eval.trial.perception_cache import file_sha256

        d = asdict(self)
        for key, off in (("settings", ()), ("mine", None), ("keep_easy", type(self).keep_easy)):
            if d[key] == off or (key == "keep_easy" and self.mine is None):
                del d[key]
            elif isinstance(d[key], tuple):
                d[key] = list(d[key])
        if self.mine is not None:
            d["mine_sha256"] = [file_sha256(f) for f in self.mine_files()]
        return d

    def maze(self, j: int, attempt: int = 0) -> tuple[int, int, int, str]:
        """(seed, rows, cols, lighting) of the j-th maze; a maze its objects do not fit is drawn
        again with the next ``attempt``."""
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, j, 9, *([attempt] if attempt else [])]))
        seed = int(rng.integers(1_000_000, 2**31 - 1))
        rows, cols = (int(v) for v in rng.integers(4, 6, size=2))
        return seed, rows, cols, LIGHTING[int(rng.integers(len(LIGHTING)))]


def _scenario(spec: RouteFramesSpec, j: int, attempt: int = 0):
    from eval.trial.scenarios import generated_scenario
    from sim.scenario import apply_settings

    seed, rows, cols, lighting = spec.maze(j, attempt)
    try:
        return apply_settings(generated_scenario(seed, rows, cols), [f"lighting={lighting}", *spec.settings])
    except ValueError as exc:  # ScenarioError: one line naming the key
        raise DatasetError(str(exc)) from exc


def _build(spec: RouteFramesSpec, j: int):
    """(scenario, Simulation) of maze j, drawn again when its objects do not fit."""
    from sim.simulator import Simulation

    def build(attempt: int):
        sc = _scenario(spec, j, attempt)
        return sc, Simulation(sc)

    return fitting_simulation(build, f"maze {j}", "ask for fewer with --set")


def _mining_detector(spec: RouteFramesSpec):
    from poi.config import DetectorConfig
    from poi.detectors import build_detector

    assert spec.mine is not None
    model, labels = spec.mine_files()
    return build_detector({"name": "onnx", "model": model, "label_model": labels, "conf": DetectorConfig().conf})


def _mistakes(detector, frame, labelled: list, ignored: list) -> list[str]:
    """``detector``'s mistakes on ``frame`` against its truth boxes, ``labelled`` and ``ignored``
    (:func:`eval.detector.dataset.label_boxes`; eval.detector.mining)."""
    from eval.detector.mining import frame_mistakes

    def boxes(labels):
        return np.array([b for _, b in labels], float).reshape(-1, 4), [c for c, _ in labels]

    gt, gt_c = boxes(labelled)
    ign, ign_c = boxes(ignored)
    dets = [d for d in detector.detect(frame) if d.class_name in RESCUE_CLASSES]
    det_boxes = np.array([d.box_xyxy for d in dets], float).reshape(-1, 4)
    det_c = [RESCUE_CLASSES.index(d.class_name) for d in dets]
    return frame_mistakes(gt, gt_c, det_boxes, det_c, ign, ign_c)


def write_route_frames(
    spec: RouteFramesSpec, out_dir: str | Path, progress: Callable[[int], None] | None = None
) -> dict:
    """Render the tours' frames into ``out_dir``; returns the summary (also in dataset.yaml)."""
    out = Path(out_dir)
    meta = out / "dataset.yaml"
    _scenario(spec, 0)  # a bad --set is refused before anything is written
    if meta.exists():
        old = safe_load_file(meta, error=DatasetError)
        before = old.get(ROUTE_FRAMES_KEY) if isinstance(old, dict) else None
        # maze j depends on the seed, j and the settings only: a folder grows by more --mazes
        wanted = spec.to_dict()
        hashes = wanted.pop("mine_sha256", None)
        kept = dict(before) if isinstance(before, dict) else None
        # a folder mined before the models' hashes were kept has none: its settings decide
        kept_hashes = None if kept is None else kept.pop("mine_sha256", hashes)
        if kept is None or {**kept, "mazes": spec.mazes} != wanted:
            raise DatasetError(f"{out} holds route frames of other settings; choose a new --out")
        if kept_hashes != hashes:
            raise DatasetError(
                f"{out} was mined with other weights in {' and '.join(spec.mine_files() or ())} (their SHA-256 "
                "differ from its dataset.yaml's mine_sha256); choose a new --out"
            )
        if before["mazes"] > spec.mazes:
            raise DatasetError(f"{out} holds the frames of {before['mazes']} mazes; ask for as many or more")
    elif out.exists() and any(out.iterdir()):
        raise DatasetError(f"{out} exists and is not a route-frames folder; choose an empty or new --out")
    for sub in ("images/train", "labels/train", "images/val", "labels/val", ".done"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    meta.write_text(yaml.safe_dump({ROUTE_FRAMES_KEY: spec.to_dict()}, sort_keys=False), encoding="utf-8")
    label_spec = DatasetSpec(images=1)  # the labelling thresholds of poibench dataset
    detector = None if spec.mine is None else _mining_detector(spec)
    for j in range(spec.mazes):
        marker = out / ".done" / f"maze_{j:04d}.csv"
        if marker.exists():
            continue
        sc, sim = _build(spec, j)
        rows = []
        easy = 0
        with sim:
            by_id = {o.id: o for o in sim.objects}
            for k in range(0, sim.n_frames, spec.every):
                frame, truth = sim.frame(k)
                if progress:
                    progress(1)
                labelled = label_boxes(truth, by_id, label_spec)
                ignored = label_boxes(truth, by_id, label_spec, ignored=True)
                mistakes = [] if detector is None else _mistakes(detector, frame, labelled, ignored)
                if detector is not None and not mistakes:
                    easy += 1
                    if (easy - 1) % spec.keep_easy:
                        continue
                height, width = frame.rgb.shape[:2]
                labels = yolo_rows(labelled, width, height)
                ignore = yolo_rows(ignored, width, height)
                name = f"r{j:04d}_{k:05d}"
                write_labelled_image(out, "train", name, frame.rgb, labels, spec.jpeg_quality, ignore)
                rows.append(
                    {
                        "image": f"images/train/{name}.jpg",
                        "split": "train",
                        "maze": j,
                        "scenario_seed": sc.seed,
                        "lighting": sc.lighting,
                        "frame": k,
                        "labels": " ".join(RESCUE_CLASSES[c] for c, *_ in labels),
                        "objects": " ".join(object_class(by_id[v.id]) for v in truth.visible),
                        **({"mistakes": "; ".join(mistakes)} if detector is not None else {}),
                    }
                )
        write_rows(marker, rows)
    return _finish(out, spec)


def _finish(out: Path, spec: RouteFramesSpec) -> dict:
    rows = gather_manifest(out, [out / ".done" / f"maze_{j:04d}.csv" for j in range(spec.mazes)])
    write_data_yaml(out)
    summary: dict = {
        "frames": len(rows),
        "frames_with_labels": sum(bool(r["labels"]) for r in rows),
        "boxes": sum(len(r["labels"].split()) for r in rows),
    }
    if spec.mine is not None:
        kinds = Counter(m for r in rows for m in r["mistakes"].split("; ") if m)
        summary["frames_with_mistakes"] = sum(bool(r["mistakes"]) for r in rows)
        summary["mistakes"] = dict(kinds.most_common())
    (out / "dataset.yaml").write_text(
        yaml.safe_dump({ROUTE_FRAMES_KEY: spec.to_dict(), "summary": summary}, sort_keys=False), encoding="utf-8"
    )
    return summary


def is_route_frames_folder(root: str | Path, *, error: type[ValueError] = DatasetError) -> bool:
    """Whether ``root`` was written by ``poibench route-frames`` (its ``dataset.yaml`` holds
    :data:`ROUTE_FRAMES_KEY`): training frames only, an empty ``val`` split. A ``dataset.yaml``
    that is not YAML raises ``error`` naming it."""
    meta = Path(root) / "dataset.yaml"
    if not meta.is_file():
        return False
    doc = safe_load_file(meta, error=error)
    return isinstance(doc, dict) and ROUTE_FRAMES_KEY in doc
