"""The Python checks' shared tally: `check` prints one line per check (`ok` or `FAIL`, its
name and detail) and records it in `results`; `finish` prints `N passed, M failed` and exits
1 on any failure. `write_tum` writes made-up poses as the daemon writes its trajectories."""

import math
import sys

results = []


def check(name, ok, detail=""):
    results.append(bool(ok))
    print(f"{'ok  ' if ok else 'FAIL'} {name}{': ' + detail if detail else ''}")


def finish():
    failed = results.count(False)
    print(f"{len(results) - failed} passed, {failed} failed")
    sys.exit(1 if failed else 0)


def write_tum(path, rows):
    """Writes (time, x, y, heading) rows to `path` as a TUM trajectory (planar: z and the
    quaternion's x and y zero)."""
    with open(path, "w") as f:
        f.write("# timestamp x y z qx qy qz qw\n")
        for t, x, y, h in rows:
            f.write(f"{t:.6f} {x:.9f} {y:.9f} 0 0 0 {math.sin(h / 2):.12f} {math.cos(h / 2):.12f}\n")
