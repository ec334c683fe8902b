"""The live view: the page in headless Chromium (extra ``gui``), the replay, the record, no data yet.

The browser tests drive the system's Chromium (``apt-get install chromium``) through
Playwright; they are skipped where either is missing.
"""

import json
import re
import shutil
import subprocess
import sys
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from eval.live.record import confirmed_rows, depth_inset, pose_2d, thermal_inset
from eval.live.server import LiveError, LiveServer, ReplaySource
from poi.core.types import TrackSnapshot

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
SHORT = ["--set", "robot.max_duration_s=20", "--quiet"]
LIVE = ["--set", "robot.max_duration_s=40", "--quiet"]  # long enough to watch markers appear


def _browser():
    sync_api = pytest.importorskip("playwright.sync_api")
    if CHROMIUM is None:
        pytest.skip("no system Chromium (apt-get install chromium)")
    pw = sync_api.sync_playwright().start()
    browser = pw.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
    return pw, browser


def _start_live(out: Path, *extra: str) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "eval.cli.main", "run", "--out", str(out), "--live", *LIVE, *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    line = proc.stdout.readline()
    m = re.search(r"live view: (http://127\.0\.0\.1:\d+/)", line)
    assert m, f"no live view URL in {line!r}"
    return proc, m.group(1)


@pytest.mark.browser
@pytest.mark.slow
def test_live_page_shows_names_and_numbered_markers_that_update(tmp_path):
    pw, browser = _browser()
    try:
        proc, url = _start_live(tmp_path / "trial")
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(url)
        # a detection's name and confidence; read in the page in one go, since the next frame
        # (the camera pans) may already show "none"
        page.wait_for_function(
            "/[A-Z][a-z]+.*\\(\\d+%\\)/.test(document.querySelector('#detections').innerText)", timeout=90_000
        )
        page.wait_for_selector("#markers .marker", timeout=90_000)
        first_clock = page.inner_text("#clock")
        n_first = page.locator("#markers .marker").count()
        page.wait_for_function(f"document.querySelectorAll('#markers .marker').length > {n_first}", timeout=90_000)
        assert page.inner_text("#clock") != first_clock  # the view follows the trial
        ids = [page.locator("#markers .marker text").nth(i).text_content() for i in range(2)]
        assert all(i.isdigit() for i in ids)
        rows = page.locator("#pois tbody tr").count()
        assert rows >= 2 and "score" in page.inner_text("#score")
        page.screenshot(path=str(tmp_path / "live.png"))
        assert (tmp_path / "live.png").stat().st_size > 20_000
        out, _ = proc.communicate(timeout=300)
        assert proc.returncode == 0, out
    finally:
        browser.close()
        pw.stop()


@pytest.mark.browser
@pytest.mark.slow
def test_closing_the_browser_does_not_stop_the_trial(tmp_path):
    pw, browser = _browser()
    try:
        proc, url = _start_live(tmp_path / "trial")
        page = browser.new_page()
        page.goto(url)
        page.wait_for_selector("#detections li.detection", timeout=90_000)
        browser.close()
        out, _ = proc.communicate(timeout=300)
        assert proc.returncode == 0, out
        assert "points" in out and (tmp_path / "trial" / "pois.csv").exists()
    finally:
        pw.stop()


@pytest.mark.browser
def test_page_with_no_trial_data_says_so(tmp_path):
    pw, browser = _browser()
    server = LiveServer(0)
    url = server.start()
    try:
        page = browser.new_page()
        page.goto(url)
        page.wait_for_function("document.getElementById('status').textContent.includes('no trial data yet')")
        assert page.locator("#markers .marker").count() == 0
    finally:
        server.stop()
        browser.close()
        pw.stop()


@pytest.fixture(scope="module")
def recorded_trial(tmp_path_factory):
    from eval.cli.main import main

    out = tmp_path_factory.mktemp("rec") / "trial"
    assert main(["run", "--out", str(out), *SHORT]) == 0
    return out


@pytest.mark.slow
def test_a_trial_records_what_the_replay_needs(recorded_trial):
    frames = (recorded_trial / "live" / "frames.jsonl").read_text().splitlines()
    init = json.loads((recorded_trial / "live" / "init.json").read_text())
    assert len(frames) == init["n_frames"] == 201
    last = json.loads(frames[-1])
    pois = (recorded_trial / "pois.csv").read_text().splitlines()
    # the replay's object list is the POI file's: same ids and count
    assert len(last["confirmed"]) == sum(1 for r in pois if re.match(r"^\d+,", r))
    assert last["score"]["total"] == json.loads((recorded_trial / "score.json").read_text())["total"]
    assert len(init["path"]) == last["path_len"] > 100 and init["walls"]
    src = ReplaySource(recorded_trial)
    msg, images = src.frame(150)
    assert msg["k"] == 150 and images["camera"].startswith("data:image/jpeg;base64,")
    assert images["thermal"] and images["depth"]
    src.close()


