#!/usr/bin/env python3
"""Absolute trajectory error after a rigid SE(2) alignment (Umeyama, no scale), as the
radar-odometry literature reports ATE, next to the unaligned RMS the daemon's summary prints.

Usage: ate_aligned.py TRAJECTORY.tum GROUNDTRUTH.tum

Both files are the daemon's outputs of one run (out/trajectory.tum or
out/trajectory-online.tum, and out/groundtruth.tum: one row per rotation, the same times).
Reads files only; needs numpy.
"""

import math
import sys

import numpy as np


def tum(path):
    """A TUM file's rows as (time, x, y, heading) in an array; comments and blank lines skipped."""
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            qz, qw = v[6], v[7]
            rows.append((v[0], v[1], v[2], 2.0 * math.atan2(qz, qw)))
    return np.array(rows)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    est, gt = tum(sys.argv[1]), tum(sys.argv[2])
    n = min(len(est), len(gt))
    if n < 2:
        sys.exit("fewer than two poses")
    est, gt = est[:n], gt[:n]
    if not np.allclose(est[:, 0], gt[:, 0], atol=0.2):
        sys.exit("the two files' times differ: not one run's outputs")
    a, b = est[:, 1:3], gt[:, 1:3]
    ma, mb = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((a - ma).T @ (b - mb))
    d = np.diag([1.0, np.sign(np.linalg.det(vt.T @ u.T))])
    r = vt.T @ d @ u.T
    t = mb - r @ ma
    e = np.hypot(*((r @ a.T).T + t - b).T)
    raw = np.hypot(*(a - b).T)
    turn = math.degrees(math.atan2(r[1, 0], r[0, 0]))
    print(
        f"unaligned RMS {np.sqrt((raw ** 2).mean()):.2f} m; SE(2)-aligned ATE RMS "
        f"{np.sqrt((e ** 2).mean()):.2f} m, max {e.max():.2f} m "
        f"(alignment turns {turn:.2f} deg, shifts {np.hypot(*t):.2f} m) over {n} poses"
    )


if __name__ == "__main__":
    main()
