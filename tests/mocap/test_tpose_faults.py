"""is_tpose_frame on hand-built bodies: straight arms, wrist span, pelvis-relative jump."""

from __future__ import annotations

import numpy as np

from humotion_gym.body import KEYPOINT_INDEX
from humotion_gym.mocap.tpose import is_tpose_frame

K = KEYPOINT_INDEX
UPPER, FORE = 300.0, 250.0  # mm; an arm is 550 mm long


def body(arms: dict[str, tuple[np.ndarray, np.ndarray]] | None = None) -> np.ndarray:
    """(15, 3) keypoints, z up, mm, whole numbers; arms hang unless ``arms`` gives
    ``{side: (elbow - shoulder, wrist - shoulder)}``."""
    kp = np.zeros((15, 3))
    kp[K["pelvis"]] = (0, 0, 1000)
    kp[K["neck"]] = (0, 0, 1500)
    kp[K["head_top"]] = (0, 0, 1750)
    for side, x in (("r", -1.0), ("l", 1.0)):
        kp[K[f"{side}_hip"]] = (100 * x, 0, 950)
        kp[K[f"{side}_knee"]] = (100 * x, 0, 500)
        kp[K[f"{side}_ankle"]] = (100 * x, 0, 80)
        sh = np.array([200 * x, 0, 1450])
        kp[K[f"{side}_shoulder"]] = sh
        elbow, wrist = (arms or {}).get(side, ((0, 0, -UPPER), (0, 0, -UPPER - FORE)))
        kp[K[f"{side}_elbow"]] = sh + elbow
        kp[K[f"{side}_wrist"]] = sh + wrist
    return kp


REST = body()


def arms_out(angle_deg: float = 0.0) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Both arms straight and horizontal, swept ``angle_deg`` forward (+y) from sideways."""
    a = np.radians(angle_deg)
    out = {}
    for side, x in (("r", -1.0), ("l", 1.0)):
        d = np.array([x * np.cos(a), np.sin(a), 0.0])
        out[side] = (UPPER * d, (UPPER + FORE) * d)
    return out


TPOSE = body(arms_out())


def right_arm_reaching(fraction: float) -> np.ndarray:
    """The T-pose with the right arm bent in the horizontal plane so the wrist is
    ``fraction`` of the arm's length from the shoulder, straight out along -x."""
    reach = fraction * (UPPER + FORE)
    # The elbow is UPPER from the shoulder and FORE from the wrist (law of cosines).
    ex = (UPPER**2 - FORE**2 + reach**2) / (2 * reach)
    elbow = np.array([-ex, np.sqrt(UPPER**2 - ex**2), 0.0])
    arms = arms_out()
    arms["r"] = (elbow, np.array([-reach, 0.0, 0.0]))
    return body(arms)


def test_the_hand_built_tpose_is_one() -> None:
    """Arms straight out, then the arms drop: a T-pose frame 0 (160 mm mean jump)."""
    assert is_tpose_frame(np.stack([TPOSE, REST]))
    assert not is_tpose_frame(np.stack([REST, TPOSE]))


def test_a_bent_arm_is_no_tpose_even_with_the_wrists_far_apart() -> None:
    """Reach below ARM_STRAIGHT (0.9) of upper arm + forearm refuses the frame by itself.

    At 0.85 the wrists are still 200 + 550 + 200 + 467.5 = 1417.5 mm apart, beyond
    the span rule's 400 + 0.9 * 1100 = 1390 mm: only the straightness rule refuses.
    """
    bent = right_arm_reaching(0.85)
    sh, el, wr = (bent[K[f"r_{j}"]] for j in ("shoulder", "elbow", "wrist"))
    np.testing.assert_allclose(
        [np.linalg.norm(el - sh), np.linalg.norm(wr - el)], [UPPER, FORE], rtol=1e-12
    )
    assert not is_tpose_frame(np.stack([bent, REST]))
    assert is_tpose_frame(np.stack([right_arm_reaching(0.95), REST]))


def test_arms_swept_forward_are_no_tpose() -> None:
    """Straight, horizontal arms 45 degrees forward: wrists 400 + 1100 cos 45 = 1178 mm
    apart, short of the shoulders' 400 mm plus 0.9 of both arms (1390 mm)."""
    swept = body(arms_out(45.0))
    assert not is_tpose_frame(np.stack([swept, REST]))
    assert is_tpose_frame(np.stack([body(arms_out(10.0)), REST]))  # 1483 mm apart


def test_the_jump_is_measured_with_the_pelvis_removed() -> None:
    """A T-pose held while the whole body moves 500 mm is a real pose, kept."""
    assert not is_tpose_frame(np.stack([TPOSE, TPOSE + [500.0, 0.0, 0.0]]))
    assert not is_tpose_frame(np.stack([TPOSE, TPOSE + [0.0, 0.0, -300.0]]))


def test_a_mean_jump_of_exactly_min_jump_mm_counts() -> None:
    """Three of 15 keypoints moving 500 mm is a mean of exactly 100 mm: enough; 499 is not."""
    for step, want in ((500.0, True), (499.0, False)):
        moved = TPOSE.copy()
        moved[[K["head_top"], K["r_ankle"], K["l_ankle"]], 1] += step
        assert is_tpose_frame(np.stack([TPOSE, moved])) is want
