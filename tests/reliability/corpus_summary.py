"""Print the bad-input corpus's size and outcome counts (docs/reliability.md quotes them).

    PYTHONPATH=. python -m tests.reliability.corpus_summary

Runs every case of tests/reliability/test_bad_inputs.py and test_hostile_bounds.py (the resource and output-target
cases, each in a child under a 4 GB address-space limit; its slow-marked cases are counted, not run) through pytest
and counts the outcomes by exit code."""
from __future__ import annotations

import collections
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def main() -> int:
    from tests.reliability.test_bad_inputs import CASES, GENERATED
    from tests.reliability.test_hostile_bounds import CASES as BOUNDS

    here = REPO / "tests" / "reliability"
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "0", "-rN",
                        str(here / "test_bad_inputs.py"), str(here / "test_hostile_bounds.py")],
                       cwd=REPO, capture_output=True, text=True)
    tail = [ln for ln in r.stdout.splitlines() if ln.strip()][-1]
    first = lambda argv: (argv.split() if isinstance(argv, str) else argv)[0]  # noqa: E731
    by_cmd = (collections.Counter(first(c[1]) for c in CASES + BOUNDS)
              + collections.Counter(c[1][0] for c in GENERATED))
    slow = sum("slow" in c[6] for c in BOUNDS)
    print(f"bad-input corpus: {len(CASES)} hand-written cases + {len(BOUNDS)} resource and output-target cases "
          f"(under a 4 GB address-space limit; {slow} slow, not run here) + {len(GENERATED)} generated (one per "
          f"subcommand argument) = {len(CASES) + len(BOUNDS) + len(GENERATED)}")
    print("per subcommand: " + ", ".join(f"{k} {v}" for k, v in sorted(by_cmd.items())))
    print(f"pytest: {tail}")
    return r.returncode


if __name__ == "__main__":
    raise SystemExit(main())
