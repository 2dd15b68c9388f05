"""MuJoCo models of gymnasium's v5 environments, loaded without gymnasium's env machinery.

The XML files are the ones gymnasium 1.4 ships for ``Hopper-v5`` (``hopper.xml``),
``Walker2d-v5`` (``walker2d_v5.xml``) and ``InvertedPendulum-v5``
(``inverted_pendulum.xml``); loading them from gymnasium's own asset folder guarantees that
the lean runner (``localpbo_sims.episode``) simulates exactly the same model.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium.envs.mujoco as _gym_mujoco
import mujoco

ASSET_DIR = Path(_gym_mujoco.__file__).resolve().parent / "assets"


def model_path(xml_file: str) -> Path:
    """Absolute path of one of gymnasium's MuJoCo asset files, e.g. ``"hopper.xml"``."""
    path = ASSET_DIR / xml_file
    if not path.is_file():
        raise ValueError(f"xml_file: no gymnasium MuJoCo asset named {xml_file!r} in {ASSET_DIR}")
    return path


def load_model(xml_file: str) -> mujoco.MjModel:
    """Compile one of gymnasium's MuJoCo asset files into an ``MjModel``."""
    return mujoco.MjModel.from_xml_path(str(model_path(xml_file)))
