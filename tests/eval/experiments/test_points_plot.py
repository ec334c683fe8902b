"""points.png: each bar's segments are the funnel's lost points by cause, a bar a maze (suite)
or a setting combination (sweep), and a fault in the funnel's sum shows."""

import pandas as pd

from eval.experiments.points_plot import CAUSE_COLOURS, UNCHARGED, PointsBar, points_figure
from eval.experiments.sweep import FUNNEL_LINES, append_funnel, plot_points, points_bars, read_funnels, read_rows
from eval.scoring.funnel import CAUSES, lost_by_type

QR_READ_FAIL = {"qr": {"objects": 2, "in_view": 2, "boxed": 2, "not read": 2.0}}
DOOR_FALSE = {"door": {"objects": 1, "in_view": 1, "false: background": 5.0}}
VALVE_MISS = {"valve": {"objects": 1, "not boxed": 6.0}}


def _bars(df, keys, folder):
    return points_bars(df, keys, folder, read_funnels(folder / FUNNEL_LINES))


def _run_folder(tmp_path, rows: list[dict], funnels: dict[str, dict]):
    """A run folder as a suite or sweep leaves it: trials.csv and funnel.jsonl."""
    base = {"suite": "mini", "suite_version": 1, "seed": 0, "error": "", "complete": 1}
    pd.DataFrame([{**base, **r} for r in rows]).to_csv(tmp_path / "trials.csv", index=False)
    for trial, per_type in funnels.items():
        append_funnel(tmp_path / FUNNEL_LINES, trial, per_type)
    return read_rows(tmp_path / "trials.csv")


def test_segments_lay_the_false_reports_then_the_object_causes_end_to_end():
    bar = PointsBar(label="m1", score=53, max_score=60, lost={"not read": 2.0, "false: background": 5.0})
    assert bar.segments() == [("false: background", 0.0, 5.0), ("not read", 5.0, 2.0)]
    assert bar.uncharged == 0


def test_points_the_funnel_did_not_charge_are_a_segment_of_their_own():
    bar = PointsBar(label="m1", score=50, max_score=60, lost={"not boxed": 6.0})
    assert bar.uncharged == 4
    assert bar.segments() == [("not boxed", 0.0, 6.0), (UNCHARGED, 6.0, 4.0)]


def test_a_suite_gives_a_bar_a_finished_maze_and_sums_its_types(tmp_path):
    rows = [
        {"trial": "a", "scenario": "m1", "score": 53, "max_score": 60},
        {"trial": "b", "scenario": "m2", "score": 48, "max_score": 54},
        {"trial": "c", "scenario": "m3", "score": 0, "max_score": 60, "error": "RuntimeError: boom"},
    ]
    df = _run_folder(tmp_path, rows, {"a": {**QR_READ_FAIL, **DOOR_FALSE}, "b": VALVE_MISS})
    bars, per_type = _bars(df, [], tmp_path)
    assert [(b.label, b.score, b.max_score, b.lost) for b in bars] == [
        ("m1", 53.0, 60.0, {"not read": 2.0, "false: background": 5.0}),
        ("m2", 48.0, 54.0, {"not boxed": 6.0}),
    ]
    assert lost_by_type(per_type) == {
        "qr": {"not read": 2.0},
        "door": {"false: background": 5.0},
        "valve": {"not boxed": 6.0},
    }


def test_a_sweep_gives_a_bar_a_setting_its_mazes_summed(tmp_path):
    rows = [
        {"trial": "a", "scenario": "m1", "score": 53, "max_score": 60, "set.tracker.gate": 4},
        {"trial": "b", "scenario": "m2", "score": 48, "max_score": 54, "set.tracker.gate": 4},
        {"trial": "c", "scenario": "m1", "score": 58, "max_score": 60, "set.tracker.gate": 9},
    ]
    funnels = {"a": {**QR_READ_FAIL, **DOOR_FALSE}, "b": VALVE_MISS, "c": QR_READ_FAIL}
    bars, _ = _bars(_run_folder(tmp_path, rows, funnels), ["tracker.gate"], tmp_path)
    assert [(b.label, b.score, b.max_score, b.lost) for b in bars] == [
        ("tracker.gate=4", 101.0, 114.0, {"not read": 2.0, "not boxed": 6.0, "false: background": 5.0}),
        ("tracker.gate=9", 58.0, 60.0, {"not read": 2.0}),
    ]


