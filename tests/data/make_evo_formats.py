"""Writes the KITTI and EuRoC versions of tests/data/evo_gt.txt for tests/eval_formats.rs.

- evo_gt.kitti / evo_gt.times: the ground truth as KITTI poses (12 numbers, row-major 3x4
  T_wc) and its stamps (one per line, as KITTI's times.txt);
- evo_gt_euroc.csv: the ground truth as EuRoC's state_groundtruth_estimate0/data.csv
  (header, nanosecond stamps, p xyz, q wxyz, then 9 velocity/bias columns of zeros);
- evo_est_all.kitti: an estimate of all 120 poses (no pose dropped, so KITTI files match by
  index): the ground truth moved by a similarity (scale 0.7, 30 deg, shift) with smooth
  position (~cm) and rotation (~0.5 deg) noise, as make_evo_pair.py but different noise.
Run: /root/.cache/vofront-peers/bin/python tests/data/make_evo_formats.py
"""
import math
import pathlib

import numpy as np
from scipy.spatial.transform import Rotation

out = pathlib.Path(__file__).parent
gt = np.loadtxt(out / "evo_gt.txt", comments="#")


def kitti_line(p, r):
    m = np.hstack([r.as_matrix(), p.reshape(3, 1)])
    return " ".join(f"{v:.9f}" for v in m.ravel())


sim_r = Rotation.from_rotvec(math.radians(30) * np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5]))
sim_s, sim_t = 0.7, np.array([1.5, -0.4, 2.0])
kitti, times, euroc, est = [], [], [], []
euroc.append("#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
             "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
             "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
             "b_a_RS_S_z [m s^-2]")
for i, row in enumerate(gt):
    t, p, q = row[0], row[1:4], row[4:8]
    r = Rotation.from_quat(q)
    kitti.append(kitti_line(p, r))
    times.append(f"{t:.6f}")
    ns = int(round(t * 1e6)) * 1000
    euroc.append(",".join([str(ns)] + [f"{v:.9f}" for v in (*p, q[3], q[0], q[1], q[2])] + ["0"] * 9))
    noise_p = 0.01 * np.array([math.cos(1.3 * i), math.sin(2.1 * i), math.cos(0.8 * i + 0.5)])
    noise_r = Rotation.from_rotvec(math.radians(0.5) * np.array([math.cos(1.9 * i), math.sin(0.6 * i), math.cos(2.2 * i)]))
    est.append(kitti_line(sim_s * sim_r.apply(p + noise_p) + sim_t, sim_r * r * noise_r))
(out / "evo_gt.kitti").write_text("\n".join(kitti) + "\n")
(out / "evo_gt.times").write_text("\n".join(times) + "\n")
(out / "evo_gt_euroc.csv").write_text("\n".join(euroc) + "\n")
(out / "evo_est_all.kitti").write_text("\n".join(est) + "\n")
