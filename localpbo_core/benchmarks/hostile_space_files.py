"""How long a refusal of a hostile space file takes, and how much memory it needs.

Each file is loaded with :func:`localpbo_core.space.load_space` in a fresh child process (so
its peak memory is its own); printed: the file's size, the wall time of the refusal, the
child's peak resident memory (``ru_maxrss``, imports included: about 32 MiB with numpy and
PyYAML) and the refusal's first 100 characters. Files: a billion-laughs alias bomb (9 levels
of 9 aliases, about 3.9e8 leaves once expanded) in ``description``, ``value_range`` and
``name``; a 10 MB file (one long description); a 1 MB description (just under the size
limit: parsed, then refused for its length, the message quoting it shortened); 500,000
nested ``[``; random bytes; ``/dev/zero``. The space loader before these limits ran the
description bomb for more than 60 s and past 3 GB of address space without an answer.
Run::

    python -m localpbo_core.benchmarks.hostile_space_files
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import json, resource, sys, time
from localpbo_core.space import load_space
from localpbo_core.validation import SettingError
start = time.perf_counter()
try:
    load_space(sys.argv[1])
    text = "accepted"
except SettingError as exc:
    text = f"{exc.field}: {exc.reason}"
seconds = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"s": seconds, "kib": peak, "text": text}))
"""


def alias_bomb(field: str, levels: int = 9) -> str:
    """A billion-laughs space file: ``field`` holds a list whose items define the anchors,
    level k being 9 aliases of level k - 1 (9**9 ≈ 3.9e8 leaves once expanded)."""
    items = ['&a0 "lol"'] + [
        f"&a{k} [" + ", ".join([f"*a{k - 1}"] * 9) + "]" for k in range(1, levels + 1)
    ]
    bomb = "[" + ", ".join(items) + "]"
    if field == "description":
        return f"parameters:\n  - {{name: kd, lower: 0, upper: 1, description: {bomb}}}\n"
    return f"{field}: {bomb}\nparameters:\n  - {{name: kd, lower: 0, upper: 1}}\n"


def files(folder: Path) -> dict[str, Path]:
    """The hostile files, written into ``folder``."""
    out: dict[str, Path] = {}
    for field in ("description", "value_range", "name"):
        out[f"alias bomb in {field}"] = folder / f"bomb_{field}.yaml"
        out[f"alias bomb in {field}"].write_text(alias_bomb(field))
    big = folder / "big.yaml"
    big.write_text(
        "parameters:\n  - {name: kd, lower: 0, upper: 1, description: '" + "x" * 10**7 + "'}\n"
    )
    out["10 MB file"] = big
    long = folder / "long.yaml"
    long.write_text(
        "parameters:\n  - {name: kd, lower: 0, upper: 1, description: '" + "y" * 10**6 + "'}\n"
    )
    out["1 MB description"] = long
    deep = folder / "deep.yaml"
    deep.write_text("parameters: " + "[" * 500_000)
    out["500,000 nested ["] = deep
    noise = folder / "random.bin"
    noise.write_bytes(os.urandom(100_000))
    out["random bytes"] = noise
    out["/dev/zero"] = Path("/dev/zero")
    return out


def main(argv: list[str] | None = None) -> None:
    """Print one row per hostile file."""
    argparse.ArgumentParser(
        prog="python -m localpbo_core.benchmarks.hostile_space_files",
        description="How long a refusal of a hostile space file takes, and how much memory it "
        "needs (prints one row per file).",
    ).parse_args(argv)
    print(f"{'file':<26} {'bytes':>10} {'refused in':>11} {'peak MiB':>10}  message")
    with tempfile.TemporaryDirectory() as tmp:
        for label, path in files(Path(tmp)).items():
            done = subprocess.run(
                [sys.executable, "-c", CHILD, str(path)],
                capture_output=True,
                text=True,
                timeout=600,
            )
            if done.returncode != 0:
                print(f"{label:<26} child failed: {done.stderr.strip()[-300:]}")
                continue
            row = json.loads(done.stdout)
            size = path.stat().st_size if path.is_file() else 0
            print(
                f"{label:<26} {size:>10} {row['s'] * 1e3:>8.1f} ms {row['kib'] / 1024:>10.1f}"
                f"  {row['text'].replace(tmp, '…')[:100]}"
            )


if __name__ == "__main__":
    main()
