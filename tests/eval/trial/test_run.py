"""`poibench run` end to end: all files written, oracle score, a killed run leaves a valid POI file."""

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from eval.cli.main import main
from eval.live.video import H264Writer
from poi.core.poi_file import read_poi_file

SMALL = ["--set", "maze.file=rrl_small", "--set", "objects.generate.counts={hazmat: 2, qr: 2, valve: 1}"]


@pytest.mark.slow
def test_run_writes_every_file_and_reruns_from_its_config(tmp_path, capsys):
    out = tmp_path / "t"
    rc = main(["run", "--out", str(out), "--detector", "oracle", "--max-frames", "80", "--quiet", *SMALL])
    assert rc == 0
    for name in ("pois.csv", "truth.csv", "score.json", "cost.json", "map.png", "trial.mp4", "config.yaml"):
        assert (out / name).stat().st_size > 0, name
    doc = json.loads((out / "score.json").read_text())
    assert {"total", "max_total", "false_reports", "misses", "located", "reports", "objects"} <= set(doc)
    assert doc["max_total"] == 2 * (2 * 1 + 2 * 1 + 3)  # ex3: every object found and located
    printed = capsys.readouterr().out
    assert "points" in printed and "TOTAL" in printed
    # what the run prints it cost is what cost.json says: one reading, after the trial's last file
    cost = json.loads((out / "cost.json").read_text())
    assert f"{cost['cpu_s']:.1f} s of CPU ({cost['cpu_s_per_sim_s']:.2f} CPU s per simulated s)" in printed
    # the closing line lists what was written, the live record included
    wrote = "pois.csv truth.csv score.json funnel.csv cost.json map.png trial.mp4 config.yaml live/"
    assert f"wrote {out}/: {wrote}\n" in printed
    assert (out / "live" / "frames.jsonl").stat().st_size > 0
    # same config, same result, byte for byte
    again = tmp_path / "again"
    assert main(["run", "--config", str(out / "config.yaml"), "--out", str(again), "--quiet", "--no-video"]) == 0
    assert f"wrote {again}/: pois.csv truth.csv score.json funnel.csv cost.json map.png config.yaml live/\n" in (
        capsys.readouterr().out
    )
    for name in ("pois.csv", "truth.csv", "score.json"):
        assert (again / name).read_bytes() == (out / name).read_bytes(), name
    # what the trial cost is the one output that differs between reruns
    run1, run2 = (json.loads((d / "cost.json").read_text()) for d in (out, again))
    sim_s = json.loads((out / "score.json").read_text())["trial"]["sim_duration_s"]
    for run in (run1, run2):
        assert run["cpu_s"] > 0 and run["wall_s"] > 0
        assert run["cpu_s_per_sim_s"] == pytest.approx(run["cpu_s"] / sim_s, abs=1e-3)
        assert run["real_time_factor"] == pytest.approx(sim_s / run["wall_s"], rel=1e-2)
    assert run1["cpu_children_s"] > 0  # the ffmpeg of trial.mp4 and of the live record count
    assert 0 < run1["cpu_children_s"] < run1["cpu_s"]
    # options beside --config apply on top of it: the rerun's own config says so
    short = tmp_path / "short"
    argv = ["run", "--config", str(out / "config.yaml"), "--out", str(short), "--quiet", "--no-video"]
    assert main([*argv, "--max-frames", "3", "--set", "lighting=dim", "--detector", "default"]) == 0
    rerun = yaml.safe_load((short / "config.yaml").read_text())
    assert (rerun["max_frames"], rerun["scenario"]["lighting"], rerun["detector"]) == (3, "dim", "default")


