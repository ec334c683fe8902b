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
unlabelled). Frames with nothing labelled stay in: they are the background
the detector must keep quiet on.

Mazes are generated from seeds drawn from ``SeedSequence([seed, j, 9])`` (31
bits: far from the suites' own seeds, 201-210, 301-...), 4-5 cells a side, a
lighting preset each. Layout: ``images/train/*.jpg``, ``labels/train/*.txt``,
``data.yaml``, ``manifest.csv``; all frames are training frames (validate on
``poibench dataset``'s val split or on trials). A rerun skips finished mazes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import yaml

from eval.detector.dataset import (
    LIGHTING,
    DatasetError,
    DatasetSpec,
    gather_manifest,
    object_class,
    write_data_yaml,
    write_labelled_image,
    write_rows,
    yolo_labels,
)
from poi.core.loader import safe_load_file
from poi.core.names import RESCUE_CLASSES


@dataclass(kw_only=True)
class RouteFramesSpec:
    mazes: int
    seed: int = 0
    every: int = 10  # one frame in this many (10 Hz frames: one a second)
    jpeg_quality: int = 95

    def __post_init__(self) -> None:
        if self.mazes < 1:
            raise DatasetError(f"--mazes must be at least 1, got {self.mazes}")
        if self.every < 1:
            raise DatasetError(f"--every must be at least 1, got {self.every}")

    def maze(self, j: int) -> tuple[int, int, int, str]:
        """(seed, rows, cols, lighting) of the j-th maze."""
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, j, 9]))
        seed = int(rng.integers(1_000_000, 2**31 - 1))
        rows, cols = (int(v) for v in rng.integers(4, 6, size=2))
        return seed, rows, cols, LIGHTING[int(rng.integers(len(LIGHTING)))]


def _scenario(spec: RouteFramesSpec, j: int):
    from eval.trial.scenarios import apply_scenario_settings, generated_scenario

    seed, rows, cols, lighting = spec.maze(j)
    return apply_scenario_settings(generated_scenario(seed, rows, cols), [f"lighting={lighting}"])


def write_route_frames(
    spec: RouteFramesSpec, out_dir: str | Path, progress: Callable[[int], None] | None = None
) -> dict:
    """Render the tours' frames into ``out_dir``; returns the summary (also in dataset.yaml)."""
    from sim.simulator import Simulation

    out = Path(out_dir)
    meta = out / "dataset.yaml"
    if meta.exists():
        old = safe_load_file(meta, error=DatasetError)
        if not isinstance(old, dict) or old.get("route_frames") != asdict(spec):
            raise DatasetError(f"{out} holds route frames of other settings; choose a new --out")
    elif out.exists() and any(out.iterdir()):
        raise DatasetError(f"{out} exists and is not a route-frames folder; choose an empty or new --out")
    for sub in ("images/train", "labels/train", "images/val", "labels/val", ".done"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    meta.write_text(yaml.safe_dump({"route_frames": asdict(spec)}, sort_keys=False), encoding="utf-8")
    label_spec = DatasetSpec(images=1)  # the labelling thresholds of poibench dataset
    for j in range(spec.mazes):
        marker = out / ".done" / f"maze_{j:04d}.csv"
        if marker.exists():
            continue
        sc = _scenario(spec, j)
        rows = []
        with Simulation(sc) as sim:
            by_id = {o.id: o for o in sim.objects}
            for k in range(0, sim.n_frames, spec.every):
                frame, truth = sim.frame(k)
                height, width = frame.rgb.shape[:2]
                labels = yolo_labels(truth, by_id, label_spec, width, height)
                name = f"r{j:04d}_{k:05d}"
                write_labelled_image(out, "train", name, frame.rgb, labels, spec.jpeg_quality)
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
                    }
                )
                if progress:
                    progress(1)
        write_rows(marker, rows)
    return _finish(out, spec)


def _finish(out: Path, spec: RouteFramesSpec) -> dict:
    rows = gather_manifest(out, [out / ".done" / f"maze_{j:04d}.csv" for j in range(spec.mazes)])
    write_data_yaml(out)
    summary = {
        "frames": len(rows),
        "frames_with_labels": sum(bool(r["labels"]) for r in rows),
        "boxes": sum(len(r["labels"].split()) for r in rows),
    }
    (out / "dataset.yaml").write_text(
        yaml.safe_dump({"route_frames": asdict(spec), "summary": summary}, sort_keys=False), encoding="utf-8"
    )
    return summary
