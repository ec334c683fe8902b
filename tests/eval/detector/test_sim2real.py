"""poibench sim2real: the card's weights and intervals by hand, its bad-input errors, and the command
end to end on a few rendered frames with a constant ONNX detector."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from eval.cli.main import main
from eval.detector.label_eval import wilson
from eval.detector.metrics import ImageBoxes
from eval.detector.quality import DetectorQualityError
from eval.detector.sim2real import (
    TOO_FEW,
    cell_weights,
    format_card,
    gap_parts,
    gap_parts_by_label,
    kish_n_eff,
    newcombe_gap,
    rate_interval,
    side_outcomes,
    sim2real_card,
    weighted_median,
    weighted_share,
)
from poi.core.names import CLASS_INDEX, RESCUE_CLASSES

sys.path.insert(0, str(Path(__file__).parents[2] / "poi" / "detectors"))
import onnx_models  # noqa: E402

C = CLASS_INDEX


def _named(label: str, side: float, named: str | None) -> ImageBoxes:
    """One image holding one placard of ``label``, ``side`` px, paired with a detection named
    ``named`` (None: no detection)."""
    box = np.array([[0.0, 0.0, side, side]])
    return ImageBoxes(
        gt_boxes=box,
        gt_classes=np.array([C[label]]),
        det_boxes=box if named else np.zeros((0, 4)),
        det_classes=np.array([C[named]] if named else [], int),
        det_scores=np.array([0.9] if named else []),
    )


def _placard(label: str, side: float, hit: bool) -> ImageBoxes:
    """One image holding one placard of ``side`` px, found with its label or not at all."""
    return _named(label, side, label if hit else None)


def _side(rows: list[tuple[str, float, int, int]], false_images: int = 0):
    """(label, side px, placards, of which found) rows as one image a placard, plus images holding
    one false poison detection and no placard."""
    ims = [_placard(lab, s, k < hits) for lab, s, n, hits in rows for k in range(n)]
    empty = ImageBoxes(
        gt_boxes=np.zeros((0, 4)),
        gt_classes=np.zeros(0, int),
        det_boxes=np.array([[0.0, 0.0, 30.0, 30.0]]),
        det_classes=np.array([C["poison"]]),
        det_scores=np.array([0.9]),
    )
    return side_outcomes(ims + [empty] * false_images, conf=0.5)


def test_weights_and_weighted_recall_by_hand():
    # photos: poison 4 at 50 px (2 found) and 4 at 100 px (4 found); explosive 2 at 50 px (none);
    # one image with a false detection. Renders: poison 6 at 50 px (3 found) and 2 at 100 px
    # (2 found); explosive 4 at 50 px (1 found).
    photos = _side([("poison", 50, 4, 2), ("poison", 100, 4, 4), ("explosive", 50, 2, 0)], false_images=1)
    renders = _side([("poison", 50, 6, 3), ("poison", 100, 2, 2), ("explosive", 50, 4, 1)])
    card = sim2real_card(photos, renders, ["explosive", "poison"], seed=0)
    # cells (label, band): p_photo / p_render = poison 40-80: 0.4 / 0.5 = 0.8; poison 80-160:
    # 0.4 / (2/12) = 2.4; explosive 40-80: 0.2 / (4/12) = 0.6
    assert card["weights"]["poison"] == [0.0, 0.0, 0.8, 2.4, 0.0]
    assert card["weights"]["explosive"] == [0.0, 0.0, 0.6, 0.0, 0.0]
    assert card["size_bins_px"] == ["0-20", "20-40", "40-80", "80-160", "160+"]
    assert card["covered"] == 1.0
    by = {r["label"]: r for r in card["per_label"]}
    # poison at the photos' sizes: (3 * 0.8 + 2 * 2.4) / (6 * 0.8 + 2 * 2.4) = 7.2 / 9.6
    assert by["poison"]["renders_matched"]["recall_right"]["value"] == 0.75
    assert by["poison"]["renders"]["recall_right"]["value"] == 0.625  # 5 / 8 unweighted
    assert by["poison"]["photos"]["recall_right"]["value"] == 0.75  # 6 / 8
    assert by["poison"]["gap"] == 0.0
    assert by["explosive"]["renders_matched"]["recall_right"]["value"] == 0.25
    assert by["explosive"]["gap"] == 0.25
    # all labels: (7.2 + 0.6) / (9.6 + 2.4) = 0.65, the photos' label mix: 0.8 * 0.75 + 0.2 * 0.25
    o = card["overall"]
    assert o["renders_matched"]["recall_right"]["value"] == 0.65
    # n_eff = 12^2 / (6 * 0.8^2 + 2 * 2.4^2 + 4 * 0.6^2) = 144 / 16.8
    assert o["renders_matched"]["recall_right"]["n_eff"] == round(144 / 16.8, 1)
    assert o["photos"]["recall_right"]["value"] == 0.6  # 6 / 10
    assert o["gap"] == 0.05
    # the false detection: one in 11 photos, of a hazmat label, poison
    assert o["photos"]["false_per_image"]["any"]["value"] == round(1 / 11, 4)
    assert o["photos"]["false_per_image"]["hazmat"]["value"] == round(1 / 11, 4)
    assert by["poison"]["photos"]["false_per_image"]["value"] == round(1 / 11, 4)
    assert o["renders"]["false_per_image"]["any"]["value"] == 0.0
    assert all(r["too_few"] for r in card["per_label"])  # under 20 placards a side
    # sorted by the size of the gap: explosive (0.25) before poison (0)
    assert [r["label"] for r in card["per_label"]] == ["explosive", "poison"]
    assert {(r["band_px"], r["n"], r["right_class"]) for r in card["by_size"]["renders"]} == {
        ("40-80", 10, 0.4),
        ("80-160", 2, 1.0),
    }


def _placards(label: str, w: float, h: float, n: int, hits: int) -> list[ImageBoxes]:
    """``n`` images of one ``w`` x ``h`` px placard, the first ``hits`` found with its label."""
    box = np.array([[0.0, 0.0, w, h]])
    return [
        ImageBoxes(
            gt_boxes=box,
            gt_classes=np.array([C[label]]),
            det_boxes=box if k < hits else np.zeros((0, 4)),
            det_classes=np.array([C[label]] if k < hits else [], int),
            det_scores=np.array([0.9] if k < hits else []),
        )
        for k in range(n)
    ]


def test_the_renders_at_the_photos_box_shapes_by_hand():
    # photos: 4 poison placards seen face on (50 x 50 px), 2 found. Renders: 4 face on, 3 found,
    # and 4 foreshortened to 50 x 100 px (shape 0.5), none found. Every placard's shorter side
    # is 50 px: one size cell, so the size-matched recall is the renders' own, 3 / 8.
    photos = side_outcomes(_placards("poison", 50, 50, 4, 2), conf=0.5)
    renders = side_outcomes(_placards("poison", 50, 50, 4, 3) + _placards("poison", 50, 100, 4, 0), conf=0.5)
    card = sim2real_card(photos, renders, ["poison"], seed=0)
    o = card["overall"]
    assert o["renders_matched"]["recall_right"]["value"] == 0.375
    assert o["gap"] == -0.125
    # shape cells: the photos all in 0.9+ (p 1), the renders half there (p 0.5): w = 2 on the
    # face-on renders, 0 on the foreshortened ones, so the recall is 3 * 2 / (4 * 2)
    assert card["shape_bins"] == ["0-0.75", "0.75-0.9", "0.9+"]
    assert o["renders_matched_shape"]["recall_right"]["value"] == 0.75
    assert o["renders_matched_shape"]["recall_right"]["n_eff"] == 4.0  # (4 * 2)^2 / (4 * 2^2)
    assert o["gap_shape"] == 0.25
    assert card["covered_shape"] == 1.0
    assert card["per_label"][0]["gap_shape"] == 0.25
    keys = ("photos", "renders", "recall_photos", "recall_renders")
    mix = {m["shape"]: tuple(m[k] for k in keys) for m in card["shape_mix"]}
    assert mix == {"0-0.75": (0, 4, None, 0.0), "0.75-0.9": (0, 0, None, None), "0.9+": (4, 4, 0.5, 0.75)}


def test_what_each_label_was_named_by_hand():
    # photos: poison at 50 px, 3 named poison, 1 infectious-substance, 1 missed; at 100 px, 5 named
    # poison. Renders: at 50 px, 1 poison, 3 infectious-substance; at 100 px, 1 poison, 1 missed.
    photos = side_outcomes(
        [_named("poison", 50, n) for n in ["poison"] * 3 + ["infectious-substance", None]]
        + [_named("poison", 100, "poison")] * 5,
        conf=0.5,
    )
    renders = side_outcomes(
        [_named("poison", 50, n) for n in ["poison"] + ["infectious-substance"] * 3]
        + [_named("poison", 100, n) for n in ("poison", None)]
        + [_named("poison", 200, "corrosive")],  # a size the photos lack: weight 0
        conf=0.5,
    )
    card = sim2real_card(photos, renders, ["poison"], seed=0)
    named = card["per_label"][0]["named"]
    values = {side: {c: v["value"] for c, v in named[side]["shares"].items()} for side in named}
    assert values["photos"] == {"poison": 0.8, "infectious-substance": 0.1, "missed": 0.1}
    # each share with Wilson's interval (at Kish's n_eff on the renders)
    assert named["photos"]["shares"]["poison"]["ci95"] == [round(v, 4) for v in wilson(8, 10)]
    # weights: 40-80 px 0.5 / (4/6) = 0.75, 80-160 px 0.5 / (2/6) = 1.5; total 4 * 0.75 + 2 * 1.5 = 6
    # poison (0.75 + 1.5) / 6, infectious-substance 3 * 0.75 / 6, missed 1.5 / 6
    # the 200 px corrosive weighs 0: counted in n, in no share
    assert values["renders_matched"] == {"infectious-substance": 0.375, "poison": 0.375, "missed": 0.25}
    n_eff = 36 / 6.75
    assert named["renders_matched"]["shares"]["missed"]["ci95"] == [
        round(v, 4) for v in wilson(0.25 * n_eff, n_eff)
    ]
    assert named["renders_matched"]["n"] == 7
    assert named["renders_matched"]["n_eff"] == round(36 / 6.75, 1)  # 6^2 / (4 * 0.75^2 + 2 * 1.5^2)
    # the named shares hold the recalls: poison's share is the right-label recall on each side
    label = card["per_label"][0]
    assert named["photos"]["shares"]["poison"]["value"] == label["photos"]["recall_right"]["value"]
    assert named["renders_matched"]["shares"]["poison"] == {
        k: label["renders_matched"]["recall_right"][k] for k in ("value", "ci95")
    }
    md = format_card(_card_for_markdown(card)).splitlines()
    # equal shares by name: infectious-substance before poison (shown as 'right')
    table = md[next(i for i, line in enumerate(md) if line.startswith("## What each label's placards")) :]
    row = next(line for line in table if line.startswith("| poison (too few) |"))
    cells = [c.strip() for c in row.split("|")[2:4]]
    assert [[part.split(" (")[0] for part in c.split("), ")] for c in cells] == [
        ["right 80%", "infectious-substance 10%", "missed 10%"],
        ["infectious-substance 38%", "right 38%", "missed 25%"],
    ]
    lo, hi = (round(100 * v) for v in wilson(8, 10))
    assert cells[0].startswith(f"right 80% ({lo}-{hi}), ")


def _card_for_markdown(card: dict) -> dict:
    """``card`` (sim2real_card's figures) with the fields the CLI adds, for format_card."""
    return {
        "model": "m.onnx",
        "conf": 0.5,
        "photos": {"folders": [{"name": "p"}], "images": 0, "placards": 0},
        "renders": {"scenes": 1, "views": 1, "seed": 0, "images": 0, "placards": 0},
        **card,
    }


def test_cells_without_renders_are_left_out_and_counted():
    # photos in 40-80 and 160+, renders only in 40-80: half the photos' placards are covered
    w = cell_weights(np.array([[0, 2], [0, 4]]), np.array([[0, 2], [0, 2]]), (1, 5))
    assert w.weight.tolist() == [[0.0, 0.0, 0.5, 0.0, 0.0]]
    assert w.covered() == 0.5 and w.covered(0) == 0.5


def test_wilson_at_kish_n_holds_its_point_inside_0_1():
    rng = np.random.default_rng(5)
    for _ in range(300):
        n = int(rng.integers(1, 60))
        hits = rng.random(n) < rng.random()
        w = rng.gamma(0.5, 2.0, size=n) if rng.random() < 0.7 else None
        s = weighted_share(hits, w)
        if s is None:  # every weight 0 cannot happen with gamma draws
            continue
        assert 0.0 <= s.lo <= s.value <= s.hi <= 1.0
        assert 0 < s.n_eff <= n + 1e-9  # Kish: never more than the placards
    # all hits and no hits: the interval reaches 1 and 0 and stays there
    assert weighted_share(np.ones(5, bool)).hi == 1.0 and weighted_share(np.zeros(5, bool)).lo == 0.0
    # unweighted, it is Wilson's interval of k / n
    s = weighted_share(np.array([True, False, False, False]))
    assert (s.lo, s.hi) == pytest.approx(wilson(1, 4))
    # equal weights leave n_eff at n; one weight of 0 drops its placard from n_eff
    assert kish_n_eff(np.full(7, 3.0)) == pytest.approx(7.0)
    assert kish_n_eff(np.array([1.0, 1.0, 0.0])) == pytest.approx(2.0)
    assert weighted_share(np.array([True]), np.array([0.0])) is None


def test_gap_interval_and_false_detection_interval_bounds():
    rng = np.random.default_rng(2)
    for _ in range(200):
        a = weighted_share(rng.random(int(rng.integers(1, 40))) < rng.random())
        b = weighted_share(rng.random(int(rng.integers(1, 40))) < rng.random())
        d, lo, hi = newcombe_gap(a, b)
        assert -1.0 <= lo <= d <= hi <= 1.0
    counts = rng.poisson(0.4, size=(50, 3))
    mean, lo, hi = rate_interval(counts, np.random.default_rng(0))
    assert np.all(lo >= 0) and np.all(lo <= mean) and np.all(mean <= hi)
    # seeded: the same draw gives the same interval
    assert np.array_equal(rate_interval(counts, np.random.default_rng(0))[1], lo)
    assert weighted_median(np.array([4.0, 1.0, 9.0]), np.array([0.0, 1.0, 1.0])) == 1.0


# ---------------------------------------------------------------------------- the command

BOX = (100, 80, 180, 160)  # where the constant model's poison lands in a 640x480 image


def _photo(root: Path, name: str, labels: list[tuple[str, tuple[int, int, int, int]]]) -> None:
    """A grey 640x480 PNG and its YOLO labels (class, xyxy pixels)."""
    (root / "images").mkdir(parents=True, exist_ok=True)
    (root / "labels").mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(root / "images" / f"{name}.png"), np.full((480, 640, 3), 90, np.uint8))
    lines = [
        f"{C[c]} {(x0 + x1) / 1280:.6f} {(y0 + y1) / 960:.6f} {(x1 - x0) / 640:.6f} {(y1 - y0) / 480:.6f}"
        for c, (x0, y0, x1, y1) in labels
    ]
    (root / "labels" / f"{name}.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")


