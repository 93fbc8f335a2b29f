"""two_view and relpose: the CLI's JSON on the same files, and the truth of rendered pairs."""

import json

import numpy as np
import pytest

import vofront
from conftest import K_RENDER, cli, cli_json, rotation_angle_deg, truth_t21

TIMING_KEYS = {"ms"}


def without_timings(v):
    """`v` without its wall-clock entries (they differ between any two runs)."""
    if isinstance(v, dict):
        return {k: without_timings(x) for k, x in v.items() if k not in TIMING_KEYS}
    if isinstance(v, list):
        return [without_timings(x) for x in v]
    return v


def pair_arrays(pair):
    img1 = vofront.load_gray(pair / "img_prev.png")
    img2 = vofront.load_gray(pair / "img_curr.png")
    depth1 = vofront.load_depth(pair / "dep_prev.png")
    return img1, img2, depth1


def test_two_view_equals_cli_json(pairs):
    pair = pairs[0]
    img1, img2, depth1 = pair_arrays(pair)
    py = vofront.two_view(img1, img2, K_RENDER, depth1=depth1)
    cli = cli_json(
        "two-view", str(pair / "img_prev.png"), str(pair / "img_curr.png"),
        "--depth1", str(pair / "dep_prev.png"),
    )
    for key in ("feature", "direct_se3"):
        t21 = py[key].pop("T_21")
        assert t21.shape == (4, 4) and t21.dtype == np.float64
        np.testing.assert_allclose(t21[:3, :3], np.array(py[key]["R"]), atol=1e-12)
    # With more than one method the report also names the estimate to trust.
    assert set(py) == set(cli) == {"feature", "direct_translation", "direct_se3", "recommended"}
    assert py["recommended"]["estimate"] in {"feature", "direct_translation", "direct_se3"}
    assert without_timings(py) == without_timings(cli)


def test_two_view_feature_pose_matches_the_truth(wide_pairs):
    for pair in wide_pairs:
        img1, img2, _ = pair_arrays(pair)
        truth = truth_t21(pair)
        feature = vofront.two_view(img1, img2, K_RENDER, method="feature")["feature"]["T_21"]
        assert rotation_angle_deg(feature[:3, :3].T @ truth[:3, :3]) < 0.5
        direction = truth[:3, 3] / np.linalg.norm(truth[:3, 3])
        assert np.degrees(np.arccos(np.clip(feature[:3, 3] @ direction, -1, 1))) < 5.0


def test_two_view_direct_pose_matches_the_truth(pairs):
    for pair in pairs:
        img1, img2, depth1 = pair_arrays(pair)
        truth = truth_t21(pair)
        out = vofront.two_view(img1, img2, K_RENDER, depth1=depth1)
        se3 = out["direct_se3"]["T_21"]
        assert rotation_angle_deg(se3[:3, :3].T @ truth[:3, :3]) < 0.2
        assert np.linalg.norm(se3[:3, 3] - truth[:3, 3]) < 0.005


def test_two_view_methods_and_float_images(pairs):
    img1, img2, _ = pair_arrays(pairs[0])
    feature_only = vofront.two_view(img1, img2, K_RENDER, method="feature")
    assert set(feature_only) == {"feature"}
    direct = vofront.two_view(img1.astype(np.float32), img2.astype(np.float32), K_RENDER,
                              method="direct")
    assert set(direct) == {"direct_translation"}
    same = vofront.two_view(img1, img2, K_RENDER, method="direct")
    assert direct["direct_translation"]["d"] == same["direct_translation"]["d"]


def test_two_view_failed_method_gives_error_entry():
    flat = np.full((120, 160), 128, np.uint8)
    out = vofront.two_view(flat, flat, K_RENDER)
    assert set(out["feature"]) == {"error"} and out["feature"]["error"]
    assert set(out["direct_translation"]) == {"error"}


def test_two_view_size_mismatch_is_reported_like_the_cli(pairs):
    img1, _, depth1 = pair_arrays(pairs[0])
    out = vofront.two_view(img1, img1[:200], K_RENDER, method="direct", depth1=depth1)
    assert "differs from frame 2 size" in out["direct_translation"]["error"]


def synthetic_correspondences(n=200, seed=3):
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-1.5, 1.5, n), rng.uniform(3, 8, n)])
    angle = np.radians(4.0)
    r = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    t = np.array([0.3, -0.05, 0.1])
    p2 = pts @ r.T + t

    def project(p):
        return (p[:, :2] / p[:, 2:]) * 525.0 + np.array([319.5, 239.5])

    return project(pts), project(p2), r, t


def test_relpose_recovers_synthetic_motion():
    x1, x2, r, t = synthetic_correspondences()
    out = vofront.relpose(x1, x2, K_RENDER)
    assert rotation_angle_deg(np.asarray(out["R"]).T @ r) < 1e-4
    np.testing.assert_allclose(out["t"], t / np.linalg.norm(t), atol=1e-6)
    assert out["inliers"] == len(x1) and out["inlier_mask"].all()
    np.testing.assert_allclose(out["T_21"][:3, 3], out["t"])
    q = out["quality"]
    assert q["verdict"] == "ok" and q["reasons"] == [] and q["inliers"] == len(x1)
    assert q["rotation_sigma_deg"] < 0.1 and q["translation_direction_sigma_deg"] < 1.0


def test_relpose_on_random_correspondences_is_not_ok():
    rng = np.random.default_rng(3)
    x1 = rng.uniform([0, 0], [640, 480], (300, 2))
    x2 = rng.uniform([0, 0], [640, 480], (300, 2))
    try:
        out = vofront.relpose(x1, x2, K_RENDER)
    except vofront.VofrontError:
        return  # no model at all: a typed error is the other honest answer
    assert out["quality"]["verdict"] != "ok", out["quality"]
    assert out["quality"]["reasons"]


def test_relpose_equals_cli(tmp_path):
    x1, x2, _, _ = synthetic_correspondences(seed=5)
    x2 = x2 + np.random.default_rng(0).normal(0, 0.5, x2.shape)
    csv = tmp_path / "m.csv"
    np.savetxt(csv, np.hstack([x1, x2]), delimiter=",", fmt="%.17g")
    cli = relpose_cli(csv)
    py = vofront.relpose(x1, x2, K_RENDER)
    np.testing.assert_allclose(py["R"], cli["R"], atol=1e-12)
    np.testing.assert_allclose(py["t"], cli["t"], atol=1e-12)
    assert py["inliers"] == cli["inliers"]
    assert py["quality"]["verdict"] == cli["quality"]["verdict"]
    assert py["quality"]["reasons"] == cli["quality"]["reasons"]


def relpose_cli(csv):
    """`vofront relpose` as JSON (`--json` where the CLI has the flag, else its default)."""
    try:
        return cli_json("relpose", str(csv))
    except RuntimeError:
        return json.loads(cli("relpose", str(csv)))


@pytest.mark.parametrize(
    "x1, x2",
    [
        (np.zeros((10, 3)), np.zeros((10, 3))),
        (np.zeros((10, 2)), np.zeros((9, 2))),
        (np.full((10, 2), np.nan), np.zeros((10, 2))),
        ("abc", np.zeros((10, 2))),
    ],
)
def test_relpose_bad_arrays_raise_value_error(x1, x2):
    with pytest.raises(ValueError):
        vofront.relpose(x1, x2, K_RENDER)


def test_relpose_too_few_points_is_a_vofront_error():
    x1, x2, _, _ = synthetic_correspondences(n=3)
    with pytest.raises(vofront.VofrontError):
        vofront.relpose(x1, x2, K_RENDER)
