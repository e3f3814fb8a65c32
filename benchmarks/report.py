"""What every benchmark table in ``docs/benchmarks/`` says about itself: the command, the date
and the machine (:func:`write_table`)."""

from __future__ import annotations

import os
import platform
import sys
from datetime import datetime, timezone
from pathlib import Path


def machine() -> str:
    """CPU model, cores, kernel and the load average now."""
    cpu = platform.processor() or "unknown CPU"
    info = Path("/proc/cpuinfo")
    if info.is_file():
        for line in info.read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, load {load}"


def command() -> str:
    """The command line that ran this benchmark, as typed from the repository root."""
    script = Path(sys.argv[0])
    try:
        script = script.resolve().relative_to(Path.cwd())
    except ValueError:
        pass
    return f"PYTHONPATH=src python {script} " + " ".join(sys.argv[1:])


def write_table(path: Path, title: str, lines: list[str], append: bool = False) -> None:
    """Write (or, with ``append``, add to) the markdown table ``lines`` under ``title`` with
    the command, the UTC date and the machine."""
    stamp = f"{datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC"
    block = [f"Command: `{command()}`", "", f"Date: {stamp}; machine: {machine()}.", ""]
    block += [*lines, ""]
    path.parent.mkdir(parents=True, exist_ok=True)
    if append and path.is_file():
        path.write_text(path.read_text().rstrip("\n") + "\n\n" + "\n".join(block))
    else:
        path.write_text("\n".join([f"# {title}", "", *block]))
