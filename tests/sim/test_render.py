"""sim.render.SceneRenderer against mujoco.Renderer, and the streamed frames against single ones."""

# isort: off
import sim.gl  # noqa: F401  (sets MUJOCO_GL before mujoco is imported)
import mujoco

# isort: on
import numpy as np
import pytest

from sim.render import SceneRenderer
from sim.scenario import apply_settings, load_scenario
from sim.simulator import Simulation
from sim.world.world import CAMERA_NAME

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI


@pytest.fixture(scope="module")
def default_sim():
    # the earlier sweeping tour (robot.pan.mode: sweep), whose frames these comparisons were built on
    with Simulation(apply_settings(load_scenario("default"), ["robot.pan.mode=sweep"])) as sim:
        yield sim


def _both(sim: Simulation, k: int):
    """(ours, mujoco.Renderer's) colour, depth and geom segmentation of frame k, on the GL thread."""

    def job():
        m, d = sim.world.model, sim.world.data
        sim._set_camera(k)
        # anisotropic filtering off: mujoco.Renderer filters as MuJoCo uploads (trilinear only)
        ours = SceneRenderer(m, 640, 480, CAMERA_NAME, anisotropic=False)
        try:
            ours.update(d)
            rgb, z = ours.color_depth()
            seg = ours.geom_segmentation()
            small = ours.geom_segmentation(160, 120)
        finally:
            ours.close()
        with mujoco.Renderer(m, 480, 640) as r:
            r.update_scene(d, CAMERA_NAME)
            rgb0 = r.render().copy()
            r.enable_depth_rendering()
            r.update_scene(d, CAMERA_NAME)
            z0 = r.render().copy()
            r.disable_depth_rendering()
            r.enable_segmentation_rendering()
            r.update_scene(d, CAMERA_NAME)
            s0 = r.render().copy()
        seg0 = np.where(s0[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM), s0[..., 0], -1)
        return (rgb, z, seg, small), (rgb0, z0, seg0)

    return sim.on_gl_thread(job)


@pytest.mark.parametrize("k", [0, 300])
def test_one_pass_matches_mujoco_renderer(default_sim, k):
    (rgb, z, seg, small), (rgb0, z0, seg0) = _both(default_sim, k)
    assert np.array_equal(rgb, rgb0)
    assert np.array_equal(seg, seg0)
    # depth of one rasterisation, converted in float32: same metres to 5e-6 relative wherever
    # geometry is drawn (the colour pass also draws the sky, at hundreds of metres, where the
    # segmentation-flagged depth pass reads the far plane; both are far beyond any sensor's range)
    geom = seg0 >= 0
    assert geom.mean() > 0.5
    assert np.max(np.abs(z[geom] - z0[geom]) / z0[geom]) < 5e-6
    assert np.all(z[~geom] > 100.0) and np.all(z0[~geom] > 100.0)
    # a quarter-size segmentation is the same view sampled coarser: pixel (i, j) covers
    # full-size pixels 4i..4i+3, so it agrees with one of them (only edges can differ, and
    # geoms thinner than a pixel, as the hall's far trusses and lamps, may fall between samples)
    agree = np.zeros(small.shape, bool)
    for di in range(4):
        for dj in range(4):
            agree |= small == seg[di::4, dj::4]
    assert agree.mean() > 0.995


def test_the_segmentation_pass_gives_each_pixels_object_from_its_geom(default_sim):
    seg = default_sim.on_gl_thread(lambda: default_sim._render_segmentation(300))
    lut = np.append(default_sim.world.geom_box_object_id, -1)
    assert np.array_equal(seg.object_ids, lut[seg.geom_ids])
    assert (seg.object_ids >= 0).any()


def test_renderer_refuses_sizes_it_cannot_draw(default_sim):
    m = default_sim.world.model
    with pytest.raises(ValueError, match="offscreen buffer"):
        SceneRenderer(m, 4000, 480, CAMERA_NAME)
    with pytest.raises(ValueError, match="no camera named"):
        SceneRenderer(m, 640, 480, "nope")


