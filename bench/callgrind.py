"""Instruction counts of whole commands (valgrind's callgrind, every thread): a cost that does not
move with the machine's load, where wall times on a shared 2-core VM move by 10 to 20 %. Used by
the benchmark scripts beside it."""

from __future__ import annotations

import re
import subprocess
import sys

COMMAND = ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null"]


def instructions(cmd: list[str], **kw) -> tuple[int, str]:
    """(instructions `cmd` executed, its stdout); exits with its stderr if it fails."""
    p = subprocess.run([*COMMAND, *cmd], capture_output=True, text=True, **kw)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed under callgrind ({p.returncode}):\n{p.stderr[-2000:]}")
    refs = re.search(r"I\s+refs:\s+([\d,]+)", p.stderr)
    if refs is None:
        sys.exit(f"no instruction count in valgrind's output:\n{p.stderr[-2000:]}")
    return int(refs.group(1).replace(",", "")), p.stdout
