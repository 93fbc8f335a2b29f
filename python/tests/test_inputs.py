"""Bad input from Python never crashes: every function raises a typed exception."""

import numpy as np
import pytest

import vofront
from conftest import K_RENDER

IMG = np.zeros((64, 64), np.uint8)

BAD_IMAGES = [
    np.zeros((64, 64, 3), np.uint8),
    np.zeros((64, 64), np.float64),
    np.zeros((0, 64), np.uint8),
    np.full((64, 64), np.nan, np.float32),
    None,
    "image.png",
    [[1, 2], [3, 4]],
]


@pytest.mark.parametrize("bad", BAD_IMAGES)
def test_bad_images_raise_value_error(bad):
    calls = [
        lambda: vofront.orb(bad),
        lambda: vofront.two_view(bad, IMG, K_RENDER),
        lambda: vofront.two_view(IMG, bad, K_RENDER),
        lambda: vofront.align_translation(bad, IMG),
        lambda: vofront.klt(IMG, bad, np.zeros((1, 2))),
        lambda: vofront.align_se3(bad, np.ones((64, 64), np.float32), IMG, K_RENDER),
        lambda: vofront.Odometry("feature", K_RENDER).track(bad),
    ]
    for call in calls:
        with pytest.raises(ValueError):
            call()


@pytest.mark.parametrize(
    "k",
    [
        np.eye(4),
        np.array([[500, 1, 320], [0, 500, 240], [0, 0, 1.0]]),
        np.array([[-500, 0, 320], [0, 500, 240], [0, 0, 1.0]]),
        np.array([[500, 0, np.inf], [0, 500, 240], [0, 0, 1.0]]),
        np.array([[500, 0, 320], [0, 500, 240], [0, 0, 2.0]]),
        "K",
    ],
)
def test_bad_intrinsics_raise_value_error(k):
    with pytest.raises(ValueError, match="K"):
        vofront.two_view(IMG, IMG, k)
    with pytest.raises(ValueError, match="K"):
        vofront.Odometry("direct", k)


def test_distortion_forms():
    k = K_RENDER.tolist()
    vofront.Odometry("direct", k, dist=[0.1, -0.2])
    vofront.Odometry("direct", k, dist=np.array([[0.1, -0.2, 0.001, 0.0, 0.05]]))
    vofront.Odometry("direct", k, dist=[0.1, -0.2, 0, 0, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="dist"):
        vofront.Odometry("direct", k, dist=[0.1, -0.2, 0, 0, 0, 0.3])
    with pytest.raises(ValueError):
        vofront.Odometry("direct", k, dist=[np.nan])


def test_bad_parameters():
    with pytest.raises(ValueError, match="method"):
        vofront.two_view(IMG, IMG, K_RENDER, method="both")
    with pytest.raises(ValueError, match="depth_scale"):
        vofront.two_view(IMG, IMG, K_RENDER, depth1=np.zeros((64, 64), np.uint16), depth_scale=0)
    with pytest.raises(ValueError):
        vofront.align_translation(IMG, IMG, levels=0)
    with pytest.raises((ValueError, OverflowError, TypeError)):
        vofront.orb(IMG, -1)


def test_missing_and_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError):
        vofront.load_gray(tmp_path / "none.png")
    not_png = tmp_path / "x.png"
    not_png.write_bytes(b"not an image")
    with pytest.raises(OSError, match="not a supported image"):
        vofront.load_gray(not_png)
    with pytest.raises(OSError):
        vofront.load_depth(not_png)


def test_estimators_release_results_for_threads():
    """Calls from several threads at once (the GIL is released) give the same results."""
    from concurrent.futures import ThreadPoolExecutor

    y, x = np.mgrid[0:120, 0:160].astype(np.float32)
    a = (100 + 50 * np.sin(x * 0.2) * np.cos(y * 0.3)).astype(np.float32)
    b = (100 + 50 * np.sin((x - 1.0) * 0.2) * np.cos(y * 0.3)).astype(np.float32)
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda _: vofront.align_translation(a, b)["d"], range(8)))
    for r in results:
        np.testing.assert_array_equal(r, results[0])
