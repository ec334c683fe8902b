"""A small MJCF builder: the scene is built in code as an XML tree plus in-memory assets.

Textures are drawn procedurally (numpy RGB arrays), encoded to PNG and handed to
``mujoco.MjModel.from_xml_string`` in its ``assets`` dict, so nothing is written
to disk and the model is a pure function of the scenario.

>>> a = SceneAssets()
>>> a.texture("hazmat_oxidizer", np.zeros((4, 4, 3), np.uint8))
'hazmat_oxidizer'
>>> a.material("m_oxidizer", texture="hazmat_oxidizer")
'm_oxidizer'
>>> sorted(a.files)
['hazmat_oxidizer.png']
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import cv2
import numpy as np


def fmt(values) -> str:
    """Format numbers for an MJCF attribute, compactly and deterministically."""
    if np.isscalar(values):
        values = [values]
    return " ".join(f"{float(v):.6g}" for v in values)


class SceneAssets:
    """Collects <texture>, <material> and <mesh> elements and their PNG bytes."""

    def __init__(self) -> None:
        self.asset = ET.Element("asset")
        self.files: dict[str, bytes] = {}
        self._names: set[str] = set()

    def _claim(self, name: str) -> None:
        if name in self._names:
            raise ValueError(f"asset name {name!r} used twice")
        self._names.add(name)

    def has(self, name: str) -> bool:
        return name in self._names

    def texture(self, name: str, rgb: np.ndarray, kind: str = "2d") -> str:
        """Register an RGB uint8 image (H, W, 3) as a texture named ``name``.

        ``kind`` ``2d`` is mapped by the geom's local x and y (planes, meshes with texcoords);
        ``cube`` puts the image on each face of a box, fitted to the face.
        """
        if kind not in ("2d", "cube"):
            raise ValueError(f"texture {name!r}: kind must be 2d or cube, got {kind!r}")
        if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"texture {name!r}: expected uint8 (H, W, 3), got {rgb.dtype} {rgb.shape}")
        self._claim(name)
        ok, png = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        if not ok:
            raise RuntimeError(f"texture {name!r}: PNG encoding failed")
        fname = f"{name}.png"
        self.files[fname] = png.tobytes()
        ET.SubElement(self.asset, "texture", name=name, type=kind, file=fname)
        return name

    def material(
        self,
        name: str,
        *,
        texture: str | None = None,
        rgba=(1.0, 1.0, 1.0, 1.0),
        specular: float = 0.1,
        shininess: float = 0.1,
        reflectance: float = 0.0,
        texrepeat=None,
        texuniform: bool = False,
    ) -> str:
        """Register a material; returns its name."""
        self._claim(name)
        attrs = {
            "name": name,
            "rgba": fmt(rgba),
            "specular": fmt(specular),
            "shininess": fmt(shininess),
            "reflectance": fmt(reflectance),
        }
        if texture is not None:
            attrs["texture"] = texture
        if texrepeat is not None:
            attrs["texrepeat"] = fmt(texrepeat)
        if texuniform:
            attrs["texuniform"] = "true"
        ET.SubElement(self.asset, "material", **attrs)
        return name

    def mesh(self, name: str, vertices: np.ndarray, faces: np.ndarray, texcoords=None) -> str:
        """Register a mesh from vertices (N, 3), triangle faces (M, 3) and optional UVs (N, 2)."""
        self._claim(name)
        attrs = {
            "name": name,
            "vertex": fmt(np.asarray(vertices, dtype=float).ravel()),
            "face": " ".join(str(int(i)) for i in np.asarray(faces).ravel()),
        }
        if texcoords is not None:
            attrs["texcoord"] = fmt(np.asarray(texcoords, dtype=float).ravel())
        ET.SubElement(self.asset, "mesh", **attrs)
        return name
