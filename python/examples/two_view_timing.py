"""Times `vofront.two_view` on one pair: the Python side of the overhead measurement (the Rust
side is `cargo run --release -p vofront-python --example two_view_timing -- SAME ARGS`).

    python examples/two_view_timing.py IMG1 IMG2 [DEPTH1] [REPS]

Images are decoded once, outside the timing; each timed call converts the numpy arrays,
runs the estimators and builds the result dict. Camera: the ROS default. Prints
`{"min_ms", "median_ms", "cpu_ms", "reps"}` (`cpu_ms`: process CPU time per call, all threads).
"""

import json
import os
import sys
import time

import numpy as np

import vofront

K = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])


def main() -> None:
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    img1, img2 = vofront.load_gray(sys.argv[1]), vofront.load_gray(sys.argv[2])
    depth1 = vofront.load_depth(sys.argv[3]) if len(sys.argv) > 3 else None
    reps = int(sys.argv[4]) if len(sys.argv) > 4 else 20
    times = []
    cpu_start = os.times()
    for _ in range(reps):
        start = time.perf_counter()
        vofront.two_view(img1, img2, K, depth1=depth1)
        times.append((time.perf_counter() - start) * 1e3)
    cpu_end = os.times()
    cpu_ms = (cpu_end.user + cpu_end.system - cpu_start.user - cpu_start.system) * 1e3 / reps
    print(json.dumps({"min_ms": round(min(times), 3), "median_ms": round(float(np.median(times)), 3),
                      "cpu_ms": round(cpu_ms, 3), "reps": reps}))


if __name__ == "__main__":
    main()
