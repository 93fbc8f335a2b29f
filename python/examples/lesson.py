"""The lesson's two paradigms on one image pair, with vofront instead of OpenCV.

The original script: ORB features -> BFMatcher (Hamming, ratio test) -> findEssentialMat
(RANSAC) -> recoverPose, printing R and t; then a translation-only photometric alignment,
printing the estimated shift. This port prints the same quantities:

    python examples/lesson.py IMG1 IMG2 [--K fx,fy,cx,cy] [--dist k1,k2,p1,p2,k3]

Defaults: the shared TUM freiburg1 pair `../shared/data/tum_fr1_xyz_pairs/case_1` and its
calibration. Convention: `x2 = R x1 + t` maps frame-1 points into frame 2; `t` has unit length
(monocular scale is unknown); the shift `d` satisfies `img2(x + d) = img1(x)`, in pixels.
"""

import argparse
import sys
from pathlib import Path

import numpy as np

import vofront

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data" / "tum_fr1_xyz_pairs" / "case_1"
FR1_K = "517.3,516.5,318.6,255.3"
FR1_DIST = "0.2624,-0.9531,-0.0054,0.0026,1.1633"


def numbers(text: str) -> list:
    return [float(v) for v in text.split(",")]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("img1", nargs="?", default=str(SHARED / "img_prev.png"))
    parser.add_argument("img2", nargs="?", default=str(SHARED / "img_curr.png"))
    parser.add_argument("--K", default=FR1_K, help="fx,fy,cx,cy in pixels")
    parser.add_argument("--dist", default=None, help="k1,k2,p1,p2,k3 (fr1's with the default pair)")
    parser.add_argument("--features", type=int, default=2000)
    args = parser.parse_args()
    using_default_pair = args.img1 == str(SHARED / "img_prev.png")
    dist = numbers(args.dist) if args.dist else (numbers(FR1_DIST) if using_default_pair else None)
    fx, fy, cx, cy = numbers(args.K)
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])

    try:
        img1, img2 = vofront.load_gray(args.img1), vofront.load_gray(args.img2)
    except OSError as e:
        print(f"lesson.py: {e}", file=sys.stderr)
        return 1

    # Paradigm 1: features. ORB keypoints and descriptors, brute-force Hamming matching with
    # Lowe's ratio test, then the essential matrix by RANSAC and the pose it implies.
    kp1, des1 = vofront.orb(img1, args.features)
    kp2, des2 = vofront.orb(img2, args.features)
    print(f"ORB keypoints: {len(kp1)} in image 1, {len(kp2)} in image 2")
    matches = vofront.match(des1, des2, ratio=0.75)
    print(f"matches after the ratio test: {len(matches)}")
    pts1 = kp1[matches[:, 0], :2].astype(np.float64)
    pts2 = kp2[matches[:, 1], :2].astype(np.float64)
    try:
        pose = vofront.relpose(pts1, pts2, K, dist=dist)
    except vofront.VofrontError as e:
        print(f"relative pose failed: {e}")
    else:
        print(f"RANSAC inliers: {pose['inliers']} ({pose['model']} model)")
        print("R =")
        print(np.array2string(np.asarray(pose["R"]), precision=6, suppress_small=True))
        print("t =")
        print(np.array2string(np.asarray(pose["t"]).reshape(3, 1), precision=6, suppress_small=True))

    # Paradigm 2: direct. Translation-only photometric alignment of the whole images.
    try:
        shift = vofront.align_translation(img1, img2)
    except vofront.VofrontError as e:
        print(f"photometric alignment failed: {e}")
        return 1
    dx, dy = shift["d"]
    print(f"estimated shift: dx = {dx:.3f} px, dy = {dy:.3f} px "
          f"(rmse {shift['rmse']:.2f} grey levels, {shift['iterations']} iterations)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