def _model(path: Path, score: float, metadata: dict[str, str] | None = None) -> Path:
    """A constant detector: one poison at BOX, scoring ``score`` (the 640x480 image is scaled by
    0.5 into 320x320 and padded 40 px at the top)."""
    scores = np.zeros((1, len(RESCUE_CLASSES)), np.float32)
    scores[0, C["poison"]] = score
    cx, cy, w, h = (BOX[0] + BOX[2]) / 2, (BOX[1] + BOX[3]) / 2, BOX[2] - BOX[0], BOX[3] - BOX[1]
    out = onnx_models.yolov8_output([[cx * 0.5, cy * 0.5 + 40, w * 0.5, h * 0.5]], scores, 8)
    meta = {"names": str(dict(enumerate(RESCUE_CLASSES))), **(metadata or {})}
    return onnx_models.make_constant_model(path, out, metadata=meta)


@pytest.fixture
def photos(tmp_path) -> Path:
    """a: poison at BOX (found) and a 50 px explosive (missed); b: explosive at BOX (found, named
    poison); c: a 42 px poison (missed), the model's poison a false detection."""
    root = tmp_path / "photos"
    _photo(root, "a", [("poison", BOX), ("explosive", (300, 200, 350, 250))])
    _photo(root, "b", [("explosive", BOX)])
    _photo(root, "c", [("poison", (400, 300, 442, 342))])
    return root


