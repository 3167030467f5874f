#!/usr/bin/env python3
"""Localisation error against the map it localised in, as the Boreas localisation benchmark
scores it (there the map is built from ground-truthed poses, so its frame is the truth's).

Our maps are built by a mapping run, so the map's frame is that run's estimate: a place the
map puts a few metres (or, far from the start, tens of metres) from where the truth has it.
The localising run is right when it publishes the pose **the map would give the true pose**:
for a true pose T of the second drive, the mapping drive's true pose M_true nearest T (by
position) and its estimate M_est (the mapping run's optimised trajectory at that time) give
the map's frame there, and the truth in the map's frame is

    T_map = M_est * inv(M_true) * T.

The error of each published pose against T_map is split along and across the true heading;
the consistency score is Boreas' sqrt(e' inv(P) e / 3) averaged over the poses, with P the
published covariance's diagonal (diagnostics.csv's pose_sigma_* columns; the daemon writes
them when it has the truth). The error against the world's truth (the map's own error
included) is printed beside it.

Usage:
  localise_in_map.py MAP_RUN LOCALISE_RUN          score the published poses
  localise_in_map.py MAP_RUN --map-frame X Y THETA  the map's frame at a true pose (a prior)

MAP_RUN is the mapping run's output folder (groundtruth.tum, trajectory.tum);
LOCALISE_RUN the localising run's (trajectory.tum: the poses published in the map's frame,
groundtruth.tum, diagnostics.csv). Reads files only; needs numpy.
"""

import csv
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ate_aligned import tum  # noqa: E402


def wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2]))


def inverse(a):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-(c * a[0] + s * a[1]), -(-s * a[0] + c * a[1]), wrap(-a[2]))


def at_time(rows, t):
    """The row of `rows` (time-sorted) nearest time t."""
    i = int(np.clip(np.searchsorted(rows[:, 0], t), 1, len(rows) - 1))
    if abs(rows[i - 1, 0] - t) < abs(rows[i, 0] - t):
        i -= 1
    return rows[i]


class MapFrame:
    """The mapping run's truth and estimate: where the map puts a true pose."""

    def __init__(self, map_run):
        self.truth = tum(os.path.join(map_run, "groundtruth.tum"))
        self.est = tum(os.path.join(map_run, "trajectory.tum"))
        if len(self.truth) < 2 or len(self.est) < 2:
            sys.exit(f"{map_run}: too few poses in groundtruth.tum or trajectory.tum")

    def by_pass(self, pose, reach_m=5.0, gap_s=30.0):
        """`pose` in the map's frame by each pass of the mapping drive within `reach_m` of it
        (passes: runs of mapping poses more than `gap_s` apart in time): where the map holds a
        street twice, each pass places it, and the spread is the map's own inconsistency."""
        d = np.hypot(self.truth[:, 1] - pose[0], self.truth[:, 2] - pose[1])
        near = np.flatnonzero(d <= reach_m)
        out = []
        if len(near) == 0:
            return out
        runs = np.split(near, np.flatnonzero(np.diff(self.truth[near, 0]) > gap_s) + 1)
        for run in runs:
            i = int(run[np.argmin(d[run])])
            m_true = tuple(self.truth[i, 1:4])
            m_est = tuple(at_time(self.est, self.truth[i, 0])[1:4])
            out.append(compose(m_est, compose(inverse(m_true), pose)))
        return out

    def of(self, pose):
        """`pose` (true, world) in the map's frame, and how far the nearest mapping pose was."""
        d = np.hypot(self.truth[:, 1] - pose[0], self.truth[:, 2] - pose[1])
        i = int(np.argmin(d))
        m_true = tuple(self.truth[i, 1:4])
        m_est = tuple(at_time(self.est, self.truth[i, 0])[1:4])
        return compose(m_est, compose(inverse(m_true), pose)), float(d[i])


def sigmas(path):
    """diagnostics.csv's published standard deviations: rows of (time, sx, sy, stheta)."""
    out = []
    if not os.path.exists(path):
        return np.zeros((0, 4))
    with open(path) as f:
        for row in csv.DictReader(f):
            try:
                out.append(
                    (
                        float(row["timestamp_s"]),
                        float(row["pose_sigma_x_m"]),
                        float(row["pose_sigma_y_m"]),
                        float(row["pose_sigma_theta_rad"]),
                    )
                )
            except (KeyError, ValueError):
                continue
    return np.array(out) if out else np.zeros((0, 4))


def rms(v):
    return math.sqrt(sum(x * x for x in v) / len(v)) if v else float("nan")


