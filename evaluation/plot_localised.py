#!/usr/bin/env python3
"""The second drive's localised trajectory over the first drive's map, as an SVG.

Usage: plot_localised.py MAP_RUN_DIR LOCALISE_RUN_DIR OUT.svg [TITLE] [--scans SCANS.csv]

MAP_RUN_DIR is the output folder of the mapping run (its map.csv: the features of the map
in the map's frame, as map.slmap holds them); LOCALISE_RUN_DIR the output folder of the run
with `--map` (trajectory.tum: the poses published in the map's frame; groundtruth.tum: the
true poses at the same times). With `--scans`, the map's scan points (slam-map's map_info
`--scan-csv`) are drawn under the features. Reads files only; needs matplotlib.
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


def scan_points(path):
    xs, ys = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("submap"):
                continue
            v = line.split(",")
            xs.append(float(v[1]))
            ys.append(float(v[2]))
    return xs, ys


def main():
    args = sys.argv[1:]
    scans = None
    if "--scans" in args:
        i = args.index("--scans")
        if i + 1 >= len(args):
            sys.exit("--scans needs the map_info --scan-csv file")
        scans = args[i + 1]
        del args[i : i + 2]
    if len(args) < 3:
        sys.exit(__doc__)
    map_dir, loc_dir, out = args[0:3]
    title = args[3] if len(args) > 3 else "localised in the saved map"
    fx, fy = features(f"{map_dir}/map.csv")
    est = tum(f"{loc_dir}/trajectory.tum")
    truth = tum(f"{loc_dir}/groundtruth.tum")
    mapped = tum(f"{map_dir}/trajectory.tum")
    fig, ax = plt.subplots(figsize=(10, 8))
    if scans:
        sx, sy = scan_points(scans)
        ax.scatter(sx, sy, s=0.3, c="0.8", lw=0, rasterized=True,
                   label=f"first drive's map: scans ({len(sx)} points)")
    ax.scatter(fx, fy, s=2, c="0.6", rasterized=True, label=f"first drive's map ({len(fx)} features)")
    ax.plot([p[1] for p in mapped], [p[2] for p in mapped], c="0.8", lw=0.8,
            label="first drive (its optimised trajectory)")
    ax.plot([p[1] for p in truth], [p[2] for p in truth], c="k", lw=1.0, ls="--",
            label="second drive, truth (the world's frame, not the map's)")
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
