"""compare: every tracker a dataset allows on the same frames, as `vofront compare --json`."""

import pytest

import vofront
from conftest import cli_json


def test_compare_equals_cli(sequence):
    methods = ["direct", "feature-rgbd"]
    out = vofront.compare(sequence, methods=methods)
    expected = cli_json("compare", str(sequence), "--methods", ",".join(methods))
    assert [t["method"] for t in out["trackers"]] == methods
    assert out["frames"] == expected["frames"] == 12 and out["ground_truth"]
    for got, want in zip(out["trackers"], expected["trackers"]):
        assert got["error"] is None and got["alignment"] == "se3"
        assert got["posed"] == want["posed"] == 12
        assert got["ate"]["rmse"] == pytest.approx(want["ate"]["rmse"], abs=1e-12)
        assert got["ate"]["rmse"] < 0.005
        assert [p["status"] for p in got["series"]] == [p["status"] for p in want["series"]]
        assert all(p["error_m"] is not None for p in got["series"])


def test_compare_runs_what_the_dataset_allows_and_says_why_not_the_rest(sequence, tmp_path):
    out = vofront.compare(sequence, max_frames=3, out_dir=tmp_path)
    names = [t["method"] for t in out["trackers"]]
    assert {"direct", "feature-rgbd", "mono"} <= set(names)
    assert "stereo" not in names and "direct-stereo" not in names
    assert {s["method"] for s in out["skipped"]} == {"stereo", "direct-stereo"}
    assert all("stereo rig" in s["reason"] for s in out["skipped"])
    assert all(t["frames"] == 3 for t in out["trackers"])
    assert "<svg" in (tmp_path / "report.html").read_text()
    failed = vofront.compare(sequence, methods=["stereo"], max_frames=2)
    assert "stereo rig" in failed["trackers"][0]["error"]
    assert "posed" not in failed["trackers"][0]
    with pytest.raises(ValueError, match="unknown tracker"):
        vofront.compare(sequence, methods=["sideways"])
