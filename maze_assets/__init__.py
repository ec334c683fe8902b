"""maze_assets: procedural textures and object models, and the example mazes (data)."""

from pathlib import Path

ASSETS_DIR = Path(__file__).resolve().parent
MAZES_DIR = ASSETS_DIR / "mazes"
SCENARIOS_DIR = ASSETS_DIR / "scenarios"
