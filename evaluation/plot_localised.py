#!/usr/bin/env python3
"""The second drive's localised trajectory over the first drive's map, as an SVG.

Usage: plot_localised.py MAP_RUN_DIR LOCALISE_RUN_DIR OUT.svg [TITLE]

MAP_RUN_DIR is the output folder of the mapping run (its map.csv: the features of the map
in the map's frame, as map.slmap holds them); LOCALISE_RUN_DIR the output folder of the run
with `--map` (trajectory.tum: the poses published in the map's frame; groundtruth.tum: the
true poses at the same times). Reads files only; needs matplotlib.
"""

import sys

import matplotlib

matplotlib.use("svg")
import matplotlib.pyplot as plt  # noqa: E402


def tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = line.split()
            rows.append((float(v[0]), float(v[1]), float(v[2])))
    return rows


def features(path):
    xs, ys = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or line.startswith("id,"):
                continue
            v = line.split(",")
            xs.append(float(v[1]))
            ys.append(float(v[2]))
    return xs, ys


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    map_dir, loc_dir, out = sys.argv[1:4]
    title = sys.argv[4] if len(sys.argv) > 4 else "localised in the saved map"
    fx, fy = features(f"{map_dir}/map.csv")
    est = tum(f"{loc_dir}/trajectory.tum")
    truth = tum(f"{loc_dir}/groundtruth.tum")
    mapped = tum(f"{map_dir}/trajectory.tum")
    fig, ax = plt.subplots(figsize=(10, 8))
    ax.scatter(fx, fy, s=2, c="0.6", rasterized=True, label=f"first drive's map ({len(fx)} features)")
    ax.plot([p[1] for p in mapped], [p[2] for p in mapped], c="0.8", lw=0.8,
            label="first drive (its optimised trajectory)")
    ax.plot([p[1] for p in truth], [p[2] for p in truth], c="k", lw=1.0, ls="--",
            label="second drive, truth")
    ax.plot([p[1] for p in est], [p[2] for p in est], c="tab:red", lw=1.0,
            label=f"second drive, localised ({len(est)} poses published)")
    if est:
        ax.plot(est[0][1], est[0][2], "o", c="tab:red", ms=6, label="first fix")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, map frame)")
    ax.set_ylabel("y (m)")
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(out)


if __name__ == "__main__":
    main()
