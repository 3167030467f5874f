#!/usr/bin/env python3
"""Checks `evaluation/ate_aligned.py` on made-up trajectories whose errors are known.

The truth drives a 400 m by 200 m rectangle at 10 m/s, one row a rotation (4 Hz). The
"optimised" estimate is the truth turned 0.8 degrees about the start and shifted 1 m, with
centimetres of noise: aligned, its ATE must be the noise's and the alignment's turn -0.8
degrees. The "online" estimate is the optimised one with 3 m added across the track over a
fifth of the drive (the drift between two loop closures): in the frame that aligns the
optimised estimate its RMS must be 3 m times the square root of a fifth, its largest error
3 m, while unaligned it is several times that. Both estimates carry the start row the truth
lacks, as the daemon writes them. Bad input is refused with exit 1 and a reason: a missing
file, a directory or a FIFO in a file's place, an unreadable row.

Prints one line per check and `N passed, M failed`; exits 1 on any failure.
"""

import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "evaluation"))
import ate_aligned  # noqa: E402

from checklist import check, check_refusals, finish, run_script, write_tum  # noqa: E402

SCRIPT = str(ROOT / "evaluation" / "ate_aligned.py")


def rectangle():
    """(time, x, y, heading) rows of the truth: 1200 m at 2.5 m a rotation."""
    rows, t = [], 1000.0
    legs = [(400.0, 0.0), (200.0, math.pi / 2), (400.0, math.pi), (200.0, -math.pi / 2)]
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
    gt = rectangle()
    rng = np.random.default_rng(7)
    turn = math.radians(-0.8)
    c, s = math.cos(turn), math.sin(turn)
    opt = gt.copy()
    opt[:, 1] = c * gt[:, 1] - s * gt[:, 2] + 1.0 + rng.normal(0, 0.02, len(gt))
    opt[:, 2] = s * gt[:, 1] + c * gt[:, 2] + rng.normal(0, 0.02, len(gt))
    opt[:, 3] = gt[:, 3] + turn
    online = opt.copy()
    n = len(gt)
    drift = slice(2 * n // 5, 3 * n // 5)
    # Across the track: each row's left, in the estimate's frame.
    online[drift, 1] += -3.0 * np.sin(opt[drift, 3])
    online[drift, 2] += 3.0 * np.cos(opt[drift, 3])
    start = np.array([[gt[0, 0] - 0.25, 0.0, 0.0, 0.0]])
    opt = np.vstack([start, opt])
    online = np.vstack([start, online])

    with tempfile.TemporaryDirectory() as d:
        paths = {k: os.path.join(d, k + ".tum") for k in ("gt", "opt", "online")}
        write_tum(paths["gt"], gt)
        write_tum(paths["opt"], opt)
        write_tum(paths["online"], online)

        raw, ate, worst, got_turn, _, poses = ate_aligned.aligned_ate(
            ate_aligned.tum(paths["opt"]), ate_aligned.tum(paths["gt"])
        )
        check("optimised: every truth row paired", poses == n, f"{poses} of {n}")
        check("optimised: aligned ATE is the noise's", ate < 0.035, f"{ate:.4f} m")
        check("optimised: the alignment turns it back", abs(got_turn - 0.8) < 0.01, f"{got_turn:.4f} deg")
        check("optimised: unaligned is the turn's", raw > 2.0, f"{raw:.2f} m")

        rms, top, frame_turn = ate_aligned.in_frame_of(
            ate_aligned.tum(paths["online"]), ate_aligned.tum(paths["gt"]), ate_aligned.tum(paths["opt"])
        )
        want = 3.0 * math.sqrt((drift.stop - drift.start) / n)
        check("online in the optimised frame: RMS the drift's", abs(rms - want) < 0.05, f"{rms:.3f} m, want {want:.3f}")
        check("online in the optimised frame: max the drift", abs(top - 3.0) < 0.1, f"{top:.3f} m")
        check("online in the optimised frame: the same turn", abs(frame_turn - got_turn) < 1e-9, f"{frame_turn:.4f} deg")

        code, out = run(paths["online"], paths["gt"], "--frame-of", paths["opt"])
        check("command: exit 0", code == 0, out.strip().splitlines()[-1] if out.strip() else "")
        check("command: prints the frame's figures", f"RMS {rms:.2f} m, max {top:.2f} m" in out)

        check_refusals(
            SCRIPT,
            d,
            paths["gt"],
            [
                ("a missing frame file", (paths["online"], paths["gt"], "--frame-of", os.path.join(d, "none.tum"))),
                ("a wrong option", (paths["online"], paths["gt"], "--frame", paths["opt"])),
            ],
        )
    finish()


if __name__ == "__main__":
    main()
