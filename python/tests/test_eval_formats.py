"""ate and rpe on evo's KITTI and EuRoC files (tests/data, made by make_evo_formats.py): the
numbers of evo v1.38.1 (`evo_ape kitti` / `evo_ape euroc`, `evo_rpe`), as in
tests/eval_formats.rs, and the same errors as the CLI."""

from pathlib import Path

import numpy as np
import pytest

import vofront

DATA = Path(__file__).resolve().parents[2] / "tests" / "data"
#: evo_ape kitti evo_gt.kitti evo_est_all.kitti --align (rmse), evo_rpe kitti ... (rmse).
KITTI_APE_SE3 = 0.06379509984447027
KITTI_RPE_TRANS = 0.01159621362770542
KITTI_RPE_DEG = 0.877385241875439
#: evo_ape euroc evo_gt_euroc.csv evo_est.txt --align --correct_scale (rmse), 100 poses.
EUROC_APE_SIM3 = 0.012286853033885638


def test_kitti_files_match_evo_by_index():
    a = vofront.ate(DATA / "evo_gt.kitti", DATA / "evo_est_all.kitti")
    assert a["pairs"] == 120 and a["rmse"] == pytest.approx(KITTI_APE_SE3, abs=1e-6)
    r = vofront.rpe(str(DATA / "evo_gt.kitti"), str(DATA / "evo_est_all.kitti"), format="kitti")
    assert r["translation"]["rmse"] == pytest.approx(KITTI_RPE_TRANS, abs=1e-6)
    assert r["rotation_deg"]["rmse"] == pytest.approx(KITTI_RPE_DEG, abs=1e-6)
    # (N, 12) arrays are KITTI rows, matched by index as the files.
    rows = np.loadtxt(DATA / "evo_est_all.kitti")
    assert vofront.ate(DATA / "evo_gt.kitti", rows)["rmse"] == pytest.approx(a["rmse"], abs=1e-12)


def test_euroc_reference_matches_evo():
    a = vofront.ate(DATA / "evo_gt_euroc.csv", DATA / "evo_est.txt", align="sim3")
    assert a["pairs"] == 100 and a["rmse"] == pytest.approx(EUROC_APE_SIM3, abs=1e-6)


def test_kitti_times_and_errors():
    timed = vofront.ate(DATA / "evo_gt.kitti", DATA / "evo_est.txt", gt_times=DATA / "evo_gt.times")
    tum = vofront.ate(DATA / "evo_gt.txt", DATA / "evo_est.txt")
    assert timed["pairs"] == tum["pairs"] == 100
    assert timed["rmse"] == pytest.approx(tum["rmse"], abs=1e-6)
    with pytest.raises(ValueError, match="matched by index"):
        vofront.ate(DATA / "evo_gt.kitti", DATA / "evo_est.txt")
    with pytest.raises(ValueError, match="only for KITTI"):
        vofront.ate(DATA / "evo_gt.txt", DATA / "evo_est.txt", est_times=DATA / "evo_gt.times")
    with pytest.raises(ValueError, match="format"):
        vofront.ate(DATA / "evo_gt.txt", DATA / "evo_est.txt", format="g2o")
    with pytest.raises(OSError, match="expected 8 fields"):
        vofront.ate(DATA / "evo_gt.kitti", DATA / "evo_est_all.kitti", format="tum")