def score(map_run, loc_run):
    frame = MapFrame(map_run)
    published = tum(os.path.join(loc_run, "trajectory.tum"))
    truth = tum(os.path.join(loc_run, "groundtruth.tum"))
    if len(published) == 0 or len(truth) == 0:
        sys.exit(f"{loc_run}: no pose published in the map's frame (no fix)")
    sig = sigmas(os.path.join(loc_run, "diagnostics.csv"))
    along, across, heading, world, cons, reach = [], [], [], [], [], []
    cons_at = {}  # published pose index -> its consistency term
    for k, row in enumerate(published):
        t = tuple(at_time(truth, row[0])[1:4])
        tm, d = frame.of(t)
        reach.append(d)
        dx, dy, dth = row[1] - tm[0], row[2] - tm[1], wrap(row[3] - tm[2])
        c, s = math.cos(tm[2]), math.sin(tm[2])
        along.append(c * dx + s * dy)
        across.append(-s * dx + c * dy)
        heading.append(dth)
        world.append(math.hypot(row[1] - t[0], row[2] - t[1]))
        sg = at_time(sig, row[0]) if len(sig) > 1 else None
        if sg is not None and abs(sg[0] - row[0]) < 0.05 and all(v > 0 for v in sg[1:]):
            sg = sg[1:]
            cons.append(math.sqrt(((dx / sg[0]) ** 2 + (dy / sg[1]) ** 2 + (dth / sg[2]) ** 2) / 3.0))
            cons_at[k] = cons[-1]
    # Where the mapping drive passed more than once: how far apart the passes put the truth
    # (the map's own inconsistency), and the error against the pass nearest the estimate.
    spread, nearest_pass, once = [], [], []
    for k, row in enumerate(published):
        t = tuple(at_time(truth, row[0])[1:4])
        passes = frame.by_pass(t)
        if len(passes) == 1:
            once.append(k)
        if len(passes) >= 2:
            spread.append(
                max(math.hypot(a[0] - b[0], a[1] - b[1]) for a in passes for b in passes)
            )
            nearest_pass.append(min(math.hypot(row[1] - a[0], row[2] - a[1]) for a in passes))
    err = [math.hypot(a, b) for a, b in zip(along, across)]
    print(
        f"{len(published)} poses published in the map's frame; against the truth in the map's "
        f"frame: RMS along {rms(along):.3f} m, across {rms(across):.3f} m, heading "
        f"{math.degrees(rms(heading)):.3f} deg; max {max(err):.2f} m; "
        f"consistency {np.mean(cons) if cons else float('nan'):.2f} over {len(cons)} poses "
        f"(diagonal covariance); the mapping drive passed within {np.median(reach):.1f} m "
        f"(median, max {max(reach):.1f} m)"
    )
    if once:
        once_cons = [cons_at[k] for k in once if k in cons_at]
        twice_cons = [v for k, v in cons_at.items() if k not in set(once)]
        print(
            f"where the mapping drive passed once ({len(once)} poses, the map consistent with "
            f"itself): RMS along {rms([along[k] for k in once]):.3f} m, across "
            f"{rms([across[k] for k in once]):.3f} m, heading "
            f"{math.degrees(rms([heading[k] for k in once])):.3f} deg; consistency "
            f"{np.mean(once_cons) if once_cons else float('nan'):.2f} over {len(once_cons)} poses "
            f"(elsewhere {np.mean(twice_cons) if twice_cons else float('nan'):.2f} over "
            f"{len(twice_cons)})"
        )
    if spread:
        print(
            f"where the mapping drive passed twice or more ({len(spread)} poses): the passes put "
            f"the truth {rms(spread):.2f} m apart (RMS; max {max(spread):.2f} m), the map's own "
            f"inconsistency; the estimate is {rms(nearest_pass):.2f} m (RMS) from the nearest "
            f"pass's"
        )
    print(
        f"against the world's truth (the map's own error included): RMS {rms(world):.2f} m, "
        f"max {max(world):.2f} m"
    )


def main():
    if len(sys.argv) == 6 and sys.argv[2] == "--map-frame":
        pose = tuple(float(v) for v in sys.argv[3:6])
        tm, d = MapFrame(sys.argv[1]).of(pose)
        print(f"{tm[0]:.3f} {tm[1]:.3f} {tm[2]:.5f}  (the mapping drive passed {d:.1f} m away)")
        return
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    score(sys.argv[1], sys.argv[2])


if __name__ == "__main__":
    main()