def _run(photos: Path, model: Path, out: Path, *extra: str) -> int:
    """sim2real on one scene of 3 views; seed 1002's show an explosive and a poison placard."""
    argv = ["sim2real", "--photos", str(photos), "--model", str(model), "--out", str(out), "--quiet"]
    return main([*argv, "--scenes", "1", "--views", "3", "--seed", "1002", "--overlay", "2", *extra])


def test_gap_parts_by_label_split_each_label_as_the_card_splits_the_whole():
    """Each label's parts are gap_parts of its own placards (adding up to its gap); labels under
    TOO_FEW pasted placards on either side are left out; the largest gap either way comes first;
    the Markdown row lists the parts in GAP_PARTS' order."""
    from eval.detector.sim2real_paste import GAP_PARTS, format_decomposition

    rng = np.random.default_rng(3)
    # photos / renders pasted, and each side's chance of a right label: poison loses much, corrosive
    # gains more (the largest gap, positive), explosive has too few photos, oxidizer too few renders
    cells = {
        "poison": (20, 25, 0.8, 0.3),
        "corrosive": (24, 20, 0.2, 0.95),
        "explosive": (TOO_FEW - 1, 40, 0.8, 0.1),
        "oxidizer": (30, TOO_FEW - 1, 0.9, 0.1),
    }
    labels = {
        side: [c for c, n in cells.items() for _ in range(n[j])] for j, side in enumerate(("photos", "renders"))
    }
    p_hit = {
        side: np.array([cells[c][2 + j] for c in labels[side]]) for j, side in enumerate(("photos", "renders"))
    }
    hits = {side: rng.random((len(labels[side]), 3)) < p_hit[side][:, None] for side in labels}
    rows = gap_parts_by_label(hits, labels, seed=5)
    assert [r["label"] for r in rows] == ["corrosive", "poison"]
    assert rows[0]["gap"]["value"] > 0 > rows[1]["gap"]["value"]
    assert abs(rows[0]["gap"]["value"]) > abs(rows[1]["gap"]["value"])
    assert rows[1]["n"] == {"photos": 20, "renders": 25}
    for r in rows:
        sel = {side: np.array(labels[side]) == r["label"] for side in labels}
        assert {k: r[k] for k in ("gap", *GAP_PARTS)} == gap_parts(
            hits["photos"][sel["photos"]], hits["renders"][sel["renders"]], seed=5
        )
        assert abs(sum(r[k]["value"] for k in GAP_PARTS) - r["gap"]["value"]) <= 0.15  # each part rounded
    side = {"value": 0.5, "ci95": [0.4, 0.6], "n": 45}
    d = {
        "min_side_px": 40.0,
        "photos": dict.fromkeys(("as it is", "the drawing", "the drawing, a trial's print"), side),
    }
    d["renders"] = d["photos"]
    d |= {"gap_parts": gap_parts(hits["photos"], hits["renders"], 5), "by_label": rows}
    md = format_decomposition(d, TOO_FEW)
    p = rows[1]
    cell = [
        f"{p[k]['value']:+.1f} ({p[k]['ci95'][0]:+.1f} to {p[k]['ci95'][1]:+.1f})" for k in ("gap", *GAP_PARTS)
    ]
    assert f"| poison | 20 / 25 | {' | '.join(cell)} |" in md
    assert f"at least {TOO_FEW} pasted placards on each side" in "\n".join(md)


