#!/usr/bin/env python3
"""Checks `evaluation/heading_budget.py` on a made-up drive whose heading errors are known.

A drive of 2.5 m rotations along a straight, a 90-degree left turn over ten rotations, and a
straight again, written as the daemon writes them (the estimate has the start row the truth
lacks, so the odometry's first rotation is not scored). The estimate's heading errs -20 urad a rotation along the straights (away
from the turn's padding) and +10 mrad spread over the turn's rotations; its positions follow
its own heading. Each rotation's registration errs -30 urad along the straights and +1 mrad
through the turn, and the estimate turns 10 urad more than the registration along the
straights (the map's pull) and 20 urad less through the turn. The script must give back:
the odometry's sums through the turn and along the straights, the registrations' error
and the pull on each, and the turn's registrations' error summed. Chained registration
errors drawn independent, and drawn with a placement share of 0.4, add up over N as the
model says. Each straight's heading error rate; the drift over 100-800 m (KITTI) of drives whose
answer is known (1 % long, crabbing 5 mrad), none on a drive of 90 m; each straight's bias
taken out leaves the drift of the same drive built without the straights' errors. Bad input is refused with exit 1: a missing file, an unreadable row, a
FIFO or a directory in a file's place, a file over its size bound; a log line over the
longest read costs that line only.

Prints one line per check and `N passed, M failed`; exits 1 on any failure.
"""

import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "evaluation"))
import heading_budget  # noqa: E402

from checklist import check, finish, write_tum  # noqa: E402


