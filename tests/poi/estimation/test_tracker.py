"""poi.estimation.tracker: Kalman update, gating, pairing, confirmation, pruning, negative update, fusion."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from poi.config import ConfigError, TrackerConfig, apply_overrides, load_config
from poi.core.names import CLASS_INDEX, CLASSES, class_to_identity
from poi.core.types import Detection, Observation
from poi.estimation.covariance import Calibration
from poi.estimation.tracker import (
    Tracker,
    TrackerError,
    kalman_update,
    mahalanobis2,
    observation_probs,
    pair_greedy,
    pair_hungarian,
)

HALF_I = 0.5 * np.eye(3)  # track Sigma = R = 0.5 I makes Sigma + R = I, so m^2 = |o - mu|^2


def obs(xyz, class_name="door", *, R=HALF_I, conf=0.9, text=None, probs=None) -> Observation:
    typ, label = class_to_identity(class_name)
    d = Detection(
        class_name=class_name,
        type=typ,
        text=label if text is None else text,
        box_xyxy=(0, 0, 10, 10),
        confidence=conf,
        class_probs=probs,
    )
    return Observation(
        detection=d,
        timestamp_s=0.0,
        position_map=np.array(xyz, dtype=float),
        R=np.array(R, dtype=float),
        position_cam=np.zeros(3),
        Sigma_c=np.eye(3),
        depth_m=1.0,
    )


def cfg(**kw) -> TrackerConfig:
    """Tracker settings for tests whose R = 0.5 I (std 0.7 m): settling is not what they test,
    nor the gate allowance (the tests' observations are doors)."""
    kw.setdefault("settle_sigma_m", 1.0)
    kw.setdefault("gate_allowance_m", {})
    return TrackerConfig(**kw)


def random_spd(rng: np.random.Generator) -> np.ndarray:
    A = rng.standard_normal((3, 3))
    return A @ A.T + 0.1 * np.eye(3)


def test_kalman_update_matches_filterpy_and_closed_form():
    rng = np.random.default_rng(7)
    for _ in range(5):
        mu, o = rng.standard_normal(3), rng.standard_normal(3)
        Sigma, R = random_spd(rng), random_spd(rng)
        mu1, Sigma1 = kalman_update(mu, Sigma, o, R)
        kf = KalmanFilter(dim_x=3, dim_z=3)
        kf.x, kf.P, kf.H = mu.copy(), Sigma.copy(), np.eye(3)
        kf.update(o, R=R)
        assert np.allclose(mu1, kf.x, atol=1e-10)
        assert np.allclose(Sigma1, kf.P, atol=1e-10)
        # [Avevor2022] 2.4.4 written out with an explicit inverse
        S_inv = np.linalg.inv(Sigma + R)
        assert np.allclose(mu1, mu + Sigma @ S_inv @ (o - mu), atol=1e-10)
        assert np.allclose(Sigma1, Sigma - Sigma @ S_inv @ Sigma, atol=1e-10)


def test_joseph_form_stays_positive_definite_when_r_is_far_below_sigma():
    """A track started from the prior diag(100, 100, 4) and a near-exact observation: the
    difference form Sigma - K Sigma rounds to negative eigenvalues, Joseph's form does not."""
    rng = np.random.default_rng(0)
    Sigma = np.diag([100.0, 100.0, 4.0])
    negative_difference_form = 0
    for _ in range(500):
        A = rng.standard_normal((3, 3))
        R = 1e-12 * A @ A.T + 1e-14 * np.eye(3)
        K = np.linalg.solve(Sigma + R, Sigma).T
        difference = Sigma - K @ Sigma
        negative_difference_form += np.linalg.eigvalsh(0.5 * (difference + difference.T)).min() < 0
        _, Sigma1 = kalman_update(np.zeros(3), Sigma, np.ones(3), R)
        assert np.linalg.eigvalsh(Sigma1).min() > 0.0
    assert negative_difference_form > 0  # the case Joseph's form is for does occur


def test_gate_is_strict():
    # a track at the origin with Sigma = 0.5 I; observations with R = 0.5 I: m^2 = x^2
    assert mahalanobis2(np.array([3.0, 0, 0]), np.zeros(3), HALF_I, HALF_I) == 9.0
    for x, paired in [(3.0, False), (2.999, True)]:
        tr = Tracker(cfg(gate=9.0))
        tr.step([obs([0, 0, 0])], 0.0)
        res = tr.step([obs([x, 0, 0])], 0.1)
        assert (res.pairs == [(0, 0)]) is paired
        assert len(tr.tracks) == (1 if paired else 2)


def test_gate_allowance_widens_the_gate_of_its_type_only_and_leaves_the_fusion_alone():
    # Sigma + R = I at the first update, so m^2 = x^2 / (1 + a^2) with allowance a
    for a, paired in [(0.0, False), (0.6, False), (0.7, True)]:  # 12.25 / 1.36 = 9.007; 12.25 / 1.49 = 8.2
        tr = Tracker(cfg(gate=9.0, gate_allowance_m={"door": a}))
        tr.step([obs([0, 0, 0])], 0.0)
        res = tr.step([obs([3.5, 0, 0])], 0.1)
        assert (res.pairs == [(0, 0)]) is paired, a
    # the pair is fused with R alone: the same mean and Sigma as the Kalman update
    mu, Sigma = kalman_update(np.zeros(3), HALF_I, np.array([3.5, 0.0, 0.0]), HALF_I)
    np.testing.assert_allclose(tr.tracks[0].mu, mu, atol=1e-12)
    np.testing.assert_allclose(tr.tracks[0].Sigma, Sigma, atol=1e-12)
    # another type's gate is not widened
    tr = Tracker(cfg(gate=9.0, gate_allowance_m={"door": 0.7}))
    tr.step([obs([0, 0, 0], "oxidizer")], 0.0)
    assert tr.step([obs([3.5, 0, 0], "oxidizer")], 0.1).pairs == []
    with pytest.raises(ConfigError, match="tracker.gate_allowance_m.cube: unknown type"):
        apply_overrides(load_config(), ["tracker.gate_allowance_m={cube: 0.1}"])
    with pytest.raises(ConfigError, match=r"tracker.gate_allowance_m.door: expected metres in \[0, 10\)"):
        apply_overrides(load_config(), ["tracker.gate_allowance_m={door: -0.1}"])


CRAFTED = np.array(
    [
        [1.0, 2.0, 50.0],
        [2.5, 50.0, 50.0],
        [50.0, 50.0, 3.0],
    ]
)


def test_greedy_follows_the_seed_loop_and_differs_from_hungarian():
    # greedy takes the closest pair (0, 0) first, which leaves observation 1 nothing
    # under the gate; then (2, 2)
    assert pair_greedy(CRAFTED, 9.0) == [(0, 0), (2, 2)]
    # the optimal assignment pairs all three: 2 + 2.5 + 3 = 7.5
    assert pair_hungarian(CRAFTED, 9.0) == [(0, 1), (1, 0), (2, 2)]
    # pairs at or above the gate are removed; the input is not modified
    D = CRAFTED.copy()
    assert pair_greedy(D, 2.2) == [(0, 0)]
    assert pair_hungarian(D, 2.2) == [(0, 0)]
    assert np.array_equal(D, CRAFTED)
    assert pair_greedy(np.zeros((0, 3)), 9.0) == [] == pair_hungarian(np.zeros((2, 0)), 9.0)


def test_tracker_hungarian_option_pairs_more():
    # tracks at x = 0 and x = 4 (m^2 = 16 apart: two objects); observations at x = 1.2
    # and x = -1.5 (m^2 = dx^2). Greedy: (obs 0, track 0) = 1.44 first; obs 1 -> track 1
    # is 30.25 >= 9, so obs 1 is left over inside track 0's gate: a duplicate.
    # Hungarian: (obs 0, track 1) = 7.84 and (obs 1, track 0) = 2.25 pair both.
    for assignment, expect, dup in [
        ("greedy", [(0, 0)], [(1, 0)]),
        ("hungarian", [(0, 1), (1, 0)], []),
    ]:
        tr = Tracker(cfg(assignment=assignment))
        tr.step([obs([0, 0, 0]), obs([4.0, 0, 0])], 0.0)
        res = tr.step([obs([1.2, 0, 0]), obs([-1.5, 0, 0])], 0.1)
        assert sorted(res.pairs) == expect
        assert res.duplicates == dup and len(tr.tracks) == 2


def test_confirmation_at_n_min_with_report_ids_in_order():
    tr = Tracker(cfg(n_min=3))
    confirmed = []
    for k in range(3):
        res = tr.step([obs([0, 0, 0]), obs([10, 0, 0], "valve")] if k else [obs([0, 0, 0])], 0.1 * k)
        confirmed.append([(s.type, s.report_id) for s in res.newly_confirmed])
    assert confirmed == [[], [], [("door", 0)]]
    res = tr.step([obs([10, 0, 0], "valve")], 0.3)
    assert [(s.type, s.report_id, s.n_detections) for s in res.newly_confirmed] == [("valve", 1, 3)]
    # a confirmed track is reported once
    assert tr.step([obs([0, 0, 0])], 0.4).newly_confirmed == []
    assert [s.report_id for s in tr.snapshots(confirmed_only=True)] == [0, 1]


def test_confirmation_waits_for_the_position_to_settle():
    # R = 1 m^2 I: after n updates Sigma = I / n; std 1/sqrt(n) <= 0.3 first at n = 12
    tr = Tracker(cfg(n_min=3, settle_sigma_m=0.3))
    for n in range(1, 13):
        res = tr.step([obs([0, 0, 0], R=np.eye(3))], 0.1 * n)
        assert bool(res.newly_confirmed) is (n == 12)
    assert tr.tracks[0].Sigma == pytest.approx(np.eye(3) / 12)


def test_a_shared_pose_error_does_not_hold_confirmation_back():
    """Settling asks for the fresh part Sigma_w only: a track whose observations share a
    0.5 m pose error (no view of the object removes it) is confirmed at n_min once its fresh
    part is settled; with the same error fresh each frame it waits."""
    fresh = 0.01 * np.eye(3)
    pose = 0.25 * np.eye(3)  # 0.5 m std, shared by every observation of the track

    def shared_obs():
        o = obs([0, 0, 0], R=fresh + pose)
        o.R_shared = pose
        return o

    tr = Tracker(cfg(n_min=3, settle_sigma_m=0.3))
    got = [bool(tr.step([shared_obs()], 0.1 * n).newly_confirmed) for n in range(1, 5)]
    assert got == [False, False, True, False]
    assert tr.tracks[0].max_std_m > 0.3 >= tr.tracks[0].max_fresh_std_m
    # all of it fresh: Sigma = 0.26 I / n settles (std <= 0.3) only from n = 3 on, as before
    tr = Tracker(cfg(n_min=1, settle_sigma_m=0.3))
    got = [bool(tr.step([obs([0, 0, 0], R=fresh + pose)], 0.1 * n).newly_confirmed) for n in range(1, 5)]
    assert got == [False, False, True, False]


@pytest.mark.parametrize("radius", [0.2, 0.0])
def test_a_track_beside_a_better_seen_track_of_another_type_waits_until_it_is_seen_more(radius):
    """One place, one object: a doll track 5 cm from a sign's track is not confirmed while the
    sign's has as many detections (a tie goes to the older track), and is once it has more, when
    the sign's track, confirmed before, is withdrawn (the vote is taken again each frame); a
    doll 0.5 m away is confirmed at n_min. Radius 0 turns the rule off."""
    R = 1e-4 * np.eye(3)  # 1 cm: every track settles, and tracks 5 cm apart do not pair

    def seen(*where):
        return [obs(xyz, name, R=R) for name, xyz in where]

    sign, far_doll, near_doll = (
        ("fire-extinguisher-sign", [0, 0, 0]),
        ("baby-doll", [0.5, 0, 0]),
        ("baby-doll", [0.05, 0, 0]),
    )
    tr = Tracker(cfg(n_min=2, cross_type_radius_m=radius))
    confirmed, withdrawn = [], []
    for k, frame in enumerate(
        [seen(sign, far_doll), seen(sign, far_doll), seen(near_doll), seen(near_doll), seen(near_doll)]
    ):
        step = tr.step(frame, 0.1 * k)
        confirmed.append(sorted((s.type, s.track_id) for s in step.newly_confirmed))
        withdrawn.append(step.withdrawn)
    near = [[], [("baby-doll", 2)], []] if radius == 0 else [[], [], [("baby-doll", 2)]]
    assert confirmed == [[], [("baby-doll", 1), ("fire-extinguisher-sign", 0)], *near]
    assert tr.tracks[2].n_detections == 3 and tr.tracks[0].n_detections == 2
    assert withdrawn == ([[]] * 5 if radius == 0 else [[], [], [], [], [0]])
    assert tr.tracks[0].confirmed == (radius == 0) and tr.tracks[0].report_id == (0 if radius == 0 else None)


def test_the_place_vote_weighs_unsure_boxes_of_another_type_by_their_class_probability():
    """A QR code the detector boxes three times as an extinguisher sign, each box unsure
    (P(sign) 0.55, P(qr) 0.40), and twice as a code (P(qr) 0.95). Counted by detections the
    sign's track would win (two each, the older, then three against two); by class mass the
    place holds 2 x 0.40 + 2 x 0.95 = 2.7 of qr against 2 x 0.55 + 2 x 0.05 = 1.2 of sign after
    two frames (3.1 against 1.75 after three), so the code's track is confirmed and the
    sign's waits."""
    R = 1e-4 * np.eye(3)

    def probs(**p):
        q = np.zeros(len(CLASSES))
        for name, v in p.items():
            q[CLASS_INDEX[name.replace("_", "-")]] = v
        return q / q.sum()

    unsure_sign = probs(fire_extinguisher_sign=0.55, qr=0.40, door=0.05)
    sure_code = probs(qr=0.95, fire_extinguisher_sign=0.05)
    tr = Tracker(cfg(n_min=2, cross_type_radius_m=0.2, fusion="mean"))
    confirmed = []
    for k, frame in enumerate([["sign", "code"], ["sign", "code"], ["sign"]]):
        seen = [
            obs([0, 0, 0], "fire-extinguisher-sign", R=R, probs=unsure_sign)
            if what == "sign"
            else obs([0.05, 0, 0], "qr", R=R, probs=sure_code, text="Chart A")
            for what in frame
        ]
        confirmed += [s.type for s in tr.step(seen, 0.1 * k).newly_confirmed]
    assert confirmed == ["qr"]
    assert tr.tracks[0].type == "fire-extinguisher-sign" and tr.tracks[0].n_detections == 3


@pytest.mark.parametrize(
    ("radius", "target", "text", "guess"),
    [
        (0.2, "landolt-c", "1:N 2:SE 3:E", "corrosive"),
        (0.2, "qr", "Chart D 5mm", "corrosive"),
        (0.2, "qr", "Chart D 5mm", "fire-extinguisher-sign"),
        (0.0, "landolt-c", "1:N 2:SE 3:E", "corrosive"),
    ],
)
def test_a_read_target_withdraws_and_holds_back_the_guesses_at_its_place(radius, target, text, guess):
    """A corrosive placard track boxed on a Landolt-C card (or a QR page; or an extinguisher-sign
    track on a QR page) is confirmed (n_min 2) before the card's rings (the code) read; once a
    track of that type with text lies within the radius, the guess is withdrawn (unconfirmed, its
    report id dropped) however many boxes it has, and a second guess there is not confirmed. A
    guess 0.5 m away is confirmed. Radius 0 turns the one-place rule off, this part with it."""
    R = 1e-4 * np.eye(3)
    card, beside = [1.0, 0.0, 0.5], [1.0, 0.5, 0.5]
    guess_type = "hazmat" if guess == "corrosive" else guess

    def placard(xyz):
        return obs(xyz, guess, R=R)

    rings = obs([1.02, 0.0, 0.5], target, R=R, text=text)
    tr = Tracker(cfg(n_min=2, cross_type_radius_m=radius))
    steps = [tr.step(f, 0.1 * k) for k, f in enumerate([[placard(card)], [placard(card)], [rings], [rings]])]
    assert [s.type for s in steps[1].newly_confirmed] == [guess_type]
    if radius:
        assert steps[2].withdrawn == [0] and not tr.tracks[0].confirmed and tr.tracks[0].report_id is None
        assert [s.type for s in steps[3].newly_confirmed] == [target]
        more = [tr.step([placard([1.0, 0.05, 0.5]), placard(beside)], 0.5 + 0.1 * k) for k in range(3)]
        confirmed = [(s.type, round(float(s.position_map[1]), 2)) for m in more for s in m.newly_confirmed]
        assert confirmed == [(guess_type, 0.5)]
        assert [t.type for t in tr.snapshots(confirmed_only=True)] == [target, guess_type]
    else:
        assert steps[2].withdrawn == [] and tr.tracks[0].confirmed


def test_the_one_place_radius_is_a_setting_refused_out_of_range():
    assert load_config(None).tracker.cross_type_radius_m == 0.2
    assert apply_overrides(load_config(None), ["tracker.cross_type_radius_m=0"]).tracker.cross_type_radius_m == 0
    with pytest.raises(ConfigError, match="cross_type_radius_m"):
        apply_overrides(load_config(None), ["tracker.cross_type_radius_m=-1"])


@pytest.mark.parametrize("radius", [1.0, 0.0])
def test_a_second_track_of_a_read_code_is_not_reported_near_the_first(radius):
    """One code, one report: views of Chart B biased alike start a second QR track 0.19 m from the
    first (1 cm covariances: neither gates the other); with its text read it is not confirmed
    while the first is, as rrl-hard's hard-02 reported the code twice. A code of another text
    beside it, and one of the same text 1.5 m away, are confirmed. Radius 0 turns the rule off."""
    R = 1e-4 * np.eye(3)

    def qr(xyz, text):
        return obs(xyz, "qr", R=R, text=text)

    first, second = qr([0, 0, 0.66], "Chart B"), qr([0.17, -0.09, 0.68], "Chart B")
    beside, far = qr([0.1, 0.0, 0.66], "Chart C"), qr([1.5, 0.0, 0.66], "Chart B")
    tr = Tracker(cfg(n_min=2, same_text_radius_m=radius))
    steps = [
        tr.step(f, 0.1 * k) for k, f in enumerate([[first], [first], [second, beside, far], [second, beside, far]])
    ]
    assert [s.track_id for s in steps[1].newly_confirmed] == [0]
    confirmed = sorted((s.text, round(float(s.position_map[0]), 2)) for s in steps[3].newly_confirmed)
    expected = [("Chart B", 1.5), ("Chart C", 0.1)] + ([("Chart B", 0.17)] if radius == 0 else [])
    assert confirmed == sorted(expected)
    assert len(tr.tracks) == 4 and tr.tracks[1].n_detections == 2  # the second track kept, not reported


@pytest.mark.parametrize(("box", "tracks"), [((40, 0, 60, 20), 2), ((5, 0, 25, 20), 1)])
def test_two_qr_boxes_that_do_not_meet_are_two_codes_not_one_boxed_twice(box, tracks):
    """rmrc's Chart E: codes of 5 and 3 mm modules 13 cm apart, seen unread in one frame, inside
    each other's gate. Boxes apart in the image are two codes, and start two tracks; boxes that
    meet are one code boxed twice (two detectors), the second a duplicate."""
    first = obs([0, 0, 0.75], "qr", text="")
    second = dataclasses.replace(
        obs([0, 0, 0.62], "qr", text=""), detection=dataclasses.replace(first.detection, box_xyxy=box)
    )
    tr = Tracker(cfg())
    step = tr.step([first, second], 0.0)
    assert np.isfinite(tr.distances([second], list(tr.tracks.values()))).all()  # inside the gate
    assert len(tr.tracks) == tracks and len(step.duplicates) == 2 - tracks


def test_tentative_tracks_pruned_after_t_max_confirmed_kept():
    tr = Tracker(cfg(n_min=2, t_max=5.0))
    tr.step([obs([0, 0, 0]), obs([5, 0, 0], "valve")], 0.0)
    tr.step([obs([0, 0, 0])], 0.5)  # the door is confirmed, the valve stays tentative
    assert tr.step([], 5.0).dropped == []  # 5.0 s since last seen: not yet (strictly more)
    assert tr.step([], 5.01).dropped == [1]
    assert tr.step([], 100.0).dropped == []
    assert [s.type for s in tr.snapshots()] == ["door"]


def test_negative_update_kills_a_false_track_but_not_a_confirmed_one():
    tr = Tracker(cfg(n_min=2, miss_penalty=0.5, drop_support=0.0))
    tr.step([obs([0, 0, 0]), obs([5, 0, 0], "valve")], 0.0)  # support 1 each
    tr.step([obs([0, 0, 0])], 0.1)  # door confirmed (support 2)
    supports = []
    for k in range(3):
        res = tr.step([], 0.2 + 0.1 * k, {0, 1})
        supports.append({tid: t.support for tid, t in tr.tracks.items()})
    # valve: 1 -> 0.5 -> 0.0 (not below 0: kept) -> -0.5 dropped; door: 2 -> 0.5, kept
    assert supports[0] == {0: 1.5, 1: 0.5}
    assert supports[1] == {0: 1.0, 1: 0.0}
    assert supports[2] == {0: 0.5}
    assert res.dropped == [1]
    # a track detected this frame is not penalised even if listed as in view
    tr.step([obs([0, 0, 0])], 1.0, {0})
    assert tr.tracks[0].support == 1.5


def test_class_aware_gating():
    tr = Tracker(cfg())
    tr.step([obs([0, 0, 0], "oxidizer")], 0.0)
    # a door at the same place never pairs with a hazmat
    res = tr.step([obs([0, 0, 0], "door")], 0.1)
    assert res.pairs == [] and len(tr.tracks) == 2
    # another hazmat label pairs: the label follows the fused probabilities
    res = tr.step([obs([0, 0, 0], "oxygen", conf=0.6), obs([0, 0, 0], "door")], 0.2)
    assert sorted(res.pairs) == [(0, 0), (1, 1)]
    assert tr.tracks[0].text == "oxidizer"  # mean: oxidizer 0.5 + small, oxygen 0.3 + small
    for k in range(2):
        tr.step([obs([0, 0, 0], "oxygen", conf=0.95)], 0.3 + 0.1 * k)
    assert tr.tracks[0].text == "oxygen"
    assert tr.tracks[0].type == "hazmat"


def test_qr_text_rule():
    tr = Tracker(cfg(n_min=2))
    tr.step([obs([0, 0, 0], "qr", text="Chart A")], 0.0)
    assert tr.step([obs([0, 0, 0], "qr", text="Chart B")], 0.1).pairs == []  # different texts
    assert len(tr.tracks) == 2
    # an empty text pairs with either (the closest; here both at m^2 = 0: the first)
    assert tr.step([obs([0, 0, 0], "qr", text="")], 0.2).pairs == [(0, 0)]
    assert tr.step([obs([0, 0, 0], "qr", text="Chart A")], 0.3).pairs == [(0, 0)]
    assert tr.tracks[0].text_votes == {"Chart A": 2}
    # a qr track without any text is not confirmed (its report could not score)
    tr2 = Tracker(cfg(n_min=2))
    for k in range(3):
        res = tr2.step([obs([0, 0, 0], "qr", text="")], 0.1 * k)
        assert res.newly_confirmed == []
    res = tr2.step([obs([0, 0, 0], "qr", text="Chart C")], 0.5)
    assert [(s.text, s.n_detections) for s in res.newly_confirmed] == [("Chart C", 4)]


def test_landolt_rings_are_voted_per_ring_and_ring_3_is_needed():
    # the default landolt_required_rings [3]: rings 1-2 read in two frames is not enough
    tr = Tracker(cfg(n_min=2))
    for k, text in enumerate(["1:E 2:N", "1:E 2:S", ""]):
        assert tr.step([obs([0, 0, 0], "landolt-c", text=text)], 0.1 * k).newly_confirmed == []
    # ring 3 reads once: confirmed; per ring the direction read most often (ring 1: E twice
    # against W once; ring 2: S twice against N once)
    res = tr.step([obs([0, 0, 0], "landolt-c", text="1:W 2:S 3:NE")], 0.3)
    assert [s.text for s in res.newly_confirmed] == ["1:E 2:S 3:NE"]
    # the finals' [3, 4]: ring 4 must read too
    fin = Tracker(cfg(n_min=1, landolt_required_rings=(3, 4)))
    assert fin.step([obs([0, 0, 0], "landolt-c", text="3:NE")], 0.0).newly_confirmed == []
    assert [s.text for s in fin.step([obs([0, 0, 0], "landolt-c", text="4:S")], 0.1).newly_confirmed] == [
        "3:NE 4:S"
    ]


def test_mean_fusion():
    p1 = np.full(len(CLASSES), 0.0)
    p1[CLASS_INDEX["door"]] = 1.0
    p2 = np.full(len(CLASSES), 1.0 / len(CLASSES))
    tr = Tracker(cfg())
    tr.step([obs([0, 0, 0], probs=p1)], 0.0)
    tr.step([obs([0, 0, 0], probs=p2)], 0.1)
    assert np.allclose(tr.tracks[0].probs, 0.5 * (p1 + p2))
    # without class_probs: p on the top class, the rest spread evenly
    q = observation_probs(obs([0, 0, 0], "valve", conf=0.77), "mean", None)
    assert q[CLASS_INDEX["valve"]] == pytest.approx(0.77)
    assert q[CLASS_INDEX["door"]] == pytest.approx(0.23 / (len(CLASSES) - 1))
    assert q.sum() == pytest.approx(1.0)


def test_confusion_fusion_seed_2_1_5():
    C = len(CLASSES)
    M = np.zeros((C, C))
    a, b, c = CLASS_INDEX["oxygen"], CLASS_INDEX["explosive"], CLASS_INDEX["flammable-gas"]
    M[:, :] = 1.0 / (C - 1)
    np.fill_diagonal(M, 0.0)
    # "when an oxygen sign is misclassified, 10 times more likely explosive than flammable"
    M[a] = 0.0
    M[a, b], M[a, c] = 10 / 11, 1 / 11
    cal = Calibration(confusion=M)
    q = observation_probs(obs([0, 0, 0], "oxygen", conf=0.8), "confusion", M)
    # p(actual oxygen | detected oxygen) = 0.8; explosive 0.2 * 10/11; flammable 0.2 * 1/11
    assert q[a] == pytest.approx(0.8)
    assert q[b] == pytest.approx(0.2 * 10 / 11)
    assert q[c] == pytest.approx(0.2 / 11)
    assert q.sum() == pytest.approx(1.0)
    tr = Tracker(cfg(fusion="confusion"), calibration=cal)
    tr.step([obs([0, 0, 0], "oxygen", conf=0.4)], 0.0)
    assert tr.tracks[0].text == "explosive"  # 0.6 * 10/11 = 0.545 > 0.4
    with pytest.raises(TrackerError, match="needs a calibration"):
        Tracker(cfg(fusion="confusion"))


def test_prior_initialisation_is_one_kalman_update():
    tr = Tracker(TrackerConfig(init="prior", mu0=(0.0, 0.0, 1.0), Sigma0_diag=(100.0, 100.0, 4.0)))
    tr.step([obs([2, 0, 1], R=np.eye(3))], 0.0)
    # x: 0 + 100/101 * 2; Sigma_xx = 100 - 100^2/101 = 100/101
    assert tr.tracks[0].mu[0] == pytest.approx(200 / 101)
    assert tr.tracks[0].Sigma[0, 0] == pytest.approx(100 / 101)
    tr = Tracker(cfg())
    tr.step([obs([2, 0, 1], R=np.eye(3))], 0.0)
    assert tr.tracks[0].mu.tolist() == [2.0, 0.0, 1.0]  # default: mu = o, Sigma = R
    assert np.array_equal(tr.tracks[0].Sigma, np.eye(3))


def test_duplicate_detections_in_one_frame_start_no_track():
    # two detectors report the same object in one frame: one track, not two
    tr = Tracker(cfg())
    res = tr.step([obs([0, 0, 0]), obs([0.1, 0, 0])], 0.0)
    assert res.new_tracks == [(0, 0)] and res.duplicates == [(1, 0)]
    res = tr.step([obs([0, 0, 0]), obs([0.1, 0, 0])], 0.1)
    assert res.pairs == [(0, 0)] and res.duplicates == [(1, 0)]
    assert len(tr.tracks) == 1 and tr.tracks[0].n_detections == 2
    # outside the gate (m^2 = 16) it is another object
    res = tr.step([obs([0, 0, 0]), obs([4.0, 0, 0])], 0.2)
    assert res.new_tracks == [(1, 1)] and res.duplicates == []


def test_kalman_update_with_the_optimal_gain_given_is_filterpys():
    """Joseph's form with a gain passed in (the shared-error update's) is the same update as
    filterpy's when that gain is the optimal one, and with another gain its covariance is the
    error's: a gain of 0 leaves (mu, Sigma), a gain of I gives (o, R)."""
    rng = np.random.default_rng(3)
    mu, o = rng.standard_normal(3), rng.standard_normal(3)
    Sigma, R = random_spd(rng), random_spd(rng)
    K = Sigma @ np.linalg.inv(Sigma + R)
    for a, b in zip(kalman_update(mu, Sigma, o, R, K), kalman_update(mu, Sigma, o, R), strict=True):
        assert np.allclose(a, b, atol=1e-10)
    mu0, Sigma0 = kalman_update(mu, Sigma, o, R, np.zeros((3, 3)))
    assert np.allclose(mu0, mu) and np.allclose(Sigma0, Sigma)
    mu1, Sigma1 = kalman_update(mu, Sigma, o, R, np.eye(3))
    assert np.allclose(mu1, o) and np.allclose(Sigma1, R)


@pytest.mark.parametrize("shared", [False, True])
def test_nis_of_a_still_target_with_known_r_averages_the_measurement_dimension(shared):
    """NIS (the step's d^2) is chi-square with 3 degrees of freedom when R is the truth: over 400
    runs of 11 frames (4,000 updates; innovations of a consistent filter are white) its mean is 3
    within 0.15, about 4 standard errors (chi-square(3) has variance 6: sqrt(6 / 4000) = 0.039).
    With a shared part, a constant error common to all of a run's observations, the filter's S
    (no shared error counted twice, ``shared_change`` 0: the error does not move) keeps NIS at 3.
    """
    rng = np.random.default_rng(61)
    A = rng.standard_normal((3, 3))
    R = 0.01 * (A @ A.T + 0.5 * np.eye(3))  # a full, known R; centimetre scale
    R_s = 0.5 * R if shared else None
    L_o = np.linalg.cholesky(R_s) if shared else np.zeros((3, 3))
    R_w = R - R_s if shared else R
    truth = np.array([2.0, -1.0, 0.3])
    nis, dims = [], set()
    for _ in range(400):
        tr = Tracker(cfg(gate=1e9, shared_change=0.0))  # no gate truncates the tail of chi-square
        z = rng.standard_normal(3)  # this run's shared error, the same in every frame
        for k in range(11):
            o = truth + L_o @ z + rng.multivariate_normal(np.zeros(3), R_w)
            ob = obs(o, R=R)
            if shared:
                ob = dataclasses.replace(ob, R_shared=R_s)
            res = tr.step([ob], 0.1 * k)
            assert len(res.innovations) == len(res.pairs) == (0 if k == 0 else 1)
            for inn in res.innovations:
                assert (inn.obs_index, inn.track_id) == res.pairs[0]
                assert inn.d2 == pytest.approx(inn.nu @ np.linalg.solve(inn.S, inn.nu))
                nis.append(inn.d2)
                dims.add(inn.nu.shape[0])
    assert len(nis) == 4000 and dims == {3}
    assert np.mean(nis) == pytest.approx(3.0, abs=0.15)


def test_the_innovation_is_taken_before_the_update_and_s_is_sigma_plus_r_without_shared_errors():
    tr = Tracker(cfg(gate=9.0))
    tr.step([obs([0, 0, 0])], 0.0)  # mu = 0, Sigma = R = 0.5 I
    res = tr.step([obs([1.0, 2.0, 0.0])], 0.1)
    (inn,) = res.innovations
    assert inn.nu.tolist() == [1.0, 2.0, 0.0]
    np.testing.assert_allclose(inn.S, np.eye(3), atol=1e-12)
    assert inn.d2 == pytest.approx(5.0)  # the gate's m^2 with no allowance, as for the doors here
    assert tr.tracks[0].mu.tolist() == pytest.approx([0.5, 1.0, 0.0])
