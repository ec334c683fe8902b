"""poibench dataset: YOLO files, labels that match the truth, split by scenario, determinism, resume."""

import hashlib
from pathlib import Path

import numpy as np
import pytest
import yaml

from eval.cli.main import main
from eval.detector.dataset import (
    DatasetError,
    DatasetSpec,
    _build,
    _check_out_dir,
    _crosses,
    sample_view,
    scenario_for,
    write_dataset,
    yolo_labels,
)
from eval.detector.train import TrainError, TrainSpec, data_yaml
from poi.core.names import HAZMAT_LABELS, RESCUE_CLASSES
from sim.simulator import FrameTruth, VisibleObject, VisiblePage


def _tree_hash(root: Path) -> str:
    h = hashlib.sha256()
    for p in sorted(root.rglob("*")):
        if p.is_file() and p.suffix in (".jpg", ".txt", ".csv"):
            h.update(str(p.relative_to(root)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds") / "tiny"
    spec = DatasetSpec(images=6, images_per_scenario=3, seed=11)
    summary = write_dataset(spec, out)
    return spec, out, summary


@pytest.mark.slow
def test_files_and_data_yaml(tiny):
    spec, out, summary = tiny
    data = yaml.safe_load((out / "data.yaml").read_text())
    assert data["names"] == dict(enumerate(RESCUE_CLASSES)) and data["nc"] == 24
    assert (out / data["train"]).is_dir() and (out / data["val"]).is_dir()
    imgs = sorted((out / "images").rglob("*.jpg"))
    assert len(imgs) == 6 and summary["images"] == {"train": 3, "val": 3}
    for img in imgs:
        lab = out / "labels" / img.parent.name / (img.stem + ".txt")
        assert lab.exists()
        for line in lab.read_text().splitlines():
            c, *xywh = line.split()
            assert 0 <= int(c) < len(RESCUE_CLASSES)
            x, y, w, h = map(float, xywh)
            assert 0 < w <= 1 and 0 < h <= 1 and x - w / 2 + 1e-6 >= 0 and x + w / 2 <= 1 + 1e-6
    assert (out / "classes.png").stat().st_size > 1000


@pytest.mark.slow
def test_split_is_by_scenario_and_targets_are_labelled(tiny):
    import pandas as pd

    _, out, _ = tiny
    m = pd.read_csv(out / "manifest.csv", keep_default_na=False)
    assert m.groupby("scenario")["split"].nunique().max() == 1  # a scenario never straddles
    assert set(m.split) == {"train", "val"}
    # the view aims at its target: it is labelled in most images
    hits = [t in labels.split() for t, labels in zip(m.target_class, m.labels, strict=True)]
    assert np.mean(hits) >= 0.5
    assert ((m.distance_m >= 0.3) & (m.distance_m <= 5.2)).all()


@pytest.mark.slow
def test_same_seed_same_bytes_and_resume_skips_finished_scenarios(tiny, tmp_path):
    spec, out, _ = tiny
    again = tmp_path / "again"
    write_dataset(spec, again)
    assert _tree_hash(again) == _tree_hash(out)
    # an interrupted run: scenario 1 unfinished (marker missing, an image deleted)
    (again / ".done" / "scenario_0001.csv").unlink()
    next((again / "images" / "val").glob("*.jpg")).unlink()
    before = (again / "images" / "train" / "s0000_000.jpg").stat().st_mtime_ns
    write_dataset(spec, again)
    assert _tree_hash(again) == _tree_hash(out)
    assert (again / "images" / "train" / "s0000_000.jpg").stat().st_mtime_ns == before  # not redone


def test_renders_of_the_trial_camera_made_with_other_colour_settings_are_refused(tmp_path):
    """A dataset drawn with the trial's colour camera (``camera: None``, as sim2real's renders are)
    records that camera's settings, so renders an earlier white balance made are not reused."""
    spec = DatasetSpec.trial_looks(images=2, images_per_scenario=2, seed=3, val_every=1, camera=None)
    same = spec.to_dict()
    assert same["trial_colour"]["wb_gains"] == [1.0, 1.0, 1.15]
    earlier = {**same, "trial_colour": {**same["trial_colour"], "wb_gains": [1.04, 1.0, 0.95]}}
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({"poibench_dataset": 1, "spec": earlier}))
    with pytest.raises(DatasetError, match="other settings"):
        _check_out_dir(tmp_path, spec)
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({"poibench_dataset": 1, "spec": same}))
    _check_out_dir(tmp_path, spec)  # the same settings: reused
    assert "trial_colour" not in DatasetSpec(images=2, images_per_scenario=2, seed=3).to_dict()  # drawn per image