def test_streamed_frames_equal_single_frames(default_sim):
    sim = default_sim
    ks = range(40, 47)
    streamed = list(sim.frames(40, 47))
    for k, (f, t) in zip(ks, streamed, strict=True):
        f1, t1 = sim.frame(k)
        assert f.index == k
        for a, b in ((f.rgb, f1.rgb), (f.depth_m, f1.depth_m), (f.thermal_c, f1.thermal_c), (f.pose, f1.pose)):
            assert np.array_equal(a, b)
        assert [(v.id, v.box_xyxy, v.pixels) for v in t.visible] == [
            (v.id, v.box_xyxy, v.pixels) for v in t1.visible
        ]


def test_a_closed_simulation_says_so():
    sim = Simulation(load_scenario("default"))
    sim.close()
    with pytest.raises(RuntimeError, match="closed"):
        sim.frame(0)
    with pytest.raises(RuntimeError, match="closed"):
        next(sim.frames())
    with pytest.raises(IndexError, match="out of range"):
        Simulation(load_scenario("default")).frame(10**6)


def _silhouette(slices: tuple[int, int]) -> np.ndarray:
    """The (240, 320) mask of a cylinder seen end on (its cap a disc 60 px in radius, 1 m
    away), tessellated ``slices``."""
    xml = f"""<mujoco><visual><global offwidth="320" offheight="240"/>
      <quality offsamples="0" numslices="{slices[0]}" numstacks="{slices[1]}"/></visual>
      <worldbody><camera name="c" pos="0 0 0" xyaxes="1 0 0 0 1 0" fovy="60"/>
      <geom type="cylinder" size="0.29 0.1" pos="0 0 -1.1"/></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    with SceneRenderer(m, 320, 240, "c") as r:
        r.update(d)
        return r.geom_segmentation() >= 0


def test_round_geoms_keep_their_silhouette_within_the_tessellation_bound():
    """sim.world's coarser tessellation of round geoms (issue 18: a capsule costs a fifth of the
    render CPU) moves a silhouette r pixels in radius by at most r (1 - cos(pi / slices)), the
    gap between a circle and its inscribed polygon, plus a pixel of rasterisation."""
    from sim.world.world import CURVE_SLICES, CURVE_STACKS

    fine, coarse = _silhouette((28, 16)), _silhouette((CURVE_SLICES, CURVE_STACKS))
    # the cap: radius 0.29 m at 1 m, focal length 120 px / tan(30 deg): 60.3 px
    r_px = 0.29 / np.tan(np.radians(30.0)) * 120.0
    assert abs(fine.sum() - np.pi * r_px**2) < 0.02 * np.pi * r_px**2
    changed = fine ^ coarse
    assert changed.any()  # the tessellations differ, so the check below means something
    ys, xs = np.nonzero(changed)
    dist_from_rim = np.abs(np.hypot(xs + 0.5 - 160.0, ys + 0.5 - 120.0) - r_px)
    assert dist_from_rim.max() <= r_px * (1.0 - np.cos(np.pi / CURVE_SLICES)) + 1.0


def _oblique_code(anisotropic: bool, angle_deg: float = 65.0, dist_m: float = 1.2) -> tuple[np.ndarray, float]:
    """(grey pixels, the renderer's max_anisotropy) of a 20 cm maze QR card (bench/bench_qr.py's
    scene, clean render, no colour model) seen ``angle_deg`` off its normal, about the
    vertical, from ``dist_m``."""
    import importlib.util
    import math
    from pathlib import Path

    import cv2

    from sim.camera import d435_intrinsics
    from sim.world.world import LAMP_WHITE_LEVEL

    spec = importlib.util.spec_from_file_location("bench_qr", Path(__file__).parents[2] / "bench" / "bench_qr.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    d = load_scenario("default").sensors.d435
    intr = d435_intrinsics(d.width, d.height, d.fx, d.fy, d.ppx, d.ppy)
    xml, files = bench.build_scene(["Chart M"], 0.20, intr, LAMP_WHITE_LEVEL["bright"])
    m = mujoco.MjModel.from_xml_string(xml, files)
    data = mujoco.MjData(m)
    a = math.radians(angle_deg)
    data.mocap_pos[0] = [dist_m * math.cos(a), dist_m * math.sin(a), 0.0]
    data.mocap_quat[0] = [math.cos((a + math.pi) / 2), 0.0, 0.0, math.sin((a + math.pi) / 2)]
    mujoco.mj_forward(m, data)
    cam = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "d435")
    with SceneRenderer(m, intr.width, intr.height, "d435", anisotropic=anisotropic) as r:
        r.update(data)
        rgb, _z = r.color_depth()
    corners = np.array([[0, -0.1, 0.1], [0, 0.1, 0.1], [0, 0.1, -0.1], [0, -0.1, -0.1]], float)
    uv = bench.project(corners, data.cam_xpos[cam], data.cam_xmat[cam].reshape(3, 3), intr)
    (x1, y1), (x2, y2) = np.floor(uv.min(axis=0)).astype(int) + 2, np.ceil(uv.max(axis=0)).astype(int) - 2
    return cv2.cvtColor(rgb[y1:y2, x1:x2], cv2.COLOR_RGB2GRAY), r.max_anisotropy


def test_anisotropic_filtering_sharpens_an_oblique_code():
    """Issue 57: MuJoCo's trilinear-only textures smear a code seen along a corridor. Measured
    here (llvmpipe, 16x): Laplacian variance inside the card 69 -> 131 at 65 degrees from
    1.2 m; the test asks for 1.4x, well clear of the 1.0 it would be without the setting."""
    import cv2

    (flat, one), (crisp, most) = _oblique_code(False), _oblique_code(True)
    assert one == 1.0 and most > 1.0
    sharp = [cv2.Laplacian(g.astype(np.float64), cv2.CV_64F).var() for g in (flat, crisp)]
    assert sharp[1] > 1.4 * sharp[0], sharp


def test_anisotropic_filtering_fails_soft_without_the_extension(monkeypatch):
    import sim.render

    monkeypatch.setattr(sim.render, "_gl_extensions", lambda: set())
    with pytest.warns(
        RuntimeWarning, match="anisotropic filtering off: .*lacks GL_EXT_texture_filter_anisotropic"
    ):
        flat, most = _oblique_code(True)
    assert most == 1.0
    assert np.array_equal(flat, _oblique_code(False)[0])


def test_a_gl_context_that_cannot_be_made_is_rendering_unavailable(monkeypatch):
    """EGL present but no device for it (MuJoCo raises RuntimeError): one line naming what to install."""
    import mujoco

    from sim.gl import RenderingUnavailableError

    def no_display(*args, **kwargs):
        raise RuntimeError(
            "Cannot initialize a EGL device display. This likely means that your EGL driver\ndoes not"
        )

    monkeypatch.setattr(mujoco, "GLContext", no_display)
    m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><camera name="c"/></worldbody></mujoco>')
    with pytest.raises(
        RenderingUnavailableError, match=r"\(RuntimeError: Cannot initialize a EGL device display"
    ) as e:
        SceneRenderer(m, 64, 48, "c")
    assert "\n" not in str(e.value) and "apt-get install libosmesa6" in str(e.value)


def test_a_blended_segmentation_code_reads_as_no_geom(monkeypatch):
    """A driver that resolves MSAA by averaging (NVIDIA's EGL: a dataset render read code 319 in
    a scene of 299 segids) blends two geoms' ID colours at their edge; a code beyond every segid
    is no geom (-1), the pixels around it keep their geoms."""
    xml = """<mujoco><visual><global offwidth="64" offheight="48"/></visual>
      <worldbody><camera name="c" pos="0 0 0" xyaxes="1 0 0 0 1 0" fovy="60"/>
      <geom name="a" type="box" size="3 3 0.1" pos="0 0 -1.5"/></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    read = mujoco.mjr_readPixels

    def blended(rgb, depth, rect, ctx):
        read(rgb, depth, rect, ctx)
        rgb[-1, 0] = (0xFF, 0x7F, 0)  # the code of the top-left pixel (rows run bottom-up): 0x7FFF

    with SceneRenderer(m, 64, 48, "c") as r:
        r.update(d)
        clean = r.geom_segmentation()
        monkeypatch.setattr(mujoco, "mjr_readPixels", blended)
        seg = r.geom_segmentation()
    assert clean[0, 0] == m.geom("a").id
    assert seg[0, 0] == -1
    assert np.array_equal(seg[1:], clean[1:]) and np.array_equal(seg[0, 1:], clean[0, 1:])
