"""The funnel in ``poibench view``: the replay's init carries funnel.csv and truth.csv, the page
lists the objects and shows a picked one's funnel (issue 57).

The trial folder is made by hand (no simulation): a two-frame live record, a funnel.csv with
three objects and a charged false report, and the truth file. The browser test drives the
system's Chromium through Playwright and is skipped where either is missing.
"""

import csv
import json
import shutil

import pytest

from eval.live.server import NO_FUNNEL_NOTE, LiveServer, ReplaySource
from eval.scoring.funnel import CSV_COLUMNS, ObjectTrace, _perception_detail

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
# the details as the funnel words them (eval.scoring.funnel), for a door never in view and the QR code below
NOT_IN_VIEW_DETAIL = _perception_detail("not in view", ObjectTrace(id=0, type="door", text=""))
NOT_READ_DETAIL = _perception_detail(
    "not read", ObjectTrace(id=2, type="qr", text="0042", modules=29, best_px=33.0, localised_frames=50)
)
FUNNEL = [
    dict(kind="object", id=0, type="door", in_view=0, best_px=0.0, boxed=0, typed=0, localised=0, read=0, tracks=0)
    | dict(points_lost=10.0, lost_to="not in view", detail=NOT_IN_VIEW_DETAIL),
    dict(kind="object", id=1, type="hazmat", text="blasting-agent", in_view=63, best_px=131.0, min_distance_m=1.03)
    | dict(min_angle_deg=56.1, median_blur_px=0.0, boxed=59, typed=59, localised=54, read=54, tracks=1)
    | dict(confirmed_frame=3, points_lost=0.0),
    # a QR code whose text looks like a number: it stays text
    dict(kind="object", id=2, type="qr", text="0042", in_view=53, best_px=33.0, min_distance_m=1.59)
    | dict(min_angle_deg=68.9, median_blur_px=0.0, boxed=50, typed=50, localised=50, read=0, qr_views=0)
    | dict(qr_decoded=0, tracks=1, points_lost=2.0, lost_to="not read", detail=NOT_READ_DETAIL),
    dict(kind="false report", id=12, type="valve", points_lost=2.0, lost_to="false: background")
    | dict(detail="valve at 1.2 m from any valve"),
]
TRUTH = [
    (0, "door", "", 1.0, -0.5, 0.54),
    (1, "hazmat", "blasting-agent", 0.3, 0.2, 0.9),
    (2, "qr", "0042", 1.5, 0.4, 0.3),
]

# the door's report, right on it: its filled marker covers the door's truth marker
REPORT = {"id": 0, "t": 0.1, "type": "door", "text": "", "name": "Door", "x": 1.0, "y": -0.5, "z": 0.5}
REPORT["cov"] = [[0.01, 0.0], [0.0, 0.01]]


def _trial_dir(d, funnel=True):
    """A finished trial as poibench view reads it: live record, truth.csv and (optionally) funnel.csv."""
    (d / "live").mkdir(parents=True)
    colors = {t: "#1060f0" if t == "qr" else "#ff6020" for t in ("door", "hazmat", "qr", "valve")}
    init = {"type": "init", "title": "hand-made", "n_frames": 2, "walls": [[-0.5, -1, 2, -1], [2, -1, 2, 1]]}
    init |= {
        "bounds": [-1, -1.5, 2.5, 1.5],
        "marker_colors": colors,
        "box_colors": colors,
        "path": [[0, 0], [0.1, 0]],
    }
    init["marker_shapes"] = {t: "circle" if t == "qr" else "diamond" for t in colors}
    (d / "live" / "init.json").write_text(json.dumps(init))
    frames = [
        {"type": "frame", "k": k, "t": k / 10, "pose": [0.1 * k, 0, 0], "path_len": k + 1, "detections": []}
        | {"confirmed": [REPORT], "score": None, "skipped": None}
        for k in range(2)
    ]
    (d / "live" / "frames.jsonl").write_text("".join(json.dumps(f) + "\n" for f in frames))
    header = "pois\n1.2\npoibench\nsim\n2000-01-01\n00:00:00\ndefault\nid,time,text,x,y,z,robot,mode,type\n"
    rows = "".join(f"{i},00:00:00,{text},{x},{y},{z},sim,GT,{t}\n" for i, t, text, x, y, z in TRUTH)
    (d / "truth.csv").write_text(header + rows)
    if funnel:
        with open(d / "funnel.csv", "w", newline="") as f:
            w = csv.DictWriter(f, CSV_COLUMNS, restval="")
            w.writeheader()
            w.writerows(FUNNEL)
    return d


