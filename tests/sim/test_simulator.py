"""The simulated world end to end: frames agree with the truth, every type shows, same seed same frames."""

import hashlib

import numpy as np
import pytest

from maze_assets.hazmat import placard_style
from maze_assets.models import BACKING_M, QUAD_OFFSET_M, body_rotation, flat_extent_m, reference_point
from maze_assets.models import FLAT_TYPES as FLAT_MODEL_TYPES
from poi.core.geometry import invert_transform, transform_points
from poi.core.names import RESCUE_TYPES
from poi.estimation.projection import BOX_CORNER_TO_CENTER_PX, project_point_to_pixel
from sim.scenario import apply_settings, load_scenario, with_noise
from sim.simulator import Simulation

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI

FLAT_TYPES = ("hazmat", "qr", "exit-sign", "fire-extinguisher-sign")
STRIDE = 4  # every 4th frame of the 10 fps route: 2.5 frames a second is plenty to see each object


def _cut(o) -> bool:
    return o.look_seed is not None and placard_style(o.text, o.look_seed).look.cut


@pytest.fixture(scope="module")
def clean_default():
    # the earlier sweeping tour (robot.pan.mode: sweep): these geometric checks were built on its
    # frames; the default tour's own coverage is the oracle trial's (tests/eval/trial/test_run.py)
    sc = apply_settings(with_noise(load_scenario("default"), False), ["robot.pan.mode=sweep"])
    with Simulation(sc) as sim:
        frames = [sim.frame(k) for k in range(0, sim.n_frames, STRIDE)]
        yield sim, frames


def test_deprojected_box_centres_land_on_true_map_positions(clean_default):
    """Intrinsics, camera frames and poses agree: box centre + clean depth + true pose -> truth within 3 cm.

    Checked on objects whose reference point is on their visible surface (flat signs), fully
    in view, at least 20 px wide and seen within 80 degrees of face-on, so the box centre is
    the sign centre (at grazing angles perspective moves a box's centre off the sign's centre
    by centimetres, which says nothing about the frames).
    """
    sim, frames = clean_default
    truth = {o.id: o.position_map for o in sim.truth_objects()}
    placed = {o.id: o for o in sim.objects}
    T_tracker_optical = sim.T_tracker_optical_nominal
    checked = set()
    for frame, ft in frames:
        K = frame.intrinsics
        for v in ft.visible:
            x1, y1, x2, y2 = v.box_xyxy
            if v.type not in FLAT_TYPES or v.visible_fraction < 0.9 or min(x2 - x1, y2 - y1) < 20:
                continue
            if x1 <= 0 or y1 <= 0 or x2 >= K.width or y2 >= K.height:
                continue
            yaw = placed[v.id].yaw
            normal_cam = ft.T_map_camera[:3, :3].T @ sim.T_map_world[:3, :3] @ [np.cos(yaw), np.sin(yaw), 0]
            if -normal_cam @ (v.position_cam / np.linalg.norm(v.position_cam)) < np.cos(np.radians(80)):
                continue
            # box edges are pixel boundaries; pixel centres are at integer coordinates
            u, w = 0.5 * (x1 + x2) - 0.5, 0.5 * (y1 + y2) - 0.5
            z = float(frame.depth_m[int(round(w)), int(round(u))])
            assert z > 0
            p_c = np.array([(u - K.ppx) / K.fx * z, (w - K.ppy) / K.fy * z, z])
            p_map = transform_points(frame.pose @ T_tracker_optical, p_c)
            err = float(np.linalg.norm(p_map - truth[v.id]))
            # a placard turned in its plane has a box whose centre perspective moves a little
            # more than an upright one's at grazing angles
            assert err < (0.03 if placed[v.id].roll == 0.0 else 0.04), (v.id, v.type, err)
            checked.add(v.id)
    flat_ids = {o.id for o in sim.objects if o.type in FLAT_TYPES}
    assert checked == flat_ids, f"never fully seen: {flat_ids - checked}"


