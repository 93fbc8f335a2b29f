"""The lesson's port runs both paradigms and prints what the original prints."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np

import vofront

LESSON = Path(__file__).resolve().parents[1] / "examples" / "lesson.py"


def test_lesson_prints_pose_and_shift(pairs):
    pair = pairs[0]
    out = subprocess.run(
        [sys.executable, str(LESSON), str(pair / "img_prev.png"), str(pair / "img_curr.png"),
         "--K", "525,525,319.5,239.5"],
        capture_output=True, text=True, check=True,
    ).stdout
    assert re.search(r"ORB keypoints: \d+ in image 1, \d+ in image 2", out)
    assert re.search(r"matches after the ratio test: \d+", out)
    r_block = out.split("R =\n")[1].split("t =")[0]
    r = np.array([[float(v) for v in row.strip(" []").split()] for row in r_block.strip().splitlines()])
    img1 = vofront.load_gray(pair / "img_prev.png")
    img2 = vofront.load_gray(pair / "img_curr.png")
    k = np.array([[525.0, 0, 319.5], [0, 525.0, 239.5], [0, 0, 1]])
    expected = np.asarray(vofront.two_view(img1, img2, k, method="feature")["feature"]["R"])
    np.testing.assert_allclose(r, expected, atol=2e-6)
    shift = re.search(r"estimated shift: dx = (\S+) px, dy = (\S+) px", out)
    d = vofront.align_translation(img1, img2)["d"]
    np.testing.assert_allclose([float(shift[1]), float(shift[2])], d, atol=1e-3)


def test_lesson_missing_file_fails_cleanly(tmp_path):
    out = subprocess.run(
        [sys.executable, str(LESSON), str(tmp_path / "a.png"), str(tmp_path / "b.png")],
        capture_output=True, text=True,
    )
    assert out.returncode == 1 and "cannot read" in out.stderr
