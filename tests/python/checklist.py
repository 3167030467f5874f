"""The Python checks' shared tally: `check` prints one line per check (`ok` or `FAIL`, its
name and detail) and records it in `results`; `finish` prints `N passed, M failed` and exits
1 on any failure. `write_tum` writes made-up poses as the daemon writes its trajectories;
`run_script` runs an evaluation script and `check_refusals` checks that it refuses bad
input with exit 1 and a reason."""

import math
import os
import subprocess
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


def run_script(script, *args):
    """Runs `script` with `args` under this Python: (exit code, stdout and stderr)."""
    p = subprocess.run([sys.executable, script, *args], capture_output=True, text=True, timeout=60)
    return p.returncode, p.stdout + p.stderr


def check_refusals(script, d, truth, cases):
    """Checks that `script` exits 1 with a reason, not a traceback, on each of `cases`
    (name, arguments) and on the bad files every TUM reader must refuse in the first
    argument's place (made in the folder `d`; `truth` the second argument): a missing file,
    a directory, a FIFO, a row too short to read."""
    bad = os.path.join(d, "bad.tum")
    with open(bad, "w") as f:
        f.write("1000.0 1 2\n")
    fifo = os.path.join(d, "fifo.tum")
    os.mkfifo(fifo)
    files = [
        ("a missing file", (os.path.join(d, "none.tum"), truth)),
        ("a directory", (d, truth)),
        ("a FIFO", (fifo, truth)),
        ("an unreadable row", (bad, truth)),
    ]
    for name, args in files + list(cases):
        code, out = run_script(script, *args)
        first = out.strip().splitlines()[0] if out.strip() else ""
        check(f"refuses {name} with exit 1", code == 1 and "Traceback" not in out, first)
