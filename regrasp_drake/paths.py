"""Where the repository's data lives (the package is installed editable)."""

from pathlib import Path

REPO_DIR = Path(__file__).resolve().parents[1]
MODELS_DIR = REPO_DIR / "models"
# Where a command writes the outputs it is not given a path for (its
# --out-dir overrides it): ignored by git, apart from the shipped models.
OUT_DIR = REPO_DIR / "out"
