"""Wall time of the README's two commands, each in a new virtual environment of a fresh copy of
the checkout, as a new user runs them (from the machine's warm package cache).

Each command is split at its last ``&&`` into the install part (venv + pip) and the job
(``usdscene run ...`` for the first, ``python -m pytest -q`` for the second); both are timed.

    python benchmarks/readme_commands.py [--only first|second]
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def readme_commands() -> list[str]:
    """The two ``bash`` blocks of the README's "Two commands" section, in order."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text.split("## Two commands", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```bash\n(.+?)\n```", section, flags=re.S)[:2]


def timed(command: str, cwd: Path) -> float:
    started = time.perf_counter()
    subprocess.run(["bash", "-c", command], cwd=cwd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=("first", "second"))
    args = parser.parse_args()
    for name, command in zip(("first", "second"), readme_commands()):
        if args.only and args.only != name:
            continue
        install, _, job = command.rpartition(" && ")
        with tempfile.TemporaryDirectory() as tmp:
            copy = Path(tmp) / "usdscene"
            # the repository as a clone would have it (tracked files only)
            files = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, check=True,
                                   capture_output=True).stdout.decode().split("\0")
            for relative in filter(None, files):
                (copy / relative).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(REPO / relative, copy / relative)
            install_s = timed(install, copy)
            job_s = timed(f". .venv/bin/activate && {job}", copy)
        print(f"{name} command: {install_s + job_s:.0f} s = install {install_s:.0f} s + `{job}` {job_s:.0f} s",
              flush=True)


if __name__ == "__main__":
    main()
