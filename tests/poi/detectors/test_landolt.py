"""The Landolt-C reader (poi/detectors/landolt.py) on drawn targets: each ring's gap direction
read from pixels, and None, never a wrong direction, where the pixels cannot tell."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from maze_assets.landolt import card_side_mm, draw_landolt
from poi.core.landolt import DIRECTIONS_DEG, LandoltSpec, random_orientations
from poi.detectors.landolt import LandoltReaderConfig, read_landolt

SPEC = LandoltSpec()


def orientations_of(reading):
    return [r.orientation_deg for r in reading.rings]


@pytest.mark.parametrize("shift", range(8))
def test_every_direction_on_every_ring(shift):
    # ring k points at direction (shift + k) mod 8: over the 8 shifts every ring takes every direction.
    # 400 px: ring 5's 0.33 mm gap is 2.1 px
    truth = [DIRECTIONS_DEG[(shift + k) % 8] for k in range(SPEC.n_rings)]
    reading = read_landolt(draw_landolt(SPEC, truth, 400))
    assert orientations_of(reading) == truth
    assert all(r.confidence > 0.6 for r in reading.rings)


def test_frame_and_box_give_the_centre_in_frame_pixels():
    truth = (135, 270, 45, 0, 180)
    card = draw_landolt(SPEC, truth, 121)
    frame = np.full((300, 400, 3), 120, np.uint8)
    x0, y0 = 211, 57
    frame[y0 : y0 + 121, x0 : x0 + 121] = card
    reading = read_landolt(frame, (x0, y0, x0 + 121, y0 + 121))
    # the card's centre pixel is (x0 + 60, y0 + 60); the hull fit is within half a pixel
    assert reading.centre_xy == pytest.approx((x0 + 60, y0 + 60), abs=0.5)
    # ring 1's outer diameter: 49 mm of the 63.7 mm card, 121 px wide
    assert np.mean(reading.axes_px) == pytest.approx(121 * 49.0 / card_side_mm(SPEC), abs=1.0)
    assert orientations_of(reading)[:4] == [135, 270, 45, 0]


@pytest.mark.parametrize("turns", range(8))
def test_rotating_the_target_turns_every_reading(turns):
    truth = (0, 90, 225, 315, 45)
    img = draw_landolt(SPEC, truth, 240)
    # cv2's positive angle turns the image counter-clockwise as seen; 10 degrees more stays nearest
    R = cv2.getRotationMatrix2D((119.5, 119.5), 45.0 * turns + 10.0, 1.0)
    turned = cv2.warpAffine(img, R, (240, 240), flags=cv2.INTER_CUBIC, borderValue=(255, 255, 255))
    got = orientations_of(read_landolt(turned))
    assert got[:4] == [(o + 45 * turns) % 360 for o in truth[:4]]
    assert got[4] in (None, (truth[4] + 45 * turns) % 360)


def test_scale_blur_noise_and_a_squashed_view():
    rng = np.random.default_rng(7)
    truth = (180, 45, 315, 90, 270)
    img = draw_landolt(SPEC, truth, 200).astype(np.float32)
    img = cv2.resize(img, (150, 150), interpolation=cv2.INTER_AREA)  # ring 3's gap 4.2 px
    img = cv2.GaussianBlur(img, (0, 0), 0.8)
    img = np.clip(img * 0.7 + 30 + rng.normal(0, 6, img.shape), 0, 255).astype(np.uint8)  # grey paper, noise
    got = orientations_of(read_landolt(img))
    assert got[:3] == [180, 45, 315]
    assert all(g in (None, t) for g, t in zip(got, truth, strict=True))
    # seen 35 degrees off the card's normal: the circle is an ellipse 0.82 as wide
    squashed = cv2.resize(img, (123, 150), interpolation=cv2.INTER_AREA)
    got = orientations_of(read_landolt(squashed))
    assert got[:3] == [180, 45, 315]


def test_unreadable_rings_read_none_never_wrong():
    # 40 draws of random targets from 24 to 120 px across, blurred a little and noised: no ring
    # may read a direction other than its own; the rings too small to resolve read None
    rng = np.random.default_rng(11)
    wrong, none_small = 0, 0
    for _ in range(40):
        n = int(rng.integers(24, 121))
        truth = random_orientations(SPEC.n_rings, rng)
        img = cv2.GaussianBlur(draw_landolt(SPEC, truth, n).astype(np.float32), (0, 0), 0.5)
        img = np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
        reading = read_landolt(img)
        assert reading is not None
        for k, r in enumerate(reading.rings):
            wrong += r.orientation_deg is not None and r.orientation_deg != truth[k]
        gap5_px = SPEC.gaps_mm()[4] * n / card_side_mm(SPEC)
        assert gap5_px < 1.0
        none_small += reading.rings[4].orientation_deg is None
    assert wrong == 0
    assert none_small == 40  # ring 5's gap is under a pixel in every draw


def test_the_third_ring_reads_down_to_about_two_pixels_and_not_at_one():
    truth = (0, 135, 225, 90, 315)
    px_per_gap3 = lambda n: SPEC.gaps_mm()[2] * n / card_side_mm(SPEC)  # noqa: E731
    big = 80  # ring 3's gap 2.3 px
    small = 35  # 0.99 px
    assert px_per_gap3(big) == pytest.approx(2.26, abs=0.01) and px_per_gap3(small) < 1.0
    assert read_landolt(draw_landolt(SPEC, truth, big)).rings[2].orientation_deg == 225
    assert read_landolt(draw_landolt(SPEC, truth, small)).rings[2].orientation_deg is None


def test_no_target_and_bad_input():
    assert read_landolt(np.full((80, 80, 3), 255, np.uint8)) is None
    assert read_landolt(np.zeros((80, 80, 3), np.uint8)) is None
    with pytest.raises(ValueError, match="box_xyxy"):
        read_landolt(np.zeros((80, 80, 3), np.uint8), (10, 10, 5, 20))
    with pytest.raises(ValueError, match="expected an RGB"):
        read_landolt(np.zeros((8, 8, 4), np.uint8))
    with pytest.raises(ValueError, match="window_frac"):
        LandoltReaderConfig(window_frac=0.0)


def _frame_with_target(truth, side_px: int, at: tuple[int, int], seed: int = 0):
    """A 480 x 640 grey frame (noise sd 3) with a drawn target's card pasted at ``at`` (x, y), a
    filled black disc and a black ring without a gap beside it (shapes that are not targets)."""
    rng = np.random.default_rng(seed)
    frame = np.clip(rng.normal(140, 3, (480, 640, 3)), 0, 255).astype(np.uint8)
    x0, y0 = at
    frame[y0 : y0 + side_px, x0 : x0 + side_px] = draw_landolt(SPEC, truth, side_px)
    cv2.rectangle(frame, (420, 280), (520, 380), (245, 245, 245), -1)
    cv2.circle(frame, (470, 330), 30, (0, 0, 0), -1)  # a filled disc
    cv2.rectangle(frame, (60, 330), (160, 430), (245, 245, 245), -1)
    cv2.circle(frame, (110, 380), 40, (0, 0, 0), 12)  # an O: a ring with no gap
    return frame


def test_the_finder_finds_the_target_and_reads_it_and_nothing_else():
    from poi.core.landolt import orientation_text
    from poi.core.types import Frame, Intrinsics
    from poi.detectors import build_detector

    truth = (90, 225, 315, 0, 135)
    frame_rgb = _frame_with_target(truth, 121, (250, 60))
    intr = Intrinsics(width=640, height=480, fx=600.0, fy=600.0, ppx=320.0, ppy=240.0)
    frame = Frame(index=0, timestamp_s=0.0, rgb=frame_rgb, depth_m=None, pose=None, intrinsics=intr)
    dets = build_detector({"name": "landolt"}).detect(frame)
    assert len(dets) == 1
    (d,) = dets
    assert (d.type, d.class_name, d.source) == ("landolt-c", "landolt-c", "landolt")
    # a sharp drawn card (121 px): every ring reads, ring 5's 0.6 px gap too
    assert d.text == orientation_text(truth) == "1:N 2:SW 3:SE 4:E 5:NW"
    # the box is the outer ring's: 49 / 63.7 of the card, centred on it
    side = 121 * 49.0 / card_side_mm(SPEC)
    assert d.box_xyxy == pytest.approx((310 - side / 2, 120 - side / 2, 310 + side / 2, 120 + side / 2), abs=1.5)


def test_boxes_without_text_get_their_rings_read_from_pixels():
    from poi.core.types import Detection
    from poi.detectors.landolt import attach_landolt_text

    truth = (180, 45, 270, 90, 0)
    frame = _frame_with_target(truth, 121, (250, 60))
    box = (250.0, 60.0, 371.0, 181.0)
    dets = [
        Detection(
            class_name="landolt-c", type="landolt-c", text="", box_xyxy=box, confidence=0.8, source="oracle"
        ),
        Detection(class_name="landolt-c", type="landolt-c", text="1:E", box_xyxy=box, confidence=0.8, source="x"),
        Detection(class_name="door", type="door", text="", box_xyxy=box, confidence=0.8, source="oracle"),
        # the O ring: no gap reads, so no text
        Detection(
            class_name="landolt-c",
            type="landolt-c",
            text="",
            box_xyxy=(60, 330, 160, 430),
            confidence=0.8,
            source="oracle",
        ),
    ]
    out = attach_landolt_text(frame, dets)
    assert [d.text for d in out] == ["1:W 2:NE 3:S 4:N", "1:E", "", ""]
    assert dets[0].text == ""  # the inputs are not changed
