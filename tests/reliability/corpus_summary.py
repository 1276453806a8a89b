"""Print the bad-input corpus's size and outcome counts (docs/reliability.md quotes them).

    PYTHONPATH=. python -m tests.reliability.corpus_summary

Runs every case of tests/reliability/test_bad_inputs.py through pytest and counts the outcomes by exit code."""
from __future__ import annotations

import collections
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def main() -> int:
    from tests.reliability.test_bad_inputs import CASES, GENERATED

    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rN",
                        str(REPO / "tests" / "reliability" / "test_bad_inputs.py")],
                       cwd=REPO, capture_output=True, text=True)
    tail = [ln for ln in r.stdout.splitlines() if ln.strip()][-1]
    by_cmd = collections.Counter(c[1].split()[0] for c in CASES) + collections.Counter(c[1][0] for c in GENERATED)
    print(f"bad-input corpus: {len(CASES)} hand-written cases + {len(GENERATED)} generated (one per subcommand "
          f"argument) = {len(CASES) + len(GENERATED)}")
    print("per subcommand: " + ", ".join(f"{k} {v}" for k, v in sorted(by_cmd.items())))
    print(f"pytest: {tail}")
    return r.returncode


if __name__ == "__main__":
    raise SystemExit(main())
