"""Run the README's shell blocks as written, in a fresh clone, and say which fail.

Every fenced ``bash`` block of README.md is run in order, each with ``bash -euo pipefail``, in a
clone of this repository's committed HEAD (so nothing uncommitted is tried and nothing is written
into this checkout). The clone sits next to this checkout (``../simgap-readme-check`` by default),
so the relative paths the README's set-up expects (``../shared``) hold there too. Each block's
seconds and exit status are printed; the exit code is the number of failing blocks.

    python scripts/readme_check.py                       # every block (the test suite included)
    python scripts/readme_check.py --skip scripts/test.sh   # leave out blocks containing a text
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^```bash\n(.*?)^```", re.S | re.M)


def blocks(markdown: str) -> list[str]:
    """The fenced ``bash`` blocks of a markdown text, in order."""
    return [m.group(1) for m in BLOCK.finditer(markdown)]


def main() -> int:
    """Clone, run every block, print a line per block; return the number of failures."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--clone", type=Path, default=REPO.parent / "simgap-readme-check")
    parser.add_argument("--skip", action="append", default=[], help="skip blocks containing TEXT")
    args = parser.parse_args()
    if args.clone.exists():
        shutil.rmtree(args.clone)
    subprocess.run(["git", "clone", "-q", str(REPO), str(args.clone)], check=True)
    failures = 0
    for number, block in enumerate(blocks((args.clone / "README.md").read_text()), start=1):
        first = block.strip().splitlines()[0]
        if any(text in block for text in args.skip):
            print(f"block {number}: skipped ({first})", flush=True)
            continue
        start = time.monotonic()
        done = subprocess.run(["bash", "-euo", "pipefail", "-c", block], cwd=args.clone)
        seconds = time.monotonic() - start
        status = "ok" if done.returncode == 0 else f"FAILED (exit {done.returncode})"
        print(f"block {number}: {status} in {seconds:.0f} s ({first})", flush=True)
        failures += done.returncode != 0
    return failures


if __name__ == "__main__":
    sys.exit(main())