@pytest.mark.browser
@pytest.mark.slow
def test_replay_page_has_a_time_slider(recorded_trial, tmp_path):
    pw, browser = _browser()
    proc = subprocess.Popen(
        [sys.executable, "-m", "eval.cli.main", "view", str(recorded_trial)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        url = re.search(r"(http://127\.0\.0\.1:\d+/)", proc.stdout.readline()).group(1)
        page = browser.new_page()
        page.goto(url)
        page.wait_for_function("document.getElementById('frame-label').textContent.includes('frame 1 /')")
        assert page.locator("#replay").is_visible()
        page.locator("#slider").fill("180")
        page.wait_for_function("document.getElementById('frame-label').textContent.includes('frame 181 /')")
        assert page.locator("#markers .marker").count() >= 3
        page.locator("#slider").fill("0")
        page.wait_for_function("document.getElementById('frame-label').textContent.includes('frame 1 /')")
        assert page.locator("#markers .marker").count() < 3  # back in time, fewer objects confirmed
    finally:
        proc.kill()
        browser.close()
        pw.stop()


def test_view_of_a_folder_without_a_record_is_one_line(tmp_path, capsys):
    from eval.cli.main import main

    assert main(["view", str(tmp_path)]) == 2
    assert "no live record" in capsys.readouterr().err
    with pytest.raises(LiveError):
        ReplaySource(tmp_path)
    assert main(["view", str(tmp_path / "nosuch")]) == 2
    assert f"error: {tmp_path / 'nosuch'}: no such folder" in capsys.readouterr().err
    # a trial stopped before its end has frames but no init.json: said so, not "run without --no-live-record"
    (tmp_path / "live").mkdir()
    (tmp_path / "live" / "frames.jsonl").write_text('{"frame": 0}\n')
    assert main(["view", str(tmp_path)]) == 2
    assert "the live record was never finished" in capsys.readouterr().err


def test_server_serves_the_page_and_static_files():
    server = LiveServer(0)
    url = server.start()
    try:
        html = urllib.request.urlopen(url, timeout=5).read().decode()
        assert "poibench live view" in html and "/static/app.js" in html
        assert b"WebSocket" in urllib.request.urlopen(url + "static/app.js", timeout=5).read()
    finally:
        server.stop()


def test_record_helpers():
    T = np.eye(4)
    T[:2, :2] = [[0.0, -1.0], [1.0, 0.0]]  # yaw 90 degrees
    T[:3, 3] = [1.0, 2.0, 0.0]
    assert pose_2d(T) == [1.0, 2.0, round(np.pi / 2, 4)] and pose_2d(None) is None
    snap = TrackSnapshot(
        track_id=4,
        report_id=2,
        type="hazmat",
        text="oxidizer",
        position_map=np.array([1.0, 2, 0.5]),
        covariance=np.diag([0.04, 0.01, 0.02]),
        first_seen_s=3.0,
        support=3,
        n_detections=3,
        confirmed=True,
    )
    (row,) = confirmed_rows([snap])
    assert row["name"] == "Oxidizer" and row["cov"] == [[0.04, 0.0], [0.0, 0.01]] and row["id"] == 2
    assert thermal_inset(None).shape == (120, 160, 3) and not thermal_inset(None).any()
    d = np.full((480, 640), 3.0, np.float32)
    d[:, :320] = 0.0
    inset = depth_inset(d)
    assert not inset[:, :70].any() and inset[:, 90:].any()  # invalid depth stays black


def test_live_port_in_use_is_a_clear_error():
    first = LiveServer(0)
    first.start()
    try:
        with pytest.raises(LiveError, match="cannot serve on 127.0.0.1"):
            LiveServer(first.port).start()
    finally:
        first.stop()


@pytest.mark.parametrize("port", ["99999", "-1"])
def test_a_port_out_of_range_is_one_line_at_parsing(port, tmp_path, capsys):
    # issue 60 edge 8: an OverflowError traceback in the server thread, then the main thread waited forever
    from eval.cli.main import main

    expected = f"error: argument --port: expected a port from 0 to 65535 (0: a free one), got {port}"
    for argv in (["run", "--live", "--out", str(tmp_path / "t")], ["view", str(tmp_path)]):
        with pytest.raises(SystemExit) as info:
            main([*argv, "--port", port])
        assert info.value.code == 2
        assert capsys.readouterr().err.strip().splitlines()[-1] == f"poibench {argv[0]}: {expected}"
    with pytest.raises(LiveError, match=rf"port {port}: expected 0 to 65535"):
        LiveServer(int(port))


def test_an_over_long_url_is_refused_quietly():
    """A 20 kB path: 400 from the server, no aiohttp traceback on the trial's stderr, still serving."""
    script = (
        "import http.client, urllib.request\n"
        "from eval.live.server import LiveServer\n"
        "server = LiveServer(0)\n"
        "url = server.start()\n"
        "c = http.client.HTTPConnection('127.0.0.1', server.port, timeout=5)\n"
        "c.request('GET', '/' + 'a' * 20000)\n"
        "print(c.getresponse().status)\n"
        "print(urllib.request.urlopen(url, timeout=5).status)\n"
        "server.stop()\n"
    )
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["400", "200"]
    assert "Traceback" not in res.stderr and "Error handling request" not in res.stderr, res.stderr
