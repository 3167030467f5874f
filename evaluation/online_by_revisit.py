#!/usr/bin/env python3
"""The online pose's error split where the route first comes back to a street it mapped:
before that no loop closure can touch it, so what it errs there is the odometry's (the
filter, its map and the near links between submaps), whatever the global layer does.

Usage: online_by_revisit.py ONLINE.tum GROUNDTRUTH.tum [--odometry ODOMETRY.tum]
                            [--revisit-m M] [--apart-m M]

ONLINE.tum is a run's out/trajectory-online.tum (the pose as published each rotation),
GROUNDTRUTH.tum its out/groundtruth.tum.

A rotation is a true revisit when the true path passes within --revisit-m (10 m) of where it
was at least --apart-m (300 m) of driving earlier: issue 35's definition of a loop a global
layer may close. Printed: the online pose's RMS and largest error over the rotations before
the first revisit (and the distance driven to it), after it, over the whole drive, and what
the whole drive's RMS would be were the pose exact from the first revisit on.

With --odometry ODOMETRY.tum (the same run's out/trajectory-odometry.tum, the online pose
without the global layer's corrections) also the odometry put back on the truth (position and
heading) at the first rotation and at each revisit, following its own motion between: what a
global layer that closed every true revisit at once and exactly would leave, were the
odometry alone between them. An estimate, not a bound: the global layer's near links correct
the odometry between revisits too, and drifts may happen to cancel.

Each pose is scored against the truth at the same time (within a millisecond; rows without a
partner are counted and left out). Reads files only; needs numpy. A file that is missing, not
a regular file, over ate_aligned.MAX_TUM_BYTES or not readable as TUM rows is refused with
the reason and exit 1; Ctrl-C stops it with exit 130.
"""

import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ate_aligned import paired, read_or_exit, run_main, travelled  # noqa: E402


def revisits(xy, s, within_m, apart_m):
    """Whether each row's position is within `within_m` of a row driven at least `apart_m`
    before it (`s`: distance driven at each row). A grid of `within_m` cells holds the rows
    far enough back, so each row looks at its nine cells only."""

    def cell(p):
        return math.floor(p[0] / within_m), math.floor(p[1] / within_m)

    cells = {}
    out = np.zeros(len(xy), dtype=bool)
    added = 0
    for i in range(len(xy)):
        while added < i and s[added] <= s[i] - apart_m:
            cells.setdefault(cell(xy[added]), []).append(added)
            added += 1
        cx, cy = cell(xy[i])
        near = (j for dx in (-1, 0, 1) for dy in (-1, 0, 1) for j in cells.get((cx + dx, cy + dy), ()))
        out[i] = any(math.hypot(*(xy[j] - xy[i])) < within_m for j in near)
    return out


def along_truth(est, gt, within_m, apart_m):
    """The rows of `est` and `gt` at the same times, the distance driven at each (m, along
    the truth), which of them are true revisits, and the rows of each without a partner."""
    est, gt, lone_e, lone_g = paired(est, gt)
    if len(est) < 2:
        raise ValueError("fewer than two poses at the same times")
    s = travelled(gt)
    return est, gt, s, revisits(gt[:, 1:3], s, within_m, apart_m), lone_e, lone_g


def floor(odo, gt, within_m=10.0, apart_m=300.0):
    """The errors (m) at each paired row of the odometry put back on the truth at the first
    row and at each true revisit, the distance driven since (m), the revisit flags, and the
    rows of each file without a partner."""
    odo, gt, s, hit, lone_o, lone_g = along_truth(odo, gt, within_m, apart_m)
    # Each row's anchor: the last revisit at or before it (the first row before any).
    anchor = np.maximum.accumulate(np.where(hit, np.arange(len(odo)), 0))
    ho, hg = odo[anchor, 3], gt[anchor, 3]
    # The odometry's motion from the anchor, in the anchor's frame, placed at the true anchor.
    dx, dy = odo[:, 1] - odo[anchor, 1], odo[:, 2] - odo[anchor, 2]
    lx, ly = np.cos(ho) * dx + np.sin(ho) * dy, -np.sin(ho) * dx + np.cos(ho) * dy
    px = gt[anchor, 1] + np.cos(hg) * lx - np.sin(hg) * ly
    py = gt[anchor, 2] + np.sin(hg) * lx + np.cos(hg) * ly
    err = np.hypot(px - gt[:, 1], py - gt[:, 2])
    since = s - s[anchor]
    return err, since, hit, lone_o, lone_g


