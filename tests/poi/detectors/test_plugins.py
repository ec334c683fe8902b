"""Teams' Python detectors: python:MODULE:CLASS, the poibench.detectors entry points, and each mistake's error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from poi.core.names import CLASSES
from poi.core.types import Frame, Intrinsics
from poi.detectors import (
    CheckedDetector,
    DetectorConfigError,
    DetectorOutputError,
    build_python_detector,
    entry_point_names,
    is_team_detector,
)

HERE = Path(__file__).resolve().parent
MOD = "python:red_detector"


@pytest.fixture(autouse=True)
def _importable(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))


def frame(rgb: np.ndarray, index: int = 0) -> Frame:
    h, w = rgb.shape[:2]
    return Frame(
        index=index,
        timestamp_s=0.0,
        rgb=rgb,
        intrinsics=Intrinsics(width=w, height=h, fx=300.0, fy=300.0, ppx=w / 2, ppy=h / 2),
    )


def red_square_frame() -> Frame:
    """Grey wall with an extinguisher-red 20 x 30 px rectangle at x 40..59, y 10..39."""
    rgb = np.full((80, 120, 3), 200, np.uint8)
    rgb[10:40, 40:60] = (199, 13, 10)
    return frame(rgb)


def test_a_python_detector_is_built_from_its_options_and_finds_the_red_box(tmp_path):
    from red_detector import write_weights

    det = build_python_detector(f"{MOD}:RedBlobDetector", {"weights": write_weights(tmp_path / "w.npz")})
    assert isinstance(det, CheckedDetector) and det.name == "python:red_detector:RedBlobDetector"
    (d,) = det.detect(red_square_frame())
    assert d.class_name == d.type == "fire-extinguisher"
    assert d.box_xyxy == (40.0, 10.0, 60.0, 40.0)
    # the logistic score of (199, 13, 10): 12 * 199/255 - 14 * 23/255 - 6 = 2.102, sigmoid 0.8911
    assert d.confidence == pytest.approx(0.8911, abs=1e-3)
    # conf reaches the object: a threshold above every score finds nothing
    strict = build_python_detector(f"{MOD}:RedBlobDetector", {"weights": str(tmp_path / "w.npz"), "conf": 0.9999})
    assert strict.detect(red_square_frame()) == []


@pytest.mark.parametrize(
    ("spec", "options", "expected"),
    [
        ("python:no_such_module_xyz:Det", {}, "cannot import module 'no_such_module_xyz' (No module named"),
        (
            f"{MOD}:Nope",
            {},
            "module 'red_detector' has no attribute 'Nope'; it defines RedBlobDetector, WrongOutput",
        ),
        (f"{MOD}:NOT_CALLABLE", {}, "int object is not a class or callable"),
        (f"{MOD}:NoDetect", {}, "the NoDetect object it built has no detect(frame) method"),
        (
            f"{MOD}:RedBlobDetector",
            {"weights": "w.npz", "thresh": 3, "gain": 1},
            "unknown option(s) gain, thresh; it takes weights, conf",
        ),
        (f"{MOD}:RedBlobDetector", {"conf": 0.3}, "missing option(s) weights; it takes weights, conf"),
        (
            f"{MOD}:make_detector",
            {"anything": 1},
            "building it failed: RuntimeError: weights missing for ['anything']",
        ),
        ("python:red_detector", {}, "expected python:MODULE:CLASS, e.g. python:mypkg.detect:MyDetector"),
    ],
)
def test_each_mistake_is_one_line_naming_the_detector(spec, options, expected):
    with pytest.raises(DetectorConfigError) as err:
        build_python_detector(spec, options)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith(f"detector {spec!r}: ")
    assert expected in msg


def test_a_module_that_fails_at_import_names_the_failure(tmp_path, monkeypatch):
    (tmp_path / "broken_det_mod.py").write_text("raise RuntimeError('no GPU here')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    expected = r"importing module 'broken_det_mod' failed: RuntimeError: no GPU here"
    with pytest.raises(DetectorConfigError, match=expected):
        build_python_detector("python:broken_det_mod:Det", {})


@pytest.mark.parametrize(
    ("kind", "expected"),
    [
        ("dict", "returned a dict, expected a list of Detection"),
        ("tuple", "detection 0: a tuple, not a poi.core.types.Detection"),
        ("class", "class_name 'Toxic' is not in poi.core.names.CLASSES (did you mean 'inhalation-hazard'?)"),
        ("unknown-class", "detection 0: class_name 'car' is not in poi.core.names.CLASSES"),
        ("raise", "ZeroDivisionError: division by zero"),
    ],
)
def test_wrong_output_stops_at_the_first_frame_naming_the_value(kind, expected):
    det = build_python_detector(f"{MOD}:WrongOutput", {"kind": kind})
    with pytest.raises(DetectorOutputError) as err:
        det.detect(frame(np.zeros((8, 8, 3), np.uint8), index=0))
    assert str(err.value).startswith("detector 'python:red_detector:WrongOutput' on frame 0: ")
    assert expected in str(err.value)


def test_bad_boxes_confidences_and_types_are_refused():
    from poi.core.types import Detection
    from poi.detectors.plugins import check_detection

    def det(**kw):
        base = dict(class_name="door", type="door", text="", box_xyxy=(1, 2, 3, 4), confidence=0.5)
        return Detection(**{**base, **kw})

    assert check_detection(det()) is None
    assert "type 'valve', expected 'door'" in check_detection(det(type="valve"))
    assert "not 4 finite numbers" in check_detection(det(box_xyxy=(1, 2, float("nan"), 4)))
    assert "not 4 finite numbers" in check_detection(det(box_xyxy=(1, 2, 3)))
    assert "x1 <= x2" in check_detection(det(box_xyxy=(5, 2, 3, 4)))
    assert "confidence 1.5 is not in [0, 1]" in check_detection(det(confidence=1.5))
    assert "class_probs of shape (3,)" in check_detection(det(class_probs=np.ones(3) / 3))
    assert "positive sum" in check_detection(det(class_probs=np.zeros(len(CLASSES))))
    assert check_detection(det(class_probs=np.full(len(CLASSES), 1 / len(CLASSES)))) is None
    assert check_detection(det(text=5)) == "text 5 is not a str"
    assert check_detection(det(confidence=True)) == "confidence True is a bool, not a score"
    assert check_detection(det(box_xyxy=(100, 100, 100, 100))) == "box_xyxy (100, 100, 100, 100) has no area"
    outside = det(box_xyxy=(5000, 5000, 6000, 6000))
    assert check_detection(outside) is None  # without the image's size, nothing to say
    assert (
        check_detection(outside, (640, 480)) == "box_xyxy (5000, 5000, 6000, 6000) lies outside the 640x480 image"
    )
    assert (
        check_detection(det(box_xyxy=(-10, -10, 5, 5)), (640, 480)) is None
    )  # partly inside: a box cut by the border


def _install_dist(site: Path, entries: dict[str, str]) -> None:
    """A minimal installed distribution (dist-info with entry points) in ``site``."""
    info = site / "teamdet-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: teamdet\nVersion: 1.0\n")
    lines = "".join(f"{name} = {value}\n" for name, value in entries.items())
    (info / "entry_points.txt").write_text(f"[poibench.detectors]\n{lines}")


def test_an_entry_point_names_a_detector_after_the_builtin_ones(tmp_path, monkeypatch):
    from red_detector import write_weights

    _install_dist(
        tmp_path,
        {"redblob": "red_detector:RedBlobDetector", "thermal": "red_detector:WrongOutput", "bare": "red_detector"},
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    assert {"redblob", "thermal"} <= set(entry_point_names())
    assert is_team_detector("redblob")
    assert not is_team_detector("thermal")  # the built-in registry's name comes first
    assert not is_team_detector("someone-elses")
    det = build_python_detector("redblob", {"weights": write_weights(tmp_path / "w.npz")})
    assert det.name == "redblob"
    assert [d.box_xyxy for d in det.detect(red_square_frame())] == [(40.0, 10.0, 60.0, 40.0)]
    with pytest.raises(DetectorConfigError, match=r"detector 'nothing': not a poibench.detectors entry point"):
        build_python_detector("nothing", {})
    with pytest.raises(
        DetectorConfigError, match=r"entry point 'red_detector' names no class \(expected MODULE:CLASS\)"
    ):
        build_python_detector("bare", {})


def test_the_readme_python_detector_runs_as_written(tmp_path, monkeypatch):
    """README "Bring your own detector": its mydet.py with the options its command gives, on an
    NMS export's rows (x1 y1 x2 y2 score class): every class it names is one poibench knows."""
    import re

    monkeypatch.syspath_prepend(str(Path(__file__).parent))
    from onnx_models import make_constant_model  # noqa: PLC0415  (the tests' model builder, beside this file)

    readme = (Path(__file__).resolve().parents[3] / "README.md").read_text()
    code = re.search(r"```python\n(# mydet\.py\n.*?)```", readme, re.S).group(1)
    names = re.search(r"detector\.options\.names=\[([^\]]*)\]", readme).group(1)
    names = [n.strip() for n in names.split(",")]
    (tmp_path / "mydet.py").write_text(code)
    monkeypatch.syspath_prepend(str(tmp_path))
    rows = [[10, 20, 60, 90, 0.9, c] for c in range(len(names))] + [[0, 0, 5, 5, 0.1, 0]]
    model = make_constant_model(tmp_path / "m.onnx", np.array([rows], np.float32), input_hw=(480, 640))
    from mydet import MyDetector  # noqa: PLC0415  (written above)

    rgb = np.zeros((480, 640, 3), np.uint8)
    K = Intrinsics(width=640, height=480, fx=612.4, fy=610.6, ppx=314.3, ppy=237.8)
    found = MyDetector(weights=str(model), names=names, conf=0.3).detect(
        Frame(index=0, timestamp_s=0.0, rgb=rgb, intrinsics=K)
    )
    assert [d.class_name for d in found] == names  # the 0.1 row is below conf
    assert all(d.box_xyxy == (10.0, 20.0, 60.0, 90.0) for d in found)