@pytest.mark.slow
def test_a_folder_with_other_settings_or_other_files_is_refused(tiny, tmp_path):
    spec, out, _ = tiny
    with pytest.raises(DatasetError, match="other settings"):
        write_dataset(DatasetSpec(images=6, images_per_scenario=3, seed=12), out)
    (tmp_path / "junk.txt").write_text("x")
    with pytest.raises(DatasetError, match="not a poibench dataset"):
        write_dataset(spec, tmp_path)


def test_scenarios_split_between_train_and_val():
    # every 5th scenario to val (j = 4, 9); a training set of one scenario keeps it for training
    assert [DatasetSpec(images=400, val_every=5).is_val(j) for j in range(10)] == [False] * 4 + [True] + [
        False
    ] * 4 + [True]
    assert not DatasetSpec(images=40, val_every=5).is_val(0)
    # three scenarios, none a 5th: the last goes to val
    assert [DatasetSpec(images=120, val_every=5).is_val(j) for j in range(3)] == [False, False, True]
    # val_every 1 (the evaluation's scenes): all of them, even one scenario of fewer images
    assert DatasetSpec(images=2, val_every=1).is_val(0)
    assert all(DatasetSpec(images=400, val_every=1).is_val(j) for j in range(10))


def test_hazmat_labels_rotate_so_every_label_is_used():
    spec = DatasetSpec(images=80, images_per_scenario=40)
    used = set()
    for j in range(2):
        used |= set(scenario_for(spec, j).objects.generate.labels)
    assert used == set(HAZMAT_LABELS)


def test_hazmat_labels_restrict_the_rotation_and_old_specs_keep_their_dict():
    """sim2real renders only its photos' labels: each scenario hangs every one of them once."""
    labels = ("explosive", "poison", "corrosive")
    spec = DatasetSpec(images=3, images_per_scenario=1, counts={"hazmat": 3}, hazmat_labels=labels)
    for j in range(3):
        assert scenario_for(spec, j).objects.generate.labels == sorted(labels)
    assert spec.to_dict()["hazmat_labels"] == list(labels)
    # a spec without the field writes the dataset.yaml it wrote before (a rerun resumes)
    assert "hazmat_labels" not in DatasetSpec(images=1).to_dict()
    with pytest.raises(DatasetError, match="^hazmat_labels must be some of explosive, "):
        DatasetSpec(images=1, hazmat_labels=("poison", "toxic"))