def test_replay_init_carries_the_funnel_rows_and_truth_positions(tmp_path):
    src = ReplaySource(_trial_dir(tmp_path / "trial"))
    funnel = src.init["funnel"]
    assert funnel["note"] is None
    rows = funnel["rows"]
    assert [(r["kind"], r["id"]) for r in rows] == [*(("object", i) for i in range(3)), ("false report", 12)]
    assert set(rows[0]) == {*CSV_COLUMNS, "name"}
    qr = rows[2]
    assert qr["text"] == "0042" and qr["name"] == "0042"  # read as text, not as the number 42
    assert (qr["in_view"], qr["read"], qr["qr_views"], qr["points_lost"]) == (53, 0, 0, 2.0)
    assert (qr["lost_to"], qr["detail"], qr["confirmed_frame"]) == ("not read", NOT_READ_DETAIL, None)
    assert rows[1]["name"] == "Blasting agent" and rows[1]["confirmed_frame"] == 3 and rows[1]["qr_views"] is None
    assert rows[3]["lost_to"] == "false: background" and rows[3]["in_view"] is None
    truth = src.init["truth"]
    assert [(o["id"], o["type"], o["x"], o["y"], o["z"]) for o in truth] == [
        (i, t, x, y, z) for i, t, _, x, y, z in TRUTH
    ]
    # what the page gets is this init, as JSON (no NaN)
    server = LiveServer(0, replay=src)
    assert json.loads(json.dumps(server._init_message(), allow_nan=False))["funnel"]["rows"] == rows
    src.close()


def test_a_trial_without_funnel_csv_gives_the_note(tmp_path):
    src = ReplaySource(_trial_dir(tmp_path / "old", funnel=False))
    assert src.init["funnel"] == {"rows": [], "note": NO_FUNNEL_NOTE}
    assert len(src.init["truth"]) == 3  # the truth markers are still drawn
    (tmp_path / "old" / "truth.csv").unlink()
    assert ReplaySource(tmp_path / "old").init["truth"] == []


def _browser():
    sync_api = pytest.importorskip("playwright.sync_api")
    if CHROMIUM is None:
        pytest.skip("no system Chromium (apt-get install chromium)")
    pw = sync_api.sync_playwright().start()
    return pw, pw.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])


def _open(browser, server):
    page = browser.new_page(viewport={"width": 1400, "height": 1100})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(server.url)
    page.wait_for_function("document.getElementById('frame-label').textContent.includes('frame 1 /')")
    return page, errors


@pytest.mark.browser
def test_picking_an_object_shows_its_funnel(tmp_path):
    pw, browser = _browser()
    new = LiveServer(0, replay=ReplaySource(_trial_dir(tmp_path / "trial")))
    old = LiveServer(0, replay=ReplaySource(_trial_dir(tmp_path / "old", funnel=False)))
    new.start()
    old.start()
    try:
        page, errors = _open(browser, new)
        assert page.locator("#funnel tbody tr[data-key]").count() == 4  # three objects, one false report
        assert page.locator("#truth .truth").count() == 3  # the hollow truth markers
        assert "not read" not in page.inner_text("#funnel-detail")
        page.locator("#funnel tr[data-key='object:2']").click()  # its row
        detail = page.inner_text("#funnel-detail")
        assert "2 points lost to not read" in detail and NOT_READ_DETAIL in detail
        assert "53 frames" in detail and "QR views given to the reader 0" in detail
        assert page.locator("#truth .truth.picked").get_attribute("data-id") == "2"  # highlighted on the map
        page.locator("#truth .truth[data-id='1']").click()  # its truth marker
        assert page.locator("#funnel tr.picked").get_attribute("data-key") == "object:1"
        assert "no points lost" in page.inner_text("#funnel-detail")
        page.locator("#markers .marker").click()  # the door's report, on the door's truth marker
        assert "lost to not in view" in page.inner_text("#funnel-detail")
        assert page.locator("#funnel tr.picked").get_attribute("data-key") == "object:0"
        page.locator("#funnel tr[data-key='false report:12']").click()
        assert "false: background" in page.inner_text("#funnel-detail")
        assert not errors, errors

        page, errors = _open(browser, old)
        assert page.inner_text("#funnel-note") == NO_FUNNEL_NOTE
        assert page.locator("#funnel tbody tr").count() == 0 and page.locator("#truth .truth").count() == 3
        assert not errors, errors
    finally:
        new.stop()
        old.stop()
        browser.close()
        pw.stop()
