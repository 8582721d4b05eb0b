"""Summarise a libFuzzer run's log in one line, and keep the figures as JSON.

    python fuzz/summary.py TARGET LOG     # prints the line, writes LOG's stem + .json

The figures: runs, seconds, executions per second, coverage (edges, features), corpus
size, and for a failed run what stopped it (the invariant, or the sanitizer's report).
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

_PROGRESS = re.compile(r"^#(\d+)\s+(\w+)\s+cov: (\d+) ft: (\d+) corp: (\d+)/(\S+)")
_STAT = re.compile(r"^stat::(\w+):\s+(\d+)")
_FAILURE = re.compile(
    r"(invariant failed at .*|ERROR: (AddressSanitizer|libFuzzer|UndefinedBehaviorSanitizer).*"
    r"|runtime error: .*|ALARM: working on the last Unit for .*)"
)


def summarise(target: str, text: str) -> dict[str, object]:
    info: dict[str, object] = {"target": target, "ok": True}
    for line in text.splitlines():
        m = _PROGRESS.match(line)
        if m:
            info.update(
                runs=int(m[1]), coverage_edges=int(m[3]), features=int(m[4]), corpus_units=int(m[5])
            )
            continue
        m = _STAT.match(line)
        if m:
            info[m[1]] = int(m[2])
            continue
        m = _FAILURE.search(line)
        if m and info["ok"]:
            info["ok"] = False
            info["failure"] = m[1].strip()
    m = re.search(r"Done (\d+) runs in (\d+) second", text)
    if m:
        info["runs"], info["seconds"] = int(m[1]), int(m[2])
    return info


def line(info: dict[str, object]) -> str:
    runs = info.get("runs", 0)
    rate = info.get("average_exec_per_sec", 0)
    text = (
        f"{info['target']}: {runs} runs in {info.get('seconds', '?')} s ({rate} exec/s), "
        f"coverage {info.get('coverage_edges', '?')} edges / {info.get('features', '?')} "
        f"features, corpus {info.get('corpus_units', '?')} inputs, "
        f"{info.get('new_units_added', 0)} new this run"
    )
    if not info["ok"]:
        text += f"; FAILED: {info['failure']}"
    return text


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: python fuzz/summary.py TARGET LOG", file=sys.stderr)
        return 2
    target, log = argv
    path = Path(log)
    info = summarise(target, path.read_text(errors="replace") if path.exists() else "")
    path.with_suffix(".json").write_text(json.dumps(info, indent=1) + "\n")
    print(line(info))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
