"""run_odometry on a ROS 2 bag (.mcap): the rendered room sequence written as a bag (mono8
images, 32FC1 depth, CameraInfo) tracks exactly as its folder."""

import numpy as np
import pytest

import vofront
from conftest import cargo_run


@pytest.fixture(scope="module")
def bag(sequence, tmp_path_factory):
    path = tmp_path_factory.mktemp("bag") / "room.mcap"
    cargo_run("-p", "vofront-python", "--example", "bag_sequence", "--", str(sequence), str(path))
    return path


def test_run_odometry_reads_a_bag_like_its_folder(sequence, bag):
    folder = vofront.run_odometry(sequence, "direct")
    out = vofront.run_odometry(bag, "direct")
    assert out["camera"]["source"] == "camera info topic /camera/camera_info"
    assert out["summary"]["frames"] == 12 and out["summary"]["lost"] == 0
    np.testing.assert_allclose(out["trajectory"], folder["trajectory"], atol=1e-6)


def test_run_odometry_names_a_bad_bag(tmp_path):
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 3)
    with pytest.raises(OSError, match="cut.mcap"):
        vofront.run_odometry(bad, "direct")
