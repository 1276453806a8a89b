"""Print the bad-input corpus's size and outcome counts (docs/reliability.md quotes them).

    PYTHONPATH=. python -m tests.reliability.corpus_summary

Runs every case of the corpus files through pytest and counts them: test_bad_inputs.py (hand-written and generated
cases), test_hostile_parsing.py (storages, numbers, scheduler addresses, the issue's parsing cases; some in a child
under a memory limit), test_hostile_bundles.py (crafted surrogate bundles on verify and optimise) and
test_hostile_bounds.py (resource and output-target cases, each in a child under a 4 GB address-space limit; its
slow-marked cases are counted, not run)."""
from __future__ import annotations

import collections
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
FILES = ("test_bad_inputs.py", "test_hostile_parsing.py", "test_hostile_bundles.py", "test_hostile_bounds.py")


def main() -> int:
    from tests.reliability.test_bad_inputs import CASES, GENERATED
    from tests.reliability.test_hostile_bounds import CASES as BOUNDS
    from tests.reliability.test_hostile_bundles import BUNDLE_CASES, COMMANDS
    from tests.reliability.test_hostile_parsing import BOUNDED, CASES as HOSTILE

    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider", "-rN",
                        *(str(REPO / "tests" / "reliability" / f) for f in FILES)],
                       cwd=REPO, capture_output=True, text=True)
    tail = [ln for ln in r.stdout.splitlines() if ln.strip()][-1]
    first = lambda argv: (argv.split() if isinstance(argv, str) else argv)[0]  # noqa: E731
    hostile = [c[1] for c in HOSTILE] + [c[1] for c in BOUNDED] + [c for c in COMMANDS.values() for _ in BUNDLE_CASES] \
        + ["verify (inflating bundle)"]
    by_cmd = collections.Counter(first(c[1]) for c in CASES + BOUNDS) + collections.Counter(c[1][0] for c in GENERATED) \
        + collections.Counter(a.split()[0] for a in hostile)
    slow = sum("slow" in c[6] for c in BOUNDS)
    total = len(CASES) + len(GENERATED) + len(hostile) + len(BOUNDS)
    print(f"bad-input corpus: {len(CASES)} hand-written cases + {len(GENERATED)} generated (one per subcommand "
          f"argument) + {len(hostile)} hostile (storages, numbers, addresses, bundles; {len(BOUNDED) + 1} under a "
          f"memory limit) + {len(BOUNDS)} resource and output-target cases (under a 4 GB address-space limit; "
          f"{slow} slow, not run here) = {total}")
    print("per subcommand: " + ", ".join(f"{k} {v}" for k, v in sorted(by_cmd.items())))
    print(f"pytest: {tail}")
    return r.returncode


if __name__ == "__main__":
    raise SystemExit(main())
