#!/usr/bin/env python3
"""Reads a run's ground truth and trajectory with evo, a reader we did not write.

    python3 tests/python/check_evo.py OUT_DIR SUMMARY_TXT

OUT_DIR holds `groundtruth.tum` and `trajectory.tum` written by slam-node on a run that
knows the truth (the simulator, or a replay with ground truth); SUMMARY_TXT is that run's
standard output, whose `pose error vs truth: RMS R m, max M m` line is compared.

1. `evo_ape tum groundtruth.tum trajectory.tum` (the command the README gives) exits 0 and
   prints an RMSE and a maximum equal to the daemon's own (to the summary's 3 decimals).
2. evo's API: every ground-truth pose has an estimate at the same time (evo's association,
   10 ms), and APE on the translation gives the same RMSE.

Prints one line per check and `N passed, M failed`; exits 1 on any failure.
"""

import re
import shutil
import subprocess
import sys
from pathlib import Path

from evo.core import metrics, sync
from evo.tools import file_interface

results = []


def check(name, ok, detail=""):
    results.append(ok)
    print(f"{'ok  ' if ok else 'FAIL'} {name}{': ' + detail if detail else ''}")


def main():
    out = Path(sys.argv[1])
    summary = Path(sys.argv[2]).read_text()
    gt_path, est_path = out / "groundtruth.tum", out / "trajectory.tum"
    m = re.search(r"pose error vs truth: RMS ([0-9.]+) m, max ([0-9.]+) m", summary)
    check("the daemon's summary states its pose error", m is not None)
    rms, worst = (float(m.group(1)), float(m.group(2))) if m else (float("nan"),) * 2

    cli = shutil.which("evo_ape")
    cmd = [cli] if cli else [sys.executable, "-m", "evo.main_ape"]
    run = subprocess.run(
        cmd + ["tum", str(gt_path), str(est_path)], capture_output=True, text=True, timeout=120
    )
    check("evo_ape tum groundtruth.tum trajectory.tum exits 0", run.returncode == 0, run.stderr[-300:])
    stats = dict(re.findall(r"^\s*(\w+)\s+([0-9.eE+-]+)\s*$", run.stdout, re.M))
    evo_rmse, evo_max = float(stats.get("rmse", "nan")), float(stats.get("max", "nan"))
    check("evo_ape's RMSE is the daemon's RMS", abs(evo_rmse - rms) <= 6e-4, f"{evo_rmse:.6f} vs {rms}")
    check("evo_ape's max is the daemon's max", abs(evo_max - worst) <= 6e-4, f"{evo_max:.6f} vs {worst}")

    gt = file_interface.read_tum_trajectory_file(str(gt_path))
    est = file_interface.read_tum_trajectory_file(str(est_path))
    n_gt = gt.num_poses
    gt, est = sync.associate_trajectories(gt, est, max_diff=0.01)
    check(
        "every ground-truth pose has an estimate at its time",
        n_gt > 5 and gt.num_poses == n_gt,
        f"{gt.num_poses} of {n_gt}",
    )
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((gt, est))
    api_rmse = ape.get_statistic(metrics.StatisticsType.rmse)
    check("evo's API gives the same RMSE", abs(api_rmse - evo_rmse) <= 1e-6, f"{api_rmse:.6f}")

    failed = results.count(False)
    print(f"{len(results) - failed} passed, {failed} failed")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
