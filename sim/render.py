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

Anisotropic filtering: MuJoCo uploads each texture with trilinear mipmapping
and no anisotropic filtering (``mjr_uploadTexture``, MuJoCo's
``src/render/render_context.c``), so a texture seen at a grazing angle (a QR
code or placard on a side wall seen along a corridor) is sampled from a mip
level chosen by its longer screen-space footprint and smeared across, as no
camera smears it. After the context is made, the texture handles of the model's
decals (:func:`decal_textures`: 2D textures drawn once over their geom, as the
placards, signs and codes are; not the tiled floor, the walls' cube maps or the
sky) are bound and given ``GL_TEXTURE_MAX_ANISOTROPY_EXT`` at the driver's
maximum (``GL_EXT_texture_filter_anisotropic``, [GLAniso]_; core in OpenGL 4.6),
through PyOpenGL. A 20 cm code seen at 65 degrees from 1.2 m: Laplacian variance
69 without, 131 with (issue 57; tests/sim/test_render.py checks the gain). Only
decals, because Mesa's llvmpipe filters anisotropically in software: on every
texture of the default world it made a colour + depth render 16 times the CPU
(13.6 -> 220 ms), on the decals alone 3 % (14.0 ms; bench/bench_aniso.py).
Where the extension is missing the renderer draws as MuJoCo does and says so in
``SceneRenderer.anisotropy_note`` and one ``RuntimeWarning``.

References
----------
Full entries in docs/SOURCES.md.

.. [GLAniso] Khronos, "EXT_texture_filter_anisotropic" OpenGL extension specification
   (registry.khronos.org/OpenGL/extensions/EXT/EXT_texture_filter_anisotropic.txt).
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np

from sim.gl import RenderingUnavailableError, missing_backend_message

GL_TEXTURE_MAX_ANISOTROPY_EXT = 0x84FE  # [GLAniso] "New Tokens"
GL_MAX_TEXTURE_MAX_ANISOTROPY_EXT = 0x84FF
ANISOTROPY_EXTENSIONS = ("GL_EXT_texture_filter_anisotropic", "GL_ARB_texture_filter_anisotropic")


def _gl_extensions() -> set[str]:
    """The current context's OpenGL extension names (empty if they cannot be read)."""
    from OpenGL import GL  # imported here: PyOpenGL picks its platform from PYOPENGL_PLATFORM (sim.gl)

    try:
        names = GL.glGetString(GL.GL_EXTENSIONS)
        if names:
            return {n.decode("ascii", "replace") for n in names.split()}
        count = int(GL.glGetIntegerv(GL.GL_NUM_EXTENSIONS))  # core profiles list them one by one
        return {GL.glGetStringi(GL.GL_EXTENSIONS, i).decode("ascii", "replace") for i in range(count)}
    except GL.GLError:
        return set()


def decal_textures(model: mujoco.MjModel) -> list[int]:
    """Ids of the model's decal textures: 2D, used by at least one material and by none that
    repeats it (``mat_texrepeat`` (1, 1)), so drawn once over a face as a sign is.

    >>> import mujoco
    >>> m = mujoco.MjModel.from_xml_string('''<mujoco><asset>
    ...   <texture name="sign" type="2d" builtin="checker" width="8" height="8"/>
    ...   <texture name="tiles" type="2d" builtin="checker" width="8" height="8"/>
    ...   <material name="sign" texture="sign"/><material name="floor" texture="tiles" texrepeat="4 4"/>
    ...   </asset><worldbody/></mujoco>''')
    >>> decal_textures(m)
    [0]
    """
    two_d = int(mujoco.mjtTexture.mjTEXTURE_2D)
    out = []
    for i in range(model.ntex):
        mats = [j for j in range(model.nmat) if i in model.mat_texid[j]]
        if int(model.tex_type[i]) == two_d and mats and all(np.all(model.mat_texrepeat[j] == 1.0) for j in mats):
            out.append(i)
    return out