@pytest.mark.parametrize(
    "flags, said",
    [
        (["--port", "8080"], "--port 8080: the live view's port; it needs --live"),
        (
            ["--poi-version", "1.3", "--set", "report.poi_version=1.2"],
            "--poi-version 1.3 and --set report.poi_version=1.2 set one thing; choose one",
        ),
        (
            ["--noise", "off", "--set", "sensors.noise=true"],
            "--noise off and --set sensors.noise=true set one thing",
        ),
    ],
)
def test_run_refuses_flags_that_cannot_take_effect_or_contradict_a_setting(tmp_path, capsys, flags, said):
    assert main(["run", *flags, "--out", str(tmp_path / "t"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"poibench run: error: {said}") and "\n" not in err
    assert not (tmp_path / "t" / "pois.csv").exists()


def test_render_refuses_a_pipeline_setting_and_no_frames(tmp_path, capsys):
    assert main(["render", "--set", "tracker.gate=4", "--out", str(tmp_path / "r")]) == 2
    assert "error: --set tracker.gate=4: a pipeline setting; render writes the simulator's frames" in (
        capsys.readouterr().err
    )
    with pytest.raises(SystemExit):
        main(["render", "--frames", "0", "--out", str(tmp_path / "r")])
    assert "argument --frames: expected a whole number of at least 1, got 0" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_an_earlier_trials_video_and_live_record_do_not_stay_beside_a_new_trial(tmp_path):
    import argparse

    from eval.cli.run import clear_stale_outputs

    for name in ("trial.mp4", "live/frames.jsonl", "trial_mcap/metadata.yaml"):
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text("earlier")
    args = argparse.Namespace(no_video=True, no_live_record=False, log=None)
    assert clear_stale_outputs(tmp_path, args) == [
        f"removed {tmp_path / 'trial.mp4'}, the earlier trial's (this run writes none)",
        f"{tmp_path / 'trial_mcap'} is the earlier trial's log (this run writes none); kept",
    ]
    assert (tmp_path / "live" / "frames.jsonl").exists() and (tmp_path / "trial_mcap").exists()
    args = argparse.Namespace(no_video=True, no_live_record=True, log="mcap")
    assert clear_stale_outputs(tmp_path, args) == [
        f"removed {tmp_path / 'live'}, the earlier trial's (this run writes none)"
    ]
    assert not (tmp_path / "live").exists()


def test_run_config_refuses_a_scenario_or_seed_beside_it(tmp_path, capsys):
    cfg = tmp_path / "config.yaml"
    cfg.write_text("poibench_trial: 1\ndetector: nosuch.onnx\nscenario: {poibench_scenario: 1}\n")
    assert main(["run", "--config", str(cfg), "--out", str(tmp_path / "t"), "--quiet"]) == 2
    assert f"error: {cfg}: detector: model file not found: nosuch.onnx" in capsys.readouterr().err
    cfg.write_text("detector: oracle\n")
    for extra in (["--seed", "9"], ["rmrc"]):
        assert main(["run", "--config", str(cfg), *extra, "--out", str(tmp_path / "t"), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert "cannot be combined with --config" in err and str(cfg) in err and "\n" not in err
    assert not (tmp_path / "t").exists()
    scenario = tmp_path / "mine.yaml"
    scenario.write_text("poibench_scenario: 1\nseed: 3\n")
    assert main(["run", "--config", str(scenario), "--out", str(tmp_path / "t"), "--quiet"]) == 2
    assert f"{scenario}: a scenario file, not a trial's config.yaml; run it with poibench run {scenario}" in (
        capsys.readouterr().err
    )


@pytest.mark.slow
def test_no_live_record_writes_no_live_folder_and_scores_the_same(tmp_path, capsys):
    base = ["run", "--detector", "oracle", "--max-frames", "80", "--quiet", "--no-video", *SMALL]
    with_live, without = tmp_path / "with", tmp_path / "without"
    assert main([*base, "--out", str(with_live)]) == 0
    assert main([*base, "--out", str(without), "--no-live-record"]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {without}/: pois.csv truth.csv score.json funnel.csv cost.json map.png config.yaml\n" in printed
    assert (with_live / "live" / "frames.jsonl").exists() and not (without / "live").exists()
    for name in ("pois.csv", "score.json"):
        assert (without / name).read_bytes() == (with_live / name).read_bytes(), name
    # run again into the first folder without the record: its earlier record goes, said in a note
    capsys.readouterr()
    assert main([*base, "--out", str(with_live), "--no-live-record"]) == 0
    assert f"note: removed {with_live / 'live'}, the earlier trial's" in capsys.readouterr().err
    assert not (with_live / "live").exists()


@pytest.mark.slow
def test_pose_error_is_reported_and_slam_keeps_a_clean_run_clean(tmp_path):
    """score.json's pose_error compares the pose each frame was mapped with to the truth: zero
    for a noise-free T265; the SLAM-corrected pose of a noise-free run stays within 2 cm."""
    errors = {}
    for mode in ("t265", "slam"):
        out = tmp_path / mode
        args = ["run", "--out", str(out), "--detector", "oracle", "--max-frames", "150", "--quiet", "--no-video"]
        assert main([*args, "--noise", "off", "--set", f"localize.mode={mode}", *SMALL]) == 0
        errors[mode] = json.loads((out / "score.json").read_text())["pose_error"]
    assert errors["t265"]["frames"] == 150 and errors["t265"]["max_m"] == 0.0
    assert errors["slam"]["max_m"] < 0.02 and errors["slam"]["heading_median_deg"] < 0.5


def test_bad_inputs_are_one_line_errors(tmp_path, capsys):
    assert main(["run", "--out", str(tmp_path), "--set", "tracker.gate=-1", "--max-frames", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("poibench run: error:") and "tracker.gate" in err and "\n" not in err
    bad = tmp_path / "bad.yaml"
    bad.write_text("seed: 1\nrobot:\n  speed_mps: fast\n")
    assert main(["run", str(bad), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert f"{bad}:3: robot.speed_mps" in err
    # a folder given as the detector is said to be one
    assert main(["run", "--detector", str(tmp_path), "--out", str(tmp_path / "t2")]) == 2
    assert f"error: model {tmp_path}: is a folder, not an ONNX file" in capsys.readouterr().err
    # an empty (or truncated to nothing) scenario file is not the built-in default maze
    bad.write_text("# nothing here\n")
    assert main(["run", str(bad), "--out", str(tmp_path)]) == 2
    assert f"error: {bad}: an empty scenario file" in capsys.readouterr().err


@pytest.mark.slow
def test_objects_that_do_not_fit_the_maze_name_the_scenario_file(tmp_path, capsys):
    bad = tmp_path / "crowded.yaml"
    bad.write_text("poibench_scenario: 1\nmaze: {file: rrl_small}\nobjects:\n  generate: {counts: {hazmat: 60}}\n")
    assert main(["run", str(bad), "--out", str(tmp_path / "t"), "--max-frames", "1", "--quiet"]) == 2
    assert f"error: {bad}: objects.generate: could not place a hazmat" in capsys.readouterr().err


@pytest.mark.slow
def test_detector_model_is_refused_with_one_line_naming_detector(tmp_path, capsys):
    # issue 60 edge 1: the trial ran the shipped detector while config.yaml recorded the team's model
    out = tmp_path / "t"
    assert main(["run", "--out", str(out), "--set", "detector.model=team.onnx", "--quiet", "--no-video"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("poibench run: error: detector.model=team.onnx: ") and "\n" not in err
    assert "--detector FILE.onnx" in err
    assert not out.exists()
    # make_detectors (the trial's and the ROS replay's) refuses it too, before any detector is built
    from eval.trial.detectors import make_detectors
    from poi.config import apply_overrides, load_config
    from poi.detectors import DetectorConfigError

    cfg = apply_overrides(load_config(), ["detector.model=team.onnx"])
    with pytest.raises(DetectorConfigError, match="--detector FILE.onnx"):
        make_detectors("default", cfg, None, [])


@pytest.mark.parametrize(
    "sets, named",
    [
        (["detector.type_conf.valve=0.6"], "detector.type_conf"),
        (["detector.conf=0.9", "detector.imgsz=320"], "detector.conf, detector.imgsz"),
        (["detector.label_model=poi/models/default_labels.onnx"], "detector.label_model"),
        (["detector.options.conf=0.3"], "detector.options.conf"),
    ],
)
def test_onnx_settings_for_the_oracle_are_refused_with_one_line(tmp_path, capsys, sets, named):
    out = tmp_path / "t"
    argv = ["run", "--detector", "oracle", *(a for s in sets for a in ("--set", s)), "--quiet", "--no-video"]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"poibench run: error: {named}: the oracle detector takes none of these")
    assert "\n" not in err
    assert not (out / "pois.csv").exists()


def _no_nan(name: str):
    raise ValueError(f"{name} is not JSON")


@pytest.mark.slow
def test_max_frames_below_one_is_refused_and_one_frame_writes_valid_json(tmp_path, capsys):
    # issue 60 edge 12: --max-frames 0 or 1 wrote NaN into cost.json, -1 was accepted
    for bad in ("0", "-1"):
        with pytest.raises(SystemExit) as info:
            main(["run", "--out", str(tmp_path / "n"), "--quiet", "--max-frames", bad])
        assert info.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err.endswith(f"run: error: argument --max-frames: expected a whole number of at least 1, got {bad}")
    assert not (tmp_path / "n").exists()
    out = tmp_path / "one"
    args = ["run", "--out", str(out), "--detector", "oracle", "--max-frames", "1", "--no-video", "--quiet", *SMALL]
    assert main(args) == 0
    cost = json.loads((out / "cost.json").read_text(), parse_constant=_no_nan)
    assert cost["cpu_s_per_sim_s"] is None and cost["cpu_s"] > 0  # 0 s simulated: no ratio
    json.loads((out / "score.json").read_text(), parse_constant=_no_nan)
    assert "; 1 frame, 0 s simulated" in capsys.readouterr().out


@pytest.mark.slow
def test_counts_take_their_number_and_the_live_header_the_trials_frames(tmp_path, capsys):
    # issue 60 edge 13: "1 false reports"; the live header said "/ 1191" frames under --max-frames 400
    from eval.text import counted

    assert counted(1, "false report") == "1 false report" and counted(2, "false report") == "2 false reports"
    assert counted(1, "miss", "misses") == "1 miss" and counted(0, "miss", "misses") == "0 misses"
    out = tmp_path / "t"
    args = ["run", "--out", str(out), "--detector", "oracle", "--max-frames", "3", "--no-video", "--quiet", *SMALL]
    assert main(args) == 0
    assert json.loads((out / "live" / "init.json").read_text())["n_frames"] == 3
    assert len((out / "live" / "frames.jsonl").read_text().splitlines()) == 3
    printed = capsys.readouterr().out
    assert "0 false reports, 5 misses; 3 frames, " in printed


@pytest.mark.slow
def test_oracle_trial_on_the_default_scenario_scores_every_point(tmp_path):
    """A perfect detector scores what a robot could see: the default tour shows every object
    (its QR codes whole), so the oracle, with its noise model, scores every point, and the
    funnel charges nothing."""
    out = tmp_path / "default"
    assert main(["run", "--out", str(out), "--detector", "oracle", "--quiet", "--no-video"]) == 0
    doc = json.loads((out / "score.json").read_text())
    assert doc["total"] == doc["max_total"] == 60 and doc["false_reports"] == 0
    assert doc["funnel"]["lost"] == 0 and doc["funnel"]["check"] == "ok"
    # every QR view whole in the image at >= 3 px a module is read, those in a slew's blur too (the
    # tour's scans slew at 120 deg/s: 13 px of blur in a 10 ms exposure)
    reads = doc["funnel"]["qr_reads"]
    assert reads["whole_views"] >= 30 and reads["whole_decoded"] == reads["whole_views"]
    # at least 95% of the objects within 0.3 m
    dist = [o["distance_m"] for o in doc["objects"]]
    assert sum(d <= 0.3 for d in dist) >= 0.95 * len(dist), dist


@pytest.mark.slow
def test_killed_run_leaves_a_valid_poi_file(tmp_path):
    out = tmp_path / "killed"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "eval.cli.main", "run", "--out", str(out), "--detector", "oracle", "--quiet"]
        + ["--log", "mcap", "--log-images", "png"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    pois = out / "pois.csv"
    deadline = time.monotonic() + 240
    try:
        while time.monotonic() < deadline:
            logged = sum(f.stat().st_size for f in out.glob("trial_mcap/*.mcap"))
            # header + 3 objects, and a log of 3 MiB (whole chunks of 1 MiB written: frames to read back)
            if pois.exists() and len(pois.read_text().splitlines()) >= 8 + 3 and logged > 3 * 2**20:
                break
            if proc.poll() is not None:
                pytest.fail("the run ended before it was killed")
            time.sleep(0.2)
        else:
            pytest.fail("no object confirmed within 240 s")
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
    parsed = read_poi_file(pois)
    assert parsed.problems == []
    assert len(parsed.rows) >= 3
    assert parsed.header.mission == "default"
    assert not list(Path(out).glob(".pois.csv*")), "no temporary file left behind"
    # and it scores: truth.csv was written before the first frame
    from eval.scoring.rules import load_rules
    from eval.scoring.scorer import score

    result = score(parsed, read_poi_file(out / "truth.csv"), load_rules("ex3"))
    assert result.identified >= 3 and result.total > 0
    # and poibench view replays what it recorded, its path rebuilt from the frames
    from eval.live.server import ReplaySource

    src = ReplaySource(out)
    assert len(src.frames) > 0 and len(src.init["path"]) > 0
    assert "the trial stopped at frame" in src.warning
    src.close()
    # and its ROS log, never closed, reads back as far as it was written
    from eval.ros.reader import open_recording

    rec = open_recording(out / "trial_mcap")
    assert any("a recording never closed" in note for note in rec.notes)
    frames = list(rec.frames())  # how many depends on when the kill came; at least the first chunks'
    assert len(frames) == rec.n_frames >= 1 and frames[0].timestamp_s == 0.0 and frames[0].depth_m is not None


@pytest.mark.slow
def test_turtlebot_goal_trial_writes_the_map_error(tmp_path, capsys):
    out = tmp_path / "tb"
    argv = ["run", "turtlebot-goal", "--out", str(out), "--detector", "oracle", "--max-frames", "60"]
    assert main([*argv, "--quiet", "--no-video"]) == 0
    printed = capsys.readouterr()
    # no --rules: the scenario's own preset, and a note that says so
    assert "note: scoring with the 'turtlebot' rules" in printed.err
    assert "Map error: mean" in printed.out and "Goal (pillar-blue pair)" in printed.out
    doc = json.loads((out / "score.json").read_text())
    assert doc["scoring"] == "map_error" and doc["rules"]["name"] == "turtlebot"
    assert {
        "mean_error_m",
        "max_error_m",
        "goal_center_error_m",
        "goal",
        "paired",
        "misses",
        "false_reports",
    } <= set(doc)
    assert doc["trial"]["frames"] == 60
    # 6 s facing the ball and the goal: the oracle's pillars are confirmed and within the pairing distance
    assert doc["paired"] >= 2 and doc["max_error_m"] <= 1.0
    truth = read_poi_file(out / "truth.csv")
    assert [r.type for r in truth.rows][:3] == ["pillar-blue", "pillar-blue", "ball"]
    assert (out / "map.png").stat().st_size > 0
    assert yaml.safe_load((out / "config.yaml").read_text())["rules"] == "turtlebot"


@pytest.mark.slow
def test_a_rescue_model_in_the_arena_falls_back_to_the_oracle_with_a_note(tmp_path, monkeypatch, capsys):
    """The shipped model knows the rescue maze's classes only: in the goal arena the default
    detector is the oracle, said so; a model given by hand runs, with a note on what it lacks."""
    import importlib.util

    import numpy as np

    import poi.models
    from poi.core.names import RESCUE_CLASSES

    helpers = Path(__file__).parents[2] / "poi" / "detectors" / "onnx_models.py"
    spec = importlib.util.spec_from_file_location("onnx_models", helpers)
    onnx_models = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(onnx_models)
    out = onnx_models.yolov8_output([[1, 1, 1, 1]], np.zeros((1, len(RESCUE_CLASSES))), 4)
    model = onnx_models.make_constant_model(
        tmp_path / "rescue.onnx", out, metadata={"names": str(dict(enumerate(RESCUE_CLASSES)))}
    )
    monkeypatch.setattr(poi.models, "DEFAULT_MODEL", model)
    args = ["run", "turtlebot-goal", "--max-frames", "5", "--quiet", "--no-video"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "knows none of this scenario's types" in err and "using the oracle detector" in err
    assert main([*args, "--detector", str(model), "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err
    assert "cannot report this scenario's ball, pillar-blue, pillar-green, pillar-red" in err


@pytest.mark.slow
def test_ctrl_c_leaves_a_complete_poi_file_and_one_line(tmp_path):
    """Ctrl-C (SIGINT to the whole process group, the encoder included) once an object is
    confirmed: exit 130, one line on stderr, every row of pois.csv whole."""
    out = tmp_path / "interrupted"
    # a robot at a third of the speed: the route lasts three times as long, so the run is still
    # going when the first confirmed object's row appears, however busy the machine
    slow = ["--set", "robot.speed_mps=0.1"]
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "eval.cli.main",
            "run",
            "--out",
            str(out),
            "--detector",
            "oracle",
            "--quiet",
            *slow,
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
    )
    pois = out / "pois.csv"
    deadline = time.monotonic() + 120
    try:
        while not (pois.exists() and len(pois.read_text().splitlines()) > 8):  # header + one object
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail("no object confirmed before the run ended or within 120 s")
            time.sleep(0.1)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    assert err.strip() == "poibench run: interrupted"
    parsed = read_poi_file(pois)
    assert parsed.problems == [] and len(parsed.rows) >= 1
    assert pois.read_text().endswith("\n")


def test_a_video_closed_before_its_first_frame_leaves_no_file_and_no_warning(tmp_path, caplog):
    empty = H264Writer(tmp_path / "empty.mp4", 64, 48, 10.0)
    empty.close()
    assert not (tmp_path / "empty.mp4").exists()
    assert not [r for r in caplog.records if "No frames have been written" in r.getMessage()]
    one = H264Writer(tmp_path / "one.mp4", 64, 48, 10.0)
    one.write(np.zeros((48, 64, 3), np.uint8))
    one.close()
    assert (tmp_path / "one.mp4").stat().st_size > 0


class _FullDiskVideo(H264Writer):
    def write(self, rgb):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _full_disk(monkeypatch, name: str) -> None:
    """Make the writer of ``name`` fail as on a full disk (ENOSPC, no file name in the error)."""
    if name == "score.json":
        write_text = Path.write_text

        def failing_write_text(self, *args, **kwargs):
            if self.name in ("score.json", ".score.partial.json"):  # written whole, then renamed
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return write_text(self, *args, **kwargs)

        monkeypatch.setattr(Path, "write_text", failing_write_text)
    elif name == "map.png":

        def failing_draw_map(*args, **kwargs):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        monkeypatch.setattr("eval.trial.run.draw_map", failing_draw_map)
    elif name == "trial.mp4":
        monkeypatch.setattr("eval.trial.run.H264Writer", _FullDiskVideo)
    else:  # the live record's insets video
        monkeypatch.setattr("eval.live.video.H264Writer", _FullDiskVideo)


@pytest.mark.parametrize("failing", ["score.json", "map.png", "trial.mp4", "live/insets.mp4"])
@pytest.mark.slow
def test_a_full_disk_names_the_file_and_every_other_output_is_written(failing, tmp_path, monkeypatch, capsys):
    out = tmp_path / "t"
    _full_disk(monkeypatch, failing)
    argv = ["run", "--out", str(out), "--detector", "oracle", "--max-frames", "30", "--quiet", *SMALL]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"poibench run: error: cannot write {out / failing}: no space left on device"), err
    assert "\n" not in err
    for name in (
        "pois.csv",
        "truth.csv",
        "score.json",
        "map.png",
        "trial.mp4",
        "config.yaml",
        "live/frames.jsonl",
    ):
        if name != failing:
            assert (out / name).stat().st_size > 0, name
    assert read_poi_file(out / "pois.csv").problems == []
