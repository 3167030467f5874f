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
3. `evaluation/ate_aligned.py` (the aligned ATE the READMEs quote) on a made-up pair of
   TUM files where the estimate has the start pose the truth lacks, as the daemon writes
   them (this run's drive is too straight for a 3-D Umeyama alignment): an exact copy of
   the truth, turned and shifted, scores 0 m (paired row by row, as that script did before
   2026-11-30, each pose was scored against the truth a rotation on); with noise added, the
   same RMSE as evo's APE after evo's own association and rigid alignment (no scale).

Prints one line per check and `N passed, M failed`; exits 1 on any failure.
"""

import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

from evo.core import metrics, sync
from evo.tools import file_interface

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "evaluation"))
from ate_aligned import aligned_ate, paired, tum  # noqa: E402

from checklist import check, finish  # noqa: E402


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

    check_made_up_pair()

    finish()


def check_made_up_pair():
    """The daemon's files have the start pose in the estimate only."""
    import tempfile

    import numpy as np

    rng = np.random.default_rng(7)
    truth = [(1.7e9 + 0.5 + 0.25 * k, 2.5 * k, 0.01 * k * k, 0.004 * k) for k in range(200)]
    turn, dx, dy = 0.3, 5.0, -2.0
    c, s = math.cos(turn), math.sin(turn)

    def moved(noise):
        rows = [(1.7e9, 0.0, 0.0, 0.0)]
        for t, x, y, h in truth:
            ex, ey = rng.normal(0.0, noise, 2)
            rows.append((t, c * x - s * y + dx + ex, s * x + c * y + dy + ey, h + turn))
        return rows

    def write(path, rows):
        with open(path, "w") as f:
            f.write("# timestamp x y z qx qy qz qw\n")
            for t, x, y, h in rows:
                f.write(f"{t:.9f} {x:.6f} {y:.6f} 0 0 0 {math.sin(h / 2):.9f} {math.cos(h / 2):.9f}\n")

    with tempfile.TemporaryDirectory() as tmp:
        gt_path, exact_path, noisy_path = (Path(tmp) / n for n in ("gt.tum", "exact.tum", "noisy.tum"))
        write(gt_path, truth)
        write(exact_path, moved(0.0))
        write(noisy_path, moved(0.5))
        gt, exact, noisy = tum(gt_path), tum(exact_path), tum(noisy_path)
        _, _, lone_e, lone_g = paired(exact, gt)
        check("made-up pair: only the start pose has no partner", (lone_e, lone_g) == (1, 0), f"{lone_e}, {lone_g}")
        ate = aligned_ate(exact, gt)[1]
        check("made-up pair: an exact trajectory has 0 aligned ATE", ate < 1e-5, f"{ate:.3g} m")
        ours = aligned_ate(noisy, gt)[1]
        g = file_interface.read_tum_trajectory_file(str(gt_path))
        e = file_interface.read_tum_trajectory_file(str(noisy_path))
        g, e = sync.associate_trajectories(g, e, max_diff=0.01)
        e.align(g, correct_scale=False)
        ape = metrics.APE(metrics.PoseRelation.translation_part)
        ape.process_data((g, e))
        theirs = ape.get_statistic(metrics.StatisticsType.rmse)
        check(
            "made-up pair with noise: ate_aligned.py's aligned ATE is evo's aligned APE",
            abs(ours - theirs) <= 1e-6 and ours > 0.3,
            f"{ours:.6f} vs {theirs:.6f}",
        )


if __name__ == "__main__":
    main()