def split(online, gt, within_m=10.0, apart_m=300.0):
    """The online pose's position errors (m) at each paired row, the index of the first true
    revisit (the row count when there is none), the distance driven to it (m), and the rows
    of each file without a partner."""
    online, gt, s, hit, lone_o, lone_g = along_truth(online, gt, within_m, apart_m)
    first = int(np.argmax(hit)) if hit.any() else len(hit)
    err = np.hypot(*(online[:, 1:3] - gt[:, 1:3]).T)
    return err, first, float(s[min(first, len(s) - 1)]), lone_o, lone_g


def rms(e):
    """Root mean square of `e`."""
    return float(np.sqrt((e**2).mean()))


def main():
    args = sys.argv[1:]
    opts = {"--revisit-m": 10.0, "--apart-m": 300.0}
    odometry = None
    files = []
    i = 0
    while i < len(args):
        if args[i] in opts:
            try:
                v = float(args[i + 1])
            except (IndexError, ValueError):
                sys.exit(f"{args[i]} needs a number\n{__doc__}")
            if not (math.isfinite(v) and v > 0):
                sys.exit(f"{args[i]} must be positive and finite, not {args[i + 1]}")
            opts[args[i]] = v
            i += 2
        elif args[i] == "--odometry":
            if i + 1 >= len(args):
                sys.exit(f"--odometry needs a file\n{__doc__}")
            odometry = args[i + 1]
            i += 2
        elif args[i].startswith("--"):
            sys.exit(f"unknown option {args[i]}\n{__doc__}")
        else:
            files.append(args[i])
            i += 1
    if len(files) != 2:
        sys.exit(__doc__)
    online, gt, *rest = read_or_exit(files + ([odometry] if odometry else []))
    odo = rest[0] if rest else None
    within, apart = opts["--revisit-m"], opts["--apart-m"]
    try:
        err, first, to_first, lone_o, lone_g = split(online, gt, within, apart)
    except ValueError as e:
        sys.exit(f"{e}: not one run's outputs")
    n = len(err)
    print(
        f"true revisits: within {within:g} m of the path {apart:g} m or more before; "
        f"{n} online poses paired ({lone_o} online and {lone_g} true rows without a partner)"
    )
    # The first row is never a revisit (nothing was driven before it), so `before` holds a row.
    if first == n:
        print(f"no true revisit: online pose RMS {rms(err):.2f} m, max {err.max():.2f} m")
    else:
        before, after = err[:first], err[first:]
        print(
            f"before the first revisit ({to_first:.0f} m driven, {first} poses): online pose "
            f"RMS {rms(before):.2f} m, max {before.max():.2f} m, {before[-1]:.2f} m at its end"
        )
        print(f"from the first revisit on ({n - first} poses): RMS {rms(after):.2f} m, max {after.max():.2f} m")
        exact_after = math.sqrt((before**2).sum() / n)
        print(
            f"whole drive: RMS {rms(err):.2f} m, max {err.max():.2f} m; "
            f"{exact_after:.2f} m RMS were the pose exact from the first revisit on"
        )
    if odo is not None:
        try:
            e2, since, hit, _, _ = floor(odo, gt, within, apart)
        except ValueError as e:
            sys.exit(f"{odometry}: {e}")
        print(
            f"odometry put back on the truth at each true revisit: RMS {rms(e2):.2f} m, "
            f"max {e2.max():.2f} m over {len(e2)} poses; {hit.mean():.1%} of them at a "
            f"revisit; longest stretch without one {since.max():.0f} m"
        )


if __name__ == "__main__":
    run_main(main)