def enable_anisotropic_filtering(
    ctx: mujoco.MjrContext, texture_ids: list[int] | None = None
) -> tuple[float, str | None]:
    """Set textures of ``ctx`` to the driver's maximum anisotropy; (that maximum, note).

    Call with ``ctx``'s OpenGL context current. Binds each handle in
    ``ctx.texture`` at ``texture_ids`` (default: all ``ctx.ntexture``) to its target
    (2D, or cube map for MuJoCo's cube and skybox textures, ``ctx.textureType``) and sets
    ``GL_TEXTURE_MAX_ANISOTROPY_EXT`` to ``GL_MAX_TEXTURE_MAX_ANISOTROPY_EXT``
    ([GLAniso]_ "New State"). Fails soft: where PyOpenGL or the extension is
    missing nothing is changed and the result is (1.0, a one-line note saying why).
    """
    try:
        from OpenGL import GL
    except ImportError as err:  # PyOpenGL comes with mujoco's viewer; a bare install may lack it
        return 1.0, f"anisotropic filtering off: PyOpenGL is not importable ({err})"
    try:
        if not set(ANISOTROPY_EXTENSIONS) & _gl_extensions():
            return 1.0, "anisotropic filtering off: the OpenGL driver lacks GL_EXT_texture_filter_anisotropic"
        max_aniso = float(GL.glGetFloatv(GL_MAX_TEXTURE_MAX_ANISOTROPY_EXT))
        if not max_aniso > 1.0:
            return 1.0, f"anisotropic filtering off: the driver's maximum anisotropy is {max_aniso}"
        cube = int(mujoco.mjtTexture.mjTEXTURE_CUBE), int(mujoco.mjtTexture.mjTEXTURE_SKYBOX)
        ids = range(ctx.ntexture) if texture_ids is None else texture_ids
        for i in ids:
            target = GL.GL_TEXTURE_CUBE_MAP if int(ctx.textureType[i]) in cube else GL.GL_TEXTURE_2D
            GL.glBindTexture(target, int(ctx.texture[i]))
            GL.glTexParameterf(target, GL_TEXTURE_MAX_ANISOTROPY_EXT, max_aniso)
            GL.glBindTexture(target, 0)
    except Exception as err:  # any GL failure (no current context, a driver error) leaves MuJoCo's filtering
        first_line = (str(err).splitlines() or [""])[0]
        return 1.0, f"anisotropic filtering off: {type(err).__name__}: {first_line}"
    return max_aniso, None


class SceneRenderer:
    """Headless renderer for one fixed camera of a model (tests/sim/test_render.py checks it
    against ``mujoco.Renderer``).

    ``anisotropic``: the decal textures filtered anisotropically at the driver's
    maximum (module docstring), or ``"all"`` the textures; False draws exactly as
    ``mujoco.Renderer`` does.
    ``max_anisotropy`` is what was set (1.0: none) and ``anisotropy_note`` why
    not, when it was asked for and could not be set.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int,
        height: int,
        camera: str,
        max_geom: int = 10000,
        *,
        anisotropic: bool | str = True,
    ) -> None:
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
        try:  # no EGL or OSMesa (or no device for them): one line that says what to install
            self._gl = mujoco.GLContext(width, height)
            self._gl.make_current()
            self._ctx = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        except (ImportError, OSError, AttributeError, RuntimeError, mujoco.FatalError) as err:
            raise RenderingUnavailableError(missing_backend_message(err)) from err
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
        self._ctx.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self.max_anisotropy, self.anisotropy_note = 1.0, None
        if anisotropic not in (True, False, "all"):
            raise ValueError(f"anisotropic: expected True, False or 'all', got {anisotropic!r}")
        if anisotropic:
            ids = None if anisotropic == "all" else decal_textures(model)
            self.max_anisotropy, self.anisotropy_note = enable_anisotropic_filtering(self._ctx, ids)
            if self.anisotropy_note is not None:
                warnings.warn(self.anisotropy_note, RuntimeWarning, stacklevel=2)
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

    def geom_segmentation(self, width: int | None = None, height: int | None = None) -> np.ndarray:
        """(h, w) int32 geom id per pixel, -1 where no geom (or a non-geom decoration) is drawn.

        ``width``/``height`` default to the colour size; a smaller size with the
        same aspect gives the same view at a coarser sampling. With an MSAA buffer
        (``offsamples`` > 0) a driver may average the samples' ID colours where two
        geoms meet; a code beyond every segid is then read as no geom (-1).
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
        lut = self._segid_to_geom()
        # IDCOLOR writes segid + 1 as 24-bit little-endian RGB; 0 is background. With fewer than
        # 2^16 codes the blue byte is always 0 and two bytes make the code (half the work)
        if lut.size <= 1 << 16:
            code = buf[::-1, :, 1].astype(np.uint16)  # (h, w)
            code <<= 8
            code |= buf[::-1, :, 0]
        else:
            code = buf[::-1, :, 0].astype(np.int32)
            code |= buf[::-1, :, 1].astype(np.int32) << 8
            code |= buf[::-1, :, 2].astype(np.int32) << 16
        # a code past the last segid names no geom (lut[-1]): MSAA resolved by averaging the samples
        # (NVIDIA's EGL driver does; llvmpipe does not) blends two geoms' codes at their common edge
        return lut.take(code, mode="clip")

    def _segid_to_geom(self) -> np.ndarray:
        scn = self._scene
        lut = np.full(scn.ngeom + 2, -1, dtype=np.int32)  # [0]: background, [-1]: no segid
        geom_type = int(mujoco.mjtObj.mjOBJ_GEOM)
        for g in scn.geoms[: scn.ngeom]:
            if g.segid >= 0 and g.objtype == geom_type:
                lut[g.segid + 1] = g.objid
        return lut
