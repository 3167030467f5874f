#!/usr/bin/env python3
"""Checks `evaluation/online_by_revisit.py` on made-up drives whose errors are known.

The truth drives a 400 m by 200 m rectangle twice at 10 m/s, one row a rotation (4 Hz): the
first lap is all new streets, the second all revisits (the path of the first lap, 1200 m
before). The online pose errs 2 m across the track until the path comes within 10 m of the
start, 0.5 m after: split there, its RMS must be 2 m before and 0.5 m after. The odometry is the truth with every step 1 % long: from an anchor its error is 1 %
of the true displacement from there. Put back on the truth at each revisit, its error over
the first lap (until the path comes within 10 m of the start) must be 1 % of the distance
from the first true row, and nothing after; with no revisit allowed (--apart-m 5000) 1 % of the
distance from the start at every row. The odometry carries the start row the truth lacks,
as the daemon writes it. Bad input is refused with exit 1 and a reason; Ctrl-C during a long
run ends it with exit 130.

Prints one line per check and `N passed, M failed`; exits 1 on any failure.
"""

import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "evaluation"))
import online_by_revisit as obr  # noqa: E402

from checklist import check, check_refusals, finish, run_script, write_tum  # noqa: E402

SCRIPT = str(ROOT / "evaluation" / "online_by_revisit.py")


def two_laps():
    """(time, x, y, heading) rows of the truth: the rectangle twice, 2.5 m a rotation."""
    rows, t = [], 1000.0
    legs = [(400.0, 0.0), (200.0, math.pi / 2), (400.0, math.pi), (200.0, -math.pi / 2)] * 2
    x = y = 0.0
    for length, h in legs:
        for _ in range(int(length / 2.5)):
            t += 0.25
            x += 2.5 * math.cos(h)
            y += 2.5 * math.sin(h)
            rows.append((t, x, y, h))
    return np.array(rows)


def run(*args):
    return run_script(SCRIPT, *args)


def main():
    gt = two_laps()
    start = np.array([[gt[0, 0] - 0.25, 0.0, 0.0, 0.0]])
    with_start = np.vstack([start, gt])
    # Every step 1 % long, the heading the truth's.
    odo = with_start.copy()
    steps = np.diff(with_start[:, 1:3], axis=0) * 1.01
    odo[1:, 1:3] = np.cumsum(steps, axis=0)
    lap = len(gt) // 2
    # From the first row the truth has (the anchor: the odometry's start row has no partner).
    from_start = np.hypot(gt[:, 1] - gt[0, 1], gt[:, 2] - gt[0, 2])
    first_revisit = next(i for i in range(lap // 2, len(gt)) if from_start[i] < 10.0)

    err, since, hit, lone_o, lone_g = obr.floor(odo, gt)
    check("pairs every truth row; the odometry's start row alone", (lone_o, lone_g) == (1, 0), f"{lone_o}, {lone_g}")
    check("the first revisit where the path comes back within 10 m", int(np.argmax(hit)) == first_revisit, f"row {int(np.argmax(hit))}, want {first_revisit}")
    check("every row of the second lap a revisit", hit[lap:].all(), f"{hit[lap:].mean():.3f}")
    want = np.where(np.arange(len(gt)) < first_revisit, 0.01 * from_start, 0.0)
    check("first lap: 1 % of the distance from the start", np.abs(err - want).max() < 1e-6, f"largest difference {np.abs(err - want).max():.2e} m")
    check("largest error 1 % of the rectangle's diagonal", abs(err.max() - 0.01 * math.hypot(400, 200)) < 0.03, f"{err.max():.3f} m")
    check("longest stretch without a revisit the first lap's", abs(since.max() - 2.5 * first_revisit) < 3.0, f"{since.max():.1f} m")

    err2, _, hit2, _, _ = obr.floor(odo, gt, apart_m=5000.0)
    check("no revisit further apart than the drive", not hit2.any())
    check("without revisits 1 % of the distance from the start", np.abs(err2 - 0.01 * from_start).max() < 1e-6)

    exact, *_ = obr.floor(with_start, gt)
    check("the truth as odometry leaves nothing", exact.max() < 1e-9, f"{exact.max():.2e} m")

    online = with_start.copy()
    online[1:first_revisit + 1, 2] += 2.0
    online[first_revisit + 1:, 2] += 0.5
    e_on, first, to_first, lone_on, _ = obr.split(online, gt)
    check("split at the first revisit", first == first_revisit, f"row {first}")
    check("distance driven to it", abs(to_first - 2.5 * first_revisit) < 1e-6, f"{to_first:.1f} m")
    check("before it the online pose's error", np.abs(e_on[:first] - 2.0).max() < 1e-6)
    check("after it the online pose's error", np.abs(e_on[first:] - 0.5).max() < 1e-6)
    check("the online pose's start row has no partner", lone_on == 1)

    with tempfile.TemporaryDirectory() as d:
        paths = {k: os.path.join(d, k + ".tum") for k in ("gt", "odo", "online")}
        write_tum(paths["gt"], gt)
        write_tum(paths["odo"], odo)
        write_tum(paths["online"], online)

        code, out = run(paths["online"], paths["gt"], "--odometry", paths["odo"])
        rms = float(np.sqrt((err**2).mean()))
        whole = math.sqrt((4.0 * first + 0.25 * (len(gt) - first)) / len(gt))
        exact_after = math.sqrt(4.0 * first / len(gt))
        check("command: exit 0", code == 0, out.strip().splitlines()[-1] if out.strip() else "")
        check("command: the online pose before the first revisit", f"online pose RMS 2.00 m, max 2.00 m, 2.00 m at its end" in out)
        check("command: after it", "RMS 0.50 m, max 0.50 m" in out)
        check("command: the whole drive, and were it exact after", f"whole drive: RMS {whole:.2f} m, max 2.00 m; {exact_after:.2f} m RMS" in out, f"want {whole:.2f}, {exact_after:.2f}")
        check("command: the odometry put back at each revisit", f"RMS {rms:.2f} m, max {err.max():.2f} m" in out)
        code, out = run(paths["online"], paths["gt"], "--apart-m", "5000")
        check("command: --apart-m taken (no revisit)", code == 0 and "no true revisit" in out, out.strip().splitlines()[-1] if out.strip() else "")

        # Ctrl-C: a long drive (200,000 rows, read row by row), interrupted while it reads.
        long_gt = os.path.join(d, "long.tum")
        n_long = 200_000
        write_tum(long_gt, [(1000.0 + 0.25 * k, 2.5 * k, 0.0, 0.0) for k in range(n_long)])
        p = subprocess.Popen([sys.executable, SCRIPT, long_gt, long_gt], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(1.0)
        p.send_signal(signal.SIGINT)
        try:
            _, err_out = p.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()
            err_out = "did not stop"
        check("Ctrl-C stops it with exit 130", p.returncode == 130 and "Traceback" not in err_out, f"exit {p.returncode}: {err_out.strip()[:80]}")

        check_refusals(
            SCRIPT,
            d,
            paths["gt"],
            [
                ("one file", (paths["online"],)),
                ("a missing odometry file", (paths["online"], paths["gt"], "--odometry", os.path.join(d, "none.tum"))),
                ("--odometry without a file", (paths["online"], paths["gt"], "--odometry")),
                ("a negative distance", (paths["online"], paths["gt"], "--revisit-m", "-1")),
                ("a distance that is not a number", (paths["online"], paths["gt"], "--apart-m", "far")),
                ("an unknown option", (paths["online"], paths["gt"], "--within", "3")),
            ],
        )
    finish()


if __name__ == "__main__":
    main()
