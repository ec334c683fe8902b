"""The in-view test: whether a ground-truth view shows an object well enough for a perfect
detector to box it (:func:`boxable_view`).

The oracle detector boxes what passes it (sim/oracle.py) and the funnel's first stage counts
the frames that do (eval/scoring/funnel.py; docs/RULES.md "The funnel"): one test, so that an
object the oracle could never box is lost to the tour and not to perception. (The goal
arena's oracle keeps boxes down to 4 px, ``sim.oracle.ARENA_MIN_BOX_PX``; the funnel counts
from 12.)

A view passes with a box of ``IN_VIEW_MIN_PX`` or more on its shorter side and
``IN_VIEW_FRACTION`` of the object visible (the rest hidden by walls, other objects or the
image's border). A share of the object is the wrong measure for what the image's border cuts
off close by: a door 0.6 m away fills the 640x480 frame with 26% of itself (the first maze
of the ``smoke`` suite), a doll lying at the frame's bottom corner shows 26% of itself in a
173 x 106 px box (``rrl-09``), and the shipped detector boxed both (IoU 0.54-0.99 with their
truth boxes) and scored them. So a view whose visible pixels make a large object in COCO's
sense ([COCO2014]_: an area of 96 x 96 px or more, ``IN_VIEW_LARGE_PX``) also passes, whatever
share of the object that is, for a type whose identity needs nothing read off its face: a
part of a placard, a code or a target does not say which it is.

A training dataset labels by thresholds of its own (``DatasetSpec``: 30% visible, 4 px) and
leaves the large views below them out of training and evaluation, as regions neither wanted
nor penalised (eval/detector/dataset.py).

References
----------
Full entries in docs/SOURCES.md.

.. [COCO2014] T.-Y. Lin et al., "Microsoft COCO: Common Objects in Context", ECCV 2014 (its
   detection evaluation's area ranges: small up to 32^2 px, large from 96^2 px).
"""

from __future__ import annotations

from poi.core.names import TEXT_IDENTITY_TYPES

IN_VIEW_FRACTION = 0.35  # of the object visible
IN_VIEW_MIN_PX = 12.0  # the visible box's shorter side
IN_VIEW_LARGE_PX = 96 * 96  # visible pixels of a large view ([COCO2014]), for types read off no face


def boxable_view(
    type_: str,
    *,
    visible_fraction: float,
    pixels: int,
    min_side_px: float,
    min_visible_fraction: float = IN_VIEW_FRACTION,
    min_large_pixels: int = IN_VIEW_LARGE_PX,
    min_box_px: float = IN_VIEW_MIN_PX,
) -> bool:
    """The test of the module docstring for one view of an object of type ``type_``: the share
    of it visible, its visible pixels, its visible box's shorter side.

    >>> frame_filling = dict(visible_fraction=0.26, pixels=640 * 480, min_side_px=480.0)
    >>> boxable_view("door", **frame_filling), boxable_view("hazmat", **frame_filling)
    (True, False)
    >>> boxable_view("valve", visible_fraction=0.35, pixels=100, min_side_px=11.0)
    False
    """
    if min_side_px < min_box_px:
        return False
    if visible_fraction >= min_visible_fraction:
        return True
    return type_ not in TEXT_IDENTITY_TYPES and pixels >= min_large_pixels