@pytest.mark.slow
def test_sim2real_end_to_end(photos, tmp_path, capsys):
    model = _model(tmp_path / "m.onnx", 0.9)
    out = tmp_path / "card"
    assert _run(photos, model, out) == 0
    card = json.loads((out / "card.json").read_text())
    for key in ("model", "conf", "photos", "renders", "labels", "size_mix", "weights", "overall", "per_label"):
        assert key in card
    assert card["labels"] == ["explosive", "poison"] and card["error"] is None
    ph = card["overall"]["photos"]
    assert (ph["recall_right"]["value"], ph["recall_right"]["n"]) == (0.25, 4)  # a's poison
    assert ph["recall_placard"]["value"] == 0.5  # and b's explosive, named poison
    named = {r["label"]: r["named"]["photos"]["shares"] for r in card["per_label"]}
    assert {c: v["value"] for c, v in named["explosive"].items()} == {"missed": 0.5, "poison": 0.5}
    assert ph["false_per_image"]["any"]["value"] == round(1 / 3, 4)  # c's
    assert ph["recall_right"]["ci95"] == [round(v, 4) for v in wilson(1, 4)]
    assert card["renders"]["placards"] >= 2
    for side in ("photos", "renders", "renders_matched"):
        s = card["overall"][side]["recall_right"]
        assert 0.0 <= s["ci95"][0] <= s["value"] <= s["ci95"][1] <= 1.0
    # the renders hang only the photos' labels, with the trial's looks and camera
    spec = yaml.safe_load((out / "renders" / "dataset.yaml").read_text())["spec"]
    assert spec["hazmat_labels"] == ["explosive", "poison"] and spec["camera"] is None
    assert spec["msaa"] == 0 and spec["print_saturation"] is None
    hazmat = {int(line.split()[0]) for p in (out / "renders" / "labels").rglob("*.txt") for line in p.open()}
    assert {RESCUE_CLASSES[c] for c in hazmat if c < 16} <= {"explosive", "poison"}
    # every render shows the model's one box: paired or false, never more than one false an image
    assert card["renders"]["images"] == 3 and card["overall"]["renders"]["false_per_image"]["any"]["value"] <= 1.0
    pm = card["photometry"]["photos"]  # four flat grey crops of 40 px or more
    assert (pm["crops"], pm["brightness"], pm["saturation"], pm["black"], pm["sharpness"]) == (4, 90, 0, 90, 0)
    md = (out / "card.md").read_text()
    assert "| right-label recall | 25.0% " in md and "0-20, 20-40, 40-80, 80-160, 160+ px" in md
    sheet = cv2.imread(str(out / "misses.jpg"))
    assert sheet is not None and sheet.shape[1] == 6 * 300
    assert "card.md, card.json and misses.jpg" in capsys.readouterr().out
    assert "decomposition" not in card  # only with --decompose

    # --decompose: a constant model ignores the pixels, so each version of a placard is named as the
    # placard is: on the photos a's poison of the four (all 40 px or more), on the renders as their card
    assert _run(photos, model, out, "--decompose") == 0
    capsys.readouterr()
    card = json.loads((out / "card.json").read_text())
    d = card["decomposition"]
    assert d["min_side_px"] == 40.0 and card["cpu_s"]["decompose"] >= 0
    assert d["by_label"] == []  # 4 pasted photo placards: no label has enough
    for variant in ("as it is", "the drawing", "the drawing, a trial's print"):
        assert (d["photos"][variant]["value"], d["photos"][variant]["n"]) == (0.25, 4)
        assert d["photos"][variant]["ci95"] == [round(v, 4) for v in wilson(1, 4)]
        assert d["renders"][variant] == d["renders"]["as it is"]
    # the gap's parts: the same recall in every version, so the whole gap lies in the frame around
    gap = round(100 * (d["renders"]["as it is"]["value"] - 0.25), 1)
    parts = d["gap_parts"]
    assert parts["gap"]["value"] == parts["the frame around the placard"]["value"] == gap
    assert parts["a trial's print"] == parts["the placard"] == {"value": 0.0, "ci95": [0.0, 0.0]}
    md = (out / "card.md").read_text()
    assert "## Where the gap lies" in md and f"| the frame around the placard | {gap:+.1f} (" in md

    # a model that boxes nothing: the card says so, the command fails in one line (renders reused)
    blind = _model(tmp_path / "blind.onnx", 0.0)
    assert _run(photos, blind, out) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"poibench sim2real: error: {blind} boxed nothing at confidence >= ")
    assert err.count("\n") == 1
    assert json.loads((out / "card.json").read_text())["error"].startswith(f"{blind} boxed nothing")
    assert "**Error: " in (out / "card.md").read_text()


