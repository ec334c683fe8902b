"""One OpenGL pass for colour and depth, and a segmentation pass at any smaller size.

``mujoco.Renderer`` renders the scene once per image kind (colour, depth,
segmentation) and does its conversions in float64 with several temporaries. A
D435 frame needs colour and depth of the *same* rasterisation, so here one
``mjr_render`` fills the colour and depth buffers and one ``mjr_readPixels``
reads both. The segmentation pass reuses the same ``mjvScene`` (no second
scene update) and may draw into a smaller viewport: with a camera defined by
its intrinsics the frustum does not depend on the viewport, so a W/s x H/s
render is the same view sampled s times more coarsely (the thermal camera uses
this).

Depth: MuJoCo renders with reversed Z (``mjDEPTH_ZEROFAR``): the stored value
is b = c + d / z with c = n / (f - n) and d = f n / (f - n) for the near and far
planes n, f (the glFrustum matrix remapped to [1, 0]); so z = d / (b + c)
(OpenGL 4.5 core spec, 13.8; the same mapping ``mujoco.Renderer`` inverts).
Done in float32 it differs from ``mujoco.Renderer``'s float64 conversion by a
few parts in a million (measured under 2e-6: micrometres at the D435's
range), far below any sensor noise; background (b = 0) reads z = f.
"""

from __future__ import annotations

import mujoco
import numpy as np

import sim.gl  # noqa: F401


class SceneRenderer:
    """Headless renderer for one fixed camera of a model (tests/sim/test_render.py checks it
    against ``mujoco.Renderer``)."""

    def __init__(self, model: mujoco.MjModel, width: int, height: int, camera: str, max_geom: int = 10000) -> None:
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise ValueError(
                f"image {width}x{height} is larger than the model's offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}"
            )
        cam_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if cam_id < 0:
            raise ValueError(f"the model has no camera named {camera!r}")
        self.model = model
        self.width, self.height = width, height
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._camera.fixedcamid = cam_id
        self._option = mujoco.MjvOption()
        self._scene = mujoco.MjvScene(model, maxgeom=max_geom)
        self._gl = mujoco.GLContext(width, height)
        self._gl.make_current()
        self._ctx = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
        self._ctx.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self._rgb = np.empty((height, width, 3), dtype=np.uint8)
        self._depth = np.empty((height, width), dtype=np.float32)
        extent = model.stat.extent
        n = np.float32(model.vis.map.znear * extent)
        f = np.float32(model.vis.map.zfar * extent)
        self._c = np.float32(n / (f - n))
        self._d = np.float32(f * n / (f - n))
        self.far_m = float(f)

    def close(self) -> None:
        if self._ctx is not None:
            self._gl.make_current()
            self._ctx.free()
            self._ctx = None
            self._gl.free()

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def update(self, data: mujoco.MjData) -> None:
        """Build the scene from ``data`` (after ``mj_kinematics``/``mj_camlight``)."""
        self._gl.make_current()
        mujoco.mjv_updateScene(
            self.model, data, self._option, None, self._camera, mujoco.mjtCatBit.mjCAT_ALL, self._scene
        )

    def color_depth(self) -> tuple[np.ndarray, np.ndarray]:
        """(rgb uint8 (H, W, 3), z-depth float32 metres (H, W)) of one rasterisation; z = far where empty."""
        if self._ctx is None:
            raise RuntimeError("the renderer is closed")
        mujoco.mjr_render(self._rect, self._scene, self._ctx)
        mujoco.mjr_readPixels(self._rgb, self._depth, self._rect, self._ctx)
        rgb = np.ascontiguousarray(self._rgb[::-1])  # OpenGL rows run bottom-up
        z = np.add(self._depth[::-1], self._c)
        np.divide(self._d, z, out=z)
        return rgb, z

    def geom_segmentation(
        self, width: int | None = None, height: int | None = None, relabel: np.ndarray | None = None
    ) -> np.ndarray:
        """(h, w) int32 geom id per pixel, -1 where no geom (or a non-geom decoration) is drawn.

        ``width``/``height`` default to the colour size; a smaller size with the
        same aspect gives the same view at a coarser sampling. ``relabel`` (one
        int32 per geom) maps geom ids to other labels (e.g. object ids) in the
        same gather; -1 stays -1.
        """
        if self._ctx is None:
            raise RuntimeError("the renderer is closed")
        w = self.width if width is None else width
        h = self.height if height is None else height
        if w > self.width or h > self.height:
            raise ValueError(f"segmentation size {w}x{h} exceeds the render size {self.width}x{self.height}")
        flags = self._scene.flags
        saved = flags.copy()
        flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = True
        flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = True
        try:
            rect = mujoco.MjrRect(0, 0, w, h)
            mujoco.mjr_render(rect, self._scene, self._ctx)
            buf = np.empty((h, w, 3), dtype=np.uint8)
            mujoco.mjr_readPixels(buf, None, rect, self._ctx)
        finally:
            np.copyto(flags, saved)
        # IDCOLOR writes segid + 1 as 24-bit little-endian RGB; 0 is background
        code = buf[::-1, :, 0].astype(np.int32)
        code |= buf[::-1, :, 1].astype(np.int32) << 8
        code |= buf[::-1, :, 2].astype(np.int32) << 16
        lut = self._segid_to_geom()
        if relabel is not None:
            lut = np.where(lut >= 0, np.asarray(relabel, dtype=np.int32)[lut], -1).astype(np.int32)
        return lut[code]

    def _segid_to_geom(self) -> np.ndarray:
        scn = self._scene
        lut = np.full(scn.ngeom + 1, -1, dtype=np.int32)
        geom_type = int(mujoco.mjtObj.mjOBJ_GEOM)
        for g in scn.geoms[: scn.ngeom]:
            if g.segid >= 0 and g.objtype == geom_type:
                lut[g.segid + 1] = g.objid
        return lut