def test_a_suite_run_with_a_setting_still_gives_a_bar_a_maze(tmp_path):
    """`suite run --set K=V` writes a one-combination grid: a bar a maze, as without it; a trial that
    finished without a funnel line is left out."""
    rows = [
        {"trial": "a", "scenario": "m1", "score": 53, "max_score": 60, "set.detector.conf": 0.3},
        {"trial": "b", "scenario": "m2", "score": 48, "max_score": 54, "set.detector.conf": 0.3},
        {"trial": "c", "scenario": "m3", "score": 60, "max_score": 60, "set.detector.conf": 0.3},
    ]
    df = _run_folder(tmp_path, rows, {"a": QR_READ_FAIL, "b": VALVE_MISS})
    bars, _ = _bars(df, ["detector.conf"], tmp_path)
    assert [(b.label, b.score) for b in bars] == [("m1", 53.0), ("m2", 48.0)]


def test_a_sweep_over_two_settings_labels_each_bar_with_both(tmp_path):
    rows = [
        {"trial": "a", "scenario": "m1", "score": 53, "max_score": 60, "set.x": 1, "set.y": "p"},
        {"trial": "b", "scenario": "m1", "score": 50, "max_score": 60, "set.x": 2, "set.y": "p"},
    ]
    bars, _ = _bars(_run_folder(tmp_path, rows, {"a": QR_READ_FAIL, "b": VALVE_MISS}), ["x", "y"], tmp_path)
    assert [b.label for b in bars] == ["x=1, y=p", "x=2, y=p"]


def test_every_funnel_cause_has_a_colour():
    assert set(CAUSE_COLOURS) == set(CAUSES)


def test_the_figure_draws_each_cause_its_points_and_writes_the_score_beside_it():
    bars = [
        PointsBar(label="m1", score=53, max_score=60, lost={"not read": 2.0, "false: background": 5.0}),
        PointsBar(label="m2", score=50, max_score=60, lost={"not boxed": 6.0}),
    ]
    fig = points_figure(bars, {**QR_READ_FAIL, **DOOR_FALSE, **VALVE_MISS}, "mini")
    top, bottom = fig.axes[:2]
    drawn = [(p.get_x(), p.get_width(), round(p.get_y() + p.get_height() / 2)) for p in top.patches]
    assert drawn == [(0.0, 5.0, 0), (5.0, 2.0, 0), (0.0, 6.0, 1), (6.0, 4.0, 1)]
    assert [t.get_text().strip() for t in top.texts] == ["53 / 60", "50 / 60, +4 not charged"]
    # lower panel: the types by points lost, most first
    assert [t.get_text() for t in bottom.get_yticklabels()] == ["valve", "door", "qr"]
    assert sorted(p.get_width() for p in bottom.patches) == [2.0, 5.0, 6.0]
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == ["false: background", "not boxed", "not read", UNCHARGED]


def test_points_png_is_written_with_a_finished_trial_and_not_without(tmp_path):
    """(A run writes it with its summaries: test_shard.py compares a merged run's with one run's.)"""
    rows = [{"trial": "a", "scenario": "m1", "score": 53, "max_score": 60}]
    df = _run_folder(tmp_path, rows, {"a": {**QR_READ_FAIL, **DOOR_FALSE}})
    assert plot_points(tmp_path, df, [])
    assert (tmp_path / "points.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    failed = tmp_path / "failed"
    failed.mkdir()
    df = _run_folder(failed, [{**rows[0], "error": "RuntimeError: boom"}], {})
    assert not plot_points(failed, df, [])
    assert not (failed / "points.png").exists()
