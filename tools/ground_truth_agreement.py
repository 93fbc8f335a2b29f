"""Do the two-view errors against KITTI's poses.txt belong to vofront or to the ground truth?

For every consecutive and 3-apart pair of the shared KITTI clips, vofront's feature two-view
pose (`vofront two-view --method feature --json`) and an independent one (OpenCV SIFT, 4000
features, ratio 0.8, PoseLib's LO-RANSAC relative pose with its refinement) are compared with
the ground truth and with each other, in units of vofront's stated sigmas. When the two
estimates agree with each other far better than either agrees with poses.txt, and their errors
against it are correlated, the ground truth carries those errors.

Run with the peers' Python (`../shared/tools/peers/setup.sh` prints it):
    python tools/ground_truth_agreement.py target/release/vofront ../shared/data
"""
import concurrent.futures as cf
import json
import subprocess
import sys

import cv2
import numpy as np
import poselib
from scipy.spatial.transform import Rotation

BIN, DATA = sys.argv[1], sys.argv[2]
CLIPS, STEPS = ("kitti_06", "kitti_01"), (1, 3)


def intrinsics(clip):
    for line in open(f"{DATA}/{clip}/calib.txt"):
        key, *values = line.split()
        if key == "P0:":
            p = np.array(list(map(float, values))).reshape(3, 4)
            return p[0, 0], p[1, 1], p[0, 2], p[1, 2]
    raise ValueError(f"no P0 in {clip}/calib.txt")


def poses(clip):
    out = []
    for line in open(f"{DATA}/{clip}/poses.txt"):
        t = np.eye(4)
        t[:3] = np.array(list(map(float, line.split()))).reshape(3, 4)
        out.append(t)
    return out


def image(clip, k):
    return f"{DATA}/{clip}/image_0/{k:06d}.png"


def vofront(clip, a, b):
    fx, fy, cx, cy = intrinsics(clip)
    cmd = [BIN, "two-view", image(clip, a), image(clip, b), "--fx", str(fx), "--fy", str(fy),
           "--cx", str(cx), "--cy", str(cy), "--method", "feature", "--json"]
    f = json.loads(subprocess.run(cmd, capture_output=True, text=True).stdout)["feature"]
    q = f["quality"]
    return (np.array(f["R"]), np.array(f["t"]), q["rotation_sigma_deg"],
            q["translation_direction_sigma_deg"])


SIFT = cv2.SIFT_create(4000)


def independent(clip, a, b):
    fx, fy, cx, cy = intrinsics(clip)
    images = [cv2.imread(image(clip, k), cv2.IMREAD_GRAYSCALE) for k in (a, b)]
    (k1, d1), (k2, d2) = [SIFT.detectAndCompute(i, None) for i in images]
    good = [m for m, n in cv2.BFMatcher().knnMatch(d1, d2, k=2) if m.distance < 0.8 * n.distance]
    p1 = np.array([k1[m.queryIdx].pt for m in good])
    p2 = np.array([k2[m.trainIdx].pt for m in good])
    h, w = images[0].shape
    cam = {"model": "PINHOLE", "width": w, "height": h, "params": [fx, fy, cx, cy]}
    pose, _ = poselib.estimate_relative_pose(p1, p2, cam, cam, {"max_epipolar_error": 1.0}, {})
    return pose.R, pose.t / np.linalg.norm(pose.t)


def angle_deg(u, v):
    c = np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v))
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def rotation_error_deg(r, truth):
    """Rotation vector of `r truth^T`, degrees."""
    return np.degrees(Rotation.from_matrix(r @ truth.T).as_rotvec())


def main():
    jobs = [(c, k, k + s) for c in CLIPS for s in STEPS for k in range(len(poses(c)) - s)]
    with cf.ThreadPoolExecutor(2) as ex:
        results = list(ex.map(lambda j: (j, vofront(*j), independent(*j)), jobs))
    ours, theirs, rot_sigma, rows = [], [], [], []
    for (clip, a, b), (r, t, sr, st), (ri, ti) in results:
        truth = np.linalg.inv(poses(clip)[b]) @ poses(clip)[a]
        ours.append(rotation_error_deg(r, truth[:3, :3]))
        theirs.append(rotation_error_deg(ri, truth[:3, :3]))
        rot_sigma.append(sr)
        rows.append((angle_deg(t, truth[:3, 3]) / st, angle_deg(t, ti) / st))
    ours, theirs, rot_sigma = np.array(ours), np.array(theirs), np.array(rot_sigma)
    print(f"{len(jobs)} pairs")
    for k, axis in enumerate("xyz"):
        print(f"  rotation error about {axis}: correlation of ours and the independent one "
              f"{np.corrcoef(ours[:, k], theirs[:, k])[0, 1]:.2f}; rms ours "
              f"{np.sqrt(np.mean(ours[:, k] ** 2)):.4f} deg, independent "
              f"{np.sqrt(np.mean(theirs[:, k] ** 2)):.4f} deg, of their difference "
              f"{np.sqrt(np.mean((ours[:, k] - theirs[:, k]) ** 2)):.4f} deg")
    against = {
        "rotation": (np.linalg.norm(ours, axis=1) / rot_sigma,
                     np.linalg.norm(ours - theirs, axis=1) / rot_sigma),
        "direction": tuple(np.array(c) for c in zip(*rows)),
    }
    for name, (truth, other) in against.items():
        print(f"  {name}: error / sigma against poses.txt median {np.median(truth):.2f}, "
              f"{np.mean(truth > 5) * 100:.1f}% beyond 5 sigma; distance to the independent "
              f"estimate / sigma median {np.median(other):.2f}, "
              f"{np.mean(other > 5) * 100:.1f}% beyond 5 sigma")
    far = [f"{c} {a}-{b}: {z:.1f} / {d:.1f}" for (c, a, b), z, d
           in zip(jobs, *against["rotation"]) if z > 5]
    print("  rotation beyond 5 sigma of poses.txt (sigmas from the truth / from the independent):")
    print("    " + "; ".join(far))


if __name__ == "__main__":
    main()
