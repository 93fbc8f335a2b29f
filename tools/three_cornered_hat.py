"""How noisy is each frame-to-frame rotation, the ground truth's included?

The "three-cornered hat" of clock metrology: with several independent estimates of the same
quantity, the variance of each pairwise difference is the sum of the two estimates' variances,
`var(a - b) = var(a) + var(b)`, so the variances of every source, the ground truth's among them,
follow from the pairwise ones by least squares. Here the quantity is each consecutive frame
pair's relative rotation, per axis (x right, y down, z forward), and the sources are KITTI's
`poses.txt` and three vofront trackers that share no estimation step (`direct-stereo`:
photometric alignment to stereo depths; `stereo`: ORB and PnP on a stereo map; `mono`: ORB
and a monocular map; rotation needs no scale).

The trackers see the same images, so an error of the images themselves (real camera vibration
that the GPS/INS does not see, for instance) is common to them and is counted here as the
ground truth's. With 50 pairs per clip each pairwise variance is known to about 20%, so a
source's own variance much smaller than the others' is only bounded, not measured.

For `direct-stereo` it also prints the median rotation sigma per axis of its g2o edges (every
frame is a keyframe on these clips, so each edge is a consecutive pair).

Further sources, a peer's trajectories for instance, are given as `NAME=PATH` with `{clip}` in
the path standing for the clip's name; they join the hat as one more source each (a peer that
shares no step with the trackers above: OpenCV's stereo chain, `opencv_peer.py stereo`).

Run with the peers' Python (`../shared/tools/peers/setup.sh` prints it):
    python tools/three_cornered_hat.py target/release/vofront ../shared/data [NAME=PATH ...]
"""
import itertools
import os
import subprocess
import sys
import tempfile

import numpy as np
from scipy.spatial.transform import Rotation

BIN, DATA = sys.argv[1], sys.argv[2]
EXTRA = dict(arg.split("=", 1) for arg in sys.argv[3:])
CLIPS = ("kitti_06", "kitti_01")
TRACKERS = ("direct-stereo", "stereo", "mono")


def tum_poses(path):
    """Camera-to-world 4x4 poses of a TUM trajectory file, in file order."""
    out = []
    for line in open(path):
        if not line.strip() or line.startswith("#"):
            continue
        v = list(map(float, line.split()[1:8]))
        t = np.eye(4)
        t[:3, :3] = Rotation.from_quat(v[3:7]).as_matrix()
        t[:3, 3] = v[:3]
        out.append(t)
    return out


def relative_rotations(poses):
    """`R_21 = R_w2^T R_w1` of every consecutive pair."""
    return [b[:3, :3].T @ a[:3, :3] for a, b in zip(poses, poses[1:])]


def g2o_rotation_sigmas_deg(path):
    """Per-axis rotation sigma of every g2o edge, degrees (the information's rotation block is
    that of the quaternion's vector part, half the angle)."""
    sigmas = []
    for line in open(path):
        p = line.split()
        if p[0] != "EDGE_SE3:QUAT":
            continue
        upper = iter(map(float, p[10:31]))
        info = np.zeros((6, 6))
        for r in range(6):
            for c in range(r, 6):
                info[r, c] = info[c, r] = next(upper)
        cov = np.linalg.inv(info)
        sigmas.append(2 * np.degrees(np.sqrt(np.diag(cov)[3:])))
    return np.array(sigmas)


def clip_report(clip, work):
    sources = {"ground truth": tum_poses(f"{DATA}/{clip}/groundtruth_tum.txt")}
    for tracker in TRACKERS:
        out, graph = f"{work}/{clip}.{tracker}.txt", f"{work}/{clip}.{tracker}.g2o"
        subprocess.run(
            [BIN, "odometry", f"{DATA}/{clip}", "--method", tracker, "--out", out, "--graph", graph],
            check=True,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        sources[tracker] = tum_poses(out)
    for name, path in EXTRA.items():
        sources[name] = tum_poses(path.replace("{clip}", clip))
    names = list(sources)
    rel = {k: relative_rotations(v) for k, v in sources.items()}
    n = min(len(r) for r in rel.values())
    rows, variances = [], []
    print(f"{clip}: {n} consecutive pairs; rms of the pairwise differences, deg (x, y, z)")
    for a, b in itertools.combinations(range(len(names)), 2):
        diff = np.array(
            [
                np.degrees(Rotation.from_matrix(rel[names[a]][i] @ rel[names[b]][i].T).as_rotvec())
                for i in range(n)
            ]
        )
        var = (diff**2).mean(axis=0)
        print(f"  {names[a]:>13} - {names[b]:<13} {np.round(np.sqrt(var), 4)}")
        row = np.zeros(len(names))
        row[[a, b]] = 1.0
        rows.append(row)
        variances.append(var)
    own = np.linalg.lstsq(np.array(rows), np.array(variances), rcond=None)[0]
    print("  each source's own rms, deg (x, y, z); a negative variance is printed as 0")
    for name, var in zip(names, own):
        print(f"  {name:>13} {np.round(np.sqrt(np.clip(var, 0.0, None)), 4)}")
    sigmas = g2o_rotation_sigmas_deg(f"{work}/{clip}.direct-stereo.g2o")
    print(f"  direct-stereo's median rotation sigma {np.round(np.median(sigmas, axis=0), 4)}")


def main():
    with tempfile.TemporaryDirectory() as work:
        for clip in CLIPS:
            if not os.path.isdir(f"{DATA}/{clip}"):
                print(f"{clip}: absent, skipped")
                continue
            clip_report(clip, work)


if __name__ == "__main__":
    main()
