#!/usr/bin/env python3
"""Absolute trajectory error after a rigid SE(2) alignment (Umeyama, no scale), as the
radar-odometry literature reports ATE, next to the unaligned RMS the daemon's summary prints.

Usage: ate_aligned.py TRAJECTORY.tum GROUNDTRUTH.tum [--frame-of OTHER.tum]

Both files are the daemon's outputs of one run (out/trajectory.tum or
out/trajectory-online.tum, and out/groundtruth.tum: one row per rotation).

With `--frame-of OTHER.tum` (the same run's optimised out/trajectory.tum, scoring
out/trajectory-online.tum) the script also scores TRAJECTORY in the frame that aligns OTHER
to the truth: on the radar alone nothing observes the world's heading but the first
rotations, and a heading lost there turns the whole map, the optimised trajectory with it;
that turn taken out, what is left of the online pose's error is made between the loop
closures. Each estimated
pose is scored against the truth at the same time (within a millisecond); rows of either
file with no partner are counted and left out. (The estimate has one row the truth lacks,
the start pose; paired row by row, as this script did before 2026-11-30, every estimate
was scored against the truth a rotation later: about 2.3 m at 10 m/s, added to every
aligned ATE reported with it.)
Reads files only; needs numpy. A file that is missing, not a regular file (a FIFO, a
device, a directory), over MAX_TUM_BYTES or not readable as TUM rows is refused with the
reason and exit 1; Ctrl-C stops it with exit 130.
"""

import math
import os
import stat
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


# Largest TUM file read (bytes): six hours at 4 Hz is about 6 MB.
MAX_TUM_BYTES = 256 << 20


def refused(path, limit):
    """Why `path` is not read: not a regular file (a directory, a FIFO, a device), or over
    `limit` bytes; None when it may be read."""
    try:
        st = os.stat(path)
    except OSError as e:
        return f"cannot be read ({e.strerror})"
    if not stat.S_ISREG(st.st_mode):
        return "is not a regular file"
    if st.st_size > limit:
        return f"is {st.st_size} bytes, over the {limit} read"
    return None


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


def alignment(est, gt):
    """The rigid SE(2) motion (rotation matrix, translation) that best fits the estimate's
    positions to the truth's at the same times (Umeyama, no scale), and the paired rows."""
    est, gt, _, _ = paired(est, gt)
    if len(est) < 2:
        raise ValueError("fewer than two poses at the same times")
    a, b = est[:, 1:3], gt[:, 1:3]
    ma, mb = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((a - ma).T @ (b - mb))
    d = np.diag([1.0, np.sign(np.linalg.det(vt.T @ u.T))])
    r = vt.T @ d @ u.T
    return r, mb - r @ ma, est, gt


def travelled(rows):
    """The distance driven to each row of `rows` (m, along its x and y), from the first."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(rows[:, 1:3], axis=0).T))])


def in_frame_of(est, gt, other):
    """(RMS, max, turn in degrees) of the estimate against the truth at the same times,
    moved by the rigid motion that aligns `other` to the truth."""
    r, t, _, _ = alignment(other, gt)
    est, gt, _, _ = paired(est, gt)
    if len(est) < 1:
        raise ValueError("no pose at the truth's times")
    e = np.hypot(*((r @ est[:, 1:3].T).T + t - gt[:, 1:3]).T)
    turn = math.degrees(math.atan2(r[1, 0], r[0, 0]))
    return float(np.sqrt((e**2).mean())), float(e.max()), turn


def aligned_ate(est, gt):
    """(unaligned RMS, aligned RMS, aligned max, turn in degrees, shift, poses) of the
    estimate against the truth at the same times, after a rigid SE(2) alignment."""
    r, t, est, gt = alignment(est, gt)
    a, b = est[:, 1:3], gt[:, 1:3]
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
    args = sys.argv[1:]
    other = None
    if len(args) == 4 and args[2] == "--frame-of":
        other = args[3]
        args = args[:2]
    if len(args) != 2:
        sys.exit(__doc__)
    est, gt = read_or_exit(args)
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
    if other is not None:
        (frame,) = read_or_exit([other])
        try:
            rms, worst, turn = in_frame_of(est, gt, frame)
        except ValueError as e:
            sys.exit(f"{other}: {e}")
        print(
            f"in the frame that aligns {other} to the truth (turned {turn:.2f} deg): "
            f"RMS {rms:.2f} m, max {worst:.2f} m"
        )


def read_or_exit(paths):
    """Each of `paths` read as TUM rows, after `refused`'s checks; a file refused, unreadable
    or without a pose row ends the run with the reason and exit 1."""
    for p in paths:
        why = refused(p, MAX_TUM_BYTES)
        if why:
            sys.exit(f"{p}: {why}")
    rows = []
    for p in paths:
        try:
            r = tum(p)
        except (OSError, ValueError, IndexError) as e:
            sys.exit(f"{p}: not a TUM trajectory: {e}")
        if len(r) == 0:
            sys.exit(f"{p}: no pose rows")
        rows.append(r)
    return rows


def run_main(main):
    """Runs `main`; Ctrl-C ends it with exit 130."""
    try:
        main()
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        sys.exit(130)


if __name__ == "__main__":
    run_main(main)
