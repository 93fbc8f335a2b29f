"""Odometry, run_odometry, ate and rpe: a rendered sequence with exact ground truth, and the
CLI's results on the same folder."""

import numpy as np
import pytest

import vofront
from conftest import K_RENDER, cli, cli_json


def frames(sequence):
    """`(timestamp, image, depth)` of the rendered sequence, in order."""
    rgb = [line.split() for line in (sequence / "rgb.txt").read_text().splitlines()
           if not line.startswith("#")]
    depth = [line.split() for line in (sequence / "depth.txt").read_text().splitlines()
             if not line.startswith("#")]
    for (stamp, img), (_, dep) in zip(rgb, depth):
        yield float(stamp), vofront.load_gray(sequence / img), vofront.load_depth(sequence / dep)


def ground_truth(sequence):
    return np.loadtxt(sequence / "groundtruth.txt", comments="#")


@pytest.mark.parametrize("method", ["direct", "feature-rgbd"])
def test_odometry_tracks_rendered_sequence(sequence, method):
    vo = vofront.Odometry(method, K_RENDER)
    est = []
    for stamp, img, depth in frames(sequence):
        out = vo.track(img, depth=depth, timestamp=stamp)
        assert out["status"] == "ok", out["message"]
        assert out["pose_wc"].shape == (4, 4)
        assert set(out["quality"]) >= {"inliers", "rmse", "keyframe", "ms"}
        pq = out["pose_quality"]
        if est:  # every frame after the first is an estimate with its record
            assert pq["verdict"] == "ok" and pq["reasons"] == [], pq
            assert 0 < pq["rotation_sigma_deg"] < 1 and 0 < pq["translation_sigma_m"] < 0.1
            assert np.asarray(pq["covariance"]).shape == (6, 6)
        else:  # the first frame is the origin by definition: no estimate behind it
            assert pq is None
        est.append(out)
    assert vo.frames == len(est)
    np.testing.assert_allclose(est[0]["pose_wc"], np.eye(4), atol=1e-12)
    rows = np.array([[e["timestamp"], *e["pose_wc"][:3, 3], 0, 0, 0, 1] for e in est])
    gt = ground_truth(sequence)
    # Positions only (ATE ignores rotations): identity quaternions are fine here.
    ate = vofront.ate(gt, rows, align="se3")
    assert ate["pairs"] == len(est) and ate["rmse"] < 0.005


@pytest.mark.parametrize("method", ["mono", "feature"])
def test_mono_odometry_locates_the_frames_its_initialisation_waited_through(sequence, method):
    vo = vofront.Odometry(method, K_RENDER)
    est, late, pending = [], {}, []
    for stamp, img, _ in frames(sequence):
        est.append(vo.track(img, timestamp=stamp))
        for frame, revised in vo.revised():
            assert est[frame]["status"] == "lost" and frame not in late
            assert len(est) - 1 - frame <= pending[-1]  # only pending frames are revised
            late[frame] = revised
        pending.append(vo.pending)
    assert late, [e["status"] for e in est]
    assert max(pending) >= len(late) and pending[-1] == 0, pending
    for frame, revised in late.items():
        assert revised["status"] == "ok" and revised["timestamp"] == est[frame]["timestamp"]
        assert revised["quality"]["inliers"] > 0 and revised["pose_quality"] is not None
        est[frame] = revised
    assert [e["status"] for e in est] == ["ok"] * len(est)
    assert vo.revised() == []


def test_odometry_bad_inputs(sequence):
    _, img, depth = next(frames(sequence))
    with pytest.raises(ValueError, match="method"):
        vofront.Odometry("sideways", K_RENDER)
    vo = vofront.Odometry("direct", K_RENDER)
    with pytest.raises(ValueError, match="depth"):
        vo.track(img)
    with pytest.raises(ValueError, match="depth"):
        vo.track(img, depth=depth[:100])
    assert vo.frames == 0
    mono = vofront.Odometry("feature", K_RENDER)
    assert mono.track(img)["status"] in {"ok", "lost"}


def test_run_odometry_equals_cli(sequence, tmp_path):
    out = vofront.run_odometry(sequence, "direct")
    traj = tmp_path / "traj.txt"
    cli("odometry", str(sequence), "--method", "direct", "--out", str(traj))
    np.testing.assert_allclose(out["trajectory"], np.loadtxt(traj, comments="#"), atol=1e-6)
    assert out["summary"]["frames"] == 12 and out["summary"]["lost"] == 0
    assert len(out["frames"]) == 12 and out["ate"]["rmse"] < 0.005
    np.testing.assert_allclose(out["ground_truth"], ground_truth(sequence), atol=1e-9)


