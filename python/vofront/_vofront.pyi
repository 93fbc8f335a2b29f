"""Type stubs of the compiled module ``vofront._vofront`` (re-exported by ``vofront``).

Pose convention: ``T_21`` maps frame-1 points into frame 2, ``x2 = R @ x1 + t`` (4x4 float64).
Trajectories are camera-to-world ``T_wc``. Images: 2-D uint8 or float32 grey levels (0..255).
``K``: 3x3 pixels, ``dist``: OpenCV ``(k1, k2, p1, p2, k3)``.
"""

from os import PathLike
from typing import Any, Optional, Tuple, Union, final

import numpy as np
import numpy.typing as npt

__version__: str
__all__ = [
    "Odometry",
    "VofrontError",
    "__version__",
    "align_se3",
    "align_translation",
    "ate",
    "klt",
    "load_depth",
    "load_gray",
    "match",
    "orb",
    "relpose",
    "rpe",
    "run_odometry",
    "two_view",
]

_ArrayLike = npt.ArrayLike
_Image = Union[npt.NDArray[np.uint8], npt.NDArray[np.float32]]
_Depth = Union[npt.NDArray[np.uint16], npt.NDArray[np.float32], npt.NDArray[np.float64]]
_TrajectoryLike = Union[str, PathLike, _ArrayLike]

class VofrontError(ValueError):
    """An estimator failed on valid input; the message is the library's."""

def load_gray(path: Union[str, PathLike]) -> npt.NDArray[np.uint8]:
    """A PNG or JPEG file as (H, W) uint8 grey (Rec. 601 luma), as ``vofront two-view`` reads it."""

def load_depth(path: Union[str, PathLike], depth_scale: float = 5000.0) -> npt.NDArray[np.float32]:
    """A 16-bit depth PNG as (H, W) float32 metres (value / depth_scale, 0 = unknown)."""

def two_view(
    img1: _Image,
    img2: _Image,
    K: _ArrayLike,
    dist: Optional[_ArrayLike] = None,
    method: str = "all",
    depth1: Optional[_Depth] = None,
    depth_scale: float = 5000.0,
    features: int = 2000,
    right1: Optional[_Image] = None,
    baseline: Optional[float] = None,
) -> dict[str, Any]:
    """Feature pose, direct 2D shift and (with ``depth1``) direct SE(3) pose of one pair.

    The same dict as ``vofront two-view --json``: keys ``feature``, ``direct_translation``,
    ``direct_se3`` (those that ran, per ``method`` = ``feature`` | ``direct`` | ``all``), each
    an estimate or ``{"error": message}``. ``depth1``: uint16 raw units divided by
    ``depth_scale`` (5000 per metre for TUM) or float metres. Every estimate with a pose also
    carries ``T_21`` as a 4x4 float64 array (feature: unit translation; SE(3): metres).
    ``right1`` (frame 1's rectified right image) with ``baseline`` (metres) adds
    ``feature_stereo``, the metric pose of frame 2 by PnP against frame 1's stereo points, and
    without ``depth1`` runs ``direct_se3`` on frame 1's stereo depth.
    """

def relpose(
    x1: _ArrayLike, x2: _ArrayLike, K: _ArrayLike, dist: Optional[_ArrayLike] = None
) -> dict[str, Any]:
    """Robust relative pose ``T_21`` (unit ``t``) from (N, 2) pixel correspondences.

    Keys of ``vofront relpose``: ``R`` (3x3), ``t`` (3,), ``inliers``, ``ms``; plus ``T_21``
    (4x4), ``model`` (``essential`` / ``homography``), ``parallax_deg``, ``inlier_mask`` (N,),
    ``quality`` (``verdict``, ``reasons``, support, ``sigma``, covariances and sigmas).
    """

def orb(img: _Image, n: int = 2000) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8]]:
    """ORB features: ``(keypoints, descriptors)``.

    ``keypoints`` (N, 6) float32 columns ``x, y`` (pixels), ``scale`` (level-0 pixels per level
    pixel), ``angle`` (radians, y down), ``response`` (Harris), ``level``; ``descriptors``
    (N, 32) uint8 in OpenCV's bit order.
    """

