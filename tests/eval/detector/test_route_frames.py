"""poibench route-frames: the robot's own tour frames, labelled with the simulator's truth boxes."""

import csv

import pytest
import yaml

from eval.detector.dataset import DatasetError
from eval.detector.route_frames import RouteFramesSpec, write_route_frames
from poi.core.names import RESCUE_CLASSES

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
    with pytest.raises(DatasetError, match="--every must be at least 1, got 0"):
        RouteFramesSpec(mazes=1, every=0)
