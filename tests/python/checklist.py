"""The Python checks' shared tally: `check` prints one line per check (`ok` or `FAIL`, its
name and detail) and records it in `results`; `finish` prints `N passed, M failed` and exits
1 on any failure."""

import sys

results = []


def check(name, ok, detail=""):
    results.append(bool(ok))
    print(f"{'ok  ' if ok else 'FAIL'} {name}{': ' + detail if detail else ''}")


def finish():
    failed = results.count(False)
    print(f"{len(results) - failed} passed, {failed} failed")
    sys.exit(1 if failed else 0)
