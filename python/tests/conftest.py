"""Shared fixtures: rendered scenes with exact ground truth, written by the workspace's own
examples, and the `vofront` command line to compare against."""

import functools
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]

#: Intrinsics of the rendered fixtures (`vofront_fixtures::scene::default_camera`).
K_RENDER = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])


@functools.lru_cache(maxsize=None)
def _target_dir() -> Path:
    """The workspace's release outputs, built once per test session.

    One `cargo build --workspace --bins --examples` resolves features as `cargo test
    --workspace` does (dev-dependencies included), so after the Rust tests it builds nothing;
    a `cargo run -p PACKAGE` per call would resolve each package's features on their own and
    rebuild hundreds of shared dependencies.
    """
    build = subprocess.run(
        ["cargo", "build", "--release", "-q", "--workspace", "--bins", "--examples"],
        cwd=REPO,
        check=False,
        capture_output=True,
        text=True,
    )
    if build.returncode != 0:
        raise RuntimeError(f"cargo build failed:\n{build.stderr}")
    meta = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=REPO,
        check=True,
        capture_output=True,
        text=True,
    )
    return Path(json.loads(meta.stdout)["target_directory"]) / "release"


def cargo_run(*args: str) -> str:
    """What `cargo run --release -q ARGS` prints, for `--bin NAME` or `--example NAME` (with
    `-p PACKAGE`) followed by `-- PROGRAM_ARGS`, run from the session's one build."""
    split = args.index("--") if "--" in args else len(args)
    cargo_args, program_args = list(args[:split]), list(args[split + 1 :])
    if "--bin" in cargo_args:
        exe = _target_dir() / cargo_args[cargo_args.index("--bin") + 1]
    elif "--example" in cargo_args:
        exe = _target_dir() / "examples" / cargo_args[cargo_args.index("--example") + 1]
    else:
        raise ValueError(f"cargo_run needs --bin or --example: {args}")
    out = subprocess.run(
        [str(exe), *program_args], cwd=REPO, check=False, capture_output=True, text=True
    )
    if out.returncode != 0:
        raise RuntimeError(f"{exe.name} {' '.join(program_args)} failed:\n{out.stderr}")
    return out.stdout


def cli(*args: str) -> str:
    """The `vofront` program's standard output."""
    return cargo_run("--bin", "vofront", "--", *args)


def cli_json(*args: str) -> dict:
    return json.loads(cli(*args, "--json"))


def tum_pose(path: Path) -> np.ndarray:
    """A `tx ty tz qx qy qz qw` file as a 4x4 camera-to-world matrix."""
    tx, ty, tz, qx, qy, qz, qw = (float(v) for v in path.read_text().split())
    return pose_from(np.array([tx, ty, tz]), np.array([qx, qy, qz, qw]))


def pose_from(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    x, y, z, w = q / np.linalg.norm(q)
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = r, t
    return m


def rotation_angle_deg(r: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))))


@pytest.fixture(scope="session")
def pairs(tmp_path_factory) -> list:
    """Two rendered RGB-D pairs (`render_pairs`): folders with img/dep/pose of prev and curr."""
    root = tmp_path_factory.mktemp("pairs")
    cargo_run("-p", "vofront-fixtures", "--example", "render_pairs", "--", str(root), "2")
    return [root / str(k) for k in range(2)]


@pytest.fixture(scope="session")
def wide_pairs(tmp_path_factory) -> list:
    """Two rendered pairs with a 5-25 cm baseline, enough parallax for a translation direction."""
    root = tmp_path_factory.mktemp("wide_pairs")
    cargo_run("-p", "vofront-fixtures", "--example", "render_pairs", "--", str(root), "2", "0.25")
    return [root / str(k) for k in range(2)]


@pytest.fixture(scope="session")
def sequence(tmp_path_factory) -> Path:
    """A 12-frame rendered TUM RGB-D sequence of the room with exact ground truth."""
    root = tmp_path_factory.mktemp("sequence") / "room"
    cargo_run("-p", "vofront-python", "--example", "room_sequence", "--", str(root), "12")
    return root


def truth_t21(pair: Path) -> np.ndarray:
    """`T_21 = inverse(T_w2) T_w1` of a rendered pair."""
    return np.linalg.inv(tum_pose(pair / "pose_curr.txt")) @ tum_pose(pair / "pose_prev.txt")


@pytest.fixture(scope="session")
def euroc_sequence(tmp_path_factory) -> Path:
    """A 30-frame rendered EuRoC MAV sequence of the room, its camera mounted on the body by a
    non-identity ``T_BS``, with ``camera_groundtruth.txt`` (TUM, the true camera poses)."""
    root = tmp_path_factory.mktemp("euroc") / "room"
    cargo_run("-p", "vofront-python", "--example", "euroc_sequence", "--", str(root), "30")
    return root


@pytest.fixture(scope="session")
def stereo_sequence(tmp_path_factory) -> Path:
    """A 30-frame rendered stereo drive (`vofront_fixtures::stereo`, 0.5 m baseline) written as
    a KITTI folder: ``image_0/``, ``image_1/``, ``calib.txt``, ``times.txt``, exact
    ``poses.txt`` and ``groundtruth_tum.txt``."""
    root = tmp_path_factory.mktemp("stereo") / "drive"
    cargo_run("-p", "vofront-fixtures", "--example", "render_stereo", "--", str(root), "30")
    return root
