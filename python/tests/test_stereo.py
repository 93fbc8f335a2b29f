"""The stereo trackers from Python: ``Odometry("stereo" | "direct-stereo", K, baseline=...)``
frame by frame with ``track(left, right, timestamp)``, ``run_odometry(path, method)``, and the
CLI on the same rendered KITTI stereo folder."""

import shutil

import numpy as np
import pytest

import vofront
from conftest import cli_json


def rig(sequence):
    """``K`` and the baseline (metres) of a KITTI ``calib.txt``: ``P1 = K [I | (-f b, 0, 0)]``."""
    rows = {line.split(":")[0]: np.array(line.split()[1:], dtype=float).reshape(3, 4)
            for line in (sequence / "calib.txt").read_text().splitlines() if ":" in line}
    k = rows["P0"][:, :3]
    return k, -rows["P1"][0, 3] / k[0, 0]


def stereo_frames(sequence):
    """``(timestamp, left, right)`` of the KITTI folder, in order."""
    times = np.loadtxt(sequence / "times.txt", ndmin=1)
    for i, t in enumerate(times):
        name = f"{i:06}.png"
        yield float(t), vofront.load_gray(sequence / "image_0" / name), \
            vofront.load_gray(sequence / "image_1" / name)


@pytest.mark.parametrize("method", ["stereo", "direct-stereo"])
def test_stereo_odometry_equals_run_odometry_and_the_cli(stereo_sequence, tmp_path, method):
    k, baseline = rig(stereo_sequence)
    assert baseline == pytest.approx(0.5)
    vo = vofront.Odometry(method, k, baseline=baseline)
    est = []
    for stamp, left, right in stereo_frames(stereo_sequence):
        out = vo.track(left, right, stamp)
        assert out["status"] == "ok", out["message"]
        est.append(out)
    assert vo.frames == 30 and est[1]["pose_quality"]["verdict"] == "ok"
    run = vofront.run_odometry(stereo_sequence, method)
    positions = np.array([e["pose_wc"][:3, 3] for e in est])
    np.testing.assert_allclose(run["trajectory"][:, 1:4], positions, atol=1e-6)
    traj = tmp_path / "traj.txt"
    expected = cli_json("odometry", str(stereo_sequence), "--method", method, "--out", str(traj))
    np.testing.assert_allclose(run["trajectory"], np.loadtxt(traj, comments="#"), atol=1e-6)
    assert run["summary"]["frames"] == expected["frames"] == 30
    assert run["ate"]["rmse"] == pytest.approx(expected["ate"]["rmse"], rel=1e-9)
    # Metric: SE(3)-aligned, no scale correction, within half a percent of the 29 m path.
    assert run["ate"]["rmse"] < 0.005 * 29.0


def test_stereo_needs_a_rig_and_a_right_image(stereo_sequence):
    k, baseline = rig(stereo_sequence)
    with pytest.raises(ValueError, match="rig"):
        vofront.Odometry("direct-stereo", k)
    vo = vofront.Odometry("direct-stereo", k, T_left_right=np.array(
        [[1, 0, 0, baseline], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float))
    _, left, right = next(stereo_frames(stereo_sequence))
    with pytest.raises(ValueError, match="right"):
        vo.track(left)
    assert vo.track(left, right=right)["status"] == "ok"


def test_run_odometry_refuses_a_stereo_method_without_a_right_camera(stereo_sequence, tmp_path):
    mono = tmp_path / "mono"
    shutil.copytree(stereo_sequence / "image_0", mono / "image_0")
    for name in ("calib.txt", "times.txt"):
        shutil.copy(stereo_sequence / name, mono / name)
    with pytest.raises(ValueError, match="stereo rig"):
        vofront.run_odometry(mono, "direct-stereo")


def test_two_view_with_a_right_image_is_metric_and_equals_the_cli(stereo_sequence):
    k, baseline = rig(stereo_sequence)
    poses = np.loadtxt(stereo_sequence / "poses.txt").reshape(-1, 3, 4)
    t_w = [np.vstack([p, [0, 0, 0, 1]]) for p in poses]
    truth = np.linalg.inv(t_w[2]) @ t_w[0]
    left0, right0, left2 = (stereo_sequence / "image_0" / "000000.png",
                            stereo_sequence / "image_1" / "000000.png",
                            stereo_sequence / "image_0" / "000002.png")
    out = vofront.two_view(vofront.load_gray(left0), vofront.load_gray(left2), k,
                           right1=vofront.load_gray(right0), baseline=baseline)
    stereo = out["feature_stereo"]
    assert stereo["quality"]["verdict"] == "ok"
    motion = np.linalg.norm(truth[:3, 3])
    assert np.linalg.norm(stereo["T_21"][:3, 3] - truth[:3, 3]) < 0.02 * motion
    assert out["recommended"]["estimate"] == "feature_stereo"
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    cli = cli_json("two-view", str(left0), str(left2), "--right1", str(right0),
                   "--baseline", str(baseline), "--fx", str(fx), "--fy", str(fy),
                   "--cx", str(cx), "--cy", str(cy))
    np.testing.assert_allclose(cli["feature_stereo"]["t"], stereo["t"], atol=1e-9)
    with pytest.raises(ValueError):
        vofront.two_view(vofront.load_gray(left0), vofront.load_gray(left2), k,
                         right1=vofront.load_gray(right0))
