"""Every documented command marked runnable works as written, with small budgets.

A shell or Python block of ``README.md`` or ``docs/*.md`` is runnable when the line before its
fence is ``<!-- runnable -->``. Shell blocks run command by command (``\\`` continuations
joined, ``#`` comments dropped) in a temporary working directory, with ``localpbo`` and
``python`` taken from this interpreter's environment, paths of the repository made absolute,
``--budget N`` made small (four evaluations past the initial design) and ``--seeds`` cut to
the first seed; each must exit 0. A renamed or removed flag makes argparse exit 2, so the test
fails. Python blocks run with a tiny ``my_experiment``/``user_prefers`` and surrogate data,
``budget=N`` made small. Long commands (sweeps, ``make demo``, ``ros2 run`` with colcon, a
person judging) are left unmarked.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MARK = "<!-- runnable -->"
SMALL_BUDGET_PAST_DESIGN = 4
COMMAND_TIMEOUT_S = 300


@dataclass(frozen=True)
class Block:
    page: str
    line: int
    language: str
    text: str

    @property
    def id(self) -> str:
        return f"{self.page}:{self.line}"


def pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def runnable_blocks(path: Path) -> list[Block]:
    """The blocks of ``path`` whose fence follows the runnable mark."""
    lines = path.read_text().splitlines()
    blocks = []
    for i, line in enumerate(lines[:-1]):
        if line.strip() != MARK:
            continue
        fence = lines[i + 1].strip()
        if not fence.startswith("```"):
            raise AssertionError(f"{path.name}:{i + 1}: the mark is not followed by a fence")
        end = next(j for j in range(i + 2, len(lines)) if lines[j].strip() == "```")
        blocks.append(
            Block(
                page=str(path.relative_to(ROOT)),
                line=i + 2,
                language=fence[3:].strip(),
                text="\n".join(lines[i + 2 : end]),
            )
        )
    return blocks


ALL_BLOCKS = [b for p in pages() for b in runnable_blocks(p)]


def shell_commands(text: str) -> list[list[str]]:
    """The commands of a shell block as argument lists (continuations joined, comments gone)."""
    commands = []
    for line in text.replace("\\\n", " ").splitlines():
        words = shlex.split(line, comments=True)
        if words:
            commands.append(words)
    return commands


def _option(words: list[str], flag: str) -> str | None:
    return words[words.index(flag) + 1] if flag in words[:-1] else None


def small(words: list[str]) -> list[str]:
    """``words`` with a small budget and one seed."""
    words = list(words)
    if "--budget" in words[:-1]:
        design = _option(words, "--initial-design")
        base = int(design) if design is not None else 2
        words[words.index("--budget") + 1] = str(base + SMALL_BUDGET_PAST_DESIGN)
    seeds = _option(words, "--seeds")
    if seeds is not None:
        words[words.index("--seeds") + 1] = re.split(r"[-,]", seeds)[0]
    return words


def resolved(words: list[str]) -> list[str]:
    """The executable from this environment, repository paths absolute."""
    bindir = Path(sys.executable).parent
    head = {"localpbo": str(bindir / "localpbo"), "python": sys.executable}.get(words[0])
    out = [head or words[0]]
    for word in words[1:]:
        candidate = ROOT / word
        out.append(str(candidate) if "/" in word and candidate.exists() else word)
    return out


def test_the_pages_have_runnable_blocks() -> None:
    """The marks are found (README and the library page at least), so the test below cannot
    pass by finding nothing."""
    found = {b.page for b in ALL_BLOCKS}
    assert {"README.md", "docs/library.md"} <= found, found
    assert {b.language for b in ALL_BLOCKS} == {"bash", "python"}


def test_small_rewrites_budget_and_seeds() -> None:
    words = small(
        ["localpbo", "bench", "--seeds", "0-4", "--initial-design", "165", "--budget", "495"]
    )
    assert words == [
        "localpbo",
        "bench",
        "--seeds",
        "0",
        "--initial-design",
        "165",
        "--budget",
        "169",
    ]


@pytest.mark.parametrize(
    "block", [b for b in ALL_BLOCKS if b.language == "bash"], ids=lambda b: b.id
)
def test_shell_block_runs(block: Block, tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    for words in shell_commands(block.text):
        argv = resolved(small(words))
        proc = subprocess.run(
            argv,
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=COMMAND_TIMEOUT_S,
            check=False,
        )
        assert proc.returncode == 0, (
            f"{block.id}: {' '.join(words)} exited {proc.returncode}\n"
            f"stdout:\n{proc.stdout[-2000:]}\nstderr:\n{proc.stderr[-4000:]}"
        )


def _python_namespace() -> dict[str, object]:
    """What the library snippets leave to the reader: an experiment, a judge who remembers
    every value the snippet computed (``values`` of each ask), and a few duels as tensors."""
    import torch

    namespace: dict[str, object] = {}
    seen: dict[int, float] = {}

    def my_experiment(theta: object) -> float:
        return -float(np.sum((np.asarray(theta) - 0.3) ** 2))

    def user_prefers(a: int, b: int) -> bool:
        values = namespace["values"]
        assert isinstance(values, dict)
        seen.update(values)
        return seen[a] > seen[b]

    g = torch.Generator().manual_seed(0)
    X = torch.rand(8, 3, generator=g, dtype=torch.float64)
    f = -((X - 0.5) ** 2).sum(1)
    pairs = [(i, j) for i in range(8) for j in range(i + 1, 8) if (i + j) % 3 == 0]
    comparisons = torch.tensor([(i, j) if f[i] > f[j] else (j, i) for i, j in pairs])
    namespace.update(
        my_experiment=my_experiment,
        user_prefers=user_prefers,
        X=X,
        comparisons=comparisons,
        X2=torch.cat([X, torch.rand(1, 3, generator=g, dtype=torch.float64)]),
        comparisons2=torch.cat([comparisons, torch.tensor([[8, 0]])]),
        x=torch.rand(2, 3, generator=g, dtype=torch.float64),
        x2=torch.rand(2, 3, generator=g, dtype=torch.float64),
    )
    return namespace


@pytest.mark.parametrize(
    "block", [b for b in ALL_BLOCKS if b.language == "python"], ids=lambda b: b.id
)
def test_python_block_runs(block: Block) -> None:
    code = re.sub(r"\bbudget=\d+", "budget=12", block.text)
    exec(compile(code, block.id, "exec"), _python_namespace())


def test_a_renamed_flag_fails(tmp_path: Path) -> None:
    """The check itself: a documented command whose flag no longer exists fails the block."""
    block = Block(
        "made-up.md",
        1,
        "bash",
        "localpbo bench --problem hartmann6 --algorithm sobol --budgett 8 --out o",
    )
    with pytest.raises(AssertionError, match="unrecognized arguments: --budgett"):
        test_shell_block_runs(block, tmp_path)