def _error(capsys, argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    return err


def test_bad_input_is_one_line(photos, tmp_path, capsys):
    model = _model(tmp_path / "m.onnx", 0.9)
    base = ["sim2real", "--model", str(model), "--out", str(tmp_path / "o"), "--quiet"]
    # a folder without labels/
    bare = tmp_path / "bare"
    (bare / "images").mkdir(parents=True)
    cv2.imwrite(str(bare / "images" / "x.png"), np.zeros((10, 10, 3), np.uint8))
    assert f"{bare}: no labels/ folder" in _error(capsys, [*base, "--photos", str(bare)])
    # a folder labelling no placard (a QR code only)
    qr = tmp_path / "qr"
    _photo(qr, "q", [("qr", BOX)])
    assert f"{qr}: no labelled hazmat placard in 1 images" in _error(capsys, [*base, "--photos", str(qr)])
    # a class index outside RESCUE_CLASSES: file and line
    lab = photos / "labels" / "b.txt"
    good = lab.read_text()
    lab.write_text(good + "24 0.5 0.5 0.1 0.1\n")
    assert f"{lab}:2: class index 24 is not in 0..23" in _error(capsys, [*base, "--photos", str(photos)])
    lab.write_text(good)
    # --holdout-of a run that held back other folders
    run = tmp_path / "run"
    run.mkdir()
    (run / "holdout.json").write_text(json.dumps({"folders": {str(tmp_path / "elsewhere"): ["a.png"]}}))
    err = _error(capsys, [*base, "--photos", str(photos), "--holdout-of", str(run)])
    assert "none of which is a --photos folder" in err and str(run) in err
    # a model trained on scenes of the default seed
    seeded = _model(tmp_path / "s.onnx", 0.9, {"poibench_dataset_seed": "1000"})
    argv = ["sim2real", "--model", str(seeded), "--photos", str(photos), "--out", str(tmp_path / "o2")]
    assert "trained on scenes from seed 1000; evaluate on another --seed" in _error(capsys, argv)
    # --option for an ONNX model; a label model trained on these photos without --holdout-of
    err = _error(capsys, [*base, "--photos", str(photos), "--option", "conf=0.3"])
    assert "--option is for a Python detector" in err
    W = np.zeros((3, 17))
    meta = {"poibench_photo_folders": str(photos.resolve())}
    labels = onnx_models.make_colour_label_model(tmp_path / "l.onnx", W, metadata=meta)
    err = _error(capsys, [*base, "--photos", str(photos), "--label-model", str(labels)])
    assert f"{labels} was trained on part of {photos}; give --holdout-of its run folder" in err
    assert not (tmp_path / "o").exists() and not (tmp_path / "o2").exists()  # nothing rendered


def test_held_back_images_only(photos, tmp_path):
    from eval.detector.label_eval import load_folders

    run = tmp_path / "run"
    run.mkdir()
    (run / "holdout.json").write_text(json.dumps({"folders": {str(photos.resolve()): ["b.png"]}}))
    ((folder, cut),) = load_folders([photos], run)
    assert cut and [im.path.name for im in folder.images] == ["b.png"]
    with pytest.raises(DetectorQualityError, match="held-back images are not in the folder"):
        (run / "holdout.json").write_text(json.dumps({"folders": {str(photos.resolve()): ["zz.png"]}}))
        load_folders([photos], run)


def test_evaluate_photos_scores_a_photo_trained_detector_on_its_held_back_images_only(photos, tmp_path, capsys):
    """A detector whose metadata names the photo folder (poibench train --holdout) is refused on
    the whole folder and scored on the held-back image with --holdout-of."""
    meta = {"poibench_photo_folders": str(photos.resolve())}
    model = _model(tmp_path / "m.onnx", 0.9, meta)
    argv = ["evaluate-photos", "--images", str(photos), "--model", str(model), "--label-model", "none", "--quiet"]
    err = _error(capsys, [*argv, "--out", str(tmp_path / "o1")])
    assert f"{model} was trained on part of {photos}; give --holdout-of its run folder" in err
    run = tmp_path / "run"
    run.mkdir()
    (run / "holdout.json").write_text(json.dumps({"folders": {str(photos.resolve()): ["a.png"]}}))
    assert main([*argv, "--out", str(tmp_path / "o2"), "--holdout-of", str(run)]) == 0
    (folder,) = json.loads((tmp_path / "o2" / "summary.json").read_text())["folders"]
    # a.png alone: its poison found at BOX, its explosive missed; no false detection
    assert (folder["images"], folder["hazmat"]["boxes"], folder["hazmat"]["right"], folder["false"]) == (
        1,
        2,
        1,
        0,
    )
    err = _error(capsys, [*argv, "--out", str(tmp_path / "o3"), "--holdout-of", str(run), "--limit", "1"])
    assert "--limit does not go with --holdout-of" in err


def test_train_stamps_the_photo_folders_it_trained_on(photos, tmp_path):
    """poibench train's export carries the photo folders and every rendered dataset's seed in its
    metadata, which evaluate-photos and sim2real read to refuse a folder without --holdout-of,
    and evaluate-detector to refuse scenes the model trained on."""
    from eval.detector.quality import model_metadata, model_training_seeds
    from eval.detector.train import _stamp_metadata

    src = _model(tmp_path / "m.onnx", 0.9, {"poibench_dataset_seed": "5"})
    folders = []
    for name, seed in [("d", 77), ("d2", 78)]:
        (tmp_path / name).mkdir()
        (tmp_path / name / "dataset.yaml").write_text(yaml.safe_dump({"spec": {"seed": seed}}))
        folders.append(tmp_path / name / "data.yaml")
    route = tmp_path / "route"  # a route-frames folder: maze seeds, not a dataset's
    route.mkdir()
    (route / "dataset.yaml").write_text(yaml.safe_dump({"route_frames": {"seed": 1}}))
    # a photo folder named twice in --data (trained on twice an epoch) is stamped once
    twice = [str(photos.resolve())] * 2
    _stamp_metadata(src, tmp_path / "out.onnx", [*folders, route / "data.yaml"], twice)
    meta = model_metadata(tmp_path / "out.onnx")
    assert meta["poibench_photo_folders"] == str(photos.resolve()) and meta["poibench_dataset_seeds"] == "77,78"
    assert "names" in meta and "poibench_dataset_seed" not in meta  # its own kept, the stale seed not
    assert model_training_seeds(tmp_path / "out.onnx") == {77, 78}
    _stamp_metadata(src, tmp_path / "plain.onnx", [tmp_path / "none" / "data.yaml"], [])
    assert "poibench_photo_folders" not in model_metadata(tmp_path / "plain.onnx")


def test_a_fine_tune_keeps_what_its_start_was_trained_on(photos, tmp_path):
    """A detector fine-tuned from a model (its ONNX export, or a checkpoint with the export
    beside it) carries the start's seeds and photo folders too: the shipped default.onnx, fine-
    tuned from a pair that trained on other seeds, named only its last data's seed."""
    from eval.detector.quality import model_photo_folders, model_training_seeds
    from eval.detector.train import TrainSpec, _stamp_metadata, start_export

    older = tmp_path / "older"
    older.mkdir()
    start = _model(
        older / "start.onnx", 0.9, {"poibench_dataset_seeds": "3,8400", "poibench_photo_folders": "/real/a"}
    )
    (older / "start.pt").write_bytes(b"checkpoint")
    run = tmp_path / "run"
    (run / "weights").mkdir(parents=True)
    (run / "weights" / "last.pt").write_bytes(b"checkpoint")
    for model, export in [(start, start), (older / "start.pt", start), (run / "weights" / "last.pt", None)]:
        assert start_export(TrainSpec(data="d", model=str(model), out=str(tmp_path / "o"))) == export
    (run / "model.onnx").write_bytes(start.read_bytes())
    spec = TrainSpec(data="d", model=str(run / "weights" / "last.pt"), out=str(tmp_path / "o"))
    assert start_export(spec) == run / "model.onnx"
    assert start_export(TrainSpec(data="d", out=str(tmp_path / "o"))) is None  # from scratch: yolo11n.yaml
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "dataset.yaml").write_text(yaml.safe_dump({"spec": {"seed": 77}}))
    _stamp_metadata(start, tmp_path / "out.onnx", [tmp_path / "d" / "data.yaml"], [str(photos.resolve())], start)
    assert model_training_seeds(tmp_path / "out.onnx") == {3, 77, 8400}
    assert model_photo_folders(tmp_path / "out.onnx") == ["/real/a", str(photos.resolve())]


