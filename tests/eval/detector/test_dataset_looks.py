"""poibench dataset's training looks (issue 58): textured floors, print colour, glossy paper, MSAA
and close-ups; none of them reaches a trial's world."""

import csv
import dataclasses
import re

import cv2
import numpy as np
import pytest

from eval.detector.dataset import (
    DatasetError,
    DatasetSpec,
    _build,
    closeup_view,
    looks_for,
    sample_view,
    scenario_for,
)
from maze_assets.hazmat import draw_hazmat, placard_style, reprint
from maze_assets.surfaces import DATASET_FLOOR_KINDS, draw_dataset_floor
from sim.simulator import Simulation
from sim.world.world import SceneLooks, build_world_xml


def _stats(rgb: np.ndarray) -> np.ndarray:
    """(mean grey, grey sd, log10 Laplacian variance, mean saturation) of a texture."""
    g = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    s = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)[..., 1]
    return np.array([g.mean(), g.std(), np.log10(cv2.Laplacian(g, cv2.CV_64F).var() + 1), s.mean()])


def test_floor_kinds_differ_and_are_deterministic():
    # averaged over 4 draws of each kind at 256 px; two kinds differ by more than 3 grey levels in
    # mean or sd, 0.3 decades of Laplacian variance (fine texture) or 10 levels of saturation
    stats = {}
    for kind in DATASET_FLOOR_KINDS:
        draws = [draw_dataset_floor(kind, 256, np.random.default_rng(k)) for k in range(4)]
        stats[kind] = np.mean([_stats(d) for d in draws], axis=0)
        assert np.array_equal(draws[0], draw_dataset_floor(kind, 256, np.random.default_rng(0)))
    tol = np.array([3.0, 3.0, 0.3, 10.0])
    kinds = list(stats)
    for i, a in enumerate(kinds):
        for b in kinds[i + 1 :]:
            assert np.any(np.abs(stats[a] - stats[b]) > tol), (a, b, stats[a], stats[b])


def _world(looks):
    sc = scenario_for(DatasetSpec(images=1, seed=3), 1)  # an RRL maze
    with Simulation(sc) as sim:  # the maze and objects the dataset's scenario 0 has
        maze, objects, intr = sim.maze, sim.objects, sim.intrinsics
    return build_world_xml(maze, objects, intr, sc.lighting, np.random.default_rng(sc.seed), looks=looks)


@pytest.mark.slow
def test_looks_change_the_floor_and_placards_only_and_trials_have_none():
    xml0, files0 = _world(None)
    assert 'offsamples="0"' in xml0
    xml1, files1 = _world(SceneLooks(seed=5, floor="terrazzo", print_saturation=(0.5, 0.5), glossy_share=1.0))
    changed = {k for k in files0 if files0[k] != files1.get(k)}
    assert "tex_floor.png" in changed
    assert changed - {"tex_floor.png"} and all(k.startswith("objtex_hazmat_") for k in changed - {"tex_floor.png"})
    # every placard's paper glossy at share 1; the walls' and other objects' draws unchanged
    spec = [float(m) for m in re.findall(r'<material name="objmat_hazmat_[^"]*"[^>]*specular="([\d.]+)"', xml1)]
    assert spec and min(spec) >= 0.7
    assert all(files0[k] == files1[k] for k in files0 if k.startswith("tex_wall"))
    # no floor kind and nothing else asked: the world is the trial's
    assert _world(SceneLooks(seed=5)) == (xml0, files0)


def test_reprint_sets_saturation_and_black():
    """Real placard crops: median saturation 60 against 88 rendered, 5th-percentile grey 73 against 83."""
    for label in ("flammable-gas", "corrosive"):  # red with white ink; black ink on white
        style = placard_style(label, 3)
        rgb = draw_hazmat(label, 256, style)
        hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
        coloured = hsv[..., 1] > 60
        inked = np.abs(rgb.mean(axis=2) - style.look.ink_black) < 3  # the black ink's pixels
        for sat, black in ((0.5, 20.0), (0.68, 80.0), (1.0, 0.0)):
            out = reprint(rgb, sat, black, style.look.ink_black)
            if coloured.mean() > 0.05:
                s0 = np.median(hsv[..., 1][coloured])
                s1 = np.median(cv2.cvtColor(out, cv2.COLOR_RGB2HSV)[..., 1][coloured])
                assert abs(s1 / s0 - sat) < 0.03, (label, sat, s1 / s0)  # rounding of 8-bit HSV
            if inked.mean() > 0.05:
                assert abs(np.median(out.mean(axis=2)[inked]) - black) < 3.0, (label, black)


def test_settings_are_checked_with_one_line_errors():
    for kw, flag in (
        ({"floor_textures": 1.5}, "--floor-textures"),
        ({"glossy_fraction": -0.1}, "--glossy-fraction"),
        ({"closeup_fraction": 2.0}, "--closeup-fraction"),
        ({"print_saturation": (0.9, 0.4)}, "--print-saturation"),
        ({"print_black": (-1.0, 10.0)}, "--print-black"),
        ({"msaa": 3}, "--msaa"),
    ):
        with pytest.raises(DatasetError, match=f"^{flag} ") as e:
            DatasetSpec(images=1, **kw)
        assert "\n" not in str(e.value)
    # the floor share: each scenario draws a textured floor with probability floor_textures
    spec = DatasetSpec(images=1, seed=1)
    floors = [looks_for(spec, j).floor for j in range(200)]
    assert 0.4 < np.mean([f is not None for f in floors]) < 0.6  # 0.5 +- 2.8 sd of 200 draws
    assert {f for f in floors if f} == set(DATASET_FLOOR_KINDS)
    assert looks_for(dataclasses.replace(spec, floor_textures=0.0), 0).floor is None