def _image_box(sim, ft, o, xs: tuple[float, ...]) -> np.ndarray:
    """The box (corner convention) of a rectangular flat item's outline at depths ``xs`` along
    its normal (its image at QUAD_OFFSET_M, its backing's back at 0), projected exactly."""
    w, h = flat_extent_m(o.type, o.size_m)
    R, origin = body_rotation(o), np.asarray(o.position, dtype=float)
    pts = [origin + R.apply([x, a * w / 2, b * h / 2]) for x in xs for a in (-1, 1) for b in (-1, 1)]
    p_c = transform_points(invert_transform(ft.T_map_camera), transform_points(sim.T_map_world, np.array(pts)))
    u, v = project_point_to_pixel(sim.intrinsics, p_c.T) + BOX_CORNER_TO_CENTER_PX
    return np.array([u.min(), v.min(), u.max(), v.max()])


def test_a_signs_truth_box_frames_its_image_not_its_backing(clean_default):
    """A detector's label frames the printed sign; so does the truth box. Every side of an
    upright rectangular sign's box (QR codes, signs, placards not cut along their diamond), in
    view but for 5% at most, lies within 0.75 px (the pixel grid's half pixel and the
    rasteriser's slack) of its image's projected outline; where the backing's edge at the wall,
    3 mm behind the image, would have moved a side by over 1 px, the box is nearer the image's
    outline than the backing's. (A diamond's or a turned square's pointed ends rasterise up to
    1.5 px short.)"""
    sim, frames = clean_default
    placed = {o.id: o for o in sim.objects}
    K = sim.intrinsics
    off, far, off_backing = [], [], []
    for _, ft in frames:
        for v in ft.visible:
            o = placed[v.id]
            x1, y1, x2, y2 = v.box_xyxy
            if o.type not in FLAT_TYPES or o.roll != 0.0 or (o.type == "hazmat" and _cut(o)):
                continue
            if v.visible_fraction < 0.95 or x1 <= 0 or y1 <= 0 or x2 >= K.width or y2 >= K.height:
                continue
            image = _image_box(sim, ft, o, (QUAD_OFFSET_M,))
            with_backing = _image_box(sim, ft, o, (0.0, BACKING_M, QUAD_OFFSET_M))
            off.append(float(np.abs(np.array(v.box_xyxy) - image).max()))
            if float(np.abs(with_backing - image).max()) > 1.0:
                off_backing.append(float(np.abs(np.array(v.box_xyxy) - with_backing).max()))
                far.append(off[-1])
    assert len(off) >= 30 and len(far) >= 5, (len(off), len(far))
    assert max(off) < 0.75, max(off)
    assert all(f < b for f, b in zip(far, off_backing, strict=True)), list(zip(far, off_backing, strict=True))


def test_a_placard_cut_along_its_diamond_reads_fully_visible(clean_default):
    """The unoccluded area of a cut placard is its diamond, not the square around it (which
    would cap its visible fraction near 0.5)."""
    sim, frames = clean_default
    cut = {o.id for o in sim.objects if o.type == "hazmat" and _cut(o)}
    assert cut, "the default scenario has no cut placard to check"
    best = max(v.visible_fraction for _, ft in frames for v in ft.visible if v.id in cut)
    assert 0.9 <= best <= 1.0


def test_every_type_is_visible_on_the_standard_route(clean_default):
    sim, frames = clean_default
    best: dict[int, float] = {}
    for _, ft in frames:
        for v in ft.visible:
            best[v.id] = max(best.get(v.id, 0.0), v.visible_fraction)
    seen_types = {o.type for o in sim.objects if best.get(o.id, 0.0) > 0.5}
    assert seen_types == set(RESCUE_TYPES)
    assert all(best.get(o.id, 0.0) > 0.5 for o in sim.objects), best


def test_every_qr_code_decodes_from_some_frame(clean_default):
    """The tour shows every QR code whole in some frame, and the pipeline's reader reads it there."""
    from poi.detectors.qr import decode_qr

    sim, frames = clean_default
    want = {o.id: o.text for o in sim.objects if o.type == "qr"}
    decoded: dict[int, str] = {}
    for frame, ft in frames:
        for v in ft.visible:
            if v.id not in want or v.id in decoded or v.visible_fraction < 0.9:
                continue
            text = decode_qr(frame.rgb, v.box_xyxy)
            if text:
                decoded[v.id] = text
    assert decoded == want


