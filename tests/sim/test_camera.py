"""The MuJoCo camera reproduces RealSense intrinsics: a point projects where K says."""

import mujoco  # noqa: E402
import numpy as np
import pytest

import sim.gl  # noqa: F401  (sets MUJOCO_GL before mujoco is imported)
from poi.core.geometry import make_transform, transform_points  # noqa: E402
from sim.camera import T_RIG_OPTICAL, d435_intrinsics, mujoco_camera_attrs  # noqa: E402

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI


def _render_segmentation(intr, point_world, rig_pos):
    attrs = " ".join(f'{k}="{v}"' for k, v in mujoco_camera_attrs(intr).items())
    xml = f"""<mujoco><visual><global offwidth="{intr.width}" offheight="{intr.height}"/>
    <quality offsamples="0"/></visual><worldbody><light pos="0 0 3"/>
    <geom name="dot" type="sphere" size="0.004" pos="{" ".join(map(str, point_world))}"/>
    <body name="rig" mocap="true" pos="{" ".join(map(str, rig_pos))}"><camera name="cam" {attrs}/></body>
    </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    with mujoco.Renderer(m, intr.height, intr.width) as r:
        r.enable_segmentation_rendering()
        r.update_scene(d, "cam")
        return r.render()[..., 0]


def test_point_projects_to_intrinsics_pixel():
    intr = d435_intrinsics()
    rig = np.array([0.0, 0.0, 1.0])
    T_world_optical = make_transform(np.eye(3), rig) @ T_RIG_OPTICAL
    for p_c in ([0.3, 0.2, 2.0], [-0.4, -0.25, 1.5], [0.0, 0.0, 3.0]):
        p_w = transform_points(T_world_optical, np.array(p_c))
        seg = _render_segmentation(intr, p_w, rig)
        ys, xs = np.nonzero(seg == 0)
        assert len(xs) > 0
        u = intr.fx * p_c[0] / p_c[2] + intr.ppx
        v = intr.fy * p_c[1] / p_c[2] + intr.ppy
        # a sphere's image centroid sits within a tenth of a pixel of its centre's
        # projection at these distances; 0.25 px allows for rasterisation
        assert abs(xs.mean() - u) < 0.25, (xs.mean(), u)
        assert abs(ys.mean() - v) < 0.25, (ys.mean(), v)
