#!/usr/bin/env python3
"""Accuracy on the new streets of an extended map against mapping them from nothing.

Usage: extend_accuracy.py FIRST_RUN EXTEND_RUN FRESH_RUN [NEW_M]

Each argument is a slam-node output folder of a run on a simulated scene with ground truth
(`trajectory.tum`, the final, globally optimised trajectory, and `groundtruth.tum`, the true
pose at each of its rows):

- FIRST_RUN maps the first drive (its true path says which streets the saved map holds);
- EXTEND_RUN drives the second route with `[map] mode = "extend"` and the first run's map;
- FRESH_RUN drives the same second route (same seeds) in map mode, from nothing.

A pose is on a new street when its true position is more than NEW_M metres (default 20)
from every true position of the first drive. The two second runs are put on one clock by
the extend run's first true pose (its trajectory starts when mapping starts, after the
fix); both are scored over the rows from then on: RMS and largest position error, RMS
heading error, on new streets and on the mapped ones. Both runs' frames are the true world
frame at the start (the daemon starts its map frame at the true pose), so the first lines
are unaligned; but a map made without wheel odometry turns and stretches its frame as it
drifts, and the extend run inherits the saved map's frame: the `aligned` lines score each
run after the one rigid motion (x, y, heading) that best fits its rows to the truth, which
leaves the shape of the drive, and the `in the first map's alignment` line scores the
extend run after the rigid motion that best fits the first run's final trajectory to its
truth (the new streets against where the saved map would put them, were it aligned).
Reads files only; needs numpy.
"""

import math
import sys

import numpy as np

from ate_aligned import tum  # the TUM reader beside this script




def run(folder):
    """The final trajectory and the true pose at each of its times (groundtruth.tum holds
    one row per published pose; an extend run publishes before its trajectory starts)."""
    est, gt = tum(f"{folder}/trajectory.tum"), tum(f"{folder}/groundtruth.tum")
    k = np.clip(np.searchsorted(gt[:, 0], est[:, 0]), 0, len(gt) - 1)
    k = np.where(
        (k > 0) & (np.abs(gt[k - 1, 0] - est[:, 0]) < np.abs(gt[k, 0] - est[:, 0])), k - 1, k
    )
    ok = np.abs(gt[k, 0] - est[:, 0]) < 0.01
    if ok.sum() < 2:
        sys.exit(f"{folder}: trajectory.tum and groundtruth.tum share no times")
    return est[ok], gt[k[ok]]


def nearest(points, queries):
    """Distance from each query to the nearest point (chunked brute force)."""
    out = np.empty(len(queries))
    for i in range(0, len(queries), 512):
        q = queries[i : i + 512]
        d = np.hypot(q[:, None, 0] - points[None, :, 0], q[:, None, 1] - points[None, :, 1])
        out[i : i + 512] = d.min(1)
    return out


def score(est, gt, mask):
    if not mask.any():
        return "no pose"
    e = np.hypot(*(est[mask, 1:3] - gt[mask, 1:3]).T)
    h = np.angle(np.exp(1j * (est[mask, 3] - gt[mask, 3])))
    return (
        f"{mask.sum()} poses: RMS {np.sqrt((e ** 2).mean()):.3f} m, max {e.max():.3f} m, "
        f"heading RMS {math.degrees(np.sqrt((h ** 2).mean())):.3f} deg"
    )


def rigid(est, gt):
    """The rigid motion (rotation R, translation t) that best fits est's positions to gt's
    (least squares), and the heading it turns by."""
    a, b = est[:, 1:3], gt[:, 1:3]
    ma, mb = a.mean(0), b.mean(0)
    h = (a - ma).T @ (b - mb)
    u, _, vt = np.linalg.svd(h)
    r = vt.T @ u.T
    if np.linalg.det(r) < 0:
        vt[-1] *= -1
        r = vt.T @ u.T
    return r, mb - r @ ma, math.atan2(r[1, 0], r[0, 0])


def moved(est, motion):
    """est moved by a rigid motion from `rigid`."""
    r, t, turn = motion
    out = est.copy()
    out[:, 1:3] = est[:, 1:3] @ r.T + t
    out[:, 3] = est[:, 3] + turn
    return out


def main():
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    new_m = float(sys.argv[4]) if len(sys.argv) == 5 else 20.0
    first = tum(f"{sys.argv[1]}/groundtruth.tum")[:, 1:3]
    ext_est, ext_gt = run(sys.argv[2])
    fre_est, fre_gt = run(sys.argv[3])
    # The fresh run's row whose true pose is where the extend run's trajectory starts.
    start = np.argmin(np.hypot(*(fre_gt[:, 1:3] - ext_gt[0, 1:3]).T))
    fre_est, fre_gt = fre_est[start:], fre_gt[start:]
    for name, est, gt in (("extend", ext_est, ext_gt), ("fresh", fre_est, fre_gt)):
        new = nearest(first, gt[:, 1:3]) > new_m
        print(f"{name}: new streets {score(est, gt, new)}; mapped streets {score(est, gt, ~new)}")
        driven = np.hypot(*np.diff(gt[new, 1:3], axis=0).T)
        print(f"{name}: new streets driven about {driven[driven < 5].sum():.0f} m")
    for name, est, gt in (("extend", ext_est, ext_gt), ("fresh", fre_est, fre_gt)):
        new = nearest(first, gt[:, 1:3]) > new_m
        al = moved(est, rigid(est, gt))
        print(f"{name} aligned: new streets {score(al, gt, new)}; mapped streets {score(al, gt, ~new)}")
    first_est, first_gt = run(sys.argv[1])
    al = moved(ext_est, rigid(first_est, first_gt))
    new = nearest(first, ext_gt[:, 1:3]) > new_m
    print(
        f"extend in the first map's alignment: new streets {score(al, ext_gt, new)}; "
        f"mapped streets {score(al, ext_gt, ~new)}"
    )


if __name__ == "__main__":
    main()
