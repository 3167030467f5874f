#!/usr/bin/env python3
"""Where a drive's odometry heading error comes from: through the turns or along the
straights, from the registrations or from the map the filter fuses with them.

Usage: heading_budget.py OUT_DIR [LOG]

OUT_DIR is a run's output directory with `trajectory-odometry.tum` (the online pose without
the global layer's corrections) and `groundtruth.tum` (a simulated run, or a recording with
its ground truth). Each rotation's heading error change (estimate minus truth, from one row
to the next) is counted through a turn when the truth turned more than TURN_RAD in that
rotation or in one of the TURN_PAD rotations either side, along a straight otherwise; the
script prints each part's sum and the RMS of its change per stretch. Along each straight it
also gives the heading error's rate (its change over the straight's length, mrad per 100 m)
and what the straights cost the drift: the translation drift over 100-800 m segments (the
KITTI definition, as slam-filter's `drift` computes it) of the odometry as estimated, of the
odometry rebuilt from its own motions with each straight's mean heading error per rotation
taken out (a bias each street holds, as a scene's geometry can give one), and with the
straights' heading changes exact.

LOG, the same run's log written with
`RUST_LOG=info,slam_node::pipeline::radar_odometry=debug`, adds radar odometry's side: its
`radar odometry registration` lines carry each registration's measured and true motion over
the same interval. Over every registration the script splits the filter's heading change into
the registration's error (its measured turn minus the true one) and the rest, the map's pull
(the filter's turn over the interval minus the registration's): the point features' updates,
through the pose and through the mark's clone. A straight here is a registration whose true
turn is under STRAIGHT_RAD. It also gives each registration's heading error RMS along the
straights and turning, the registrations' error summed over each junction's turn (left and
right apart), and how the errors add up when chained: the variance of the sum of N
consecutive errors against N independent ones (the placement share's long run).

Reads files only; needs numpy. A file that is missing, not a regular file (a FIFO, a device, a
directory), over its size bound, or has no rows readable is refused with the reason and exit
1; Ctrl-C stops it with exit 130.
"""

import math
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ate_aligned import MAX_TUM_BYTES, paired, refused, travelled, tum  # noqa: E402

# A rotation turns (through a junction) when the truth turns more than this (rad).
TURN_RAD = math.radians(0.5)
# Rotations either side of a turning one counted with the turn (its onset and end).
TURN_PAD = 4
# A registration is along a straight when its true turn is under this (rad).
STRAIGHT_RAD = 0.002
# A run of turning registrations is a junction's turn when it turns at least this (rad).
TURN_MIN_RAD = math.radians(20.0)
# Spans (registrations) over which chained heading errors are summed (long_run).
LONG_RUN_SPANS = (1, 4, 16, 64, 256)
# A span is reported only with at least this many sums (overlapping) behind it.
LONG_RUN_MIN_SUMS = 500
# KITTI's segment lengths (m) and the frames between a segment's first frames.
SEGMENT_LENGTHS_M = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)
KITTI_STEP_FRAMES = 10
# The debug line radar odometry writes for every registration.
REGISTRATION = "radar odometry registration"
FIELD = re.compile(r"(\w+)=([-+\w.]+)")
# Largest log read (bytes); it is read a line at a time, each line at most MAX_LINE_BYTES.
MAX_LOG_BYTES = 4 << 30
MAX_LINE_BYTES = 64 << 10


def stretches(turning):
    """The runs of equal flags in `turning`: (start, end, flag), end exclusive."""
    out, start = [], 0
    for i in range(1, len(turning) + 1):
        if i == len(turning) or turning[i] != turning[start]:
            out.append((start, i, bool(turning[start])))
            start = i
    return out


def turning_rows(gt):
    """Whether each row's rotation is counted with a turn (see `odometry_split`)."""
    step = np.abs(np.diff(np.unwrap(gt[:, 3]), prepend=gt[0, 3]))
    return np.convolve((step > TURN_RAD).astype(float), np.ones(2 * TURN_PAD + 1), "same") > 0