def test_labels_follow_visibility_and_size_rules():
    from maze_assets.objects import PlacedObject

    objs = {
        0: PlacedObject(id=0, type="hazmat", text="oxidizer"),
        1: PlacedObject(id=1, type="door", mount="opening"),
    }

    def vis(i, box, frac):
        return VisibleObject(
            id=i,
            type=objs[i].type,
            text=objs[i].text,
            box_xyxy=box,
            pixels=1,
            visible_fraction=frac,
            position_cam=np.zeros(3),
        )

    truth = FrameTruth(
        index=0,
        timestamp_s=0.0,
        T_map_camera=np.eye(4),
        T_map_tracker=np.eye(4),
        visible=[vis(0, (100, 40, 164, 104), 0.9), vis(1, (0, 0, 3, 200), 1.0), vis(1, (0, 0, 50, 50), 0.1)],
    )
    labels = yolo_labels(truth, objs, DatasetSpec(images=1), 640, 480)
    # only the placard: the door box is 3 px wide (< 4), then only 10% visible (< 30%)
    assert labels == [(RESCUE_CLASSES.index("oxidizer"), 132 / 640, 72 / 480, 64 / 640, 64 / 480)]
    # the 10%-visible door is big enough to be an ignored object; the 3 px one is not
    ignored = yolo_labels(truth, objs, DatasetSpec(images=1), 640, 480, ignored=True)
    assert ignored == [(RESCUE_CLASSES.index("door"), 25 / 640, 25 / 480, 50 / 640, 50 / 480)]
    # a QR chart's page in view is ignored as one qr box, when big enough; never labelled
    truth.pages = [
        VisiblePage(codes=(2, 3), box_xyxy=(200, 100, 240, 160), pixels=2000),
        VisiblePage(codes=(4,), box_xyxy=(300, 100, 303, 160), pixels=150),
    ]
    assert yolo_labels(truth, objs, DatasetSpec(images=1), 640, 480) == labels
    assert yolo_labels(truth, objs, DatasetSpec(images=1), 640, 480, ignored=True) == [
        (RESCUE_CLASSES.index("qr"), 220 / 640, 130 / 480, 40 / 640, 60 / 480),
        *ignored,
    ]


def test_sight_line_crossing():
    a, b = np.array([0.0, -1.0]), np.array([0.0, 1.0])
    assert _crosses(np.array([-1.0, 0.0]), np.array([1.0, 0.0]), a, b)
    assert not _crosses(np.array([0.5, 0.0]), np.array([1.0, 0.0]), a, b)