@pytest.fixture(scope="module")
def scene():
    spec = DatasetSpec(images=1, seed=3)
    _, sim = _build(spec, 1)
    yield spec, sim
    sim.close()


@pytest.mark.slow
def test_closeups_fill_about_a_third_of_the_image(scene):
    spec, sim = scene
    H = sim.intrinsics.height
    rng = np.random.default_rng(2)
    fills = []
    for o in [o for o in sim.objects if o.type == "hazmat"]:
        view = closeup_view(sim, o, rng)
        if view is None:
            continue
        _, truth = sim.view(view[0], 0)
        box = [v.box_xyxy for v in truth.visible if v.id == o.id]
        if box:
            fills.append((box[0][3] - box[0][1]) / H)
    # CLOSEUP_FILL is 0.28-0.4 of the height for the placard's side; a diamond turned in its plane
    # or seen off its normal spans 0.7-1.4 times that
    assert len(fills) >= 4
    assert 0.25 < np.median(fills) < 0.45 and min(fills) > 0.15 and max(fills) < 0.6, fills


@pytest.mark.slow
def test_msaa_smooths_placard_edges_and_keeps_the_truth():
    """MSAA (offsamples 4) against none, on the same views: the truth boxes are the same, and the
    placard crops' Laplacian variance falls (aliased steps along the cut diamond's edges go)."""
    spec = DatasetSpec(images=1, seed=3)
    sc = scenario_for(spec, 1)
    out = {}
    for msaa in (0, 4):
        looks = dataclasses.replace(looks_for(spec, 1), offsamples=msaa)
        with Simulation(sc, looks=looks) as sim:
            hz = [o for o in sim.objects if o.type == "hazmat"]
            rng = np.random.default_rng(4)
            near = dataclasses.replace(spec, distance_m=(0.5, 1.5))
            res = []
            for k in range(8):
                o = hz[k % len(hz)]
                view = sample_view(sim, o, near, rng)
                frame, truth = sim.view(view[0], k)
                boxes = {v.id: tuple(round(x) for x in v.box_xyxy) for v in truth.visible}
                lap = None
                if o.id in boxes:
                    x1, y1, x2, y2 = boxes[o.id]
                    crop = cv2.cvtColor(frame.rgb[y1:y2, x1:x2], cv2.COLOR_RGB2GRAY)
                    lap = cv2.Laplacian(crop, cv2.CV_64F).var() if crop.size > 400 else None
                res.append((boxes, lap))
            out[msaa] = res
    laps = [(a[1], b[1]) for a, b in zip(out[0], out[4], strict=True) if a[1] and b[1]]
    assert len(laps) >= 4
    assert np.median([b / a for a, b in laps]) < 1.0
    for a, b in zip(out[0], out[4], strict=True):
        assert a[0].keys() == b[0].keys()
        for i in a[0]:  # an edge pixel may fall either way
            assert max(abs(p - q) for p, q in zip(a[0][i], b[0][i], strict=True)) <= 2


@pytest.mark.slow
def test_landolt_targets_appear_unlabelled_standalone_and_on_boards(tmp_path, monkeypatch):
    """Landolt-C targets have no detector class: they stand in the scenes (one by itself on a wall,
    one on the placard board) and are neither labelled nor ignored, so detections of them count
    as false."""
    spec = DatasetSpec(images=1, seed=3)
    _, sim = _build(spec, 1)  # an RRL maze (an RMRC one has none: its walls are too low for them)
    with sim:
        rings = [o for o in sim.objects if o.type == "landolt-c"]
        assert len(rings) == spec.landolt_targets == 2
        assert {o.holder for o in rings} == {None, "board"}
    with pytest.raises(DatasetError, match=r"^--landolt-targets must be a whole number >= 0, got -1$"):
        DatasetSpec(images=1, landolt_targets=-1)
    out = tmp_path / "ds"
    import eval.detector.dataset as ds

    monkeypatch.setattr(ds, "UNLABELLED_VIEW_SHARE", 0.5)  # 5% of views: too few in 12 images to test
    ds.write_dataset(DatasetSpec(images=12, images_per_scenario=12, seed=1), out)  # an RRL maze
    rows = list(csv.DictReader((out / "manifest.csv").read_text(encoding="utf-8").splitlines()))
    aimed = [r for r in rows if r["target_class"] == "landolt-c"]
    assert aimed and all("landolt" not in r["labels"] for r in rows)


@pytest.mark.slow
def test_milk_crates_stand_near_placards_unlabelled():
    spec = DatasetSpec(images=1, seed=3)
    sc = scenario_for(spec, 1)  # an RRL maze: 1.2 m cells (RMRC lanes get no crates)
    with Simulation(sc, looks=looks_for(spec, 1)) as sim:
        m = sim.world.model
        crates = {}
        for g in range(m.ngeom):
            name = m.geom(g).name
            if name.startswith("milkcrate_"):
                crates.setdefault(name.split("_")[1], []).append(g)
                assert sim.world.geom_object_id[g] == -1  # no object: never labelled
        assert len(crates) == spec.milk_crates
        placards = np.array([o.position[:2] for o in sim.objects if o.type == "hazmat"])
        for geoms in crates.values():
            xy = m.geom_pos[geoms[0]][:2]  # the crate's floor plate, at its centre
            # MILK_CRATE_NEAR_M: 0.25-0.7 m from a placard's reference point
            assert np.min(np.linalg.norm(placards - xy, axis=1)) < 0.75
