"""The perception cache: exact depth tiles, keys, corrupt records recomputed, and a replayed
trial that writes the same pois.csv and score.json as a full one, byte for byte."""

import dataclasses
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import eval.trial.sources as trial_sources
import sim.gl
from eval.cli.main import main
from eval.experiments.suites import load_suite
from eval.experiments.sweep import read_rows
from eval.scoring.rules import load_rules
from eval.trial.perception_cache import (
    CONF_FLOOR,
    PerceptionCache,
    PerceptionCacheError,
    PerceptionRecord,
    TiledDepth,
    perception_key,
)
from eval.trial.run import run_trial
from eval.trial.sources import cached_perception
from poi.config import apply_overrides, load_config
from poi.core.depth_units import from_z16, to_z16
from sim.scenario import apply_settings

TINY = str(Path(__file__).parents[1] / "experiments" / "data" / "tiny_suite.yaml")
RESULT_COLS = ["trial", "scenario", "seed", "score", "max_score", "fraction", "false_reports", "misses"]


@pytest.mark.parametrize("z16", [False, True])
def test_tiled_depth_reads_exactly_what_the_array_holds(z16):
    """Float32 tiles, or (on the Z16 grid, as the simulator's depth is) tiles of counts: the same
    values bit for bit either way, and the counts' tiles smaller."""
    rng = np.random.default_rng(3)
    a = rng.uniform(0.3, 6.0, (75, 101)).astype(np.float32)  # not a multiple of the tile either way
    a[rng.random(a.shape) < 0.1] = 0.0
    if z16:
        a = from_z16(to_z16(a, 0.001), 0.001)
    t = TiledDepth.from_array(a, tile=16, unit_m=0.001 if z16 else None)
    assert t.shape == a.shape and t.ndim == 2 and t.unit_m == (0.001 if z16 else None)
    if z16:
        assert len(t.blob) < 0.8 * len(TiledDepth.from_array(a, tile=16).blob)
        assert np.array_equal(np.asarray(t).view(np.uint32), a.view(np.uint32))
    for r, c in [(0, 0), (74, 100), (15, 16), (16, 15), (-1, -1), (40, 63)]:
        got = t[r, c]
        assert got.dtype == np.float32 and got == a[r, c]
    for rows, cols in [
        (slice(0, 75), slice(0, 101)),
        (slice(14, 18), slice(30, 49)),
        (slice(70, 90), slice(95, 200)),  # past the border, as numpy clips it
        (slice(5, 5), slice(0, 3)),
    ]:
        assert np.array_equal(t[rows, cols], a[rows, cols])
    assert np.array_equal(t[3, 10:40], a[3, 10:40]) and np.array_equal(t[10:40, 7], a[10:40, 7])
    with pytest.raises(IndexError):
        t[75, 0]


def _smoke(i: int):
    suite = load_suite("smoke")
    return suite.build(suite.scenarios[i])


def test_the_key_changes_with_what_changes_perception_only(monkeypatch):
    sc, cfg = _smoke(0), load_config()
    key = perception_key(sc, "oracle", cfg, None, None)
    sets = ["tracker.gate=4", "tracker.n_min=2", "detector.conf=0.6", "localize.inner_fraction=0.3"]
    sets += ["slam.n_min=2", "thermal.confirm_colour_boxes=false"]  # read after detection
    sets += ["detector.type_conf.valve=0.7"]
    downstream = apply_overrides(cfg, sets)
    assert perception_key(sc, "oracle", downstream, None, None) == key
    assert perception_key(dataclasses.replace(sc, seed=sc.seed + 1), "oracle", cfg, None, None) != key
    assert perception_key(apply_settings(sc, ["lighting=dim"]), "oracle", cfg, None, None) != key
    assert perception_key(sc, "oracle", apply_overrides(cfg, ["detector.nms_iou=0.5"]), None, None) != key
    assert perception_key(sc, "oracle", apply_overrides(cfg, ["thermal.enabled=false"]), None, None) != key
    assert perception_key(sc, "oracle", cfg, 50, None) != key
    assert perception_key(sc, "default", cfg, None, None) != key
    # another Mesa (or LLVM, or llvmpipe flags) draws other pixels
    assert sim.gl.renderer_identity().count("; ") >= 1  # the renderer's names (or why none), the flags
    other = "Mesa; llvmpipe (LLVM 19.1.7, 256 bits); 4.5 (Compatibility Profile) Mesa 25.0.7; GALLIVM_PERF="
    monkeypatch.setattr(sim.gl, "renderer_identity", lambda: other)
    assert perception_key(sc, "oracle", cfg, None, None) != key
    monkeypatch.undo()
    # no replay where the key cannot cover the detector, or below the recorded floor
    assert perception_key(sc, "python:team_det:Detector", cfg, None, None) is None
    low = apply_overrides(cfg, [f"detector.conf={CONF_FLOOR / 2}"])
    assert perception_key(sc, "oracle", low, None, None) is None
    low = apply_overrides(cfg, [f"detector.type_conf.door={CONF_FLOOR / 2}"])
    assert perception_key(sc, "default", low, None, None) is None


