#!/usr/bin/env python3
"""Whether a map's scans agree with the mapping run's own trajectory: each point feature of
the simulated scene (trees, lamp posts) is placed in the map's frame through the mapping
drive's estimate where it passed nearest (estimate * inv(truth) * feature), and the nearest
scan point of the map is found; the offset is split along and across the street and its
median printed per street and minute. Offsets near zero everywhere mean the scans sit where
the trajectory says the vehicle saw them (a localiser scored against the truth in the map's
frame, evaluation/localise_in_map.py, is then scored against the scans it registers to).

Usage: map_scans_vs_truth.py MAP_RUN

MAP_RUN is an embedded-simulator mapping run's output folder: ground-truth.jsonl (the scene's
features; `[output] ground_truth` true), groundtruth.tum, trajectory.tum and scans.csv
(`cargo run -p slam-map --example map_info -- MAP_RUN/map.slmap --scan-csv MAP_RUN/scans.csv`).
Reads files only; needs numpy.
"""

import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ate_aligned import tum  # noqa: E402
from localise_in_map import at_time, compose, inverse  # noqa: E402


def point_features(path):
    out = []
    with open(path) as f:
        for line in f:
            head = line[:40]
            if '"pose"' in head:
                break
            if '"feature"' in head:
                r = json.loads(line)
                if r.get("kind") in ("tree", "lamp-post", "pole", "post"):
                    out.append((r["x_m"], r["y_m"]))
    return out


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    d = sys.argv[1]
    feats = point_features(os.path.join(d, "ground-truth.jsonl"))
    truth, est = tum(os.path.join(d, "groundtruth.tum")), tum(os.path.join(d, "trajectory.tum"))
    scans = np.loadtxt(os.path.join(d, "scans.csv"), delimiter=",", skiprows=1)[:, 1:3]
    groups = {}
    for fx, fy in feats:
        dd = np.hypot(truth[:, 1] - fx, truth[:, 2] - fy)
        k = int(np.argmin(dd))
        if dd[k] > 25.0:
            continue
        m_true = tuple(truth[k, 1:4])
        m_est = tuple(at_time(est, truth[k, 0])[1:4])
        fm = compose(compose(m_est, inverse(m_true)), (fx, fy, 0.0))
        ds = np.hypot(scans[:, 0] - fm[0], scans[:, 1] - fm[1])
        i = int(np.argmin(ds))
        if ds[i] > 2.5:
            continue
        o = scans[i] - np.array(fm[:2])
        th = m_est[2]
        along = o[0] * math.cos(th) + o[1] * math.sin(th)
        across = -o[0] * math.sin(th) + o[1] * math.cos(th)
        h = truth[k, 3]
        street = (
            f"y = {truth[k, 2]:.0f} {'E' if math.cos(h) > 0 else 'W'}"
            if abs(math.sin(h)) < 0.5
            else f"x = {truth[k, 1]:.0f} {'N' if math.sin(h) > 0 else 'S'}"
        )
        key = (int(truth[k, 0] - truth[0, 0]) // 60, street.split(" ")[0], round(float(street.split(" ")[2])), street[-1])
        groups.setdefault(key, []).append((along, across))
    print(f"{len(feats)} point features; offsets of the map's nearest scan point (median per street and minute):")
    for key in sorted(groups):
        a = np.array(groups[key])
        if len(a) >= 5:
            print(
                f"  minute {key[0]}, {key[1]} = {key[2]} m heading {key[3]}: {len(a)} features, "
                f"along {np.median(a[:, 0]):+.2f} m, across {np.median(a[:, 1]):+.2f} m"
            )


if __name__ == "__main__":
    main()
