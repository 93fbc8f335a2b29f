"""vofront: a pure-Rust visual-odometry front-end, numpy in and out.

Pose convention: ``T_21`` maps frame-1 points into frame 2, ``x2 = R @ x1 + t``, returned as a
4x4 float64 matrix (``R`` 3x3, ``t`` 3-vector; unit length for monocular feature poses,
metres for RGB-D poses). Trajectories are camera-to-world (``T_wc``), TUM rows
``t tx ty tz qx qy qz qw``. Images are 2-D ``uint8`` or ``float32`` arrays of grey levels
(0..255); pixel (0, 0) is the centre of the top-left pixel. ``K`` is the 3x3 intrinsic matrix
in pixels, ``dist`` OpenCV's ``(k1, k2, p1, p2, k3)``.

Errors: bad arrays or parameters raise ``ValueError``; an estimator that fails on valid input
raises ``VofrontError`` (a ``ValueError``) with the library's message; unreadable files raise
``OSError``. The GIL is released while Rust computes.
"""

from ._vofront import (
    Odometry,
    VofrontError,
    __version__,
    align_se3,
    align_translation,
    ate,
    compare,
    klt,
    load_depth,
    load_gray,
    orb,
    relpose,
    rpe,
    run_odometry,
    two_view,
)
from ._vofront import match  # noqa: A004 -- the library's name for descriptor matching

__all__ = [
    "Odometry",
    "VofrontError",
    "__version__",
    "align_se3",
    "align_translation",
    "ate",
    "compare",
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
