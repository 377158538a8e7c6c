"""Where the repository's data lives (the package is installed editable):
every path of the repository the package reads or writes starts here."""

from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
REPO_DIR = PACKAGE_DIR.parent
# The robot, hand and object descriptions, and the object catalogue.
SDF_DIR = REPO_DIR / "sdf"
MODELS_DIR = REPO_DIR / "models"
# Where a command writes the outputs it is not given a path for (its
# --out-dir overrides it): ignored by git, apart from the shipped models.
OUT_DIR = REPO_DIR / "out"
