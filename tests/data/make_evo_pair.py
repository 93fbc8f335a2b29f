"""Writes tests/data/evo_gt.txt and evo_est.txt (TUM format) for tests/eval.rs.

Ground truth: vofront_fixtures::scene::room_trajectory(120) stamped 1000 + i/30 s.
Estimate: the ground truth moved by a similarity (scale 0.7, 30 deg about a tilted axis,
shift), with smooth deterministic position (~cm) and rotation (~0.5 deg) noise, every 7th
pose dropped, stamps jittered by up to 4 ms and three stamps pushed 20 ms off (unmatchable
with evo's 10 ms tolerance).
Run: /root/.cache/vofront-peers/bin/python tests/data/make_evo_pair.py
"""
import math
import pathlib

import numpy as np
from scipy.spatial.transform import Rotation

out = pathlib.Path(__file__).parent


def room_pose(i):
    s = i / 30.0
    pos = np.array([0.4 * math.sin(0.7 * s), 0.15 * math.sin(1.1 * s), 0.3 * math.sin(s) - 0.2])
    yaw, pitch, roll = 0.12 * math.sin(0.9 * s), 0.06 * math.sin(1.3 * s), 0.03 * math.sin(0.5 * s)
    # nalgebra from_euler_angles(r, p, y) = Rz(y) Ry(p) Rx(r), called with (pitch, yaw, roll)
    rot = Rotation.from_euler("ZYX", [roll, yaw, pitch])
    return pos, rot


def line(t, p, r):
    q = r.as_quat()  # x y z w
    return f"{t:.6f} " + " ".join(f"{v:.9f}" for v in (*p, *q))


n = 120
sim_r = Rotation.from_rotvec(math.radians(30) * np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5]))
sim_s, sim_t = 0.7, np.array([1.5, -0.4, 2.0])
gt, est = ["# ground truth: room_trajectory(120)"], ["# estimate"]
for i in range(n):
    t = 1000.0 + i / 30.0
    p, r = room_pose(i)
    gt.append(line(t, p, r))
    if i % 7 == 3:
        continue
    noise_p = 0.01 * np.array([math.sin(1.7 * i), math.cos(2.3 * i), math.sin(0.9 * i + 1.0)])
    noise_r = Rotation.from_rotvec(math.radians(0.5) * np.array([math.sin(1.1 * i), math.cos(0.7 * i), math.sin(2.9 * i)]))
    pe = sim_s * sim_r.apply(p + noise_p) + sim_t
    re = sim_r * r * noise_r
    jitter = 0.004 * math.sin(3.7 * i)
    if i in (20, 55, 90):
        jitter = 0.02
    est.append(line(t + jitter, pe, re))
(out / "evo_gt.txt").write_text("\n".join(gt) + "\n")
(out / "evo_est.txt").write_text("\n".join(est) + "\n")