def match(
    d1: npt.NDArray[np.uint8],
    d2: npt.NDArray[np.uint8],
    ratio: Optional[float] = 0.75,
    cross_check: bool = False,
    max_distance: int = 100,
) -> npt.NDArray[np.int64]:
    """Hamming matching of (N, 32) descriptors ``d1`` (query) to ``d2`` (train).

    Lowe's ratio test ``d_best < ratio * d_second`` (``None`` disables it), at most
    ``max_distance`` bits, optional mutual check. Returns (M, 3) rows ``query, train, distance``.
    """

def align_translation(
    img1: _Image,
    img2: _Image,
    levels: int = 4,
    max_iterations: int = 30,
    affine_brightness: bool = False,
) -> dict[str, Any]:
    """The shift ``d`` (pixels) with ``img2(x + d) = img1(x)``: robust coarse-to-fine alignment.

    Keys: ``d`` (2,), ``iterations``, ``iterations_per_level``, ``rmse`` (grey levels),
    ``used_fraction``, ``covariance`` (2x2 pixels^2, None when unknown), ``a``, ``b``, ``converged``, ``ms``.
    """

def align_se3(
    ref_img: _Image,
    ref_depth: _Depth,
    cur_img: _Image,
    K: _ArrayLike,
    dist: Optional[_ArrayLike] = None,
    prior: Optional[_ArrayLike] = None,
    depth_scale: float = 5000.0,
) -> dict[str, Any]:
    """Direct photometric SE(3) alignment: ``T_21`` of the current camera w.r.t. the reference.

    Model ``cur(pi(K T_21 pi^-1(p, Z))) = a ref(p) + b``; ``prior`` an initial 4x4 ``T_21``.
    Keys: ``T_21`` (4x4, metres), ``R``, ``t``, ``a``, ``b``, ``inlier_ratio``, ``rmse``,
    ``sigma`` (grey levels), ``valid_pixels``, ``iterations``, ``covariance`` (6x6, left
    increment ``(rho, phi)``, metres and radians; None when unknown), ``reason``, ``ms``.
    """

def klt(
    img1: _Image,
    img2: _Image,
    points: _ArrayLike,
    window: int = 21,
    levels: int = 4,
    forward_backward: Optional[float] = 1.0,
) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8], npt.NDArray[np.float32]]:
    """Pyramidal Lucas-Kanade: ``(next_points (N, 2), status (N,) 1 = tracked, error (N,))``."""

@final
class Odometry:
    """Frame-by-frame visual odometry: ``direct``, ``feature-rgbd``, ``mono`` (``feature``,
    its former name, is still accepted), ``stereo``, ``direct-stereo`` or ``direct-mono``
    (``direct_mono``; sparse photometric, monocular, scale arbitrary), the trackers of
    ``vofront odometry --method``. The stereo methods need the rig: ``T_left_right`` (4x4
    pose of the right camera in the left camera frame, metres) or ``baseline`` (metres, a
    rectified pair), and ``K_right``/``dist_right`` when the right camera differs."""

    def __new__(
        cls,
        method: str,
        K: _ArrayLike,
        dist: Optional[_ArrayLike] = None,
        depth_scale: float = 5000.0,
        baseline: Optional[float] = None,
        K_right: Optional[_ArrayLike] = None,
        dist_right: Optional[_ArrayLike] = None,
        T_left_right: Optional[_ArrayLike] = None,
    ) -> "Odometry": ...
    def track(
        self,
        image: _Image,
        depth: Optional[Union[_Depth, _Image]] = None,
        timestamp: Optional[float] = None,
        right: Optional[_Image] = None,
    ) -> dict[str, Any]:
        """Tracks the next frame (for ``stereo`` and ``direct-stereo``: ``track(left, right,
        timestamp)``, the second argument the right image); returns ``timestamp``, ``pose_wc`` (4x4 ``T_wc``), ``status``
        (``ok`` / ``unreliable`` / ``lost`` / ``reinitialised``), ``quality``, ``message`` and
        ``pose_quality`` (the estimate's quality record: ``verdict``, ``reasons``, sigmas; None
        without an estimate)."""
    def revised(self) -> list[Tuple[int, dict[str, Any]]]:
        """Late estimates made by the last ``track`` call for earlier frames, oldest first, as
        ``(frame index, estimate dict)``: the ``mono`` tracker reports the frames its
        initialisation waits through ``lost``, then locates them once its map exists. Each
        list is handed over once."""
    @property
    def pending(self) -> int:
        """How many of the most recent frames may still be revised (hold them back when
        writing estimates as they come)."""
    @property
    def frames(self) -> int:
        """Frames tracked so far."""