def odometry_split(est, gt):
    """Heading error change through turns and along straights: (turns, straights), each a
    list of per-stretch changes (deg). `est` and `gt` are paired rows: the rotation into the
    first one (from the start row the truth lacks) is not scored."""
    err = np.degrees(np.unwrap(est[:, 3]) - np.unwrap(gt[:, 3]))
    turns, straights = [], []
    for start, end, flag in stretches(turning_rows(gt)):
        change = err[end - 1] - err[max(start - 1, 0)]
        (turns if flag else straights).append(change)
    return turns, straights


def straight_rates(est, gt):
    """Each straight's heading error rate: [(length m, error change rad, rate rad/m)], the
    straights of `odometry_split` with at least one rotation and some travel."""
    err = np.unwrap(est[:, 3]) - np.unwrap(gt[:, 3])
    travel = travelled(gt)
    out = []
    for start, end, flag in stretches(turning_rows(gt)):
        first = max(start - 1, 0)
        length = travel[end - 1] - travel[first]
        if not flag and end - 1 > first and length > 0.0:
            change = err[end - 1] - err[first]
            out.append((float(length), float(change), float(change / length)))
    return out


def drift_percent(est, gt):
    """Translation drift over 100-800 m segments (%): the KITTI definition (first frames every
    KITTI_STEP_FRAMES rows, each segment to the first row at least its length further along
    the truth), rows paired by index. NaN when the truth travels no more than 100 m."""
    travel = travelled(gt)

    def motion(rows, i, j):
        c, s = math.cos(rows[i, 3]), math.sin(rows[i, 3])
        dx, dy = rows[j, 1] - rows[i, 1], rows[j, 2] - rows[i, 2]
        return c * dx + s * dy, -s * dx + c * dy, rows[j, 3] - rows[i, 3]

    errors = []
    for first in range(0, len(gt), KITTI_STEP_FRAMES):
        for length in SEGMENT_LENGTHS_M:
            last = int(np.searchsorted(travel, travel[first] + length))
            if last >= len(gt):
                continue
            tx, ty, _ = motion(gt, first, last)
            ex, ey, eh = motion(est, first, last)
            # The estimated motion's inverse composed with the true one: its translation.
            c, s = math.cos(eh), math.sin(eh)
            dx, dy = tx - ex, ty - ey
            errors.append(math.hypot(c * dx + s * dy, -s * dx + c * dy) / length)
    return 100.0 * float(np.mean(errors)) if errors else float("nan")


def rebuilt(est, turn):
    """`est` rebuilt from its first row with its own motion between rows (in the frame of
    the row before) but the heading change `turn[k]` into row k+1."""
    h0 = est[:-1, 3]
    c, s = np.cos(h0), np.sin(h0)
    dx, dy = np.diff(est[:, 1]), np.diff(est[:, 2])
    fwd, side = c * dx + s * dy, -s * dx + c * dy
    heading = est[0, 3] + np.concatenate([[0.0], np.cumsum(turn)])
    c, s = np.cos(heading[:-1]), np.sin(heading[:-1])
    out = est.copy()
    out[:, 1] = est[0, 1] + np.concatenate([[0.0], np.cumsum(c * fwd - s * side)])
    out[:, 2] = est[0, 2] + np.concatenate([[0.0], np.cumsum(s * fwd + c * side)])
    out[:, 3] = heading
    return out


def straights_cost(est, gt):
    """The drift (%) of the odometry as estimated, with each straight's mean heading error
    per rotation taken out, and with the straights' heading changes exact."""
    turn = np.diff(np.unwrap(est[:, 3]))
    true = np.diff(np.unwrap(gt[:, 3]))
    # Row k+1's rotation is counted as that row is (see `odometry_split`).
    turning = turning_rows(gt)[1:]
    debiased, exact = turn.copy(), turn.copy()
    for start, end, flag in stretches(turning):
        if not flag:
            part = slice(start, end)
            debiased[part] -= np.mean(turn[part] - true[part])
            exact[part] = true[part]
    return (
        drift_percent(est, gt),
        drift_percent(rebuilt(est, debiased), gt),
        drift_percent(rebuilt(est, exact), gt),
    )


