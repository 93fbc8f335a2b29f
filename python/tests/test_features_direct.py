"""orb, match, align_translation, align_se3, klt on synthetic images with known motion."""

import numpy as np
import pytest

import vofront
from conftest import K_RENDER, rotation_angle_deg, truth_t21


def texture(width=320, height=240, dx=0.0, dy=0.0):
    """A smooth float32 texture moved by (dx, dy): `texture(dx, dy)(x + d) = texture()(x)`."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    x, y = x - dx, y - dy
    v = 100 + 40 * np.sin(x * 0.3) * np.cos(y * 0.25) + 30 * np.sin((x + y) * 0.17)
    return v.astype(np.float32)


def test_orb_shapes_and_ranges(pairs):
    img = vofront.load_gray(pairs[0] / "img_prev.png")
    kp, desc = vofront.orb(img, 500)
    assert kp.dtype == np.float32 and kp.shape[1] == 6 and 0 < len(kp) <= 500
    assert desc.dtype == np.uint8 and desc.shape == (len(kp), 32)
    h, w = img.shape
    assert (kp[:, 0] >= 0).all() and (kp[:, 0] < w).all()
    assert (kp[:, 1] >= 0).all() and (kp[:, 1] < h).all()
    np.testing.assert_allclose(kp[:, 2], 1.2 ** kp[:, 5], rtol=1e-5)
    assert len(vofront.orb(img, 0)[0]) == 0


def test_match_finds_a_known_shift(pairs):
    img = vofront.load_gray(pairs[0] / "img_prev.png")
    shifted = np.zeros_like(img)
    shifted[:, 7:] = img[:, :-7]
    k1, d1 = vofront.orb(img, 800)
    k2, d2 = vofront.orb(shifted, 800)
    m = vofront.match(d1, d2)
    assert m.shape[1] == 3 and len(m) > 100
    dx = k2[m[:, 1], 0] - k1[m[:, 0], 0]
    dy = k2[m[:, 1], 1] - k1[m[:, 0], 1]
    good = (np.abs(dx - 7) < 1.5) & (np.abs(dy) < 1.5)
    assert good.mean() > 0.9
    assert (m[:, 2] <= 100).all()


def test_match_self_is_identity_and_filters_apply():
    rng = np.random.default_rng(1)
    d = rng.integers(0, 256, (50, 32), dtype=np.uint8)
    m = vofront.match(d, d, ratio=None, cross_check=True)
    np.testing.assert_array_equal(m[:, 0], np.arange(50))
    np.testing.assert_array_equal(m[:, 1], np.arange(50))
    assert (m[:, 2] == 0).all()
    assert len(vofront.match(d, d[::-1].copy(), ratio=None, max_distance=0)) == 50
    assert len(vofront.match(d, np.zeros((0, 32), np.uint8))) == 0


@pytest.mark.parametrize("ratio", [0.0, 1.5, float("nan")])
def test_match_bad_ratio(ratio):
    d = np.zeros((3, 32), np.uint8)
    with pytest.raises(ValueError):
        vofront.match(d, d, ratio=ratio)


@pytest.mark.parametrize("d", [np.zeros((3, 31), np.uint8), np.zeros((3, 32), np.float32), [1, 2]])
def test_match_bad_descriptors(d):
    with pytest.raises(ValueError):
        vofront.match(d, np.zeros((3, 32), np.uint8))


@pytest.mark.parametrize("shift", [(1.3, -0.6), (-4.2, 2.5)])
def test_align_translation_recovers_shift(shift):
    out = vofront.align_translation(texture(), texture(dx=shift[0], dy=shift[1]))
    np.testing.assert_allclose(out["d"], shift, atol=0.02)
    assert out["converged"] and out["covariance"].shape == (2, 2)
    assert out["iterations"] == sum(out["iterations_per_level"])


def test_align_translation_uint8_equals_float32_of_same_values():
    a, b = texture().round().astype(np.uint8), texture(dx=2.0).round().astype(np.uint8)
    r8 = vofront.align_translation(a, b)
    r32 = vofront.align_translation(a.astype(np.float32), b.astype(np.float32))
    np.testing.assert_array_equal(r8["d"], r32["d"])


def test_align_translation_non_contiguous_input():
    big = texture(640, 240)
    out = vofront.align_translation(big[:, ::2], texture(640, 240, dx=4.0)[:, ::2])
    np.testing.assert_allclose(out["d"], (2.0, 0.0), atol=0.02)


def test_align_translation_flat_image_is_a_vofront_error():
    flat = np.full((100, 100), 50, np.float32)
    with pytest.raises(vofront.VofrontError):
        vofront.align_translation(flat, flat)


def test_align_se3_matches_truth_and_prior(pairs):
    pair = pairs[1]
    img1 = vofront.load_gray(pair / "img_prev.png")
    img2 = vofront.load_gray(pair / "img_curr.png")
    depth_m = vofront.load_depth(pair / "dep_prev.png")
    truth = truth_t21(pair)
    out = vofront.align_se3(img1, depth_m, img2, K_RENDER)
    assert rotation_angle_deg(out["T_21"][:3, :3].T @ truth[:3, :3]) < 0.2
    assert np.linalg.norm(out["T_21"][:3, 3] - truth[:3, 3]) < 0.005
    assert out["covariance"].shape == (6, 6)
    # Raw uint16 depth with its scale is the same input.
    from_raw = vofront.align_se3(img1, (depth_m * 5000).round().astype(np.uint16), img2, K_RENDER)
    np.testing.assert_allclose(from_raw["T_21"], out["T_21"], atol=1e-6)
    # Starting at the truth stays there.
    at_truth = vofront.align_se3(img1, depth_m, img2, K_RENDER, prior=truth)
    assert np.linalg.norm(at_truth["T_21"][:3, 3] - truth[:3, 3]) < 0.005


def test_align_se3_bad_inputs(pairs):
    img = vofront.load_gray(pairs[0] / "img_prev.png")
    depth = vofront.load_depth(pairs[0] / "dep_prev.png")
    with pytest.raises(ValueError, match="prior"):
        vofront.align_se3(img, depth, img, K_RENDER, prior=np.ones((4, 4)))
    with pytest.raises(ValueError, match="cur_img"):
        vofront.align_se3(img, depth, img[:100], K_RENDER)
    with pytest.raises(vofront.VofrontError):
        vofront.align_se3(img, np.zeros_like(depth), img, K_RENDER)
    with pytest.raises(ValueError, match="depth"):
        vofront.align_se3(img, depth.astype(np.int32), img, K_RENDER)


def test_klt_tracks_a_known_shift():
    img1, img2 = texture(), texture(dx=1.5, dy=-0.7)
    pts = np.array([[100.0, 80.0], [160.0, 120.0], [200.0, 150.0]])
    nxt, status, err = vofront.klt(img1, img2, pts)
    assert nxt.shape == (3, 2) and status.dtype == np.uint8 and err.shape == (3,)
    assert status.all()
    np.testing.assert_allclose(nxt, pts + [1.5, -0.7], atol=0.05)


def test_klt_point_outside_is_not_tracked():
    img = texture()
    _, status, _ = vofront.klt(img, img, np.array([[-50.0, -50.0], [160.0, 120.0]]))
    assert list(status) == [0, 1]


def test_klt_bad_config_and_points():
    img = texture()
    with pytest.raises(vofront.VofrontError):
        vofront.klt(img, img, np.zeros((1, 2)), window=4)
    with pytest.raises(ValueError):
        vofront.klt(img, img, np.zeros((1, 3)))