@pytest.mark.parametrize("method", ["mono", "feature"])
def test_run_odometry_equals_cli_against_the_camera_ground_truth(euroc_sequence, tmp_path, method):
    out = vofront.run_odometry(euroc_sequence, method)
    traj = tmp_path / "traj.txt"
    expected = cli_json("odometry", str(euroc_sequence), "--method", method, "--out", str(traj),
                        "--metrics", str(tmp_path / "m.csv"))
    assert expected["method"] == "mono" and expected["ate"]["alignment"] == "sim3"
    assert out["summary"]["frames"] == expected["frames"] == 30
    assert out["camera"]["source"] == expected["camera"]["source"]
    np.testing.assert_allclose(out["trajectory"], np.loadtxt(traj, comments="#"), atol=1e-6)
    # The ground truth is the camera's (body poses times T_BS), as the CLI evaluates against.
    truth = np.loadtxt(euroc_sequence / "camera_groundtruth.txt")
    np.testing.assert_allclose(out["ground_truth"][:, 1:4], truth[:, 1:4], atol=1e-6)
    assert out["ate"]["rmse"] == pytest.approx(expected["ate"]["rmse"], rel=1e-9)
    assert out["ate"]["rmse"] < 0.005


def test_odometry_accepts_mono_and_depth_methods_refuse_euroc(euroc_sequence):
    assert vofront.Odometry("mono", K_RENDER).frames == 0
    with pytest.raises(ValueError, match="needs depth"):
        vofront.run_odometry(euroc_sequence, "direct")


def test_run_odometry_errors(tmp_path):
    with pytest.raises(OSError):
        vofront.run_odometry(tmp_path / "missing", "direct")
    with pytest.raises(ValueError, match="method"):
        vofront.run_odometry(tmp_path, "nope")


def test_ate_rpe_equal_cli_eval(sequence, tmp_path):
    out = vofront.run_odometry(sequence, "direct")
    est = tmp_path / "est.txt"
    np.savetxt(est, out["trajectory"], fmt="%.9f")
    gt = sequence / "groundtruth.txt"
    for align in ("se3", "sim3", "none"):
        expected = cli_json("eval", str(gt), str(est), "--align", align)
        ate = vofront.ate(gt, est, align=align)
        rpe = vofront.rpe(gt, est, align=align)
        assert ate["pairs"] == expected["pairs"]
        assert ate["scale"] == pytest.approx(expected["scale"], rel=1e-12)
        for k, v in expected["ate"].items():
            assert ate[k] == pytest.approx(v, rel=1e-9, abs=1e-15), k
        for part in ("translation", "rotation_deg"):
            for k, v in expected["rpe"][part].items():
                assert rpe[part][k] == pytest.approx(v, rel=1e-9, abs=1e-15), (part, k)
        for k in ("scale", "sigma"):
            v = expected["rpe"]["rotation_scale"][k]
            assert rpe["rotation_scale"][k] == pytest.approx(v, rel=1e-9, abs=1e-15), k


def random_trajectory(n=30, seed=0):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.normal(0, 0.1, (n, 3)), axis=0)
    q = rng.normal(0, 1, (n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.column_stack([np.arange(n) * 0.1, t, q])


def test_ate_alignment_removes_a_rigid_or_similar_motion():
    gt = random_trajectory()
    est = gt.copy()
    angle = np.radians(30)
    r = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    est[:, 1:4] = 2.0 * gt[:, 1:4] @ r.T + [1.0, -2.0, 0.5]
    assert vofront.ate(gt, est, align="sim3")["rmse"] < 1e-9
    assert vofront.ate(gt, est, align="sim3")["scale"] == pytest.approx(0.5)
    assert vofront.ate(gt, est, align="se3")["rmse"] > 0.01
    assert vofront.ate(gt, est, align="none")["rmse"] > 0.1
    errors = vofront.ate(gt, gt, align=None)["errors"]
    assert errors.shape == (30,) and (errors == 0).all()


def test_rpe_of_identical_trajectories_is_zero():
    gt = random_trajectory()
    out = vofront.rpe(gt, gt)
    assert out["translation"]["max"] < 1e-12 and out["rotation_deg"]["max"] < 1e-6
    assert out["pairs"] == 30
    assert out["rotation_scale"]["scale"] == pytest.approx(1.0, abs=1e-9)


def test_eval_bad_inputs(tmp_path):
    gt = random_trajectory()
    with pytest.raises(ValueError, match="align"):
        vofront.ate(gt, gt, align="affine")
    with pytest.raises(ValueError):
        vofront.ate(gt[:, :7], gt)
    with pytest.raises(FileNotFoundError):
        vofront.ate(tmp_path / "missing.txt", gt)
    bad = tmp_path / "bad.txt"
    bad.write_text("1 2 3\n")
    with pytest.raises(OSError):
        vofront.rpe(bad, gt)
    with pytest.raises(vofront.VofrontError):
        vofront.ate(gt, gt[:, :] + [100.0, 0, 0, 0, 0, 0, 0, 0])