def registrations(log):
    """Each registration's (since_s, until_s, true turn, measured turn) from the debug lines."""
    rows = []
    with open(log, errors="replace") as f:
        while line := f.readline(MAX_LINE_BYTES):
            if REGISTRATION not in line:
                continue  # a line longer than MAX_LINE_BYTES comes in pieces: none of them is one
            g = dict(FIELD.findall(line))
            try:
                rows.append(
                    tuple(
                        float(g[k])
                        for k in ("since_s", "until_s", "truth_theta", "measured_theta")
                    )
                )
            except (KeyError, ValueError):
                continue  # no truth over this interval
    return np.array(rows).reshape(-1, 4)


def pull_split(est, reg):
    """Over the registrations whose interval both ends at a row of `est` (the whole estimate,
    its start row too, which the truth lacks): the registration's
    heading error and the map's pull, summed along straights and through turns (deg), and
    how many registrations each."""
    times = est[:, 0]
    heading = np.unwrap(est[:, 3])
    out = {"straight": [0.0, 0.0, 0], "turn": [0.0, 0.0, 0]}
    for since, until, true_turn, measured in reg:
        i = int(np.searchsorted(times, since - 1e-4))
        j = int(np.searchsorted(times, until - 1e-4))
        if j >= len(times) or abs(times[i] - since) > 1e-3 or abs(times[j] - until) > 1e-3:
            continue
        part = out["straight" if abs(true_turn) < STRAIGHT_RAD else "turn"]
        part[0] += measured - true_turn
        part[1] += (heading[j] - heading[i]) - measured
        part[2] += 1
    return {k: (math.degrees(a), math.degrees(b), n) for k, (a, b, n) in out.items()}


def turn_sums(reg):
    """Each turn's registrations (a run of registrations whose true turn is at least
    STRAIGHT_RAD, turning TURN_MIN_RAD or more in all): (true turn, the registrations'
    heading error summed over it, how many registrations), rad."""
    out = []
    for start, end, turning in stretches(np.abs(reg[:, 2]) >= STRAIGHT_RAD):
        true = float(reg[start:end, 2].sum())
        if turning and abs(true) >= TURN_MIN_RAD:
            out.append((true, float((reg[start:end, 3] - reg[start:end, 2]).sum()), end - start))
    return out


def long_run(errors):
    """How the registrations' heading errors add up when chained: for each span N (of
    LONG_RUN_SPANS, those with at least LONG_RUN_MIN_SUMS sums), the variance of the sum of
    N consecutive errors (their mean taken out) over N times one error's variance; 1 for
    independent errors. A registration erring `d_k - d_{k-1} + w` with the placement share
    `s` (slam-node's `[odometry] radar_odometry_placement_share`) gives
    `(2 s + N (1 - 2 s)) / N`, so the longest span's ratio `r` asks for the share
    `(1 - r) / 2`. [(N, ratio)]."""
    e = np.asarray(errors, dtype=float)
    if len(e) < 2:
        return []
    e = e - e.mean()
    one = e.var()
    if one <= 0.0:
        return []
    c = np.concatenate([[0.0], np.cumsum(e)])
    out = []
    for n in LONG_RUN_SPANS:
        if len(e) - n + 1 < LONG_RUN_MIN_SUMS:
            break
        sums = c[n:] - c[:-n]
        out.append((n, float(sums.var() / (n * one))))
    return out


def rms(values):
    return math.sqrt(sum(v * v for v in values) / len(values)) if len(values) else float("nan")