def run_odometry(
    dataset_path: Union[str, PathLike],
    method: str = "direct",
    K: Optional[_ArrayLike] = None,
    dist: Optional[_ArrayLike] = None,
    max_frames: Optional[int] = None,
) -> dict[str, Any]:
    """Tracks a TUM RGB-D, KITTI or EuRoC folder like ``vofront odometry`` (the same
    camera choice, tracker and evaluation: the same trajectory and ATE).

    ``method``: ``direct``, ``feature-rgbd`` or ``mono`` (alias ``feature``). Keys:
    ``trajectory`` (N, 8) TUM rows, ``frames`` (per-frame dicts), ``summary``, ``camera``
    (``source``: where the camera came from); with ground truth ``ground_truth`` (M, 8), the
    CAMERA poses (EuRoC: the body poses times ``T_BS``), and ``ate`` (statistics, metres;
    SE(3)-aligned, Sim(3) for ``mono``; None with ``ate_error`` when it cannot be computed).
    """

def compare(
    dataset_path: Union[str, PathLike],
    methods: Optional[list[str]] = None,
    K: Optional[_ArrayLike] = None,
    dist: Optional[_ArrayLike] = None,
    max_frames: Optional[int] = None,
    out_dir: Optional[Union[str, PathLike]] = None,
) -> dict[str, Any]:
    """Runs every tracker the dataset allows (RGB-D ones with depth, stereo ones with a stereo
    rig, monocular ones always), or the ``methods`` named, on the same frames, like
    ``vofront compare``, and returns the report of ``vofront compare --json``: ``dataset``,
    ``format``, ``frames``, ``camera``, ``ground_truth``, ``trackers`` (per tracker
    ``method``, ``paradigm``, ``alignment``, ``error`` (None when it ran), ``frames``,
    ``tracked``, ``posed``, ``lost``, ``segment_breaks``, ``lost_spans``, ``ms_mean``,
    ``ms_median``, ``ate``, ``ate_percent``, ``rpe``, ``series``), ``skipped``, ``wall_ms``,
    ``interrupted``. ``out_dir``: also write ``report.json`` and ``report.html`` there.
    """

def ate(
    gt: _TrajectoryLike,
    est: _TrajectoryLike,
    align: Optional[str] = "se3",
    max_dt: float = 0.01,
    format: Optional[str] = None,
    gt_times: Optional[Union[str, PathLike]] = None,
    est_times: Optional[Union[str, PathLike]] = None,
) -> dict[str, Any]:
    """Absolute trajectory error (metres) as ``evo_ape``: ``rmse``, ``mean``, ``median``,
    ``std``, ``min``, ``max``, ``sse``, ``count``, ``pairs``, ``alignment``, ``scale``,
    ``errors``. ``align``: ``se3``, ``sim3`` or ``none``.
    ``gt``, ``est``: TUM, KITTI or EuRoC CSV files (``format``: ``tum``, ``kitti`` or
    ``euroc`` for both, else detected from each file), (N, 8) TUM rows or (N, 12) KITTI rows.
    ``gt_times``/``est_times``: KITTI ``times.txt`` of a KITTI file; a KITTI trajectory
    without times is matched to the other by index (same number of poses, else ValueError)."""

def rpe(
    gt: _TrajectoryLike,
    est: _TrajectoryLike,
    align: Optional[str] = "se3",
    max_dt: float = 0.01,
    format: Optional[str] = None,
    gt_times: Optional[Union[str, PathLike]] = None,
    est_times: Optional[Union[str, PathLike]] = None,
) -> dict[str, Any]:
    """Relative pose error per frame as ``evo_rpe --delta 1``: ``translation`` (metres) and
    ``rotation_deg`` statistics, ``rotation_scale`` (``{"scale", "sigma"}``: estimated over
    true rotation, 1 when the calibration agrees; ``None`` without true rotation), ``pairs``.
    ``gt``, ``est``: TUM, KITTI or EuRoC CSV files (``format``: ``tum``, ``kitti`` or
    ``euroc`` for both, else detected from each file), (N, 8) TUM rows or (N, 12) KITTI rows.
    ``gt_times``/``est_times``: KITTI ``times.txt`` of a KITTI file; a KITTI trajectory
    without times is matched to the other by index (same number of poses, else ValueError)."""