def test_the_key_holds_the_label_model_by_its_bytes_not_its_path(tmp_path):
    """The same label model at another path (another checkout) keys the same record; other bytes
    at the same path do not."""
    from poi.models import DEFAULT_LABEL_MODEL

    sc, cfg = _smoke(0), load_config()
    copy = tmp_path / "elsewhere" / "labels.onnx"
    copy.parent.mkdir()
    copy.write_bytes(DEFAULT_LABEL_MODEL.read_bytes())
    here = perception_key(
        sc, "default", apply_overrides(cfg, [f"detector.label_model={DEFAULT_LABEL_MODEL}"]), None, None
    )
    there = perception_key(sc, "default", apply_overrides(cfg, [f"detector.label_model={copy}"]), None, None)
    assert here == there
    copy.write_bytes(DEFAULT_LABEL_MODEL.read_bytes() + b"\0")
    assert (
        perception_key(sc, "default", apply_overrides(cfg, [f"detector.label_model={copy}"]), None, None) != here
    )


@pytest.mark.slow
def test_a_torn_corrupt_or_foreign_record_is_recomputed_never_trusted(tmp_path, monkeypatch):
    sc, cfg = apply_settings(_smoke(0), ["robot.max_duration_s=1"]), load_config()
    cache = PerceptionCache(tmp_path / "c")
    made = []
    real = trial_sources.record_perception
    monkeypatch.setattr(trial_sources, "record_perception", lambda *a: made.append(1) or real(*a))
    rec = cached_perception(cache, sc, cfg, "oracle", None)
    assert len(made) == 1 and rec.n_frames == 11 and len(rec.frames) == 11  # 1 s at 10 frames per second
    path = cache.path(rec.key)
    good = path.read_bytes()
    again = cached_perception(cache, sc, cfg, "oracle", None)
    assert len(made) == 1 and [len(f.detections) for f in again.frames] == [len(f.detections) for f in rec.frames]
    assert np.array_equal(again.frames[5].depth[0:480, 0:640], rec.frames[5].depth[0:480, 0:640])
    flipped = bytearray(good)
    flipped[len(good) // 2] ^= 0xFF
    for bad in (good[: len(good) // 3], b"POIBPCR\x00" + good[8:12], bytes(flipped)):
        path.write_bytes(bad)
        assert cache.load(rec.key) is None
    cached_perception(cache, sc, cfg, "oracle", None)
    assert len(made) == 2 and path.read_bytes() == good  # recorded again, the same bytes
    n = len(made)
    other = cache.path("0" * 40)
    other.write_bytes(good)  # a valid record filed under another key
    assert cache.load("0" * 40) is None
    assert len(made) == n and not list(cache.folder.glob(".*.tmp"))  # no temporary file left behind


def _record(key: str, n_bytes: int) -> PerceptionRecord:
    """A record of about n_bytes (its fields need not be a real trial's for the cache's bookkeeping)."""
    fields = {f.name: None for f in dataclasses.fields(PerceptionRecord)}
    return PerceptionRecord(**{**fields, "key": key, "notes": ["x" * n_bytes], "frames": []})


def test_the_cache_stays_under_its_size_limit_dropping_the_least_recently_used(tmp_path, monkeypatch):
    """Four records of about 1.3 kB under a limit of three and a half: storing the fourth drops the one used
    longest ago (a load counts as a use), and a record larger than the limit is kept alone.
    The limit comes from $POIBENCH_CACHE_MAX_GB, checked."""
    cache = PerceptionCache(tmp_path, max_bytes=10**9)
    keys = [c * 40 for c in "abcde"]
    cache.store(keys[0], _record(keys[0], 1000))
    cache.max_bytes = int(3.5 * cache.path(keys[0]).stat().st_size)  # room for three
    for i, k in enumerate(keys[:3]):
        cache.store(k, _record(k, 1000))
        os.utime(cache.path(k), (1000.0 + i, 1000.0 + i))  # stored a, b, c in that order
    assert cache.load(keys[0]).key == keys[0]  # a is used now: b is the least recently used
    cache.store(keys[3], _record(keys[3], 1000))
    assert sorted(p.name[0] for p in tmp_path.glob("*.pcache")) == ["a", "c", "d"]
    cache.store(keys[4], _record(keys[4], 5000))  # alone over the limit: kept, every other dropped
    assert [p.name[0] for p in tmp_path.glob("*.pcache")] == ["e"]
    assert cache.load(keys[4]).key == keys[4]
    monkeypatch.setenv("POIBENCH_CACHE_MAX_GB", "0.5")
    assert PerceptionCache(tmp_path).max_bytes == 500_000_000
    monkeypatch.delenv("POIBENCH_CACHE_MAX_GB")
    assert PerceptionCache(tmp_path).max_bytes == 20_000_000_000
    for bad in ("lots", "0", "-1", "nan"):
        monkeypatch.setenv("POIBENCH_CACHE_MAX_GB", bad)
        with pytest.raises(PerceptionCacheError, match="MAX_GB=.*expected a number of gigabytes > 0"):
            PerceptionCache(tmp_path)


@pytest.mark.slow
def test_a_replayed_trial_writes_the_full_trials_files_byte_for_byte(tmp_path, monkeypatch):
    sc = _smoke(1)
    kw = dict(detector="default", rules=load_rules("ex3"), rules_name="ex3", video=False, progress=False)
    kw.update(record_live=False, max_frames=50)
    cache = PerceptionCache(tmp_path / "c")
    # recorded with the default settings (and replayed: a cached trial always replays) ...
    run_trial(sc, tmp_path / "first", perception_cache=cache, **kw)
    # ... then settings only the stages after detection read: replayed, nothing rendered again
    sets = ["detector.conf=0.6", "tracker.gate=4", "tracker.n_min=2", "localize.inner_fraction=0.3"]
    sets += ["detector.type_conf.hazmat=0.8", "detector.type_conf.door=0.3"]  # each type's threshold too
    full = run_trial(sc, tmp_path / "full", pipeline_sets=sets, **kw)

    def no_recording(*a):
        raise AssertionError("the record was made again")

    monkeypatch.setattr(trial_sources, "record_perception", no_recording)
    replay = run_trial(sc, tmp_path / "replay", pipeline_sets=sets, perception_cache=cache, **kw)
    assert len(full.score.reports) > 0  # objects were found and reported
    for name in ("pois.csv", "score.json", "truth.csv", "config.yaml"):
        assert (tmp_path / "replay" / name).read_bytes() == (tmp_path / "full" / name).read_bytes(), name
    assert replay.cost.cpu_s < full.cost.cpu_s / 4


def test_cache_flags_are_checked(tmp_path, capsys, monkeypatch):
    args = ["sweep", "--suite", TINY, "--out", str(tmp_path / "s"), "--quiet"]
    assert main([*args, "--cache", str(tmp_path / "c"), "--no-cache"]) == 2
    assert "--cache and --no-cache" in capsys.readouterr().err
    # a file as the cache, or a bad size limit: refused before any trial, not left unused in each
    afile = tmp_path / "afile"
    afile.write_text("x")
    assert main([*args, "--cache", str(afile)]) == 2
    assert f"error: --cache {afile}: is a file, not a folder" in capsys.readouterr().err
    monkeypatch.setenv("POIBENCH_CACHE_MAX_GB", "abc")
    assert main([*args, "--cache", str(tmp_path / "c")]) == 2
    assert "error: POIBENCH_CACHE_MAX_GB='abc': expected a number of gigabytes > 0" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


@pytest.mark.slow
def test_a_sweep_killed_while_it_caches_resumes_to_the_table_of_an_uncached_one(tmp_path):
    args = ["--suite", TINY, "--set", "tracker.gate=4,9,16", "--quiet", "--cache", str(tmp_path / "c")]
    cmd = [sys.executable, "-m", "eval.cli.main", "sweep", *args, "--out", str(tmp_path / "k")]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    trials = tmp_path / "k" / "trials.csv"
    deadline = time.time() + 120
    while time.time() < deadline and len(read_rows(trials)) < 1:
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGKILL)  # trial 2 is recording tiny-2's perception now
    proc.wait()
    before = read_rows(trials)
    assert 1 <= len(before) < 6, "the sweep was killed midway"
    assert main(["sweep", *args, "--out", str(tmp_path / "k"), "--resume"]) == 0
    after = read_rows(trials)
    assert len(after) == 6
    pd.testing.assert_frame_equal(
        after.set_index("trial").loc[before["trial"], RESULT_COLS[1:]], before.set_index("trial")[RESULT_COLS[1:]]
    )
    plain = ["--suite", TINY, "--set", "tracker.gate=4,9,16", "--quiet", "--no-cache"]
    assert main(["sweep", *plain, "--out", str(tmp_path / "u")]) == 0
    unbroken = read_rows(tmp_path / "u" / "trials.csv")
    pd.testing.assert_frame_equal(
        after[RESULT_COLS].sort_values("trial").reset_index(drop=True),
        unbroken[RESULT_COLS].sort_values("trial").reset_index(drop=True),
    )
    assert len(list((tmp_path / "c").glob("*.pcache"))) == 2  # one record per scenario