def test_a_photo_set_moved_to_another_folder_is_known_by_its_name(photos, tmp_path):
    """A holdout file or a model's metadata written on another machine names the photo set by a
    path that does not exist here: the folder of the same name is taken for it."""
    from eval.detector.label_eval import listed_folder, load_folders

    elsewhere = f"/elsewhere/{photos.name}"
    assert listed_folder(photos, [elsewhere, "/x/other"]) == elsewhere
    assert listed_folder(photos, [str(photos.resolve()), elsewhere]) == str(photos.resolve())
    assert listed_folder(photos, ["/x/other"]) is None
    assert listed_folder(photos, [f"/a/{photos.name}", f"/b/{photos.name}"]) is None  # which one: neither
    run = tmp_path / "run"
    run.mkdir()
    (run / "holdout.json").write_text(json.dumps({"folders": {elsewhere: ["b.png"]}}))
    ((folder, cut),) = load_folders([photos], run)
    assert cut and [im.path.name for im in folder.images] == ["b.png"]


def test_box_sizes_are_compared_at_the_frames_scale(tmp_path):
    """A photo of 320 px on its long side is letterboxed twice as large as its pixels: its 30 px placard
    is the size of a 60 px one in a 640x480 render, and falls in the same size band as that one."""
    from PIL import Image

    from eval.detector.metrics import ImageBoxes
    from eval.detector.quality import LabelledImage, frame_scales
    from eval.detector.sim2real import side_outcomes

    small, frame = tmp_path / "small.png", tmp_path / "frame.png"
    Image.new("RGB", (320, 240)).save(small)
    Image.new("RGB", (640, 480)).save(frame)
    images = [LabelledImage(path=p, boxes_norm=np.zeros((0, 4)), classes=np.zeros(0, int)) for p in (small, frame)]
    scales = frame_scales(images)
    assert scales.tolist() == [2.0, 1.0]
    box = np.array([[10.0, 10.0, 40.0, 45.0]])  # 30 x 35 px
    two = np.array([2])
    found = ImageBoxes(gt_boxes=box, gt_classes=two, det_boxes=box, det_classes=two, det_scores=np.array([0.9]))
    side = side_outcomes([found, found], conf=0.4, scales=scales)
    assert side.side_px.tolist() == [60.0, 30.0]
    assert np.array_equal(side.box, np.vstack([box, box]))  # the boxes stay in each image's pixels
    bands = {r["band_px"]: r["n"] for r in side.by_size}
    assert bands["20-40"] == 1 and bands["40-80"] == 1


def test_a_pasted_drawing_fills_the_diamond_inscribed_in_the_box_and_nothing_else():
    from eval.detector.sim2real_paste import diamond_mask, paste

    rgb = np.full((60, 80, 3), 30, np.uint8)
    picture = np.full((256, 256, 3), 200, np.uint8)
    out = paste(rgb, (10, 20, 50, 40), picture)  # a 40 x 20 box
    changed = np.any(out != rgb, axis=2)
    ys, xs = np.nonzero(changed)
    assert ys.min() >= 20 and ys.max() < 40 and xs.min() >= 10 and xs.max() < 50  # inside the box only
    assert tuple(out[30, 30]) == (200, 200, 200)  # the box's centre: the picture
    for y, x in ((20, 10), (20, 49), (39, 10), (39, 49)):  # the box's corners: the frame's own
        assert tuple(out[y, x]) == (30, 30, 30)
    # the diamond covers half the box, as the inscribed rhombus does (within 1%)
    for w, h in ((40, 20), (57, 33), (100, 100)):
        assert abs(float(diamond_mask(w, h).sum()) / (w * h / 2) - 1.0) < 0.01