def main(argv):
    if len(argv) not in (2, 3):
        print(next(l for l in __doc__.splitlines() if l.startswith("Usage:")), file=sys.stderr)
        return 2
    out_dir = argv[1]
    paths = [os.path.join(out_dir, f) for f in ("trajectory-odometry.tum", "groundtruth.tum")]
    for p in paths:
        if not os.path.exists(p):
            print(f"{p}: missing (a run with ground truth writes it)", file=sys.stderr)
            return 1
        why = refused(p, MAX_TUM_BYTES)
        if why:
            print(f"{p}: {why}", file=sys.stderr)
            return 1
    try:
        whole = tum(paths[0])
        est, gt, _, _ = paired(whole, tum(paths[1]))
    except (ValueError, IndexError) as e:
        print(f"{out_dir}: a TUM row cannot be read ({e}): is the run still writing?", file=sys.stderr)
        return 1
    if len(est) < 2:
        print(f"{out_dir}: fewer than two rows with the truth at their time", file=sys.stderr)
        return 1
    turns, straights = odometry_split(est, gt)
    print(
        f"odometry heading error over {len(est)} rotations: through {len(turns)} turns "
        f"{sum(turns):+.2f} deg (per turn RMS {rms(turns):.2f}), along {len(straights)} "
        f"straights {sum(straights):+.2f} deg (per straight RMS {rms(straights):.2f})"
    )
    rates = straight_rates(est, gt)
    if rates:
        length = sum(r[0] for r in rates)
        per_100 = [1e5 * r[2] for r in rates]
        print(
            f"  along the straights ({length / 1000:.2f} km): the heading error's rate "
            f"{1e5 * sum(r[1] for r in rates) / length:+.2f} mrad per 100 m over them all, "
            f"per straight RMS {rms(per_100):.2f} (weighted alike)"
        )
    as_is, debiased, exact = straights_cost(est, gt)
    if not math.isnan(as_is):
        print(
            f"  drift over 100-800 m: {as_is:.3f} % as estimated; {debiased:.3f} % with each "
            f"straight's mean heading error per rotation taken out; {exact:.3f} % with the "
            f"straights' heading exact"
        )
    if len(argv) == 3:
        why = refused(argv[2], MAX_LOG_BYTES)
        if why:
            print(f"{argv[2]}: {why}", file=sys.stderr)
            return 1
        reg = registrations(argv[2])
        if len(reg) == 0:
            print(f"{argv[2]}: no '{REGISTRATION}' lines with the truth (run with "
                  "RUST_LOG=info,slam_node::pipeline::radar_odometry=debug)", file=sys.stderr)
            return 1
        split = pull_split(whole, reg)
        for name in ("straight", "turn"):
            r, p, n = split[name]
            print(
                f"  {name}s ({n} registrations): registrations' heading error {r:+.2f} deg "
                f"({1e6 * math.radians(r) / max(n, 1):+.1f} urad each), the map's pull "
                f"{p:+.2f} deg ({1e6 * math.radians(p) / max(n, 1):+.1f} urad each)"
            )
        errors = reg[:, 3] - reg[:, 2]
        along = np.abs(reg[:, 2]) < STRAIGHT_RAD
        print(
            f"  each registration's heading error, RMS: {1e3 * rms(errors[along]):.2f} mrad "
            f"along straights, {1e3 * rms(errors[~along]):.2f} mrad turning"
        )
        turns = turn_sums(reg)
        for name, sign in (("left", 1.0), ("right", -1.0)):
            sums = [s for s in turns if sign * s[0] > 0]
            if sums:
                errs = [math.degrees(s[1]) for s in sums]
                print(
                    f"  {name} turns ({len(sums)}, {sum(s[2] for s in sums) / len(sums):.1f} "
                    f"registrations each): the registrations' heading error summed over a "
                    f"turn {sum(errs) / len(errs):+.2f} deg on the mean, RMS {rms(errs):.2f} deg"
                )
        ratios = long_run(errors)
        if ratios:
            text = ", ".join(f"{n}: {r:.3f}" for n, r in ratios)
            share = (1.0 - ratios[-1][1]) / 2.0
            print(
                f"  chained, the heading errors' variance over N registrations against N "
                f"independent ones: {text} (the placement share that matches the longest "
                f"span: {share:.2f})"
            )
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        sys.exit(130)
