#!/usr/bin/env python3
"""Monte Carlo consistency of the online pose over several runs of one drive (or of drives
of the same length): at every rotation the pose NEES averaged over the runs, against the
two-sided 95 % band of chi-square with 3 x runs dof divided by the runs (Bar-Shalom, Li and
Kirubarajan, "Estimation with Applications to Tracking and Navigation", 5.4.2). A
consistent filter's ensemble NEES lies inside it at 95 % of the rotations; below it the
covariance is larger than the errors (conservative), above smaller (optimistic).

Usage: nees_ensemble.py RUN_DIR [RUN_DIR ...]

Each RUN_DIR is the output folder of one daemon run with ground truth (its
diagnostics.csv, the `pose_nees` column: the filter's pose as published each rotation).
Rotations are matched by number; only those every run scored are counted. Also prints each
run's own figures against the single-sample band of chi-square with 3 dof, as the daemon's
summary does. tests/tests/ensemble_consistency.rs computes the same over its own runs.
Reads files only; needs scipy.
"""

import csv
import signal
import sys

from scipy.stats import chi2

SINGLE = (chi2.ppf(0.025, 3), chi2.ppf(0.975, 3))


def per_rotation(run_dir):
    """{rotation: pose NEES} of one run's diagnostics.csv (rows without a NEES skipped)."""
    out = {}
    with open(f"{run_dir}/diagnostics.csv", newline="") as f:
        for row in csv.DictReader(f):
            cell = row.get("pose_nees", "")
            if cell:
                out[int(row["rotation"])] = float(cell)
    return out


def main(dirs):
    if not dirs:
        sys.exit(__doc__)
    runs = [per_rotation(d) for d in dirs]
    n = len(runs)
    lo, hi = chi2.ppf(0.025, 3 * n) / n, chi2.ppf(0.975, 3 * n) / n
    common = sorted(k for k in runs[0] if all(k in r for r in runs))
    if not common:
        sys.exit("no rotation is scored in every run")
    means = [sum(r[k] for r in runs) / n for k in common]
    inside = sum(lo <= m <= hi for m in means)
    below = sum(m < lo for m in means)
    print(
        f"ensemble NEES {sum(means) / len(means):.2f} over {len(means)} rotations of {n} runs; "
        f"band [{lo:.2f}, {hi:.2f}]: inside at {100 * inside / len(means):.1f}% of rotations, "
        f"below (conservative) {100 * below / len(means):.1f}%, "
        f"above (optimistic) {100 * (len(means) - inside - below) / len(means):.1f}% (consistent: 95 / 2.5 / 2.5)"
    )
    cuts = [len(means) * i // 10 for i in range(11)]
    print(
        "  by tenth of the rotations, ensemble NEES (rotations below / above the band): "
        + "  ".join(
            f"{sum(c) / len(c):.2f} ({sum(m < lo for m in c)}/{sum(m > hi for m in c)})"
            for c in (means[cuts[i] : cuts[i + 1]] for i in range(10))
            if c
        )
    )
    for d, r in zip(dirs, runs):
        v = list(r.values())
        b = sum(x < SINGLE[0] for x in v)
        a = sum(x > SINGLE[1] for x in v)
        print(
            f"  {d}: mean NEES {sum(v) / len(v):.2f} over {len(v)} rotations; single-sample band "
            f"[{SINGLE[0]:.2f}, {SINGLE[1]:.2f}]: inside {100 * (len(v) - a - b) / len(v):.1f}%, "
            f"below {100 * b / len(v):.1f}%, above {100 * a / len(v):.1f}%"
        )


if __name__ == "__main__":
    # Piped into head: end quietly when the reader stops reading.
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    main(sys.argv[1:])
