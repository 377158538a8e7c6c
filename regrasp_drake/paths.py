"""Where the repository's data lives (the package is installed editable)."""

from pathlib import Path

REPO_DIR = Path(__file__).resolve().parents[1]
MODELS_DIR = REPO_DIR / "models"
