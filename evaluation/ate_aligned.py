#!/usr/bin/env python3
"""Absolute trajectory error after a rigid SE(2) alignment (Umeyama, no scale), as the
radar-odometry literature reports ATE, next to the unaligned RMS the daemon's summary prints.

Usage: ate_aligned.py TRAJECTORY.tum GROUNDTRUTH.tum

Both files are the daemon's outputs of one run (out/trajectory.tum or
out/trajectory-online.tum, and out/groundtruth.tum: one row per rotation). Each estimated
pose is scored against the truth at the same time (within a millisecond); rows of either
file with no partner are counted and left out. (The estimate has one row the truth lacks,
the start pose; paired row by row, as this script did before 2026-11-30, every estimate
was scored against the truth a rotation later: about 2.3 m at 10 m/s, added to every
aligned ATE reported with it.)
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


# Two rows are the same rotation's when their times differ by less than this (s).
SAME_TIME_S = 1e-3


def paired(est, gt):
    """The rows of `est` and `gt` at the same times (within SAME_TIME_S): two arrays of
    equal length, and how many rows of each had no partner."""
    order = np.argsort(gt[:, 0])
    times = gt[order, 0]
    keep_e, keep_g = [], []
    for i, t in enumerate(est[:, 0]):
        j = int(np.searchsorted(times, t))
        best = None
        for k in (j - 1, j):
            if 0 <= k < len(times) and abs(times[k] - t) < SAME_TIME_S:
                if best is None or abs(times[k] - t) < abs(times[best] - t):
                    best = k
        if best is not None:
            keep_e.append(i)
            keep_g.append(order[best])
    used = len(set(keep_g))
    return est[keep_e], gt[keep_g], len(est) - len(keep_e), len(gt) - used


def aligned_ate(est, gt):
    """(unaligned RMS, aligned RMS, aligned max, turn in degrees, shift, poses) of the
    estimate against the truth at the same times, after a rigid SE(2) alignment."""
    est, gt, _, _ = paired(est, gt)
    if len(est) < 2:
        raise ValueError("fewer than two poses at the same times")
    a, b = est[:, 1:3], gt[:, 1:3]
    ma, mb = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((a - ma).T @ (b - mb))
    d = np.diag([1.0, np.sign(np.linalg.det(vt.T @ u.T))])
    r = vt.T @ d @ u.T
    t = mb - r @ ma
    e = np.hypot(*((r @ a.T).T + t - b).T)
    raw = np.hypot(*(a - b).T)
    turn = math.degrees(math.atan2(r[1, 0], r[0, 0]))
    return (
        float(np.sqrt((raw**2).mean())),
        float(np.sqrt((e**2).mean())),
        float(e.max()),
        turn,
        float(np.hypot(*t)),
        len(est),
    )


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    est, gt = tum(sys.argv[1]), tum(sys.argv[2])
    _, _, lone_e, lone_g = paired(est, gt)
    try:
        raw, ate, worst, turn, shift, n = aligned_ate(est, gt)
    except ValueError as e:
        sys.exit(f"{e}: not one run's outputs")
    print(
        f"unaligned RMS {raw:.2f} m; SE(2)-aligned ATE RMS {ate:.2f} m, max {worst:.2f} m "
        f"(alignment turns {turn:.2f} deg, shifts {shift:.2f} m) over {n} poses at the same "
        f"times ({lone_e} estimated and {lone_g} true rows without a partner)"
    )


if __name__ == "__main__":
    main()