def test_thermal_sees_heat_source_hot_and_dolls_warm(clean_default):
    sim, frames = clean_default
    hot = [o for o in sim.objects if o.type == "heat-source"][0]
    peak = 0.0
    for frame, ft in frames:
        if any(v.id == hot.id and v.visible_fraction > 0.5 for v in ft.visible):
            peak = max(peak, float(frame.thermal_c.max()))
    assert peak > 55.0  # heat sources are drawn at 60-90 C; area averaging keeps the core hot


def _frame_hash(sc, ks):
    h = hashlib.sha256()
    with Simulation(sc) as sim:
        for k in ks:
            f, _ = sim.frame(k)
            h.update(f.rgb.tobytes())
            h.update(f.depth_m.tobytes())
            h.update(f.thermal_c.tobytes())
            h.update(np.asarray(f.pose).tobytes())
    return h.hexdigest()


def test_same_seed_same_frames_different_seed_different():
    sc = apply_settings(load_scenario("default"), ["sensors.t265.jumps.rate_per_min=2"])
    ks = [0, 37, 120]
    a = _frame_hash(sc, ks)
    assert a == _frame_hash(sc, ks)
    assert a != _frame_hash(apply_settings(sc, ["seed=8"]), ks)


def test_frames_are_independent_of_which_frames_were_rendered():
    sc = load_scenario("default")
    with Simulation(sc) as a:
        f1, _ = a.frame(50)
    with Simulation(sc) as b:
        b.frame(10)
        f2, _ = b.frame(50)
    assert np.array_equal(f1.depth_m, f2.depth_m) and np.array_equal(f1.rgb, f2.rgb)


def test_frames_without_truth_boxes_are_the_same_frames_without_boxes():
    """Switching the truth boxes off (a trial with a trained detector) leaves out the object
    segmentation render and nothing else: the same pixels, depth, thermal image and pose."""
    sc = load_scenario("default")
    with Simulation(sc) as sim:
        k = 280  # a QR code and the heat source in view
        f1, t1 = sim.frame(k)
        sim.truth_boxes = False
        f2, t2 = sim.frame(k)
    assert t1.visible and t1.object_mask is not None
    assert t2.visible == [] and t2.object_mask is None
    assert np.array_equal(f1.rgb, f2.rgb) and np.array_equal(f1.depth_m, f2.depth_m)
    assert np.array_equal(f1.thermal_c, f2.thermal_c) and np.array_equal(f1.pose, f2.pose)


def test_ground_truth_positions_are_in_the_map_frame():
    sc = load_scenario("default")
    with Simulation(sc) as sim:
        # map origin is the robot's start on the floor: the first true base position is (0, 0)
        assert np.allclose(sim.robot_path_map()[0], [0.0, 0.0])
        flat = 0
        for o in sim.truth_objects():
            back = transform_points(sim.T_world_map, o.position_map)
            assert np.allclose(back, reference_point(o.placed))
            assert 0.0 <= o.position_map[2] <= sim.maze.settings.wall_height_m
            if o.type in FLAT_MODEL_TYPES:
                # a sign's reference is its image's centre, QUAD_OFFSET_M out from the wall it hangs on
                flat += 1
                out = back - o.placed.position
                assert np.linalg.norm(out) == pytest.approx(QUAD_OFFSET_M)
                if o.placed.tilt == 0.0:  # on a wall: straight out along its yaw, into the room
                    assert out[:2] @ [np.cos(o.placed.yaw), np.sin(o.placed.yaw)] == pytest.approx(QUAD_OFFSET_M)
            else:
                assert np.allclose(back, o.placed.position)
        assert flat > 0


def test_map_walls_leave_the_door_opening_and_nothing_else(clean_default):
    sim, _ = clean_default
    (door,) = [o for o in sim.truth_objects() if o.type == "door"]
    walls = sim.walls_in_map()
    total = sum(np.hypot(b[0] - a[0], b[1] - a[1]) for a, b in walls)
    full = sum(np.hypot(s.x1 - s.x0, s.y1 - s.y0) for s in sim.maze.wall_segments())
    width = 0.8 + 2 * 0.05  # door_frame_extent_m(0.8 m door): 5 cm of frame each side
    assert door.placed.size_m == pytest.approx(0.8)
    assert total == pytest.approx(full - width, abs=1e-9)

    # the door's centre is in the gap: every wall segment stays at least half the opening away
    def dist(p, a, b):
        a, b, p = np.array(a), np.array(b), np.asarray(p[:2])
        t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        return float(np.linalg.norm(p - (a + t * (b - a))))

    assert min(dist(door.position_map, a, b) for a, b in walls) == pytest.approx(width / 2, abs=0.06)