def main():
    n, turn_start, turn_len = 400, 200, 10
    turn_step = (math.pi / 2) / turn_len
    pad = heading_budget.TURN_PAD
    t0 = 1_700_000_000.0
    truth, est, log = [(t0, 0.0, 0.0, 0.0)], [(t0, 0.0, 0.0, 0.0)], []
    odo_straight = odo_turn = 0.0
    reg_straight = reg_turn = pull_straight = pull_turn = 0.0
    for k in range(1, n + 1):
        turning = turn_start <= k < turn_start + turn_len
        padded = turn_start - pad <= k < turn_start + turn_len + pad
        true_turn = turn_step if turning else 0.0
        odo_error = 0.01 / turn_len if turning else (0.0 if padded else -20e-6)
        reg_error = 1e-3 / turn_len if turning else -30e-6
        measured = true_turn + reg_error
        # The estimate's turn over the rotation: the truth's plus its error; the pull is
        # what it turned beyond the registration.
        est_turn = true_turn + odo_error
        pull = est_turn - measured
        if padded:
            odo_turn += odo_error
        elif k > 1:
            # The first rotation ends at the truth's first row: nothing before it to pair.
            odo_straight += odo_error
        if abs(true_turn) < heading_budget.STRAIGHT_RAD:
            reg_straight += reg_error
            pull_straight += pull
        else:
            reg_turn += reg_error
            pull_turn += pull
        for rows, dh in ((truth, true_turn), (est, est_turn)):
            t, x, y, h = rows[-1]
            h2 = h + dh
            rows.append((t0 + 0.25 * k, x + 2.5 * math.cos(h2), y + 2.5 * math.sin(h2), h2))
        log.append(
            f"2026-12-05T00:00:00Z DEBUG slam_node::pipeline::radar_odometry: "
            f"radar odometry registration since_s={t0 + 0.25 * (k - 1)} until_s={t0 + 0.25 * k} "
            f"truth_x=2.5 truth_y=0.0 truth_theta={true_turn} measured_x=2.5 measured_y=0.0 "
            f"measured_theta={measured} pairs=500"
        )
    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        write_tum(out / "groundtruth.tum", truth[1:])
        write_tum(out / "trajectory-odometry.tum", est)
        (out / "run.log").write_text("\n".join(log) + "\n")
        est_rows, gt_rows, _, _ = heading_budget.paired(
            heading_budget.tum(str(out / "trajectory-odometry.tum")),
            heading_budget.tum(str(out / "groundtruth.tum")),
        )
        turns, straights = heading_budget.odometry_split(est_rows, gt_rows)
        check("one turn and two straights", len(turns) == 1 and len(straights) == 2,
              f"{len(turns)} and {len(straights)}")
        check(
            "the odometry's error through the turn",
            abs(sum(turns) - math.degrees(odo_turn)) < 1e-6,
            f"{sum(turns):.6f} against {math.degrees(odo_turn):.6f} deg",
        )
        check(
            "the odometry's error along the straights",
            abs(sum(straights) - math.degrees(odo_straight)) < 1e-6,
            f"{sum(straights):.6f} against {math.degrees(odo_straight):.6f} deg",
        )
        split = heading_budget.pull_split(
            heading_budget.tum(str(out / "trajectory-odometry.tum")),
            heading_budget.registrations(str(out / "run.log")),
        )
        for name, reg, pull, count in (
            ("straight", reg_straight, pull_straight, n - turn_len),
            ("turn", reg_turn, pull_turn, turn_len),
        ):
            r, p, k = split[name]
            check(
                f"{name}s: the registrations' error and the map's pull",
                abs(r - math.degrees(reg)) < 1e-6 and abs(p - math.degrees(pull)) < 1e-6 and k == count,
                f"{r:.6f} / {p:.6f} deg over {k} against {math.degrees(reg):.6f} / "
                f"{math.degrees(pull):.6f} over {count}",
            )
        turns = heading_budget.turn_sums(heading_budget.registrations(str(out / "run.log")))
        check(
            "one left turn, its registrations' error summed",
            len(turns) == 1
            and abs(turns[0][0] - math.pi / 2) < 1e-9
            and abs(turns[0][1] - 1e-3) < 1e-9
            and turns[0][2] == turn_len,
            f"{turns}",
        )
        rates = heading_budget.straight_rates(est_rows, gt_rows)
        check(
            "each straight's heading error rate (-20 urad per 2.5 m rotation)",
            len(rates) == 2 and all(abs(r[2] + 8e-6) < 1e-9 for r in rates),
            f"{rates}",
        )
        as_is, debiased, exact = heading_budget.straights_cost(est_rows, gt_rows)
        # The same drive with the straights' heading errors left out, built directly: each
        # rotation's step as the estimate made it (2.5 m along the heading it turned to, in
        # the frame of the heading before), its turn without the straights' error.
        clean = [(t0, 0.0, 0.0, 0.0)]
        for k in range(1, n + 1):
            turning = turn_start <= k < turn_start + turn_len
            padded = turn_start - pad <= k < turn_start + turn_len + pad
            est_turn = turn_step + 0.01 / turn_len if turning else (0.0 if padded else -20e-6)
            # The first rotation's error is the paired rows' start (not scored, kept).
            dh = est_turn if turning or k == 1 else 0.0
            t, x, y, h = clean[-1]
            fwd, side = 2.5 * math.cos(est_turn), 2.5 * math.sin(est_turn)
            c, s_ = math.cos(h), math.sin(h)
            clean.append((t0 + 0.25 * k, x + c * fwd - s_ * side, y + s_ * fwd + c * side, h + dh))
        # Its rows paired with the truth as the estimate's were (the start row has no partner).
        want = heading_budget.drift_percent(np.array(clean[1:]), gt_rows)
        check(
            "a bias each straight holds, taken out, leaves the straights exact",
            abs(debiased - exact) < 1e-9 and abs(exact - want) < 1e-9 and abs(as_is - exact) > 1e-3,
            f"{as_is:.4f} / {debiased:.4f} / {exact:.4f} % against {want:.4f}",
        )
        code = heading_budget.main(["heading_budget.py", str(out), str(out / "run.log")])
        check("the command runs on the files", code == 0, f"exit {code}")
        missing = heading_budget.main(["heading_budget.py", str(out / "none")])
        check("a directory without the files is refused", missing == 1, f"exit {missing}")
        (out / "bad").mkdir()
        (out / "bad" / "groundtruth.tum").write_text("1.0 2.0\n")
        (out / "bad" / "trajectory-odometry.tum").write_text("1.0 2.0 3.0\n")
        bad = heading_budget.main(["heading_budget.py", str(out / "bad")])
        check("a row that cannot be read is refused", bad == 1, f"exit {bad}")
        # A FIFO in a file's place is refused, not opened (opening would wait for a writer).
        (out / "fifo").mkdir()
        write_tum(out / "fifo" / "trajectory-odometry.tum", est)
        os.mkfifo(out / "fifo" / "groundtruth.tum")
        code = heading_budget.main(["heading_budget.py", str(out / "fifo")])
        check("a FIFO for a file is refused", code == 1, f"exit {code}")
        code = heading_budget.main(["heading_budget.py", str(out), str(out / "fifo")])
        check("a directory for the log is refused", code == 1, f"exit {code}")
        bound = heading_budget.MAX_TUM_BYTES
        heading_budget.MAX_TUM_BYTES = 1000
        try:
            code = heading_budget.main(["heading_budget.py", str(out)])
        finally:
            heading_budget.MAX_TUM_BYTES = bound
        check("a TUM file over its bound is refused", code == 1, f"exit {code}")
        # A line far longer than the longest read comes in pieces; the registrations after
        # it are all read.
        long_log = out / "long.log"
        long_log.write_text("x" * (3 * heading_budget.MAX_LINE_BYTES) + "\n" + "\n".join(log) + "\n")
        got = len(heading_budget.registrations(str(long_log)))
        check("a line over the longest read costs that line only", got == n, f"{got} of {n}")
    # The drift's definition on drives whose answer is known: 1,000 m straight, the estimate
    # 1 % long, or crabbing 5 mrad off its heading; 90 m is too short for a segment.
    line = np.array([(0.25 * k, 2.5 * k, 0.0, 0.0) for k in range(401)])
    long = line.copy()
    long[:, 1] *= 1.01
    crab = line.copy()
    crab[:, 1], crab[:, 2] = line[:, 1] * math.cos(0.005), line[:, 1] * math.sin(0.005)
    for name, est_rows, want in (
        ("1 % long", long, 1.0),
        ("crabbing 5 mrad", crab, 100.0 * 2.0 * math.sin(0.0025)),
    ):
        got = heading_budget.drift_percent(est_rows, line)
        check(f"drift over 100-800 m of a drive {name}", abs(got - want) < 1e-9, f"{got} against {want}")
    short = heading_budget.drift_percent(line[:37], line[:37])
    check("no segment on a drive of 90 m", math.isnan(short), f"{short}")
    # Chained errors: independent ones add up as N of them; a registration erring
    # d_k - d_{k-1} + w with the placement share s (var d = s, var w = 1 - 2 s) as
    # (2 s + N (1 - 2 s)) / N of them, and the longest span gives the share back.
    rng = np.random.default_rng(35)
    m, s = 100_000, 0.4
    white = rng.standard_normal(m)
    d = math.sqrt(s) * rng.standard_normal(m + 1)
    placed = d[1:] - d[:-1] + math.sqrt(1.0 - 2.0 * s) * white
    for name, errors, share in (("independent", white, 0.0), ("placed, share 0.4", placed, s)):
        ratios = heading_budget.long_run(errors)
        want = [(2 * share + n * (1 - 2 * share)) / n for n, _ in ratios]
        check(
            f"chained {name} errors add up as the model says",
            [n for n, _ in ratios] == list(heading_budget.LONG_RUN_SPANS)
            and all(abs(r - w) < 0.1 for (_, r), w in zip(ratios, want)),
            f"{ratios} against {[round(w, 3) for w in want]}",
        )
    few = heading_budget.long_run(white[:600])
    check("a span with too few sums is not reported", [n for n, _ in few] == [1, 4, 16, 64],
          f"{few}")
    check("no errors, no ratios", heading_budget.long_run([]) == [], "")
    finish()


if __name__ == "__main__":
    main()