def test_dataset_cli_errors_are_one_line(tmp_path, capsys):
    assert main(["dataset", "--out", str(tmp_path / "d"), "--images", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--images must be at least 1" in err[0]
    # each count is checked as the flag it is, not as the field it fills
    for flag, value, said in (("--per-scenario", "0", "at least 1"), ("--hazmat", "-1", "at least 0")):
        with pytest.raises(SystemExit):
            main(["dataset", "--out", str(tmp_path / "d"), "--images", "4", flag, value])
        assert f"argument {flag}: expected a whole number of {said}, got {value}" in capsys.readouterr().err


@pytest.mark.parametrize(
    "flags, said",
    [
        (["--keep-easy", "3"], "--keep-easy goes with --mine MODEL"),
        (["--set", "seed=5"], "--set seed=5: each maze takes its own seed, drawn from --seed; give --seed"),
        (["--set", "rules=ex3"], "--set rules=ex3: route-frames scores nothing"),
        (["--mine", "missing.onnx", "--mine-labels", "x.onnx"], "--mine missing.onnx: no such file"),
        (["--mine", "oracle"], "--mine oracle: expected 'default' or a detector ONNX file"),
        (["--mine", "default", "--mine-labels", "x.onnx"], "--mine-labels goes only with --mine FILE.onnx"),
    ],
)
def test_route_frames_refuses_settings_that_cannot_take_effect(tmp_path, capsys, flags, said):
    assert main(["route-frames", "--out", str(tmp_path / "rf"), "--mazes", "1", *flags]) == 2
    err = capsys.readouterr().err
    assert f"poibench route-frames: error: {said}" in err and err.count("\n") == 1
    assert not (tmp_path / "rf").exists()


@pytest.mark.slow
def test_train_checks_its_inputs_before_needing_ultralytics(tiny, tmp_path):
    _, out, _ = tiny
    assert data_yaml(out) == out / "data.yaml"
    with pytest.raises(TrainError, match="no such file"):
        data_yaml(tmp_path)
    bad = tmp_path / "data.yaml"
    bad.write_text("names: {0: cat}\n")
    with pytest.raises(TrainError, match="24 classes in order"):
        data_yaml(bad)
    with pytest.raises(TrainError, match="multiple of 32"):
        TrainSpec(data=str(out), out=str(tmp_path / "run"), imgsz=300)
    with pytest.raises(TrainError, match="--threads must be at least 1"):
        TrainSpec(data=str(out), out=str(tmp_path / "run"), threads=0)


# The class names of every dataset written before the arena types were added, spelled out:
# such datasets (and the models trained on them) must keep working unchanged.
DATASET_NAMES_V1 = [
    *("explosive", "blasting-agent", "flammable-gas", "non-flammable-gas", "oxygen", "fuel-oil"),
    *("dangerous-when-wet", "flammable-solid", "spontaneously-combustible", "oxidizer", "organic-peroxide"),
    *("inhalation-hazard", "poison", "radioactive", "corrosive", "infectious-substance", "qr", "door"),
    *("valve", "baby-doll", "fire-extinguisher", "exit-sign", "fire-extinguisher-sign", "heat-source"),
]


def test_existing_24_class_datasets_still_pass_the_train_check(tmp_path):
    old = tmp_path / "data.yaml"
    old.write_text(yaml.safe_dump({"nc": 24, "names": dict(enumerate(DATASET_NAMES_V1))}))
    assert data_yaml(old) == old
    assert list(RESCUE_CLASSES) == DATASET_NAMES_V1
    # the arena's classes are not part of a rescue dataset
    grown = tmp_path / "grown.yaml"
    grown.write_text(yaml.safe_dump({"names": [*DATASET_NAMES_V1, "pillar-blue"]}))
    with pytest.raises(TrainError, match="24 classes in order"):
        data_yaml(grown)


@pytest.mark.slow
def test_trial_camera_dataset_is_still_and_unblurred(tmp_path):
    out = tmp_path / "trial"
    assert (
        main(
            ["dataset", "--out", str(out), "--images", "2", "--per-scenario", "2", "--camera", "trial", "--quiet"]
        )
        == 0
    )
    spec = yaml.safe_load((out / "dataset.yaml").read_text())["spec"]
    assert spec["camera"] is None and spec["blur_fraction"] == 0.0 and spec["hazmat_on_floor"] == 0.25
    rows = (out / "manifest.csv").read_text().splitlines()
    col = rows[0].split(",").index("blur")
    assert len(rows) == 3 and all(r.split(",")[col] == "" for r in rows[1:])
    with pytest.raises(DatasetError, match=r"--hazmat-on-floor must be in \[0, 1\], got 2"):
        DatasetSpec(images=1, hazmat_on_floor=2)


@pytest.mark.slow
def test_log_distance_and_free_roll_views():
    """--distance log puts more views close (log-uniform over 0.3-5 m: P(d < 1 m) = ln(1/0.3)/ln(5/0.3)
    = 0.43 where room allows, against 0.15 uniform); --free-roll 1 rolls anywhere, 0 keeps +-5 deg."""
    base = DatasetSpec(images=1, seed=3)
    _, sim = _build(base, 1)  # an RRL maze (1.2 m cells): room for far views
    # placards hanging on walls by themselves (not in a crate, on a ramp or on a board)
    targets = [o for o in sim.objects if o.type == "hazmat" and o.mount == "wall" and o.holder is None]

    def views(spec, n=100):
        rng = np.random.default_rng(5)
        out = [sample_view(sim, targets[k % len(targets)], spec, rng) for k in range(n)]
        return [info for v in out if v is not None for info in [v[1]]]

    uni = views(base)
    log = views(DatasetSpec(images=1, seed=3, distance_draw="log", free_roll=1.0))
    near = lambda vs: np.mean([v["distance_m"] < 1.0 for v in vs])  # noqa: E731
    assert near(log) > near(uni) + 0.15
    assert max(abs(v["roll_deg"]) for v in uni) <= 5.0
    rolls = np.array([v["roll_deg"] for v in log])
    assert np.mean(np.abs(rolls) > 90) > 0.3 and rolls.min() < -90 < 90 < rolls.max()
    with pytest.raises(DatasetError, match=r"--distance must be one of uniform, log, got 'near'"):
        DatasetSpec(images=1, distance_draw="near")
    with pytest.raises(DatasetError, match=r"--hazmat-on-doors must be a whole number >= 0, got -1"):
        DatasetSpec(images=1, hazmat_on_doors=-1)
    sc = scenario_for(DatasetSpec(images=1, seed=3, hazmat_on_doors=5), 1)
    assert sc.objects.generate.hazmat_on_doors == 2  # one door: two faces
    with pytest.raises(DatasetError, match=r"--free-roll must be in \[0, 1\], got -0.5"):
        DatasetSpec(images=1, free_roll=-0.5)


@pytest.mark.slow
def test_crates_and_boards_reach_the_scenarios_and_views_stay_out_of_crates():
    # views as near as 5 cm: without the crates counted as obstacles, some would stand inside one
    spec = DatasetSpec(
        images=1, seed=3, hazmat_in_crates=2, hazmat_on_ramps=1, hazmat_on_boards=1, distance_m=(0.05, 1.0)
    )
    sc = scenario_for(spec, 0)
    g = sc.objects.generate
    assert (g.hazmat_in_crates, g.hazmat_on_ramps, g.hazmat_on_boards) == (2, 1, 1)
    for flag, kw in (
        ("crates", {"hazmat_in_crates": -1}),
        ("ramps", {"hazmat_on_ramps": -2}),
        ("boards", {"hazmat_on_boards": 1.5}),
    ):
        with pytest.raises(DatasetError, match=rf"--hazmat-(in|on)-{flag} must be a whole number >= 0"):
            DatasetSpec(images=1, **kw)
    from sim.simulator import Simulation

    with Simulation(sc) as sim:
        crated = [o for o in sim.objects if o.holder == "crate"]
        assert len(crated) == 2
        rng = np.random.default_rng(0)
        for o in crated:
            for _ in range(20):
                view = sample_view(sim, o, spec, rng)
                assert view is not None
                cam = (sim.T_world_map @ view[0])[:2, 3] - o.position[:2]
                n = np.array([np.cos(o.yaw), np.sin(o.yaw)])
                left, right, _, _ = o.holder_m
                inside = cam @ n < o.size_m + 0.02 and abs(cam @ np.array([-n[1], n[0]])) < right + 0.02
                assert not inside  # the crate is as deep as the placard's side


def test_the_randomised_camera_blurs_a_share_of_the_images_and_defocuses_at_most_1_px():
    import numpy as np

    from eval.detector.dataset import CameraRandomisation
    from sim.sensors.d435_color import ColourSpec

    rng = np.random.default_rng(0)
    cam = CameraRandomisation()
    draws = [cam.draw(ColourSpec(), rng) for _ in range(2000)]
    smeared = np.mean([np.hypot(*blur) > 0 for _, blur in draws])
    assert abs(smeared - cam.motion_blur_share) < 0.04
    assert max(np.hypot(*blur) for _, blur in draws) <= 20.0
    assert max(spec.defocus_sigma_px for spec, _ in draws) <= 1.0


def test_evaluation_scenes_look_as_a_trial_does():
    """evaluate-detector and calibrate score on scenes without the training looks."""
    from eval.detector.dataset import DatasetSpec, looks_for

    spec = DatasetSpec.trial_looks(images=40, seed=3)
    assert spec.images == 40 and spec.seed == 3
    for j in range(8):
        looks = looks_for(spec, j)
        assert looks.floor is None and looks.offsamples == 0 and looks.milk_crates == 0
        assert looks.print_saturation is None and looks.print_black is None and looks.glossy_share == 0.0
    assert spec.closeup_fraction == 0.0 and spec.landolt_targets == 0
    assert DatasetSpec(images=1).msaa == 4  # the training defaults keep them
