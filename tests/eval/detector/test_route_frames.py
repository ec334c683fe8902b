"""poibench route-frames: the robot's own tour frames, labelled with the simulator's truth boxes."""

import csv
import shutil

import pytest
import yaml

from eval.detector.dataset import DatasetError
from eval.detector.route_frames import RouteFramesSpec, write_route_frames
from poi.core.names import HAZMAT_LABELS, RESCUE_CLASSES

pytestmark = pytest.mark.slow  # each test tours a simulated maze


@pytest.fixture(scope="module")
def tour(tmp_path_factory):
    out = tmp_path_factory.mktemp("route")
    spec = RouteFramesSpec(mazes=1, every=150)
    return spec, out, write_route_frames(spec, out)


def test_every_nth_frame_of_the_tour_with_its_truth_boxes(tour):
    spec, out, summary = tour
    with open(out / "manifest.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    frames = [int(r["frame"]) for r in rows]
    assert frames == list(range(0, frames[-1] + 1, spec.every)) and len(frames) == summary["frames"]
    assert summary["frames_with_labels"] >= 1
    for r in rows:
        lines = (out / "labels" / "train" / f"r0000_{int(r['frame']):05d}.txt").read_text().splitlines()
        classes = [RESCUE_CLASSES[int(line.split()[0])] for line in lines]
        assert classes == r["labels"].split()
        # every label is an object in view; a box lies inside the image
        assert set(classes) <= set(r["objects"].split())
        for line in lines:
            cx, cy, w, h = map(float, line.split()[1:])
            assert -1e-6 <= cx - w / 2 <= cx + w / 2 <= 1 + 1e-6 and -1e-6 <= cy - h / 2 <= cy + h / 2 <= 1 + 1e-6
            assert w > 0 and h > 0
    data = yaml.safe_load((out / "data.yaml").read_text())
    assert [data["names"][k] for k in sorted(data["names"])] == list(RESCUE_CLASSES)


def test_mazes_are_drawn_from_the_seed_apart_from_the_suites(tour):
    spec, _, _ = tour
    seeds = [RouteFramesSpec(mazes=4, seed=0).maze(j) for j in range(4)]
    assert seeds == [RouteFramesSpec(mazes=4, seed=0).maze(j) for j in range(4)]  # deterministic
    assert all(s >= 1_000_000 and 4 <= r <= 5 and 4 <= c <= 5 for s, r, c, _ in seeds)
    assert len({s for s, *_ in seeds}) == 4
    assert RouteFramesSpec(mazes=1, seed=1).maze(0) != seeds[0]


def test_a_folder_of_other_settings_is_refused_and_a_rerun_resumes(tour):
    spec, out, summary = tour
    before = {p.name: p.stat().st_mtime_ns for p in (out / "images" / "train").iterdir()}
    assert write_route_frames(spec, out) == summary  # finished: nothing rendered again
    assert {p.name: p.stat().st_mtime_ns for p in (out / "images" / "train").iterdir()} == before
    with pytest.raises(DatasetError, match="holds route frames of other settings"):
        write_route_frames(RouteFramesSpec(mazes=1, every=149), out)


def test_a_folder_grows_by_more_mazes_and_refuses_fewer(tour, tmp_path):
    spec, out, summary = tour
    grown = tmp_path / "grown"
    shutil.copytree(out, grown)
    more = write_route_frames(RouteFramesSpec(mazes=2, every=spec.every), grown)
    with open(grown / "manifest.csv", newline="") as f:
        mazes = [int(r["maze"]) for r in csv.DictReader(f)]
    assert mazes.count(0) == summary["frames"] and more["frames"] == len(mazes) > summary["frames"]
    with pytest.raises(DatasetError, match="holds the frames of 2 mazes; ask for as many or more"):
        write_route_frames(RouteFramesSpec(mazes=1, every=spec.every), grown)

    with pytest.raises(DatasetError, match="--every must be at least 1, got 0"):
        RouteFramesSpec(mazes=1, every=0)


def test_mining_keeps_the_frames_the_detector_errs_on_and_one_easy_frame_in_keep_easy(tour, tmp_path):
    spec, out, _ = tour
    mined = RouteFramesSpec(mazes=1, every=spec.every, mine=_shipped_pair(), keep_easy=2)
    summary = write_route_frames(mined, tmp_path)
    with open(out / "manifest.csv", newline="") as f:
        every_frame = [int(r["frame"]) for r in csv.DictReader(f)]
    with open(tmp_path / "manifest.csv", newline="") as f:
        kept = {int(r["frame"]): r for r in csv.DictReader(f)}
    assert set(kept) <= set(every_frame)
    easy = [k for k in every_frame if k not in kept or not kept[k]["mistakes"]]
    assert [k for k in easy if k in kept] == easy[::2]  # the 1st, 3rd, ... easy frame
    assert summary["frames_with_mistakes"] == len(every_frame) - len(easy) >= 1
    for k, r in kept.items():
        name = f"r0000_{k:05d}.txt"
        assert (tmp_path / "labels" / "train" / name).read_text() == (out / "labels" / "train" / name).read_text()
        types = {"hazmat" if c in HAZMAT_LABELS else c for c in r["labels"].split()}
        for m in filter(None, r["mistakes"].split("; ")):
            # a missed or misnamed object is one of the frame's labelled ones
            if m.startswith("missed "):
                assert m.removeprefix("missed ") in types
            elif " as " in m:
                assert m.split(" as ")[0] in types
            else:
                assert m.startswith("false ")


def test_a_mined_folder_keeps_its_models_hashes_and_refuses_other_weights_at_the_same_path(tmp_path):
    """A folder mined with a detector is not grown with other weights under the same file name
    (the shipped detector's path, after a new model ships): the hashes in dataset.yaml say so."""
    from eval.trial.perception_cache import file_sha256

    model, labels = tmp_path / "m.onnx", tmp_path / "labels.onnx"
    shipped, shipped_labels = _shipped_pair()
    shutil.copy(shipped, model)
    shutil.copy(shipped_labels, labels)
    spec = RouteFramesSpec(mazes=1, every=150, mine=(str(model), str(labels)))
    out = tmp_path / "mined"
    out.mkdir()
    (out / "dataset.yaml").write_text(yaml.safe_dump({"route_frames": spec.to_dict()}))
    kept = yaml.safe_load((out / "dataset.yaml").read_text())["route_frames"]
    assert kept["mine_sha256"] == [file_sha256(shipped), file_sha256(shipped_labels)]
    model.write_bytes(model.read_bytes() + b"\0")  # other weights, same path
    with pytest.raises(DatasetError, match=r"mined with other weights in .*m\.onnx .*choose a new --out"):
        write_route_frames(RouteFramesSpec(mazes=2, every=150, mine=(str(model), str(labels))), out)


def _shipped_pair():
    from poi.models import DEFAULT_LABEL_MODEL, DEFAULT_MODEL

    return str(DEFAULT_MODEL), str(DEFAULT_LABEL_MODEL)
