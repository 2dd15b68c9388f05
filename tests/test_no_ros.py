"""The core never loads ROS, and importing it loads neither torch nor BoTorch."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

PROBE = """
import sys
{body}
heavy = sorted(m for m in ("rclpy", "torch", "botorch") if m in sys.modules)
print("loaded:" + ",".join(heavy))
"""


def loaded_after(body: str) -> set[str]:
    """Heavy modules in ``sys.modules`` after running ``body`` in a fresh interpreter."""
    out = subprocess.run(
        [sys.executable, "-c", PROBE.format(body=body)],
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    ).stdout.strip()
    last = out.splitlines()[-1]
    assert last.startswith("loaded:"), out
    return set(filter(None, last.removeprefix("loaded:").split(",")))


def test_import_localpbo_core_is_light() -> None:
    assert loaded_after("import localpbo_core") == set()
    assert loaded_after("from localpbo_core import make_optimizer, available_optimizers") == set()


def test_bench_help_and_top_level_help_do_not_load_ros() -> None:
    for argv in (["bench", "--help"], ["--help"], ["run", "--help"]):
        body = (
            "from localpbo_core.cli import main\n"
            f"try:\n    main({argv!r})\nexcept SystemExit:\n    pass"
        )
        assert "rclpy" not in loaded_after(body), argv


def test_a_bench_run_does_not_load_ros(tmp_path: Path) -> None:
    body = (
        "from localpbo_core.cli import main\n"
        f"main(['bench', '--problem', 'hartmann6', '--algorithm', 'sobol,turpbo', '--budget',"
        f" '8', '--no-progress', '--out', {str(tmp_path)!r}])"
    )
    loaded = loaded_after(body)
    assert "rclpy" not in loaded
    assert "torch" in loaded  # TuRPBO ran (the probe sees what a real run loads)