@pytest.mark.parametrize(
    ("settings", "fields"),
    [
        ([], ["rgb", "depth_m", "thermal_c"]),
        (["sensors.d435.enabled=false"], ["rgb", "thermal_c"]),
        (["sensors.thermal.enabled=false"], ["rgb", "depth_m"]),
    ],
)
def test_the_frame_sensors_are_a_list_in_drawing_order_of_those_switched_on(settings, fields):
    """Colour, then depth, then thermal draw from a frame's generator (sim/sensors/base.py);
    a sensor switched off is not in the list and its Frame field stays None."""
    sc = apply_settings(load_scenario("default"), ["robot.max_duration_s=1", *settings])
    with Simulation(sc) as sim:
        assert [s.frame_field for s in sim.sensors] == fields and sim.sensors[0] is sim.colour
        frame, _ = sim.frame(0)
    for name in ("depth_m", "thermal_c"):
        assert (getattr(frame, name) is not None) == (name in fields)
    assert (frame.thermal_intrinsics is not None) == ("thermal_c" in fields)


def test_the_frame_tells_the_camera_s_turn_as_the_blur_it_rendered():
    """Each frame carries the tracker's gyro rate, and its exposure where the D435 reports one
    (manual exposure only); turned into the colour camera's axes by the mount, they give the
    motion blur the colour stream rendered: in a scan's slew (120 deg/s, frame 244 of the
    default tour, auto-exposure at its 10 ms cap) about 13 px, in a dwell (frame 248) none."""
    from poi.core.motion_blur import camera_motion

    sc = load_scenario("default")
    manual = apply_settings(sc, ["sensors.d435.colour.auto_exposure=false", "sensors.d435.colour.exposure_ms=6"])
    for scenario, exposure_s in ((sc, None), (manual, 0.006)):
        with Simulation(scenario) as sim:
            T = np.array(sim.T_tracker_optical_nominal)
            for k, moving in ((244, True), (248, False)):
                frame, truth = sim.frame(k)
                assert frame.exposure_s == exposure_s
                m = camera_motion(frame, T, 0.010)
                assert m is not None and m.exposures_s[0] == (exposure_s or 0.010)
                got = float(np.hypot(*m.motion_px(frame.intrinsics.ppx, frame.intrinsics.ppy, m.exposures_s[0])))
                if moving:
                    assert truth.blur_px > 0.5 * 12.8 * (exposure_s or 0.010) / 0.010
                    assert got == pytest.approx(truth.blur_px, rel=0.1)
                else:
                    assert truth.blur_px < 0.5 and got < 0.5


def test_a_qr_chart_page_in_view_boxes_its_sheet_and_codes():
    """A QR chart's A4 page (its white sheet and the codes on it) is boxed as one: a detector may
    box it so, and no code's own truth box covers the sheet."""
    sc = with_noise(load_scenario("rmrc"), False)
    with Simulation(sc) as sim:
        charts = {o.text.rsplit(" ", 1)[0] for o in sim.objects if o.page_m is not None}
        frame, truth = sim.frame(640)  # Chart B's page face-on at about 1.5 m (found by touring)
        by_id = {v.id: v for v in truth.visible}
        assert len(truth.pages) == 1
        page = truth.pages[0]
        texts = {by_id[c].text.rsplit(" ", 1)[0] for c in page.codes if c in by_id}
        assert len(page.codes) == 3 and len(texts) == 1 and texts <= charts
        codes = np.array([by_id[c].box_xyxy for c in page.codes])
        union = (*codes[:, :2].min(axis=0), *codes[:, 2:].max(axis=0))
        px1, py1, px2, py2 = page.box_xyxy
        # the sheet shows around the codes on every side (the page's margins)
        assert px1 < union[0] and py1 < union[1] and union[2] < px2 and union[3] < py2
        assert page.pixels > sum(by_id[c].pixels for c in page.codes)
    sc_default = with_noise(load_scenario("default"), False)
    with Simulation(sc_default) as sim:
        assert sim.frame(0)[1].pages == [] and not sim._page_codes
