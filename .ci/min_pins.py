"""Print pip constraints that pin each core dependency to its lowest declared minor version.

    python .ci/min_pins.py [pyproject.toml]  ->  numpy==1.24.*  scipy==1.10.*  ...
    python .ci/min_pins.py --verify          ->  checks the installed versions match the pins

Read from ``[project] dependencies`` in pyproject.toml, so the minimum-versions CI pass cannot
drift from what the project declares. Every core dependency must carry a ``>=`` lower bound.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    tomllib = None


def core_dependencies(pyproject: Path) -> list[str]:
    text = pyproject.read_text(encoding="utf-8")
    if tomllib is not None:
        return list(tomllib.loads(text)["project"]["dependencies"])
    block = re.search(r"^dependencies\s*=\s*\[(.*?)^\]", text, re.S | re.M)
    return re.findall(r'"([^"]+)"', block.group(1)) if block else []


def min_pins(requirements: list[str]) -> list[str]:
    pins = []
    for req in requirements:
        match = re.fullmatch(r"\s*([A-Za-z0-9_.\-]+)\s*>=\s*(\d+)(?:\.(\d+))?[\d.]*\s*(?:,.*)?", req)
        if match is None:
            raise SystemExit(f"pyproject.toml: dependency {req!r} has no '>=' lower bound")
        name, major, minor = match.group(1), match.group(2), match.group(3) or "0"
        pins.append(f"{name}=={major}.{minor}.*")
    return pins


def verify(pins: list[str]) -> int:
    """Print the installed version of each pinned package; 1 if one does not match its pin."""
    from importlib.metadata import version

    bad = 0
    for pin in pins:
        name, wanted = pin.split("==")
        got = version(name)
        ok = got.split(".")[:2] == wanted.split(".")[:2]
        bad += not ok
        print(f"  {name} {got} ({'ok' if ok else 'expected ' + wanted})")
    return 1 if bad else 0


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--verify"]
    root = Path(__file__).resolve().parents[1]
    pins = min_pins(core_dependencies(Path(args[0]) if args else root / "pyproject.toml"))
    if "--verify" in sys.argv[1:]:
        raise SystemExit(verify(pins))
    print("\n".join(pins))
